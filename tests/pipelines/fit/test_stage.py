"""``scioc fit`` end to end on a small simulated study: artifacts, sidecar, contrasts, seeds,
the diagnostics notebook and the design errors."""

import json
import re
from pathlib import Path

import arviz as az
import numpy as np
import pandas as pd
import pytest

from scioc.models.adequacy import STATISTICS
from scioc.pipelines import cli
from scioc.pipelines.fit import ESS_MIN, RHAT_MAX, fit_to_dir
from scioc.pipelines.simulate import simulate_to_dir
from scioc.pipelines.storage import write_table_atomic
from tests.pipelines.conftest import N_SUBJECTS, SMALL

NOTEBOOK = Path(__file__).resolve().parents[3] / "reports" / "notebooks" / "posterior_diagnostics.py"


def _cli_main(argv):
    """The ``scioc`` command line, as a newcomer calls it."""
    return cli.main(argv)


@pytest.mark.validation
def test_fit_writes_posteriors_sidecar_and_contrasts(small_fit):
    root, _, paths = small_fit
    fit = root / "fit"
    assert set(paths) == {"posterior", "posterior_pooled", "ppc", "sidecar", "contrasts"}
    idata = az.from_netcdf(fit / "posterior.nc")
    pooled = az.from_netcdf(fit / "posterior_pooled.nc")
    for d in (idata, pooled):
        assert {"posterior", "sample_stats", "log_likelihood", "observed_data"} <= set(d.children)
        ll = d["log_likelihood"]["u_H"]
        assert ll.dims == ("chain", "draw", "segment") and ll.shape == (2, 100, 2 * N_SUBJECTS)
    assert "beta" in idata["posterior"] and "beta" not in pooled["posterior"]
    # One DataTree with the predictive draws and the data the likelihood conditions on, dims matching.
    assert {"posterior_predictive", "constant_data"} <= set(idata.children)
    obs, pp, const = idata["observed_data"]["u_H"], idata["posterior_predictive"]["u_H"], idata["constant_data"]
    assert pp.dims == ("chain", "draw") + obs.dims and (pp["step"].values == obs["step"].values).all()
    assert set(pp["segment"].values) == {"S03/MC", "S03/SC"} <= set(obs["segment"].values)
    assert list(const["segment"].values) == list(obs["segment"].values)
    assert const["u_A"].dims == obs.dims and const["x0"].sizes["state"] == 2
    lt1 = pooled["posterior"]["log_theta1"]
    np.testing.assert_array_equal(lt1.sel(condition="MC").values, lt1.sel(condition="SC").values)

    side = json.loads((fit / "posterior.json").read_text())
    assert {"seed", "seeds", "sampler", "identify_settings", "criteria", "diagnostics", "convergence_verdict", "seconds",
            "versions", "inputs"} <= set(side)
    assert side["seed"] == SMALL["seed"] and side["sampler"]["draws"] == 100 and side["sampler"]["chains"] == 2
    assert side["versions"]["nutpie"] and side["versions"]["pymc"]
    for name in ("condition", "pooled"):
        d = side["diagnostics"][name]
        assert {"divergences", "ebfmi", "max_tree_depth", "mean_steps_per_draw"} <= set(d["sampler"])
        assert len(d["sampler"]["ebfmi"]) == 2
        pop = d["population"]
        assert {"mu_log_theta1", "sigma_log_theta1", "mu_log_R", "tau_theta2"} <= set(pop)
        assert ("beta" in pop) == (name == "condition")
        # The verdict is exactly the three criteria applied to the numbers beside it.
        expected = (d["sampler"]["divergences"] == 0
                    and all(p["rhat"] <= RHAT_MAX for p in pop.values())
                    and all(min(p["ess_bulk"], p["ess_tail"]) >= ESS_MIN for p in pop.values()))
        assert d["passed"] == expected
        assert side["convergence_verdict"][name] == d["convergence_verdict"] and d["convergence_verdict"].startswith("pass" if expected else "fail")
        assert side["seconds"][name]["sample_s"] > 0
    # 2 × 100 draws cannot give 400 effective draws: this fit must fail its verdict.
    assert not side["diagnostics"]["condition"]["passed"]

    res = json.loads((fit / "contrasts.json").read_text())
    beta = idata["posterior"]["beta"].values.ravel()
    b = res["beta"]
    assert b["mean"] == pytest.approx(beta.mean(), rel=1e-12)
    assert b["p_negative"] == pytest.approx((beta < 0).mean())
    assert b["hdi"][0] < b["mean"] < b["hdi"][1]
    # At least 94 % of the draws (rounded up) lie in the HDI.
    assert ((beta >= b["hdi"][0]) & (beta <= b["hdi"][1])).sum() >= int(np.ceil(0.94 * beta.size))
    assert np.exp(b["hdi"][0]) <= res["ratio"]["median"] <= np.exp(b["hdi"][1])
    assert [s["subject"] for s in res["subjects"]] == [f"S{i:02d}" for i in range(1, N_SUBJECTS + 1)]
    loo = res["loo"]
    assert loo["condition"]["pareto_k"]["n"] == 2 * N_SUBJECTS
    assert loo["difference"]["elpd_diff"] == pytest.approx(loo["condition"]["elpd_loo"] - loo["pooled"]["elpd_loo"])
    assert isinstance(loo["difference"]["reliable"], bool)
    ls = res["loo_subject"]
    for name in ("condition", "pooled"):
        assert ls[name]["pareto_k"]["n"] == N_SUBJECTS and ls[name]["is_ess_min"] > 1.0
    assert ls["difference"]["elpd_diff"] == pytest.approx(ls["condition"]["elpd_loo"] - ls["pooled"]["elpd_loo"])
    assert ls["difference"]["n"] == N_SUBJECTS
    mm = res["mixedlm"]
    assert mm["ci95"][0] < mm["coef"] < mm["ci95"][1] and 0 <= mm["p_value"] <= 1 and mm["n_obs"] == 2 * N_SUBJECTS
    tr = res["truth"]
    assert tr["beta"]["truth"] == -0.7
    assert tr["beta"]["in_hdi"] == (b["hdi"][0] <= -0.7 <= b["hdi"][1])
    assert tr["subjects"]["n"] == N_SUBJECTS

    adq = res["adequacy"]
    assert adq["verdict"] in ("pass", "fail") and adq["segments"] == 2 * N_SUBJECTS
    assert set(adq["combined_p"]) == set(STATISTICS) and "posterior" in adq["theta"]

    ppc = pd.read_parquet(fit / "ppc.parquet")
    assert res["ppc"]["subject"] == "S03" and set(ppc.subject) == {"S03"}
    assert sorted(ppc.condition.unique()) == ["MC", "SC"] and len(ppc) == 2 * 1501
    u = ppc.dropna(subset=["u_H_q05"])
    assert len(u) == 2 * 1500
    assert (u.u_H_q05 <= u.u_H_q50).all() and (u.u_H_q50 <= u.u_H_q95).all()
    assert (ppc.angle_q05 <= ppc.angle_q95).all()
    # The stored bands are the quantiles of the stored draws.
    draws = idata["posterior_predictive"]["u_H"].sel(segment="S03/SC").values.reshape(-1, 1500)
    np.testing.assert_allclose(u[u.condition == "SC"].u_H_q95.to_numpy(), np.quantile(draws, 0.95, axis=0))


