"""Adequacy statistics against direct computations; residuals against the kernel; exact uniformity."""

import numpy as np
import pytest
from scipy import stats as sps
from statsmodels.tsa.stattools import acf

from models import adequacy as adq
from models.lq import lq_policy
from models.maxent import loglik_grad
from models.plant import DT_HUMAN, discretize, propagate
from models.segment import Segment, planning_plant, prepare_batch
from models.simulate import Population, simulate_windows

#: False-failure budget of each seeded statistical test in this module.
FALSE_FAILURE = 0.001


def test_autocorrelation_matches_statsmodels():
    x = np.random.default_rng(1).standard_normal((3, 200)).cumsum(axis=1)
    got = adq.autocorrelation(x, 7)
    for row, g in zip(x, got):
        np.testing.assert_allclose(g, acf(row, nlags=7, fft=False)[1:], rtol=1e-12, atol=1e-14)


def test_cross_correlation_matches_direct_sum():
    rng = np.random.default_rng(2)
    e, u = rng.standard_normal((2, 4, 97))
    got = adq.cross_correlation(e, u, 12)
    for i in range(4):
        ec, uc = e[i] - e[i].mean(), u[i] - u[i].mean()
        den = np.sqrt(np.sum(ec**2) * np.sum(uc**2))
        want = [sum(ec[k - lag] * uc[k] for k in range(lag, 97)) / den for lag in range(13)]
        np.testing.assert_allclose(got[i], want, rtol=1e-12, atol=1e-14)


def test_band_log_power_matches_explicit_dft():
    rng = np.random.default_rng(3)
    u = rng.standard_normal((2, 64))
    dt = 0.01
    got = adq.band_log_power(u, dt, bands=((0.0, 10.0), (10.0, 25.0), (25.0, 50.0)))
    freq = np.arange(33) / (64 * dt)
    k = np.arange(64)
    for i in range(2):
        uc = u[i] - u[i].mean()
        power = np.array([abs(np.sum(uc * np.exp(-2j * np.pi * m * k / 64))) ** 2 for m in range(33)])
        for j, (lo, hi) in enumerate(((0.0, 10.0), (10.0, 25.0), (25.0, 50.0))):
            sel = (freq > lo) & (freq <= hi)
            assert got[i, j] == pytest.approx(np.log(power[sel].sum() / 64), rel=1e-12)


def test_coverage_matches_ranks():
    x = np.random.default_rng(4).standard_normal((20, 50))
    got = adq.coverage(x, 0.9)
    ranks = np.argsort(np.argsort(x, axis=0), axis=0)  # continuous data: no ties
    np.testing.assert_allclose(got, ((ranks >= 1) & (ranks <= 18)).mean(axis=1))
    assert got.mean() == pytest.approx(18 / 20)  # every sample has exactly 18 rows inside


def test_discrepancy_and_exceedance():
    s = np.array([0.0, 1.0, 2.0, 3.0, 10.0])
    T = adq.discrepancy(s)  # |s - 3.2|
    np.testing.assert_allclose(T, [3.2, 2.2, 1.2, 0.2, 6.8])
    np.testing.assert_allclose(adq.exceedance(T), [0.4, 0.6, 0.8, 1.0, 0.2])
    v = np.array([[0.0, 0.0], [1.0, 2.0], [2.0, 4.0]])
    np.testing.assert_allclose(adq.discrepancy(v), [2.0, 0.0, 2.0])  # standardized per column


def test_fisher_matches_scipy():
    p = np.array([0.02, 0.5, 0.9, 0.04])
    assert adq.fisher(p) == pytest.approx(sps.combine_pvalues(p, method="fisher").pvalue, rel=1e-12)


def test_study_verdict_bonferroni():
    ok = {k: np.full(10, 0.5) for k in adq.STATISTICS}
    assert adq.study_verdict(ok, np.full(10, 0.5))["verdict"] == "pass"
    bad = dict(ok, xcorr=np.full(10, 0.02))
    res = adq.study_verdict(bad, np.full(10, 0.5))
    assert res["verdict"] == "fail" and res["failed_checks"] == ["xcorr"]


