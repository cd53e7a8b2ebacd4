"""Where a fit's chains start (pipelines/fit/start.py): near the ML estimates, on any form of the blocks."""

import numpy as np
import pandas as pd
import pymc as pm
import pytensor
import pytest

from scioc.pipelines.fit.start import scale_estimate, scale_sources, start_point

SUBJECTS = ["S1", "S2", "S3", "S4"]
LEVELS = ["MC", "SC"]


def toy_model(noncentred: bool):
    """A population of log θ1 per unit (non-centred or centred) and a per-subject τ_nm, as the delayed model has them."""
    with pm.Model(coords={"subject": SUBJECTS, "condition": LEVELS}) as model:
        mu = pm.Normal("mu_log_theta1", 3.0, 1.0)
        sigma = pm.HalfNormal("sigma_log_theta1", 1.0)
        if noncentred:
            z = pm.Normal("z", 0.0, 1.0, dims=("subject", "condition"))
            pm.Deterministic("log_theta1", mu + sigma * z, dims=("subject", "condition"))
        else:
            pm.Normal("log_theta1", mu, sigma, dims=("subject", "condition"))
        pm.HalfNormal("tau_nm", 0.1, dims="subject")
    return model


def estimates(log_theta1, tau):
    rows = []
    for i, s in enumerate(SUBJECTS):
        for j, c in enumerate(LEVELS):
            rows.append({"subject": s, "condition": c, "theta1": float(np.exp(log_theta1[i, j])),
                         "se_log_theta1": 0.05, "tau_nm": tau[i], "se_tau_nm": 0.005})
    return pd.DataFrame(rows)


@pytest.mark.parametrize("noncentred", [True, False])
def test_start_is_near_the_estimates_in_any_form(noncentred):
    rng = np.random.default_rng(1)
    target = 3.0 + 0.5 * rng.standard_normal((4, 2))
    tau = np.array([0.05, 0.08, 0.11, 0.07])
    model = toy_model(noncentred)
    start = start_point(model, estimates(target, tau))
    fn = pytensor.function(model.free_RVs, [model["log_theta1"], model["tau_nm"]], on_unused_input="ignore")
    log_theta1, tau_nm = fn(*[start[rv.name] for rv in model.free_RVs])
    # within the stand-in likelihood's SE of the ML value (the prior pulls only a little), where PyMC's own
    # start (all log θ1 at 3, every τ_nm at the half-normal's support point) is up to 1.2 and 0.04 away
    assert np.max(np.abs(log_theta1 - target)) < 0.05
    assert np.max(np.abs(tau_nm - tau)) < 0.005
    assert np.max(np.abs(3.0 - target)) > 0.5


def test_missing_estimates_follow_the_prior_and_none_without_estimates():
    target = np.full((4, 2), 4.0)
    est = estimates(target, np.full(4, 0.06))
    est.loc[0, "theta1"] = np.nan  # S1/MC: no estimate, so its log θ1 follows the population
    model = toy_model(noncentred=True)
    start = start_point(model, est)
    fn = pytensor.function(model.free_RVs, model["log_theta1"], on_unused_input="ignore")
    log_theta1 = fn(*[start[rv.name] for rv in model.free_RVs])
    assert np.all(np.isfinite(log_theta1))
    assert np.max(np.abs(log_theta1.ravel()[1:] - 4.0)) < 0.05
    assert start_point(model, None) is None
    assert start_point(model, est.iloc[0:0]) is None


def test_no_start_without_cost_targets():
    """Without θ1 targets the centred units would collapse onto μ and σ -> 0 (the funnel's neck): no start."""
    est = estimates(np.full((4, 2), 4.0), np.full(4, 0.06))
    model = toy_model(noncentred=False)
    assert start_point(model, est.drop(columns=["theta1", "se_log_theta1"])) is None


def test_population_scales_are_held_where_the_targets_agree():
    """Centred units whose targets agree: the optimum over σ would be its funnel's neck (σ -> 0); σ is held at
    the targets' spread, SE/√(n - 1) of the baseline level's four values, not at 0 and not optimized."""
    model = toy_model(noncentred=False)
    start = start_point(model, estimates(np.full((4, 2), 4.0), np.full(4, 0.06)))
    assert start["sigma_log_theta1"] == pytest.approx(0.05 / np.sqrt(3), rel=1e-5)
    assert np.max(np.abs(start["log_theta1"] - 4.0)) < 0.05


