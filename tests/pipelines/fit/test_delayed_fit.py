"""``scioc fit`` with the ``delayed`` human end to end: the sidecar records the human model and every unit's delay,
delays come from the estimates or from the profile, the max-ent fit of the same study is as before, and the two fits
compare by leave-one-subject-out."""

import json
from dataclasses import replace

import arviz as az
import numpy as np
import pandas as pd
import pytest
import xarray as xr

from scioc.models.bayes.delayed_blocks import SIGNED_FORMS, motor_coordinate
from scioc.models.bayes.delayed_model import (
    PILOT_ADAPTATION_TARGET_ACCEPT,
    WHITENED_TARGET_ACCEPT,
    DelayedForm,
)
from scioc.models.design import STUDY
from scioc.models.plant import discretize
from scioc.pipelines.fit import fit_to_dir, format_fit
from scioc.pipelines.fit.delayed import unit_delays
from scioc.pipelines.fit.delayed_forms import CENTRED_Z, choose_delayed_form, log_R_form, rho_pinned
from scioc.pipelines.fit.human_models import compare_human_models, format_human_models
from scioc.pipelines.fit.warmup import PILOT_CHAINS, PILOT_MAX_TREE_DEPTH, PILOT_RUNS, PILOT_TARGET_ACCEPT
from scioc.pipelines.fit.whiten import nutpie_setting
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.io import load_study
from scioc.pipelines.lineage import file_sha256
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.simulate import simulate_to_dir

#: Small fits: the samplers are not meant to converge (numbers are checked for consistency).
TINY = {"seed": 5, "chains": 2, "draws": 60, "tune": 100}
#: The paper's design with a torque sensor: the hierarchical delayed model is that of recorded torques.
SENSOR = replace(STUDY, torque_sensor=True)
#: Few adequacy replicates: the verdict's path is exercised, its power is not the point here.
SETTINGS = IdentifySettings.for_design(SENSOR, human_model="delayed", adequacy_boot=4)


@pytest.fixture(scope="module")
def delayed_study(tmp_path_factory):
    """3 subjects of the ``kbl`` human (each its own delay and lag), identified with the delayed model."""
    root = tmp_path_factory.mktemp("delayed") / "study"
    sim = simulate_to_dir(root / "data", n_subjects=3, seed=13, human="kbl", design=SENSOR)
    prepared = prepare_study(load_study(sim["study"], SENSOR), SETTINGS)
    identify_to_dir(sim["study"], root / "identify", SETTINGS, show_progress=False, prepared=prepared)
    return root, sim, prepared


@pytest.fixture(scope="module")
def delayed_fit(delayed_study):
    root, sim, prepared = delayed_study
    paths = fit_to_dir(sim["study"], root / "fit_delayed", settings=SETTINGS, prepared=prepared, **TINY)
    return paths