@pytest.mark.validation
def test_same_seed_same_results(small_fit, tmp_path):
    """The fit from the study file equals the fit from the study prepared once for identify and fit (scioc run)."""
    root, sim, _ = small_fit
    fit_to_dir(sim["study"], tmp_path / "again", **SMALL)
    a, b = az.from_netcdf(root / "fit" / "posterior.nc"), az.from_netcdf(tmp_path / "again" / "posterior.nc")
    for v in ("beta", "log_theta1", "log_R", "theta2"):
        np.testing.assert_array_equal(a["posterior"][v].values, b["posterior"][v].values)
    np.testing.assert_array_equal(a["log_likelihood"]["u_H"].values, b["log_likelihood"]["u_H"].values)
    ca, cb = (json.loads((d / "contrasts.json").read_text()) for d in (root / "fit", tmp_path / "again"))
    # The truth's source is written relative to its own fit folder, and these two folders sit in
    # different places: the paths differ, the folder they name must not.
    sa, sb = ca["truth"].pop("source"), cb["truth"].pop("source")
    assert (root / "fit" / sa).resolve() == (tmp_path / "again" / sb).resolve() == Path(sim["study"]).parent.resolve()
    assert ca == cb
    pd.testing.assert_frame_equal(pd.read_parquet(root / "fit" / "ppc.parquet"),
                                  pd.read_parquet(tmp_path / "again" / "ppc.parquet"))
    for group in ("posterior_predictive", "constant_data"):
        assert a[group].to_dataset().identical(b[group].to_dataset()), group


