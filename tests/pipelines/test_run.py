"""End-to-end: the whole workflow on a small simulated study, through the CLI."""

import json
from dataclasses import replace
from html import unescape
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scioc.models.design import STUDY
from scioc.pipelines.cli import main
from scioc.pipelines.identify import identify_study
from scioc.pipelines.io import StudyFileError, load_study
from scioc.pipelines.prepare import IdentifySettings


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    # The Bayesian fit has its own end-to-end test (tests/pipelines/test_fit.py).
    assert main(["run", "--out", str(out), "--subjects", "6", "--seed", "11", "--skip-fit"]) == 0
    return out / "default-study"


def test_run_writes_every_artifact_and_the_report(small_run):
    for rel in ("data/study.parquet", "data/truth.parquet", "data/simulation.json", "identify/estimates.parquet",
                "identify/trajectories.parquet", "identify/validation.parquet", "identify_true_torque/estimates.parquet",
                "compare.json", "index.html"):
        assert (small_run / rel).exists(), rel
    html = (small_run / "index.html").read_text()
    assert html.count("data:image/png;base64,") >= 5  # self-contained: figures embedded
    assert "Wilcoxon" in html and "Fig. 6" in html and "reconstruct" in html
    assert "http://" not in html and "https://" not in html  # opens offline


def test_study_table_has_only_what_a_lab_records(small_run):
    study = pd.read_parquet(small_run / "data" / "study.parquet")
    assert list(study.columns) == ["subject", "condition", "t", "angle", "angle_ref", "u_A"]
    load_study(small_run / "data" / "study.parquet")  # valid in the data convention


def test_estimates_are_sane(small_run):
    est = pd.read_parquet(small_run / "identify" / "estimates.parquet")
    assert len(est) == 12 and est.converged.all() and est.reconstructed.all()
    cmp = json.loads((small_run / "compare.json").read_text())
    assert cmp["theta1"]["n_pairs"] == 6 and cmp["theta1"]["w_minus"] > cmp["theta1"]["w_plus"]


def test_same_seed_same_results(small_run, tmp_path):
    assert main(["simulate", "--subjects", "6", "--seed", "11", "--out", str(tmp_path / "data")]) == 0
    a = pd.read_parquet(small_run / "data" / "study.parquet")
    b = pd.read_parquet(tmp_path / "data" / "study.parquet")
    pd.testing.assert_frame_equal(a, b, check_exact=True)
    assert main(["identify", str(tmp_path / "data" / "study.parquet"), "--out", str(tmp_path / "id")]) == 0
    ea = pd.read_parquet(small_run / "identify" / "estimates.parquet")
    eb = pd.read_parquet(tmp_path / "id" / "estimates.parquet")
    pd.testing.assert_frame_equal(ea, eb, check_exact=True)


def test_report_command_rebuilds_from_artifacts(small_run, capsys):
    assert main(["report", str(small_run), "--subject", "S01"]) == 0
    assert "index.html" in capsys.readouterr().out


def test_compare_command(small_run, capsys, tmp_path):
    out = tmp_path / "cmp.json"
    assert main(["compare", str(small_run / "identify" / "estimates.parquet"), "--out", str(out)]) == 0
    assert "theta1" in capsys.readouterr().out and out.exists()


def test_window_outside_the_recording_is_a_clear_error(small_run):
    study = load_study(small_run / "data" / "study.parquet")
    with pytest.raises(StudyFileError, match="does not contain the window") as info:
        identify_study(study, IdentifySettings(window_start=235.0, window_seconds=15.0), show_progress=False)
    assert "column 't'" in str(info.value)


def test_whole_run_and_other_windows(small_run):
    study = load_study(small_run / "data" / "study.parquet")
    sub = type(study)(study.path, study.segments[:2])
    est, *_ = identify_study(sub, IdentifySettings(window_start=60.0, window_seconds=20.0), show_progress=False)
    assert (est.K == 2000).all() and (est.window_start == 60.0).all()
    est, *_ = identify_study(sub, IdentifySettings(window_start=None, window_seconds=None), show_progress=False)
    assert (est.K == 24000).all() and (est.preview == 0).all() and est.converged.all()
    assert np.all(est.se_log_theta1 < 0.05)  # 4 minutes identify θ1 to a few percent