@pytest.mark.validation
def test_sidecar_records_the_human_model_and_the_delays(delayed_study, delayed_fit):
    root, _, prepared = delayed_study
    side = json.loads(open(delayed_fit["sidecar"]).read())
    assert side["human_model"] == "delayed"
    assert side["start"].startswith("the chains start near the ML estimates")  # the fit's own profile's, no --estimates
    # the kbl human's estimates leave some subject's R loose: the population of R is the policy scale's
    assert side["delayed_priors"]["R_population"] == "policy_scale"
    assert side["R_population_reason"].startswith("policy_scale: the estimates leave the R of")
    # the population scales held at their units' spread, each below its prior's scale (PyMC's initial point)
    assert set(side["start_scales"]) == {"sigma_log_theta1", "sigma_beta", "rho_scale", "sigma_beta_log_R",
                                         "tau_theta2", "tau_nm_scale", "sigma_m_scale_sq"}
    assert all(0 < np.max(v) for v in side["start_scales"].values())
    # which of them the units' ML targets informed: all but s_m², which starts at its inverse gamma's point, and
    # ρ's scale, which has no target
    assert side["start_scales_from"] == {**{k: "units' spread" for k in side["start_scales"]},
                                         "sigma_m_scale_sq": "PyMC's initial point", "rho_scale": "PyMC's initial point"}
    # on each subject's whitened coordinates curved along its ridge, with what the whitening found: along ρ's
    # coordinate where it is signed (σ_m's block is centred here, the data fix σ_m), else along σ_m's; ρ's form as
    # the data chose it
    form = side["delayed_form"]
    assert form["sigma_m"] == "centred" and set(form) == {"tau_nm", "sigma_m", "rho", "reason"}
    signed_rho = {"folded_centred": [True] * 3, "centred": [False] * 3}[form["rho"]]
    rho = motor_coordinate("rho", form["rho"])
    pivots = [rho if signed else "sigma_m" for signed in signed_rho]
    assert side["whitening"]["pivot_by_subject"] == pivots
    assert side["whitening"]["curved_along"] == {p: pivots.count(p) for p in (rho, "sigma_m") if p in pivots}
    assert side["sampler"]["adaptation"].startswith("diag (nutpie), per-subject whitened, curved along ")
    # ... and measured again on a pilot run's draws, as long as the fit's own warm-up and draws allow
    # (pipelines/fit/warmup.py)
    assert side["sampler"]["adaptation"].endswith(", measured again on a pilot run's draws")
    [pilot] = side["whitening"]["pilot"]
    assert (pilot["tune"], pilot["draws"]) == (min(PILOT_RUNS[0][0], TINY["tune"]),
                                               min(PILOT_RUNS[0][1], TINY["draws"]))
    # on its own chains (at most the fit's), at the fit's target acceptance rate unless the pilot has its own: as
    # nutpie recorded them
    assert pilot["chains"] == min(PILOT_CHAINS, TINY["chains"])
    # the fit's rate: 0.8 with the pilot where ρ is signed (its pivots' tail maps), else 0.9 (models/bayes/delayed_model.py)
    rho_signed = (side["delayed_priors"]["R_population"] == "policy_scale"
                  and side["delayed_form"]["rho"] in SIGNED_FORMS)
    rate = PILOT_ADAPTATION_TARGET_ACCEPT if rho_signed else WHITENED_TARGET_ACCEPT
    assert pilot["target_accept"] == (PILOT_TARGET_ACCEPT or rate)
    # how many subjects' pivots its draws gave a tail map (models/bayes/pivot_tails.py), and θ2's form
    assert 0 <= pilot["pivots_with_tail_map"] <= len(side["whitening"]["pivot_by_subject"])
    assert side["delayed_parameterization"]["theta2"] == "quantile"
    assert pilot["leapfrog_steps"] > 0 and "pilot run" in side["start"]
    for name in side["whitening"]["curved_along"]:
        scales = side["whitening"]["ridge"][name]["pivot_scale_range"]
        assert 0 < scales[0] <= scales[1]
    assert side["nutpie_options"] == {"adaptation": "diag", "target_accept": rate}
    # the pilot's trees as deep as the kept run's, nutpie's own limit (pipelines/fit/warmup.py, "Tree depth"): as
    # nutpie recorded them
    stats = xr.open_datatree(delayed_fit["posterior"])["sample_stats"]
    assert PILOT_MAX_TREE_DEPTH is None and pilot["max_tree_depth"] == nutpie_setting(stats.attrs, "maxdepth") >= 10
    assert side["sampler"]["target_accept"] == rate and (PILOT_ADAPTATION_TARGET_ACCEPT, WHITENED_TARGET_ACCEPT) == (0.8, 0.9)
    assert side["whitening"]["coordinates_per_subject"] == 8 and side["whitening"]["mode_used"]
    assert "whitened coordinates" in side["start"]
    assert side["seconds"]["condition"]["whitening_s"] > 0
    assert "posterior_pooled" not in delayed_fit
    est = pd.read_parquet(root / "identify" / "estimates.parquet")
    by_unit = side["delay"]["by_unit"]
    assert len(by_unit) == len(est) == 6
    for subject, rows in est.groupby("subject"):
        total = np.sum([np.asarray(p, dtype=float) for p in rows["profile_loglik"]], axis=0)
        d = int(np.argmax(total))  # the grid is 0, 1, ..., 30 samples at 100 Hz
        assert {by_unit[f"{subject}/{c}"]["delay_samples"] for c in rows["condition"]} == {d}
    assert "profile_loglik" in side["delay"]["source"] and "estimates" in side["delay"]["source"]
    assert {"tau_nm_scale", "sigma_m_scale", "beta"} <= set(
        side["diagnostics"]["condition"]["population"])
    # the log R blocks' form follows the motor noise's, as the data chose it, and says why
    chosen, _ = choose_delayed_form(est)
    form, why = log_R_form(chosen)
    par = side["delayed_parameterization"]
    assert par["R_mc"] == par["R_sc"] == form and par["log_R_reason"] == why
    res = json.loads(open(delayed_fit["contrasts"]).read())
    assert res["human_model"] == "delayed" and "beta" in res and "delayed" in res["loo"]
    motor = res["truth"]["motor"]["tau_nm"]
    assert motor["n"] == 3 and 0 <= motor["truth_in_interval"] <= 3
    assert motor["largest_upper"] >= motor["median_posterior_median"] > 0
    assert res["adequacy"]["verdict"] in ("pass", "fail")
    text = format_fit(root / "fit_delayed")
    assert "human model: delayed" in text and "pooled" not in text and "tau_nm: truth" in text
    assert "population of R, chosen by the estimates: policy_scale: the estimates leave" in text
    # A tiny fit's verdict fails; its advice comes from its own numbers (tests/pipelines/fit/test_diagnostics.py).
    side = json.loads(open(delayed_fit["sidecar"]).read())
    assert side["convergence_verdict"]["condition"] != "pass"
    advice = [line for line in text.splitlines() if line.startswith("  to try (condition model): ")]
    assert advice and (side["diagnostics"]["condition"]["sampler"]["divergences"] == 0) == (
        "divergent" not in advice[0])