@pytest.mark.validation
def test_diagnostics_notebook_runs_on_the_fit(small_fit, tmp_path, monkeypatch):
    import jupytext
    from ipykernel.kernelspec import write_kernel_spec
    from nbclient import NotebookClient

    root, _, _ = small_fit
    # A kernel spec for this very interpreter, whatever the machine has installed.
    write_kernel_spec(tmp_path / "kernels" / "scioc-test", overrides={"display_name": "scioc test"})
    monkeypatch.setenv("JUPYTER_PATH", str(tmp_path))
    monkeypatch.setenv("SCIOC_RUN", str(root))
    nb = jupytext.read(NOTEBOOK)
    NotebookClient(nb, kernel_name="scioc-test", timeout=300, resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if o.output_type == "display_data" and "image/png" in o.get("data", {})]
    # trace, rank, energy, pair, two forests, the predictive draws, k-hat and the comparison
    assert len(images) == 9
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    assert "elpd_loo" in text and "beta" in text


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    root = tmp_path_factory.mktemp("bad")
    sim = simulate_to_dir(root / "data", n_subjects=3, seed=12)
    return pd.read_parquet(sim["study"]), root


@pytest.mark.parametrize("drop, message", [
    (lambda t: (t.subject == "S02") & (t.condition == "SC"), r"subject 'S02' has no SC segment"),
    (lambda t: t.condition == "SC", r"no SC segments at all"),
], ids=["one-subject-without-SC", "no-SC-at-all"])
def test_bad_design_is_a_clear_cli_error(tiny_study, drop, message, capsys):
    table, root = tiny_study
    path = write_table_atomic(table[~drop(table)], root / "bad.parquet")
    out = root / "out"
    with pytest.raises(ValueError, match=message):
        fit_to_dir(path, out, chains=1, draws=25, tune=10)
    assert _cli_main(["fit", str(path), "--out", str(out), "--draws", "10", "--tune", "10"]) == 3  # bad input data
    err = capsys.readouterr().err
    assert err.startswith("scioc fit: error:") and re.search(message, err)
    assert not out.exists()


def test_fit_options_are_validated(tiny_study):
    table, root = tiny_study
    with pytest.raises(ValueError, match="--draws must be an integer >= 1"):
        fit_to_dir(root / "data" / "study.parquet", root / "x", draws=0)
    with pytest.raises(ValueError, match="--chains × --draws must be at least 25"):
        fit_to_dir(root / "data" / "study.parquet", root / "x", chains=1, draws=20)
    with pytest.raises(ValueError, match="--subject 'S99' is not in the study"):
        fit_to_dir(root / "data" / "study.parquet", root / "x", subject="S99", draws=10)
    with pytest.raises(ValueError, match="unknown key.*adaptation for the maxent human model's fit"):
        fit_to_dir(root / "data" / "study.parquet", root / "x", human_model="maxent",
                   sampler_options={"adaptation": "diag"})
    with pytest.raises(ValueError, match="adequacy_at must be one of draw, means"):
        fit_to_dir(root / "data" / "study.parquet", root / "x", sampler_options={"adequacy_at": "mode"})
    for bad in (0.0, 1.0, 1.5):
        with pytest.raises(ValueError, match="--target-accept must lie between 0 and 1"):
            fit_to_dir(root / "data" / "study.parquet", root / "x", target_accept=bad)
    assert not (root / "x").exists()


