"""The delayed fit's speed goal (``scioc bench --parts fit_delayed``): judged only at the size it is for, and measured
on the path ``scioc fit --human-model delayed`` runs (ML start, whitening), not on ``scioc bench-fit``'s own study."""

import json

import pytest

from scioc.pipelines.bench.delayed_workflow import (
    FIT_DELAYED_GOAL_S,
    bench_angle_workflow,
    bench_delayed_workflow,
    format_angle_workflow,
    format_delayed_workflow,
    goal_text,
    within_goal,
)
from scioc.pipelines.cli import main
from scioc.pipelines.fit.warmup import PILOT_CHAINS


def test_the_goal_applies_to_the_full_size_fit_only():
    assert within_goal(84, 4, 1000, FIT_DELAYED_GOAL_S - 1) is True
    assert within_goal(84, 4, 1000, FIT_DELAYED_GOAL_S + 1) is False
    # 12 subjects, or fewer chains or draws, fast or slow: no verdict either way.
    for size in ((24, 4, 1000), (84, 2, 1000), (84, 4, 300)):
        assert within_goal(*size, 10.0) is None and within_goal(*size, 1e6) is None
    text = goal_text({"goal_s": FIT_DELAYED_GOAL_S, "within_goal": None})
    assert "not this size" in text and "met" not in text
    assert goal_text({"goal_s": FIT_DELAYED_GOAL_S, "within_goal": False}).endswith("NOT met")


@pytest.mark.validation
def test_the_workflow_benchmark_times_scioc_fits_own_path(tmp_path):
    """Two subjects of the kbl human: the fit is scioc fit's default (whitened, started at the ML estimates), its
    time is the sidecar's, and the numbers derived from it are consistent with the sampler's own. ``keep`` keeps
    the study, estimates and fit, and is not written into twice."""
    keep = tmp_path / "kept"
    res = bench_delayed_workflow(human="kbl", seed=3, chains=2, draws=30, tune=40, n_subjects=2, adequacy_boot=4,
                                 keep=keep)
    assert {p.name for p in keep.iterdir()} == {"data", "identify_delayed", "fit_delayed"}
    assert (keep / "fit_delayed" / "posterior.nc").is_file()
    with pytest.raises(ValueError, match="not empty"):
        bench_delayed_workflow(human="kbl", n_subjects=2, keep=keep)
    st, s, smp = res["settings"], res["seconds"], res["sampler"]
    assert (st["human"], st["segments"], st["subjects"], st["chains"], st["draws"], st["tune"]) == \
        ("kbl", 4, 2, 2, 30, 40)
    assert st["adaptation"] in ("diag (nutpie), per-subject whitened, curved along " + v
                                + ", measured again on a pilot run's draws"
                                for v in ("sigma_m", "sigma_m_signed", "rho_signed"))  # the default, forms by the data
    assert st["experiment"] == "data/examples/paper-torque-sensor/experiment.toml"
    assert 0 < st["delays"][0] <= st["delays"][1] <= 30  # the kbl human's delays are found, within the grid
    assert 0 < s["sample"] < s["fit"] and s["identify"] > 0
    # the pilot run (pipelines/fit/warmup.py: as long as the fit's own warm-up and draws allow) counts too
    [pilot] = smp["pilot"]
    assert (pilot["tune"], pilot["draws"], pilot["chains"]) == (40, 30, min(2, PILOT_CHAINS))
    assert pilot["steps_per_draw"] > 0
    assert smp["gradients"] == pytest.approx(2 * (40 * smp["warmup_steps_per_draw"] + 30 * smp["steps_per_draw"])
                                             + pilot["chains"] * 70 * pilot["steps_per_draw"])
    assert smp["ms_per_gradient_on_a_core"] == pytest.approx(1e3 * s["sample"] * st["cores"] / smp["gradients"])
    assert res["within_goal"] is None  # not the goal's size
    assert res["truth"]["beta"]["truth"] == -0.7 and set(res["truth"]["motor"]) == {"tau_nm", "sigma_m"}
    assert res["adequacy"]["segments"] == 4 and res["adequacy"]["verdict"] in ("pass", "fail")
    text = format_delayed_workflow(res)
    assert "kbl human" in text and "not this size" in text and "per-subject whitened" in text
    assert f"after a pilot of 40 + 30 draws on {pilot['chains']} chains" in text


def test_bench_refuses_an_unknown_human_and_a_kept_folder_in_use_before_any_work(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["bench", "--parts", "fit_delayed", "--humans", "maxent,robot"])
    assert e.value.code == 2 and "robot" in capsys.readouterr().err
    (tmp_path / "kbl").mkdir()
    (tmp_path / "kbl" / "old.txt").write_text("earlier run")
    argv = ["bench", "--parts", "fit_delayed", "--humans", "kbl", "--keep", str(tmp_path), "--json",
            str(tmp_path / "b.json")]
    assert main(argv) == 2
    assert "not empty" in capsys.readouterr().err and not (tmp_path / "b.json").exists()
    assert (tmp_path / "kbl" / "old.txt").read_text() == "earlier run"


@pytest.mark.validation
def test_the_angle_workflow_benchmark_fits_both_models_to_the_paper_designs_angles(tmp_path):
    """Two subjects of the kbl human on the paper's design (no torque sensor): the delayed fit scores the angles,
    the max-ent fit goes through the same likelihood, and neither goal is judged at this size."""
    keep = tmp_path / "kept"
    res = bench_angle_workflow(human="kbl", seed=3, chains=2, draws=30, tune=40, n_subjects=2, adequacy_boot=4,
                               keep=keep)
    assert {p.name for p in keep.iterdir()} == {"data", "identify_delayed", "fit_delayed", "fit_angles"}
    side = json.loads((keep / "fit_delayed" / "posterior.json").read_text())
    assert side["likelihood"] == "angles"
    assert res["settings"]["experiment"] == "the paper's design, angles only, true shift of log θ1 -0.7"
    assert res["settings"]["segments"] == 4
    m = res["maxent"]
    assert m["likelihood"] == "angles" and m["fit_s"] > 0 and m["adequacy"]["segments"] == 4
    assert res["goals"]["delayed_met"] is None and res["goals"]["maxent_met"] is None
    text = format_angle_workflow(res)
    assert "max-ent fit through the angle likelihood" in text and "not this size" in text
    assert "identification, below" in text


def test_the_angle_workflow_refuses_a_kept_folder_in_use_and_writes_its_own_report_section(tmp_path, capsys):
    from scioc.pipelines.bench.suite import DEFAULT_PARTS, report_section

    (tmp_path / "angles-kbl-0").mkdir()
    (tmp_path / "angles-kbl-0" / "old.txt").write_text("earlier run")
    argv = ["bench", "--parts", "fit_angles", "--humans", "kbl", "--keep", str(tmp_path)]
    assert main(argv) == 2
    assert "angles-kbl-0" in capsys.readouterr().err
    # make bench-angles keeps make bench's tables: each writes its own section of docs/validation.md
    assert report_section(DEFAULT_PARTS) == "speed"
    assert report_section(("delayed", "fit_angles")) == "speed-delayed-fit_angles"
