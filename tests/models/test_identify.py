"""Maximum-likelihood identification: calibrated standard errors, with a negative control."""

import numpy as np
import pytest
from scipy import stats

from scioc.models.identify import identify_segment
from scioc.models.maxent import sample_maxent
from scioc.models.plant import discretize
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Segment, prepare_batch

# False-failure budget of each seeded statistical test below.
ALPHA = 1e-3
N_REP = 40
K = 800
TRUE = np.array([400.0, 0.0, 20.0])  # θ1 = 20, θ2 = 0, R = 20


def _zscores(shared_in_data: bool, shared_in_fit: bool, seed: int) -> np.ndarray:
    plant = discretize(0.01)
    ref = reference_trajectory(30.0).angle[: K + 1]
    rng = np.random.default_rng(seed)
    t = np.arange(K) * 0.01
    u_A = 0.3 * np.sin(2 * np.pi * 0.3 * t) if shared_in_data else np.zeros(K)
    z = []
    for _ in range(N_REP):
        x0 = np.array([ref[0], 0.0])
        demo = sample_maxent(TRUE, x0, ref, u_A, plant, rng)
        # The fit sees the states the data produced; it may or may not know u_A.
        fit_u_A = u_A if shared_in_fit else np.zeros(K)
        u_seen = demo.u_H if shared_in_fit else demo.u_H + u_A  # all torque attributed to the human
        est = identify_segment(prepare_batch(plant, [Segment(x0, ref, u_seen, fit_u_A)]), plant)
        assert est.converged
        z.append((np.log(est.theta1) - np.log(TRUE[0] / TRUE[2])) / est.se_log_theta1)
    return np.array(z)


def test_estimates_and_standard_errors_are_calibrated():
    # With exact max-ent data the z-scores of log θ1 are approximately N(0, 1): test the mean
    # (t-test) and the spread (chi-square on the variance), each at ALPHA.
    z = _zscores(True, True, seed=1)
    assert stats.ttest_1samp(z, 0.0).pvalue > ALPHA
    chi2 = (N_REP - 1) * np.var(z, ddof=1)
    p_var = 2 * min(stats.chi2.cdf(chi2, N_REP - 1), stats.chi2.sf(chi2, N_REP - 1))
    assert p_var > ALPHA


def test_calibration_test_catches_a_likelihood_that_ignores_u_A():
    # Negative control: the same test at the same size must flag a fit that treats the
    # assistant's torque as the human's.
    z = _zscores(True, False, seed=2)
    assert stats.ttest_1samp(z, 0.0).pvalue < ALPHA


def test_theta2_on_the_bound_is_reported_as_zero():
    plant = discretize(0.01)
    ref = reference_trajectory(30.0).angle[: K + 1]
    rng = np.random.default_rng(3)
    found_bound = False
    for _ in range(10):
        demo = sample_maxent(TRUE, [ref[0], 0.0], ref, np.zeros(K), plant, rng)
        est = identify_segment(prepare_batch(plant, [Segment(np.array([ref[0], 0.0]), ref, demo.u_H, np.zeros(K))]),
                               plant)
        assert est.theta2 >= 0.0
        if est.theta2 == 0.0:
            found_bound = True
            assert np.isnan(est.se_theta2) and np.isfinite(est.se_log_theta1)
    assert found_bound  # with θ2 = 0 true, about half the estimates sit on the bound


def test_rejects_a_batch_of_two():
    plant = discretize(0.01)
    seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    with pytest.raises(ValueError, match="one segment"):
        identify_segment(prepare_batch(plant, [seg, seg]), plant)


def test_a_units_trials_are_fitted_together():
    # Two trials of one unit (the same θ): identify_unit maximizes the sum of their log-likelihoods,
    # whether the trials come as one batch of two rows or as two batches (trials of different lengths).
    from scioc.models.identify import identify_unit
    from scioc.models.maxent import loglik_grad

    plant = discretize(0.01)
    ref = reference_trajectory(8.0).angle
    rng = np.random.default_rng(4)
    theta = np.array([400.0, 0.0, 20.0])
    segs = []
    for K in (600, 600, 400):
        demo = sample_maxent(theta, np.array([ref[0], 0.0]), ref[: K + 1], np.zeros(K), plant, rng)
        segs.append(Segment(np.array([ref[0], 0.0]), ref[: K + 1], demo.u_H[:K], np.zeros(K)))
    one = identify_unit([prepare_batch(plant, segs[:2])], plant)
    two = identify_unit([prepare_batch(plant, [s]) for s in segs[:2]], plant)
    assert one.loglik == pytest.approx(two.loglik, rel=1e-12)
    np.testing.assert_allclose(one.theta, two.theta, rtol=1e-6)
    parts = [loglik_grad(one.theta, prepare_batch(plant, [s]), plant).loglik[0] for s in segs[:2]]
    assert one.loglik == pytest.approx(sum(parts), rel=1e-12)
    # Three trials of unequal length, and more data: a smaller standard error than one trial's.
    three = identify_unit([prepare_batch(plant, segs[:2]), prepare_batch(plant, [segs[2]])], plant)
    single = identify_unit([prepare_batch(plant, [segs[0]])], plant)
    assert three.converged and three.se_log_theta1 < single.se_log_theta1
    assert abs(np.log(three.theta1 / 20.0)) < 3 * three.se_log_theta1