@pytest.mark.validation
def test_delays_without_estimates_are_the_profile_maxima(delayed_study):
    """Without estimates the fit computes each unit's delay by the same profile identify uses."""
    root, _, prepared = delayed_study
    est = pd.read_parquet(root / "identify" / "estimates.parquet")
    plant = discretize(0.01)
    own = unit_delays(prepared, None, plant)
    given = unit_delays(prepared, est, plant, "estimates.parquet")
    np.testing.assert_array_equal(own.samples, given.samples)
    assert "computed here" in own.source
    # Its ML points are identify's, so the chains start from the same targets with or without --estimates.
    cols = ["theta1", "se_log_theta1", "R", "se_log_R", "theta2", "se_theta2", "tau_nm", "se_tau_nm", "sigma_m"]
    pd.testing.assert_frame_equal(own.estimates[["subject", "condition", *cols]].reset_index(drop=True),
                                  est[["subject", "condition", *cols]].reset_index(drop=True), check_dtype=False)


@pytest.mark.validation
def test_human_models_compare_by_leaving_subjects_out(delayed_study, delayed_fit):
    root, sim, prepared = delayed_study
    maxent_settings = IdentifySettings.for_design(SENSOR, adequacy_boot=0)
    mx = fit_to_dir(sim["study"], root / "fit_maxent", settings=maxent_settings, estimates_path=None, **TINY)
    assert json.loads(open(mx["sidecar"]).read())["human_model"] == "maxent"
    with pytest.raises(ValueError, match="not a delayed fit"):
        compare_human_models(root / "fit_maxent", root / "fit_maxent", prepared=prepared)
    res = compare_human_models(root / "fit_maxent", root / "fit_delayed", prepared=prepared, seed=3, out=root,
                               relative_to=root)
    # scioc run names its fits relative to its run folder, which it stages under another name and renames
    assert json.loads((root / "human_models.json").read_text())["fits"] == res["fits"] \
        == {"maxent": "fit_maxent", "delayed": "fit_delayed"}
    assert res["adequacy"]["delayed"]["where"] == "at the posterior θ (fit_delayed/contrasts.json)"
    by = res["by_subject"]
    assert set(by) == {"S01", "S02", "S03"}
    diffs = np.array([v["difference"] for v in by.values()])
    assert res["difference"]["elpd_diff"] == pytest.approx(diffs.sum())
    assert res["difference"]["n_preferring_delayed"] == int((diffs > 0).sum())
    # The kbl human has a lag and motor noise the max-ent human lacks: the delayed model predicts it better.
    assert res["difference"]["preferred"] == "delayed"
    text = format_human_models(res)
    assert "elpd(delayed) - elpd(maxent)" in text
    for k, folder in (("maxent", "fit_maxent"), ("delayed", "fit_delayed")):
        verdict = json.loads((root / folder / "posterior.json").read_text())["convergence_verdict"]["condition"]
        assert res["convergence"][k] == verdict
        assert (f"CAVEAT: the {k} fit's sampler did not converge ({verdict})" in text) == (verdict != "pass")