# --------------------------------------------------------------------------- the chain


def _measured_chain(seg: Segment, theta, plant, horizon_ref, horizon_known, gain) -> adq.Chain:
    """A chain for a segment whose velocity and torque were recorded exactly (no encoder)."""
    K = seg.K
    plan = planning_plant(plant, gain) if np.any(gain) else plant
    pol = lq_policy(plan, theta, horizon_ref, horizon_known)
    x = propagate(plant, seg.x0, seg.u_H + seg.u_A[:K])
    c = np.ascontiguousarray
    return adq.Chain(A=c(plant.A), b=c(plant.b), gain=np.asarray(gain, float), known=c(horizon_known[:K]),
                     L=c(pol.L[:K]), f=c(pol.f[:K]), S=c(pol.S[:K]), x0=np.asarray(seg.x0, float),
                     angle=c(x[:, 0]), velocity=c(x[:, 1]), u_H=np.append(seg.u_H, 0.0),
                     u_A=np.append(seg.u_A[:K], 0.0), ref=c(seg.angle_ref[: K + 1]), w0=0, K=K, recon=None,
                     resolution=0.0)


def test_residuals_are_the_kernels():
    """Σ [-z²/2 + ½ log 2S - ½ log 2π] over the recorded row equals the O(K) log-likelihood."""
    plant = discretize(DT_HUMAN)
    w = simulate_windows(2, np.random.default_rng(5), K=400, preview=100)
    for seg, th in zip(w.segments, w.theta.T):
        gain = np.zeros(2) if seg.feedback is None else seg.feedback.gain
        known = seg.u_A if seg.feedback is None else seg.feedback.feedforward
        chain = _measured_chain(seg, th, plant, seg.angle_ref, known, gain)
        z = adq.bootstrap_records(chain, 1, np.random.default_rng(0)).z[0]
        S = chain.S
        ll = np.sum(-0.5 * z**2 + 0.5 * np.log(2 * S) - 0.5 * np.log(2 * np.pi))
        ref = loglik_grad(th, prepare_batch(plant, [seg]), plant).loglik[0]
        assert ll == pytest.approx(ref, rel=1e-9)


def test_pvalues_exactly_uniform_when_data_and_replicates_share_the_model():
    """True θ, true torques: the recorded row is exchangeable with the replicates, so every
    p-value is uniform on {1/20, ..., 1}. χ² goodness of fit per statistic, false-failure
    budget FALSE_FAILURE per test (7 tests: ≤ 0.7 %)."""
    plant = discretize(DT_HUMAN)
    K, B, n_sub = 300, 19, 120
    rng = np.random.default_rng(6)
    w = simulate_windows(n_sub, rng, Population(), K=K, preview=100)
    from models.assistant import design_assistant, human_feedback
    from models.reference import reference_trajectory

    full_ref = reference_trajectory(DT_HUMAN * (K + 100 + 200)).angle
    fb = human_feedback(design_assistant(), full_ref)
    P = []
    for seg, th in zip(w.segments, w.theta.T):
        # The replicates plan over the same horizon as the simulated run did.
        if seg.feedback is None:
            chain = _measured_chain(seg, th, plant, full_ref, np.zeros(full_ref.shape[0] - 1), np.zeros(2))
        else:
            chain = _measured_chain(seg, th, plant, full_ref, fb.feedforward, fb.gain)
        res = adq.segment_adequacy(adq.bootstrap_records(chain, B, rng), DT_HUMAN)
        P.append([res.p[k] for k in adq.STATISTICS] + [res.p_segment])
    P = np.array(P)
    grid = np.arange(1, B + 2) / (B + 1)
    for j in range(P.shape[1]):
        # Ties can only raise a p-value; on continuous statistics they do not occur.
        counts = np.array([np.sum(np.isclose(P[:, j], g)) for g in grid])
        assert counts.sum() == P.shape[0]
        assert sps.chisquare(counts).pvalue > FALSE_FAILURE, (j, counts)
