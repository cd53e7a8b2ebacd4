"""``scioc fit`` on another experiment: three levels with linear assistants, two trials per unit, 200 Hz,
another wheel, a torque sensor; and the summaries of more than two levels on their own."""

import json
import math
from pathlib import Path

import arviz as az
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from scioc.models.design import AssistantSpec, Design, WheelParameters
from scioc.pipelines.experiment import experiment_hash, load_experiment
from scioc.pipelines.fit import fit_to_dir, format_fit, mixedlm_check
from scioc.pipelines.fit.contrasts import contrasts, hdi
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.simulate import simulate_to_dir

LEVELS = ("none", "weak", "strong")
#: Small enough for a test (4 subjects × 3 levels × 2 trials of 2 s at 200 Hz); the numbers
#: are checked for consistency, not for quality.
DESIGN = Design(
    dt=0.005, wheel=WheelParameters(0.05, 1.5, 0.3), encoder_counts=0, levels=LEVELS, baseline="none",
    assistants=(("weak", AssistantSpec(kind="linear", gain=(2.0, 0.1), reference_gain=2.0)),
                ("strong", AssistantSpec(kind="linear", gain=(6.0, 0.3), reference_gain=6.0))),
    run_seconds=6.0, subjects=4, trials=2, torque_sensor=True, effects=(-0.3, -0.8),
    window_start=2.0, window_seconds=2.0, preview=1.0)
FIT = {"seed": 5, "chains": 2, "draws": 30, "tune": 60}


@pytest.fixture(scope="module")
def three_level_fit(tmp_path_factory):
    """Simulated, identified and fitted in the layout of ``scioc run``, the experiment read back from its file."""
    root = tmp_path_factory.mktemp("levels") / "study"
    sim = simulate_to_dir(root / "data", seed=21, design=DESIGN)
    design = load_experiment(sim["experiment"])
    settings = IdentifySettings.for_design(design, adequacy_boot=9)
    identify_to_dir(sim["study"], root / "identify", settings, show_progress=False, experiment_file=sim["experiment"])
    paths = fit_to_dir(sim["study"], root / "fit", settings=settings, experiment_file=sim["experiment"], **FIT)
    return root, sim, design, settings, paths