def test_population_scales_start_at_their_units_spread_capped_at_pymcs_point():
    """Spread targets: σ starts at their sample SD (the SEs are small beside it), where PyMC's point is σ's prior
    scale 1; a spread above that stays at 1."""
    rng = np.random.default_rng(3)
    target = 3.0 + 0.3 * rng.standard_normal((4, 2))
    model = toy_model(noncentred=True)
    start = start_point(model, estimates(target, np.full(4, 0.06)))
    v, se = target[:, 0], 0.05
    expected = scale_estimate(v, np.full(4, se), centred=True, upper=1.0)
    assert start["sigma_log_theta1"] == pytest.approx(expected, rel=1e-9)
    assert abs(expected - np.std(v, ddof=1)) < 0.1 * np.std(v, ddof=1)
    wide = start_point(model, estimates(3.0 + 5.0 * rng.standard_normal((4, 2)), np.full(4, 0.06)))
    assert wide["sigma_log_theta1"] == pytest.approx(1.0, rel=1e-9)


def test_scale_sources_say_which_scales_the_targets_informed():
    """σ_log θ1 has the units' log θ1 as targets; a motor-noise scale whose units have no σ_m estimates does not, and
    starts at PyMC's point; without estimates every scale does. Every population scale of the model is listed."""
    model = toy_model(noncentred=True)
    with model:
        pm.HalfNormal("sigma_m", pm.HalfNormal("sigma_m_scale", 0.3), dims="subject")
    est = estimates(np.full((4, 2), 4.0), np.full(4, 0.06))
    assert scale_sources(model, est) == {"sigma_log_theta1": "units' spread", "sigma_m_scale": "PyMC's initial point"}
    assert scale_sources(model, None) == {"sigma_log_theta1": "PyMC's initial point",
                                          "sigma_m_scale": "PyMC's initial point"}
    start = start_point(model, est)
    assert start["sigma_m_scale"] == pytest.approx(np.exp(model.initial_point()["sigma_m_scale_log__"]))
    assert start["sigma_log_theta1"] != pytest.approx(1.0)  # the informed scale moved off PyMC's point


def test_scale_estimate():
    rng = np.random.default_rng(0)
    v = rng.normal(2.0, 0.5, 40)
    # no SEs: the unbiased SD about the fitted centre, and about 0 for a half-normal population
    assert scale_estimate(v, np.full(40, 1e-9), centred=True, upper=10.0) == pytest.approx(np.std(v, ddof=1), rel=1e-5)
    a = np.abs(v - 2.0)
    assert scale_estimate(a, np.full(40, 1e-9), centred=False, upper=10.0) == pytest.approx(
        np.sqrt(np.sum(a**2) / 39), rel=1e-5)
    # values that agree within their SEs: about se/sqrt(n - 1), positive (not the neck)
    assert scale_estimate(np.zeros(42), np.full(42, 0.002), centred=False, upper=0.1) == pytest.approx(
        0.002 / np.sqrt(41), rel=1e-5)
    assert scale_estimate(v, np.full(40, 1e-9), centred=True, upper=0.3) == pytest.approx(0.3)
    # too few values, or none finite: no estimate
    assert scale_estimate([1.0], [0.1], centred=False, upper=1.0) is None
    assert scale_estimate([np.nan, 1.0], [0.1, np.nan], centred=True, upper=1.0) is None


def test_an_estimate_at_its_bound_without_se_still_pulls():
    """τ_nm = 0 with no SE (identify's NaN at a bound, the rule for a human without lag) pulls τ_nm to ~0.

    Without it such subjects started at the prior's initial point (0.1 s here), where the delayed
    likelihood of a lag-free human is about -1e7 per segment and the chains never left.
    """
    est = estimates(np.full((4, 2), 4.0), np.array([0.0, 0.0, 0.06, 0.0]))
    est.loc[est["tau_nm"] == 0.0, "se_tau_nm"] = np.nan
    model = toy_model(noncentred=True)
    start = start_point(model, est)
    tau_nm = start["tau_nm"]
    assert np.all(tau_nm[[0, 1, 3]] < 0.01) and abs(tau_nm[2] - 0.06) < 0.005
    # a value inside its range without an SE still does not pull
    est.loc[est["subject"] == "S3", "se_tau_nm"] = np.nan
    free = start_point(model, est)["tau_nm"][2]
    assert abs(free - 0.06) > 0.005