def test_bad_simulate_options_exit_nonzero(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:  # a usage error, found by the parser
        main(["simulate", "--subjects", "0", "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "subjects" in capsys.readouterr().err


def test_outputs_are_refused_or_replaced_whole(tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["simulate", "--subjects", "1", "--run-seconds", "35", "--out", str(data)]) == 0
    first = (data / "study.parquet").read_bytes()
    # An existing output folder is refused without --force ...
    assert main(["simulate", "--subjects", "1", "--run-seconds", "35", "--seed", "5", "--out", str(data)]) == 2
    assert "--force" in capsys.readouterr().err and (data / "study.parquet").read_bytes() == first
    # ... an input inside the output folder is never replaced, even with --force ...
    assert main(["identify", str(data / "study.parquet"), "--out", str(data), "--force", "--window", "20,10"]) == 2
    assert "input" in capsys.readouterr().err and (data / "study.parquet").read_bytes() == first
    # ... and a folder replaced with --force holds the new run's files only.
    ident = tmp_path / "id"
    ident.mkdir()
    (ident / "compare.json").write_text("{}")
    assert main(["identify", str(data / "study.parquet"), "--out", str(ident), "--window", "20,10"]) == 2
    assert main(["identify", str(data / "study.parquet"), "--out", str(ident), "--window", "20,10",
                 "--force"]) == 0
    assert sorted(p.name for p in ident.iterdir()) == ["estimates.parquet", "identify.json", "trajectories.parquet",
                                                       "validation.parquet"]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temporary folder left


def test_run_reconstructs_every_segment_once_for_identify_and_fit(tmp_path, monkeypatch):
    """``scioc run`` prepares the study once and hands the same prepared segments to identify and to the fit."""
    import scioc.pipelines.fit
    import scioc.pipelines.prepare
    from scioc.pipelines.run import run_all

    calls, seen = [], {}
    real = scioc.pipelines.prepare.reconstruct
    monkeypatch.setattr(scioc.pipelines.prepare, "reconstruct", lambda *a, **k: calls.append(1) or real(*a, **k))

    def fake_fit(study_path, out, *, prepared=None, **kwargs):  # stands in for minutes of sampling
        seen["prepared"] = prepared

    monkeypatch.setattr(scioc.pipelines.fit, "fit_to_dir", fake_fit)
    run_all(tmp_path, n_subjects=2, seed=5, fit=True, settings=IdentifySettings(adequacy_boot=0),
            human_models=("maxent",))
    assert len(calls) == 4  # 2 subjects × MC and SC, from the angle; the true-torque runs need none
    assert [p.data.subject for p in seen["prepared"].segments] == ["S01", "S01", "S02", "S02"]


def test_a_run_of_the_models_own_human_has_the_maxent_artifacts_only_and_says_why(small_run):
    """The built-in study's max-ent human passes the max-ent model's adequacy checks: the run stops at that model."""
    assert sorted(p.name for p in small_run.iterdir()) == [
        "compare.json", "data", "identify", "identify_true_torque", "identify_true_torque_exogenous", "index.html",
        "run.json"]
    assert json.loads((small_run / "run.json").read_text())["human_models"] == ["maxent"]
    html = (small_run / "index.html").read_text()
    assert "<h2 id='human-models'>Human models</h2>" in html and "Only the max-ent human model" in html
    assert "The max-ent human model passes its adequacy checks, so the delayed human model was not run" in html


#: A study with a torque sensor small enough for the delayed model's identification: 8-s runs, 4-s windows.
SENSOR = replace(STUDY, torque_sensor=True, run_seconds=8.0, window_start=2.0, window_seconds=4.0, preview=1.0)


def test_a_run_with_a_torque_sensor_adds_the_delayed_model(tmp_path, monkeypatch, capsys):
    """Both models when the max-ent model's adequacy fails (the kbl human: delay, lag, motor noise); the delayed
    stages share the prepared study; fits and LOSO stand in here."""
    import scioc.pipelines.fit
    import scioc.pipelines.fit.human_models
    import scioc.pipelines.prepare
    from scioc.pipelines.run import run_all, run_verdicts

    calls, seen = [], {}
    real = scioc.pipelines.prepare.reconstruct
    monkeypatch.setattr(scioc.pipelines.prepare, "reconstruct", lambda *a, **k: calls.append(1) or real(*a, **k))

    def fake_fit(study_path, out, *, prepared=None, settings=None, **kwargs):  # stands in for minutes of sampling
        seen[Path(out).name] = (prepared, settings.human_model)

    def fake_compare(maxent_dir, delayed_dir, *, prepared=None, seed=None, out=None, relative_to=None):
        # written into the run folder, naming the fits relative to it (the folder is staged and renamed)
        seen["human_models"] = (Path(maxent_dir).name, Path(delayed_dir).name,
                                Path(out) == Path(maxent_dir).parent == Path(relative_to))
        return {"difference": {"elpd_diff": 1.0, "se": 1.0, "z": 1.0, "reliable": True, "n": 2,
                               "n_preferring_delayed": 1, "preferred": "delayed"}}

    monkeypatch.setattr(scioc.pipelines.fit, "fit_to_dir", fake_fit)
    monkeypatch.setattr(scioc.pipelines.fit.human_models, "compare_human_models", fake_compare)
    root = run_all(tmp_path, n_subjects=2, seed=5, design=SENSOR, human="kbl",  # 39: 4 segments can fail at 1 %
                   settings=IdentifySettings.for_design(SENSOR, adequacy_boot=39)).parent
    log = capsys.readouterr().out
    assert "human models: maxent, delayed: the max-ent human model's adequacy verdict is 'fail'" in log
    assert json.loads((root / "run.json").read_text()) == {
        "human_models": ["maxent", "delayed"], "requested": None,
        "why": "the max-ent human model's adequacy verdict is 'fail', so the delayed human model was run beside it"}
    for stage in ("[1/10] simulating", "[5/10] identifying again with the delayed human model",
                  "[6/10] Wilcoxon matched-pairs tests of the delayed model's estimates", "[7/10] hierarchical",
                  "[8/10] hierarchical Bayesian fit of the delayed human model", "[9/10] leave-one-subject-out",
                  "[10/10] writing the report"):
        assert stage in log, stage
    assert len(calls) == 0  # a torque sensor: nothing reconstructed, once or twice
    assert seen["fit"][1] == "maxent" and seen["fit_delayed"][1] == "delayed"
    assert seen["fit_delayed"][0].segments is seen["fit"][0].segments  # the one prepared study
    assert seen["human_models"] == ("fit", "fit_delayed", True)
    for rel in ("identify_delayed/estimates.parquet", "identify_delayed/identify.json", "compare_delayed.json"):
        assert (root / rel).exists(), rel
    assert json.loads((root / "identify_delayed" / "identify.json").read_text())["human_model"] == "delayed"
    assert set(run_verdicts(root)) == {"maxent", "delayed"}
    html = unescape((root / "index.html").read_text())
    assert "delayed human" in html and "Which human model the data support" in html


#: The same without a torque sensor (the paper's rig).
ANGLES = replace(SENSOR, torque_sensor=False)


def test_a_run_without_a_torque_sensor_compares_the_two_models_on_the_angles(tmp_path, monkeypatch, capsys):
    """The kbl human on the paper's rig: the max-ent model fails its adequacy checks, so the delayed model is identified
    from the encoder's angles and fitted to them, the max-ent model too (beside its fit of the reconstructed
    torques), and leave-one-subject-out compares the two fits of the angles; fits and LOSO stand in here."""
    import scioc.pipelines.fit
    import scioc.pipelines.fit.human_models
    from scioc.pipelines.report.human_models import ANGLE_FIT, ANGLE_ONLY
    from scioc.pipelines.run import run_all

    seen = {}

    def fake_fit(study_path, out, *, settings=None, likelihood=None, **kwargs):  # stands in for minutes of sampling
        seen[Path(out).name] = (settings.human_model, likelihood)

    def fake_compare(maxent_dir, delayed_dir, *, prepared=None, seed=None, out=None, relative_to=None):
        seen["human_models"] = (Path(maxent_dir).name, Path(delayed_dir).name)
        return {"difference": {"elpd_diff": 1.0, "se": 1.0, "z": 1.0, "reliable": True, "n": 2,
                               "n_preferring_delayed": 1, "preferred": "delayed"}}

    monkeypatch.setattr(scioc.pipelines.fit, "fit_to_dir", fake_fit)
    monkeypatch.setattr(scioc.pipelines.fit.human_models, "compare_human_models", fake_compare)
    root = run_all(tmp_path, n_subjects=2, seed=5, design=ANGLES, human="kbl",
                   settings=IdentifySettings.for_design(ANGLES, adequacy_boot=39)).parent
    log = capsys.readouterr().out
    assert f"human models: maxent, delayed: the max-ent human model's adequacy verdict is 'fail', so the delayed " \
           f"human model was run beside it; {ANGLE_ONLY}" in log
    for stage in ("[5/11] identifying again with the delayed human model", "[6/11] Wilcoxon matched-pairs tests of "
                  "the delayed model's estimates", "[7/11] hierarchical", "[8/11] hierarchical Bayesian fit of the "
                  "max-ent human model to the encoder's angles", "[9/11] hierarchical Bayesian fit of the delayed",
                  "[10/11] leave-one-subject-out", "[11/11] writing the report"):
        assert stage in log, stage
    assert seen == {"fit": ("maxent", None), ANGLE_FIT: ("maxent", "angles"), "fit_delayed": ("delayed", None),
                    "human_models": (ANGLE_FIT, "fit_delayed")}
    est = pd.read_parquet(root / "identify_delayed" / "estimates.parquet")
    assert set(est.likelihood) == {"angles"} and (root / "compare_delayed.json").exists()


def test_run_with_maxent_only_on_a_torque_sensor_says_delayed_was_not_requested(tmp_path, capsys):
    from scioc.pipelines.run import run_all

    root = run_all(tmp_path, n_subjects=2, seed=5, design=SENSOR, fit=False, human_models=("maxent",),
                   settings=IdentifySettings.for_design(SENSOR, adequacy_boot=0)).parent
    assert "[1/5] simulating" in capsys.readouterr().out and not (root / "identify_delayed").exists()
    assert "The delayed human model was not requested" in unescape((root / "index.html").read_text())


def test_by_default_a_maxent_model_that_fits_is_not_joined_by_the_delayed_one(tmp_path, capsys):
    """The max-ent human with a torque sensor: its model passes adequacy, so the run stops at it and says why."""
    from scioc.pipelines.run import run_all

    root = run_all(tmp_path, n_subjects=2, seed=5, design=SENSOR, fit=False,
                   settings=IdentifySettings.for_design(SENSOR, adequacy_boot=39)).parent
    log = capsys.readouterr().out
    assert "human models: maxent: the max-ent human model passes its adequacy checks" in log
    assert "[1/7] simulating" in log and "[5/7] identify delayed: not needed" in log  # counted, then said unneeded
    assert "[7/7] writing the report" in log
    assert not (root / "identify_delayed").exists()
    run = json.loads((root / "run.json").read_text())
    assert run["human_models"] == ["maxent"] and run["requested"] is None
    html = unescape((root / "index.html").read_text())
    assert "The max-ent human model passes its adequacy checks, so the delayed human model was not run" in html


def test_analyse_compares_the_torque_fits_where_the_torques_are_recorded(tmp_path, monkeypatch, capsys):
    """Recorded torques decide, not the experiment's ``torque_sensor``: a lab's export with u_H whose experiment does
    not say it has a sensor gets no fit of the angles, and the comparison reads the two torque fits."""
    import scioc.pipelines.fit
    import scioc.pipelines.fit.human_models
    from scioc.pipelines.run import analyse_to_dir
    from scioc.pipelines.simulate import simulate_to_dir

    sim = simulate_to_dir(tmp_path / "data", n_subjects=2, seed=5, human="kbl", design=SENSOR)
    exp = Path(sim["experiment"])
    exp.write_text(exp.read_text().replace("torque_sensor = true", "torque_sensor = false"))
    seen = {}
    monkeypatch.setattr(scioc.pipelines.fit, "fit_to_dir",
                        lambda study, out, *, likelihood=None, **kw: seen.__setitem__(Path(out).name, likelihood))
    monkeypatch.setattr(scioc.pipelines.fit.human_models, "compare_human_models",
                        lambda a, b, **kw: seen.__setitem__("human_models", (Path(a).name, Path(b).name)) or
                        {"difference": {"elpd_diff": 1.0, "se": 1.0, "z": 1.0, "reliable": True, "n": 2,
                                        "n_preferring_delayed": 1, "preferred": "delayed"}})
    analyse_to_dir(sim["study"], tmp_path / "run", human_models=("maxent", "delayed"))
    assert seen == {"fit": None, "fit_delayed": None, "human_models": ("fit", "fit_delayed")}
    assert "[7/8] leave-one-subject-out" in capsys.readouterr().out