@pytest.mark.validation
def test_three_level_fit_with_trials(three_level_fit):
    root, sim, design, settings, paths = three_level_fit
    fit = root / "fit"
    idata = az.from_netcdf(paths["posterior"])
    post = idata["posterior"]
    assert post["beta"].dims == ("chain", "draw", "contrast") and list(post["contrast"].values) == ["weak", "strong"]
    assert post["log_theta1"].dims == ("chain", "draw", "subject", "condition")
    assert list(post["condition"].values) == list(LEVELS)
    # Trials are segments of their unit: 4 × 3 × 2 segments, labelled with the trial.
    obs = idata["observed_data"]["u_H"]
    assert obs.sizes["segment"] == 24 and "S01/weak/2" in obs["segment"].values
    assert list(idata["constant_data"]["trial"].values[:2]) == ["1", "2"]

    side = json.loads((fit / "posterior.json").read_text())
    assert side["experiment_file"] == sim["experiment"] and side["experiment_sha256"] == experiment_hash(design)
    assert side["experiment"]["conditions"]["levels"] == list(LEVELS)
    assert side["identify_settings"] == json.loads(json.dumps(settings.as_dict()))
    # The prior on log R at 200 Hz: the 100-Hz centre + log(0.5).
    assert side["priors"]["mu_log_R"][0] == pytest.approx(3.0 + math.log(0.5))
    pop = side["diagnostics"]["condition"]["population"]
    assert {"beta[weak]", "beta[strong]", "sigma_beta[strong]", "sigma_beta_log_R[weak]", "mu_log_R"} <= set(pop)
    assert "beta" not in pop and "beta_log_R[strong]" in side["diagnostics"]["pooled"]["population"]

    res = json.loads((fit / "contrasts.json").read_text())
    assert res["baseline"] == "none" and res["levels"] == list(LEVELS) and "beta" not in res
    assert set(res["contrasts"]) == {"weak", "strong"}
    for level, c in res["contrasts"].items():
        beta = post["beta"].sel(contrast=level).values.ravel()
        assert c["beta"]["mean"] == pytest.approx(beta.mean(), rel=1e-12) and c["beta"]["hdi"] == hdi(beta)
        assert c["beta"]["p_negative"] == pytest.approx((beta < 0).mean())
        assert {"ratio", "sigma_beta", "beta_log_R", "subjects_with_hdi_below_zero"} <= set(c)
        assert [s["subject"] for s in c["subjects"]] == ["S01", "S02", "S03", "S04"]
        change = (post["log_theta1"].sel(condition=level) - post["log_theta1"].sel(condition="none")).sel(subject="S02")
        assert c["subjects"][1]["hdi"] == hdi(change.values)
    assert res["loo"]["condition"]["pareto_k"]["n"] == 24
    assert res["loo_subject"]["difference"]["n"] == 4
    # The mixed model: one coefficient per non-baseline level, one value per unit.
    mm = res["mixedlm"]
    assert set(mm["coefficients"]) == {"weak", "strong"} and mm["n_obs"] == 12 and mm["baseline"] == "none"
    # The truth: one θ per unit though truth.parquet repeats it per trial; the effects per level.
    truth = pd.read_parquet(sim["truth"])
    assert "trial" in truth.columns
    assert (truth[["delay_s", "tau_nm", "motor_sd"]] == 0.0).all().all()  # the paper's agent: no delay, lag, noise
    tr = res["truth"]
    side = json.loads((fit / "posterior.json").read_text())
    # The truth, found from the fit folder (relative paths: a run stages its folders, then moves them).
    assert tr["source"] == side["truth_relative"]
    assert (fit / tr["source"]).resolve() == Path(sim["truth"]).parent.resolve()
    assert {lv: tr["contrasts"][lv]["beta"]["truth"] for lv in ("weak", "strong")} == {"weak": -0.3, "strong": -0.8}
    assert tr["contrasts"]["strong"]["subjects"]["n"] == 4
    assert tr["population"]["mu_log_R"]["truth"] == pytest.approx(math.log(20.0) + math.log(0.5))
    assert set(tr["ml_log_error"]) == {*LEVELS, "weak_minus_none", "strong_minus_none"}
    # Adequacy at the posterior θ: the trials of a unit are combined, one p per unit.
    adq = res["adequacy"]
    assert adq["verdict"] in ("pass", "fail") and adq["segments"] == 12
    # The predictive bands of one subject: every level and trial.
    ppc = pd.read_parquet(fit / "ppc.parquet")
    K = round(design.window_seconds / design.dt)
    assert res["ppc"]["subject"] == "S03" and len(ppc) == 3 * 2 * (K + 1)
    assert set(zip(ppc.condition, ppc.trial)) == {(lv, t) for lv in LEVELS for t in ("1", "2")}
    assert set(res["ppc"]["coverage_5_95"]) == set(LEVELS) and "in weak, strong:" in res["ppc"]["note"]
    assert set(idata["posterior_predictive"]["segment"].values) == {f"S03/{lv}/{t}" for lv in LEVELS for t in "12"}

    text = format_fit(fit)
    assert "weak against none" in text and "strong against none" in text and "true beta (strong) -0.8" in text


@pytest.mark.validation
def test_two_level_sidecar_names_the_built_in_study(small_fit):
    """Without an experiment file the sidecar records the paper's study and no file."""
    root, _, _ = small_fit
    side = json.loads((root / "fit" / "posterior.json").read_text())
    assert side["experiment_file"] is None and side["experiment"]["conditions"]["levels"] == ["MC", "SC"]
    assert side["priors"]["mu_log_R"] == [3.0, 1.0] and "design" not in side["identify_settings"]
    assert "contrasts" not in json.loads((root / "fit" / "contrasts.json").read_text())
    assert "beta (mean SC change of log theta1)" in format_fit(root / "fit")


