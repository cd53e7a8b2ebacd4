"""Checks of the fit against other evidence: the mixed model against its closed form."""

import numpy as np
import pandas as pd
import pytest

from pipelines.fit import mixedlm_check


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
    from pipelines.fit.checks import ADEQUACY_POINTS, posterior_point

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

    from pipelines.fit.checks import posterior_point

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