@pytest.mark.validation
def test_ctrl_c_stops_the_fit_and_leaves_the_old_folder(tiny_study, tmp_path):
    """SIGINT while sampling: exit 130 within seconds, the previous results untouched, no temporary folder."""
    import os
    import signal
    import subprocess
    import sys
    import time

    _, root = tiny_study
    out = tmp_path / "fit"
    out.mkdir()
    (out / "contrasts.json").write_text('{"old": true}')
    cmd = [sys.executable, "-m", "scioc.pipelines.cli", "fit", str(root / "data" / "study.parquet"), "--out", str(out),
           "--force", "--draws", "200000", "--tune", "200", "--chains", "2"]
    # PYTHONFAULTHANDLER: if it does not stop, SIGABRT makes it print where every thread is.
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONFAULTHANDLER": "1"})
    time.sleep(25)  # well into compiling or sampling: 200000 draws take far longer
    assert proc.poll() is None, proc.communicate()
    t0 = time.perf_counter()
    proc.send_signal(signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        pytest.fail("still running 60 s after SIGINT; its threads:\n" + proc.communicate(timeout=60)[1][-8000:])
    assert proc.returncode == 130, err[-2000:]
    assert time.perf_counter() - t0 < 30
    assert "interrupted" in err
    assert [p.name for p in out.iterdir()] == ["contrasts.json"] and "old" in (out / "contrasts.json").read_text()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_the_sidecar_names_a_curved_whitenings_pivots_with_their_subjects_where_there_are_several():
    from types import SimpleNamespace

    from scioc.pipelines.human_model import get

    def sampler_record(model, delay, nutpie, whitening):
        outcome = SimpleNamespace(sidecar={"nutpie_options": nutpie, **({"whitening": whitening} if whitening is not
                                                                          None else {})})
        return get(model).sampler_record(SimpleNamespace(options={"delay": delay}), outcome)

    record = sampler_record("delayed", "profile", {"adaptation": "diag"},
                            {"curved_along": {"rho_signed": 30, "sigma_m_signed": 12}})
    assert record["adaptation"] == ("diag (nutpie), per-subject whitened, curved along rho_signed (30 subjects), "
                                    "sigma_m_signed (12 subjects)")
    one = sampler_record("delayed", "profile", {"adaptation": "diag"}, {"curved_along": {"sigma_m": 42}})
    assert one["adaptation"] == "diag (nutpie), per-subject whitened, curved along sigma_m"
    assert sampler_record("delayed", "profile", {"adaptation": "diag"}, {})["adaptation"] == (
        "diag (nutpie), per-subject whitened")


def test_the_plan_names_each_choice_and_its_reason_and_writes_nothing(tiny_study, capsys, monkeypatch):
    from scioc.pipelines.cli import main

    _, root = tiny_study
    study = root / "data" / "study.parquet"
    before = sorted(root.rglob("*"))
    assert main(["fit", str(study), "--plan", "--tune", "321"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("plan of the maxent fit (nothing sampled):")
    assert "  tune: 321  (given)" in out and "  target accept: 0.8  (nutpie's default)" in out
    assert "  parameterization: theta1_mc " in out and "median SE of log θ1 per unit" in out
    assert "  likelihood: torques  (the human model's default for these recordings)" in out
    assert sorted(root.rglob("*")) == before
    # from inside the study's folder, where an output folder "." would hold the study: a plan writes nothing
    monkeypatch.chdir(study.parent)
    assert main(["fit", study.name, "--plan", "--likelihood", "angles"]) == 0
    out = capsys.readouterr().out
    assert "  likelihood: angles  (given)" in out and "  models: condition effects  (" in out
    assert sorted(root.rglob("*")) == before