@pytest.mark.validation
def test_without_recorded_torques_the_delayed_fit_scores_the_angles(tmp_path):
    """The paper's rig (angles only): the fit's likelihood is the encoder's angles (sidecar, log-likelihood, LOO), the
    delays the angle identification's profile maxima; its comparison with a max-ent fit of the reconstructed torques
    is refused, as the two score different data."""
    from scioc.pipelines.lineage import LineageError

    small = replace(STUDY, run_seconds=8.0, window_start=2.0, window_seconds=4.0, preview=1.0)
    sim = simulate_to_dir(tmp_path / "data", n_subjects=2, seed=3, human="kbl", design=small)
    rec = IdentifySettings.for_design(small, human_model="delayed", adequacy_boot=19)
    fit_to_dir(sim["study"], tmp_path / "fit_delayed", settings=rec, **TINY)
    side = json.loads((tmp_path / "fit_delayed" / "posterior.json").read_text())
    assert side["likelihood"] == "angles" and side["human_model"] == "delayed"
    idata = az.from_netcdf(tmp_path / "fit_delayed" / "posterior.nc")
    assert set(idata["log_likelihood"].data_vars) == {"angle"}
    res = json.loads((tmp_path / "fit_delayed" / "contrasts.json").read_text())
    assert np.isfinite(res["loo"]["delayed"]["elpd_loo"]) and res["adequacy"]["verdict"] in ("pass", "fail")
    assert {"tau_nm", "sigma_m", "beta"} <= set(idata["posterior"].data_vars)
    maxent = replace(rec, human_model="maxent")
    fit_to_dir(sim["study"], tmp_path / "fit", settings=maxent, **TINY)
    with pytest.raises(LineageError, match="score different data"):
        compare_human_models(tmp_path / "fit", tmp_path / "fit_delayed")
    # the max-ent human through the same angle likelihood: leave-one-subject-out compares the two on the same data
    fit_to_dir(sim["study"], tmp_path / "fit_angles", settings=maxent, likelihood="angles", **TINY)
    side = json.loads((tmp_path / "fit_angles" / "posterior.json").read_text())
    assert side["likelihood"] == "angles" and "tau_nm" not in az.from_netcdf(tmp_path / "fit_angles" /
                                                                           "posterior.nc")["posterior"]
    res = compare_human_models(tmp_path / "fit_angles", tmp_path / "fit_delayed", points=200)
    assert all(np.isfinite(v[k]) for v in res["by_subject"].values() for k in ("elpd_maxent", "elpd_delayed"))


def test_the_delayed_fit_refuses_to_score_reconstructed_torques(tmp_path):
    # A reconstructed torque is smoothed, which the torque likelihood reads as lag: --likelihood torques is refused.
    from scioc.pipelines.io import InputDataError

    small = replace(SENSOR, run_seconds=8.0, window_start=2.0, window_seconds=4.0, preview=1.0)
    sim = simulate_to_dir(tmp_path / "data", n_subjects=2, seed=3, human="kbl", design=small)
    rec = IdentifySettings.for_design(small, human_model="delayed", adequacy_boot=0, reconstruct="always")
    with pytest.raises(InputDataError, match="4 of 4 segments have no recorded torque .*--likelihood angles"):
        fit_to_dir(sim["study"], tmp_path / "fit", settings=rec, likelihood="torques", **TINY)
    assert not (tmp_path / "fit").exists()


def test_the_comparison_says_when_a_fit_did_not_converge():
    res = {"difference": {"n": 3, "n_preferring_delayed": 2, "se": 1.0, "z": 3.0, "elpd_diff": 3.0, "reliable": True,
                          "preferred": "delayed"},
           "adequacy": {}, "convergence": {"maxent": "pass", "delayed": "fail: rhat_le_1.01"}}
    text = format_human_models(res)
    assert "CAVEAT: the delayed fit's sampler did not converge (fail: rhat_le_1.01)" in text
    assert "the maxent fit's sampler" not in text


