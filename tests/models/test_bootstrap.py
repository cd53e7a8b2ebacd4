"""The bootstrap chain: residuals equal the kernel's; p-values exactly uniform when data and replicates share the model."""

import numpy as np
import pytest
from scipy import stats as sps

from scioc.models import adequacy as adq
from scioc.models.bootstrap import Chain, bootstrap_records
from scioc.models.lq import lq_policy
from scioc.models.maxent import loglik_grad
from scioc.models.plant import DT_HUMAN, discretize, propagate
from scioc.models.segment import Segment, planning_plant, prepare_batch
from scioc.models.simulate import Population, simulate_windows

#: False-failure budget of each seeded statistical test in this module.
FALSE_FAILURE = 0.001


def _measured_chain(seg: Segment, theta, plant, horizon_ref, horizon_known, gain) -> Chain:
    """A chain for a segment whose velocity and torque were recorded exactly (no encoder)."""
    K = seg.K
    plan = planning_plant(plant, gain) if np.any(gain) else plant
    pol = lq_policy(plan, theta, horizon_ref, horizon_known)
    x = propagate(plant, seg.x0, seg.u_H + seg.u_A[:K])
    c = np.ascontiguousarray
    return Chain(A=c(plant.A), b=c(plant.b), gain=np.asarray(gain, float), known=c(horizon_known[:K]),
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
        z = bootstrap_records(chain, 1, np.random.default_rng(0)).z[0]
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
    from scioc.models.assistant import design_assistant, human_feedback
    from scioc.models.reference import reference_trajectory

    full_ref = reference_trajectory(DT_HUMAN * (K + 100 + 200)).angle
    fb = human_feedback(design_assistant(), full_ref)
    P = []
    for seg, th in zip(w.segments, w.theta.T):
        # The replicates plan over the same horizon as the simulated run did.
        if seg.feedback is None:
            chain = _measured_chain(seg, th, plant, full_ref, np.zeros(full_ref.shape[0] - 1), np.zeros(2))
        else:
            chain = _measured_chain(seg, th, plant, full_ref, fb.feedforward, fb.gain)
        res = adq.segment_adequacy(bootstrap_records(chain, B, rng), DT_HUMAN)
        P.append([res.p[k] for k in adq.STATISTICS] + [res.p_segment])
    P = np.array(P)
    grid = np.arange(1, B + 2) / (B + 1)
    for j in range(P.shape[1]):
        # Ties can only raise a p-value; on continuous statistics they do not occur.
        counts = np.array([np.sum(np.isclose(P[:, j], g)) for g in grid])
        assert counts.sum() == P.shape[0]
        assert sps.chisquare(counts).pvalue > FALSE_FAILURE, (j, counts)
