"""Checks of the fit against other evidence: the mixed model against its closed form."""

import numpy as np
import pandas as pd
import pytest

from scioc.pipelines.fit import mixedlm_check


def test_mixedlm_of_a_balanced_paired_design_is_the_paired_mean_difference():
    """Closed form: with two observations per subject, the REML fixed effect of SC is the mean
    paired difference of log θ1 and its SE is SD(d)/√n (the paired t-test), when the subject
    variance is not at its boundary."""
    rng = np.random.default_rng(7)
    n = 30
    a = rng.normal(3.0, 0.5, n)
    d = rng.normal(-0.7, 0.2, n)
    est = pd.DataFrame({"subject": np.repeat([f"S{i}" for i in range(n)], 2), "condition": ["MC", "SC"] * n,
                        "theta1": np.exp(np.column_stack([a, a + d]).ravel())})
    mm = mixedlm_check(est)
    assert mm["coef"] == pytest.approx(d.mean(), rel=1e-6)
    # The optimizer stops at a tolerance of its own: agreement to 1e-4 relative.
    assert mm["se"] == pytest.approx(d.std(ddof=1) / np.sqrt(n), rel=1e-4)
    assert mm["ratio"] == pytest.approx(np.exp(d.mean()), rel=1e-6)


def _posterior(chains=3, draws=50, seed=0):
    import xarray as xr

    rng = np.random.default_rng(seed)
    subjects, conditions = ["S01", "S02"], ["MC", "SC"]
    shape = (chains, draws, 2, 2)
    coords = {"chain": np.arange(chains), "draw": np.arange(draws), "subject": subjects, "condition": conditions}
    dims = ("chain", "draw", "subject", "condition")
    return xr.Dataset({"log_theta1": (dims, rng.normal(2, 1, shape)), "log_R": (dims, rng.normal(3, 1, shape)),
                       "theta2": (dims, rng.random(shape)),
                       "sigma_m": (dims[:3], rng.random(shape[:3]))}, coords=coords)


def test_the_adequacy_point_is_one_joint_draw_or_the_means():
    from scioc.pipelines.fit.checks import ADEQUACY_POINTS, posterior_point

    post = _posterior()
    point, what = posterior_point(post, "draw", 2018)
    assert what["at"] == "draw" and set(point.dims) == {"subject", "condition"}
    # Every variable from the same (chain, draw): not a mixture of draws.
    same = post.sel(chain=what["chain"], draw=what["draw"])
    for v in post.data_vars:
        np.testing.assert_array_equal(point[v].values, same[v].values)
    # The adequacy seed picks it: same seed, same draw; the seeds do not all pick one draw.
    assert posterior_point(post, "draw", 2018)[1] == what
    picked = {(w["chain"], w["draw"]) for w in (posterior_point(post, "draw", s)[1] for s in range(40))}
    assert len(picked) > 30 and {c for c, _ in picked} == {0, 1, 2}
    means, what = posterior_point(post, "means", 2018)
    assert what["at"] == "means"
    np.testing.assert_allclose(means["log_R"].values, post["log_R"].mean(("chain", "draw")).values)
    assert set(ADEQUACY_POINTS) == {"draw", "means"}
    with pytest.raises(ValueError, match="draw, means"):
        posterior_point(post, "median", 2018)


def test_the_draw_point_stays_on_a_curved_ridge_where_the_means_leave_it():
    # Why the check takes a draw: where two parameters trade off along a curved ridge (the delayed human's
    # torque variance exp(-log R) + σ_m² shared between policy and motor noise), every draw keeps the variance
    # the data fix, and the means of log R and σ_m predict less (Jensen). A negative control for the rule.
    import xarray as xr

    from scioc.pipelines.fit.checks import posterior_point

    rng = np.random.default_rng(1)
    log_R = rng.normal(0.0, 0.8, (4, 500))
    sigma_m = np.sqrt(np.maximum(3.0 - np.exp(-log_R), 0.0))
    keep = np.exp(-log_R) < 3.0
    post = xr.Dataset({"log_R": (("chain", "draw"), np.where(keep, log_R, 0.0)),
                       "sigma_m": (("chain", "draw"), np.where(keep, sigma_m, np.sqrt(2.0)))},
                      coords={"chain": np.arange(4), "draw": np.arange(500)})
    variance = lambda p: float(np.exp(-p["log_R"]) + p["sigma_m"] ** 2)  # noqa: E731
    for seed in range(20):
        assert variance(posterior_point(post, "draw", seed)[0]) == pytest.approx(3.0, rel=1e-12)
    assert variance(posterior_point(post, "means", 0)[0]) < 3.0 * (1 - 1e-3)  # 2.72 here


def test_motor_truth_counts_intervals_and_says_how_near_zero(tmp_path):
    """τ_nm, σ_m per subject against the truth: the HDI for a positive truth, [0, q94] for a truth of 0."""
    import json

    import xarray as xr

    from scioc.pipelines.fit.checks import motor_truth

    rng = np.random.default_rng(1)
    subjects = ["S1", "S2", "S3"]
    tau = np.stack([np.abs(rng.normal(0, 1e-3, (2, 500))), rng.normal(0.06, 0.005, (2, 500)),
                    rng.normal(0.2, 0.005, (2, 500))], axis=-1)
    sig = np.abs(rng.normal(0, 0.02, (2, 500, 3)))
    post = xr.Dataset({"tau_nm": (("chain", "draw", "subject"), tau), "sigma_m": (("chain", "draw", "subject"), sig)},
                      coords={"subject": subjects})
    pd.DataFrame({"subject": subjects * 2, "condition": ["MC"] * 3 + ["SC"] * 3, "theta1": 1.0,
                  "tau_nm": [0.0, 0.06, 0.06] * 2, "motor_sd": 0.0}).to_parquet(tmp_path / "truth.parquet")
    m = motor_truth({"posterior": post}, tmp_path)
    # S1 (truth 0, one-sided) and S2 (inside the HDI) hold it; S3's posterior sits at 0.2 s, far from 0.06 s.
    assert m["tau_nm"]["truth_in_interval"] == 2 and m["tau_nm"]["n"] == 3
    assert m["tau_nm"]["interval_kinds"] == ["hdi94", "one-sided [0, q94]"]
    assert m["tau_nm"]["largest_upper"] == pytest.approx(0.2 + 1.88 * 0.005, abs=0.003)
    assert m["tau_nm"]["mean_error"] == pytest.approx(np.mean([tau[..., 0].mean(), 0.0, 0.14]), abs=0.002)
    s = m["sigma_m"]
    assert s["truth_in_interval"] == 3 and s["truth_max"] == 0.0
    assert s["median_posterior_median"] == pytest.approx(0.02 * 0.6745, rel=0.1)
    assert max(np.quantile(sig[..., j], 0.94) for j in range(3)) == s["largest_upper"]
    # The paper's agent in a truth file without the columns: 0 when simulation.json says so, else no check.
    pd.DataFrame({"subject": subjects, "condition": "MC", "theta1": 1.0}).to_parquet(tmp_path / "truth.parquet")
    assert motor_truth({"posterior": post}, tmp_path) is None
    (tmp_path / "simulation.json").write_text(json.dumps({"human": {"name": "maxent"}}))
    zero = motor_truth({"posterior": post}, tmp_path)["tau_nm"]
    # A truth of 0 is always inside [0, q94]: how near zero the fit puts τ_nm is the largest upper end's to say.
    assert zero["truth_in_interval"] == 3 and zero["truth_max"] == 0.0 and zero["largest_upper"] > 0.2