def test_the_lag_and_noise_blocks_are_centred_only_where_the_data_pin_them():
    assert choose_delayed_form(None)[0] == DelayedForm("noncentred", "noncentred")
    # A delayed human: both well away from 0 in SE units.
    pinned = pd.DataFrame({"tau_nm": [0.06, 0.08], "se_tau_nm": [0.005, 0.006], "sigma_m": [0.25, 0.24],
                           "se_sigma_m": [0.02, 0.02]})
    form, reason = choose_delayed_form(pinned)
    assert form == DelayedForm("centred", "centred") and f"threshold {CENTRED_Z:g}" in reason
    # A max-ent human: the lag at its bound (no SE), the motor noise small against its SE.
    at_zero = pinned.assign(tau_nm=[0.0, 0.0], se_tau_nm=[np.nan, np.nan], sigma_m=[0.05, 0.03])
    assert choose_delayed_form(at_zero)[0] == DelayedForm("noncentred", "folded_centred")
    # An SE of exactly 0 (or of log R) is no SE: it counts as z = 0, without a division warning.
    import warnings

    zero_se = at_zero.assign(se_tau_nm=[0.0, 0.0], se_log_R=[0.0, 0.5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        form = choose_delayed_form(zero_se)[0]
    assert form == DelayedForm("noncentred", "folded_centred", rho="folded_centred")


def test_rhos_block_is_centred_only_where_the_data_pin_it():
    # ρ = R^(-1/2): ρ̂/SE(ρ̂) = 2/SE(log R̂). The max-ent human's R is pinned (SE of log R 0.2: z = 10), the kbl human's
    # is not (SE 1.3: z 1.5; R at its bound: no SE, z 0); without SEs of log R, ρ keeps DelayedForm's default
    pinned = pd.DataFrame({"tau_nm": [0.06, 0.08], "se_tau_nm": [0.005, 0.006], "sigma_m": [0.25, 0.24],
                           "se_sigma_m": [0.02, 0.02]})
    form, reason = choose_delayed_form(pinned.assign(se_log_R=[0.2, 0.19]))
    assert form.rho == "centred" and "rho centred (median estimate/SE 10.3, threshold 3)" in reason
    assert choose_delayed_form(pinned.assign(se_log_R=[1.3, np.nan]))[0].rho == "folded_centred"
    at_threshold = 2.0 / CENTRED_Z
    assert choose_delayed_form(pinned.assign(se_log_R=[at_threshold] * 2))[0].rho == "centred"
    assert choose_delayed_form(pinned.assign(se_log_R=[at_threshold * 1.001] * 2))[0].rho == "folded_centred"
    assert choose_delayed_form(pinned)[0].rho == DelayedForm().rho == "folded"


def test_the_population_of_R_is_lognormal_where_the_estimates_fix_the_R_of_at_least_half_the_subjects():
    from scioc.pipelines.fit.delayed_forms import choose_R_population

    est = pd.DataFrame({"subject": ["A", "A", "B", "B"], "se_log_R": [0.2, 0.3, 0.5, 0.4]})  # z 10, 6.7; 4, 5
    population, reason = choose_R_population(est, ["A", "B"])
    assert population == "lognormal" and "fix the R of 2 of 2 subjects" in reason
    loose = est.assign(se_log_R=[1.0, np.nan, np.nan, 1.5])  # A: 2 and R at its bound; B: the bound and 1.33
    population, reason = choose_R_population(loose, ["A", "B"])
    assert population == "policy_scale" and "leave the R of 2 of 2 subjects loose" in reason
    half = est.assign(se_log_R=[0.2, 0.3, np.nan, 1.5])  # A fixed, B loose: half, lognormal
    assert choose_R_population(half, ["A", "B"])[0] == "lognormal"
    assert choose_R_population(half, ["A", "B", "C"])[0] == "policy_scale"  # C has no estimates: not fixed
    assert choose_R_population(None, ["A"])[0] == "lognormal"
    assert choose_R_population(est.drop(columns="se_log_R"), ["A"])[0] == "lognormal"


def test_given_the_subjects_rhos_form_is_centred_only_where_their_units_combined_fix_every_subjects_rho():
    # each subject's units' z = 2/SE(log R̂) combined as sqrt(Σ z²): A 2.5 and 2.5 -> 3.54, pinned; B 2.5 and no SE (R at
    # its bound) -> 2.5, not; C 3.2 alone; D has no units in the estimates, not pinned. Flags in the order given.
    est = pd.DataFrame({"subject": ["A", "A", "B", "B", "C", "C"], "tau_nm": 0.06, "se_tau_nm": 0.005,
                        "sigma_m": 0.25, "se_sigma_m": 0.02,
                        "se_log_R": [0.8, 0.8, 0.8, np.nan, 0.625, 50.0]})
    form, reason = choose_delayed_form(est, ["C", "B", "A", "D"])
    assert rho_pinned(est, ["C", "B", "A", "D"]) == (True, False, True, False)
    assert form.rho == "folded_centred" and "rho folded_centred (2 of 4 subjects" in reason  # not every one fixed
    assert choose_delayed_form(est, ["A", "C"])[0] == DelayedForm("centred", "centred", "centred")
    assert choose_delayed_form(est, ["B", "D"])[0].rho == "folded_centred"


def test_the_log_R_blocks_are_centred_only_where_no_motor_noise_is_found():
    # the max-ent human (no motor noise found): the policy noise alone fixes R per unit
    form, reason = log_R_form(DelayedForm("noncentred", "noncentred"))
    assert form == "centred" and "no motor noise" in reason
    form, reason = log_R_form(DelayedForm("noncentred", "folded_centred"))
    assert form == "centred" and "σ_m's block is folded_centred (no motor noise" in reason
    # the delayed human (motor noise found): R trades off against it, loose per unit
    assert log_R_form(DelayedForm("centred", "centred"))[0] == "noncentred"
    assert log_R_form(DelayedForm("noncentred", "centred"))[0] == "noncentred"


@pytest.mark.validation
def test_a_given_log_R_form_is_fitted_and_recorded(delayed_study):
    # scioc fit --human-model delayed --log-R-form centred: the blocks take it whatever the data say, the sidecar
    # says it was given, and the posterior has the units' log R without the non-centred z of the baseline level.
    import arviz as az

    root, sim, prepared = delayed_study
    small = {**TINY, "chains": 1, "draws": 30, "tune": 30, "cores": 1}
    paths = fit_to_dir(sim["study"], root / "fit_log_R_centred", settings=SETTINGS, prepared=prepared,
                       sampler_options={"log_R_form": "centred"}, **small)
    par = json.loads(open(paths["sidecar"]).read())["delayed_parameterization"]
    assert par["R_mc"] == par["R_sc"] == "centred" and par["log_R_reason"] == "given"
    post = az.from_netcdf(paths["posterior"])["posterior"]
    assert "log_R" in post and "z_log_R_MC" not in post and "z_log_R_SC" not in post
    with pytest.raises(ValueError, match="log_R_form"):
        fit_to_dir(sim["study"], root / "fit_bad_log_R", settings=IdentifySettings.for_design(SENSOR),
                   prepared=prepared, human_model="maxent", sampler_options={"log_R_form": "centred"}, **small)


@pytest.mark.validation
def test_estimates_without_motor_noise_fold_its_block_end_to_end(delayed_study, tmp_path):
    # Estimates that find no motor noise (every σ_m at its bound 0, no SE, as for the max-ent human): the fit folds
    # σ_m's block, centred (σ_m = |v|, v ~ N(0, s_m) unconstrained), under the inverse gamma on s_m², and centres
    # log R, records why, and its draws of σ_m are |v|, of s_m the square root of s_m².
    import arviz as az

    root, sim, prepared = delayed_study
    est = pd.read_parquet(root / "identify" / "estimates.parquet").assign(sigma_m=0.0, se_sigma_m=np.nan)
    est.to_parquet(tmp_path / "estimates.parquet")
    # Estimates edited by hand come with their identification's sidecar, recording them as its output.
    meta = json.loads((root / "identify" / "identify.json").read_text())
    meta["outputs"]["estimates.parquet"] = file_sha256(tmp_path / "estimates.parquet")
    (tmp_path / "identify.json").write_text(json.dumps(meta))
    small = {**TINY, "chains": 1, "draws": 30, "tune": 30, "cores": 1}
    paths = fit_to_dir(sim["study"], root / "fit_folded", settings=SETTINGS, prepared=prepared,
                       estimates_path=tmp_path / "estimates.parquet", **small)
    side = json.loads(open(paths["sidecar"]).read())
    assert side["delayed_form"]["sigma_m"] == "folded_centred"
    assert "sigma_m folded_centred" in side["delayed_form"]["reason"]
    assert side["delayed_parameterization"]["R_mc"] == "centred"
    assert side["delayed_priors"]["sigma_m_variance_inverse_gamma"] == [1.0, 0.03]
    post = az.from_netcdf(paths["posterior"])["posterior"]
    np.testing.assert_array_equal(post["sigma_m"].values, np.abs(post["sigma_m_signed"].values))
    np.testing.assert_allclose(post["sigma_m_scale"].values, np.sqrt(post["sigma_m_scale_sq"].values), rtol=1e-15)


@pytest.mark.validation
def test_sampled_delays_fit_end_to_end(delayed_study):
    # --delay sampled: PyMC's NUTS beside DelayMetropolis; the sidecar records each subject's delay posterior, and
    # every artifact of the profile fit is written. Same seed, same draws.
    root, sim, prepared = delayed_study
    small = {**TINY, "chains": 1, "draws": 40, "tune": 60, "cores": 1}
    paths = fit_to_dir(sim["study"], root / "fit_sampled", settings=SETTINGS, prepared=prepared,
                       sampler_options={"delay": "sampled"}, **small)
    side = json.loads(open(paths["sidecar"]).read())
    assert side["delay"]["mode"] == "sampled" and side["sampler"]["name"].startswith("PyMC NUTS")
    assert side["sampler"]["adaptation"] == "diag (PyMC's NUTS)" and "nutpie_options" not in side
    for unit in side["delay"]["by_unit"].values():
        assert unit["q03_s"] <= unit["delay_s"] <= unit["q97_s"] <= 0.3 and 0 <= unit["mean_s"] <= 0.3
    res = json.loads(open(paths["contrasts"]).read())
    assert res["human_model"] == "delayed" and "beta" in res and res["adequacy"]["verdict"] in ("pass", "fail")
    assert res["adequacy"]["theta"].endswith("the delays of that draw")  # the draw's own delays, not the modes
    import arviz as az

    post = az.from_netcdf(paths["posterior"]) if str(paths["posterior"]).endswith(".nc") else None
    if post is not None:
        assert "delay_index" in post["posterior"]
    again = fit_to_dir(sim["study"], root / "fit_sampled_again", settings=SETTINGS, prepared=prepared,
                       sampler_options={"delay": "sampled"}, **small)
    assert json.loads(open(again["sidecar"]).read())["delay"]["by_unit"] == side["delay"]["by_unit"]
    with pytest.raises(ValueError, match="unknown key.*delay for the maxent"):
        fit_to_dir(sim["study"], root / "fit_bad", settings=IdentifySettings.for_design(SENSOR), prepared=prepared,
                   human_model="maxent", sampler_options={"delay": "sampled"}, **small)


@pytest.mark.validation
def test_the_fit_takes_the_policy_scale_population_of_R(delayed_study):
    # scioc fit --R-population policy_scale --rho-form folded_centred: the sidecar records the population, the ρ form
    # and the rate (0.8: ρ signed), the lag and noise forms are still the data's, the posterior has ρ and no
    # log-normal μ_R. Each subject's block bends along ρ's signed coordinate
    # (models.bayes.delayed_blocks.ridge_pivots), not σ_m's, and says so.
    root = delayed_study[0]
    paths, side = _small_fit(delayed_study, "fit_rho", R_population="policy_scale", rho_form="folded_centred")
    assert side["nutpie_options"] == {"adaptation": "diag", "target_accept": PILOT_ADAPTATION_TARGET_ACCEPT}
    assert side["sampler"]["target_accept"] == 0.8
    assert side["delayed_form"]["sigma_m"] not in SIGNED_FORMS  # chosen by these data: ρ's is the only pivot
    assert side["whitening"]["curved_along"] == {"rho_signed": 3}
    assert side["sampler"]["adaptation"] == ("diag (nutpie), per-subject whitened, curved along rho_signed, "
                                             "measured again on a pilot run's draws")
    assert "curved along its ridge in rho_signed (models" in side["start"]
    scales = side["whitening"]["ridge"]["rho_signed"]["pivot_scale_range"]
    assert 0 < scales[0] <= scales[1]
    assert side["delayed_priors"]["R_population"] == "policy_scale" and side["R_population_reason"] == "given"
    assert "population of R: policy_scale (given)" in format_fit(root / "fit_rho")
    chosen, _ = choose_delayed_form(pd.read_parquet(root / "identify" / "estimates.parquet"))
    assert side["delayed_form"] == {**side["delayed_form"], "rho": "folded_centred", "tau_nm": chosen.tau_nm,
                                    "sigma_m": chosen.sigma_m}
    assert "rho_scale" in side["diagnostics"]["condition"]["population"]
    assert "mu_log_R" not in side["diagnostics"]["condition"]["population"]
    res = json.loads(open(paths["contrasts"]).read())
    assert "beta" in res and res["adequacy"]["verdict"] in ("pass", "fail")


def _small_fit(delayed_study, out: str, **kwargs):
    """A one-chain, 30-draw fit of the 3-subject study into ``out``: its paths and its sidecar."""
    root, sim, prepared = delayed_study
    small = {**TINY, "chains": 1, "draws": 30, "tune": 30, "cores": 1}
    paths = fit_to_dir(sim["study"], root / out, settings=SETTINGS, prepared=prepared, sampler_options=kwargs, **small)
    return paths, json.loads(open(paths["sidecar"]).read())


@pytest.mark.validation
def test_the_adequacy_of_a_finished_fit_is_checked_again_as_the_fit_checked_it(delayed_study, delayed_fit, tmp_path):
    # scioc adequacy FIT: at the fit's own point and seed it reproduces contrasts.json's verdict exactly; at the means
    # it is the former rule; --out writes a file of its own and never one of the fit's.
    from scioc.pipelines import cli
    from scioc.pipelines.fit.recheck import recheck_adequacy

    root, sim, _ = delayed_study
    fit = root / "fit_delayed"
    stored = json.loads(open(delayed_fit["contrasts"]).read())["adequacy"]
    assert stored["point"]["at"] == "draw" and "that draw" not in stored["theta"]  # profile delays: plug-in
    again = recheck_adequacy(fit)
    assert again["human_model"] == "delayed"
    assert json.loads(json.dumps(again["adequacy"])) == stored
    means = recheck_adequacy(fit, at="means")["adequacy"]
    assert means["point"]["at"] == "means" and means["combined_p"] != stored["combined_p"]
    other = recheck_adequacy(fit, seed=7)["adequacy"]["point"]
    assert (other["chain"], other["draw"]) != (stored["point"]["chain"], stored["point"]["draw"])
    out = tmp_path / "adequacy.json"
    code = cli.main(["adequacy", str(fit), "--at", "means", "--out", str(out)])
    assert code == (1 if means["verdict"] == "fail" else 0)
    assert json.loads(out.read_text())["adequacy"]["combined_p"] == means["combined_p"]
    before = (fit / "contrasts.json").read_bytes()
    assert cli.main(["adequacy", str(fit), "--out", str(fit / "contrasts.json")]) == 2
    assert (fit / "contrasts.json").read_bytes() == before
    assert cli.main(["adequacy", str(tmp_path)]) == 2  # not a fit folder: a usage error


@pytest.mark.validation
def test_same_seed_same_delayed_fit(delayed_study, delayed_fit, tmp_path):
    """The delayed fit (the start, the whitening, the jitter, nutpie) repeats bit for bit with its seed."""
    import arviz as az

    _, sim, prepared = delayed_study
    fit_to_dir(sim["study"], tmp_path / "again", settings=SETTINGS, prepared=prepared, **TINY)
    a = az.from_netcdf(delayed_fit["posterior"])
    b = az.from_netcdf(tmp_path / "again" / "posterior.nc")
    for v in ("beta", "log_theta1", "log_R", "tau_nm", "sigma_m"):
        np.testing.assert_array_equal(a["posterior"][v].values, b["posterior"][v].values)
    np.testing.assert_array_equal(a["sample_stats"]["step_size"].values, b["sample_stats"]["step_size"].values)


def test_the_whitened_fits_rate_is_08_only_with_a_signed_rho():
    from scioc.models.bayes.delayed_model import nutpie_options

    assert nutpie_options(rho_signed=True) == {"adaptation": "diag", "target_accept": 0.8}
    assert nutpie_options(rho_signed=False) == nutpie_options() == {"adaptation": "diag", "target_accept": 0.9}