def _posterior(rng, levels=LEVELS, n_subjects=3):
    C = len(levels) - 1
    beta = rng.normal([-0.3, -0.8][:C], 0.05, (2, 200, C))
    lt1 = rng.normal(3.0, 0.1, (2, 200, n_subjects, len(levels)))
    lt1[..., 1:] += beta[:, :, None, :]
    subjects = [f"S{i}" for i in range(1, n_subjects + 1)]
    return xr.Dataset({"beta": (("chain", "draw", "contrast"), beta),
                       "sigma_beta": (("chain", "draw", "contrast"), np.abs(beta) / 7),
                       "beta_log_R": (("chain", "draw", "contrast"), beta / 10),
                       "log_theta1": (("chain", "draw", "subject", "condition"), lt1)},
                      coords={"subject": subjects, "condition": list(levels), "contrast": list(levels[1:])})


def test_contrasts_of_three_levels_have_one_block_per_non_baseline_level():
    post = _posterior(np.random.default_rng(2))
    res = contrasts({"posterior": post})
    assert res["baseline"] == "none" and list(res["contrasts"]) == ["weak", "strong"]
    for level in ("weak", "strong"):
        beta = post["beta"].sel(contrast=level).values
        block = res["contrasts"][level]
        assert block["beta"]["hdi"] == hdi(beta) and block["ratio"]["hdi"] == hdi(np.exp(beta))
        d = (post["log_theta1"].sel(condition=level) - post["log_theta1"].sel(condition="none")).sel(subject="S3")
        assert block["subjects"][2]["hdi"] == hdi(d.values)


def test_mixedlm_of_three_balanced_levels_gives_the_mean_differences():
    """Closed form: with every subject once in every level, the REML fixed effect of a level is
    the mean difference of log θ1 from the baseline (the design is balanced, so GLS is OLS)."""
    rng = np.random.default_rng(8)
    n = 30
    a = rng.normal(3.0, 0.5, n)
    d = rng.normal([-0.3, -0.8], 0.2, (n, 2))
    lt = np.column_stack([a, a + d[:, 0], a + d[:, 1]])
    est = pd.DataFrame({"subject": np.repeat([f"S{i}" for i in range(n)], 3), "condition": list(LEVELS) * n,
                        "theta1": np.exp(lt.ravel())})
    mm = mixedlm_check(est, LEVELS)
    for j, level in enumerate(("weak", "strong")):
        # The optimizer stops at a tolerance of its own: agreement to 1e-6 relative.
        assert mm["coefficients"][level]["coef"] == pytest.approx(d[:, j].mean(), rel=1e-6)
    assert mm["n_obs"] == 3 * n
    with pytest.raises(ValueError, match="one estimate per subject × condition"):
        mixedlm_check(pd.concat([est, est.iloc[:1]]), LEVELS)


def test_the_log_theta1_form_follows_how_tightly_the_data_pin_each_unit():
    import pandas as pd

    from scioc.models.bayes.hierarchical import Parameterization
    from scioc.pipelines.fit.stage import CENTRED_SE_LOG_THETA1, choose_parameterization

    assert choose_parameterization(None)[0] == Parameterization()
    loose = pd.DataFrame({"se_log_theta1": [0.2, 0.3, 0.4]})  # like the default study cut to 3-s windows
    assert choose_parameterization(loose)[0] == Parameterization()
    for tight in ([0.015, 0.02, 0.06], [0.04, 0.062, 0.09]):  # the example's three 12-s trials; the default study
        form, reason = choose_parameterization(pd.DataFrame({"se_log_theta1": tight}))
        assert (form.theta1_mc, form.theta1_sc) == ("centred", "centred") and str(CENTRED_SE_LOG_THETA1) in reason
    edge = pd.DataFrame({"se_log_theta1": [CENTRED_SE_LOG_THETA1 * 1.01] * 3})
    assert choose_parameterization(edge)[0] == Parameterization()
