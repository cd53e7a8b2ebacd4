"""The delayed human's bootstrap chain: its residuals are the likelihood's innovations, its p-values are
exactly uniform when the recorded data and the replicates share the model, and a wrong delay is caught."""

import numpy as np
import pytest
from scipy import stats as sps

from scioc.models import adequacy as adq
from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.bootstrap import Chain, bootstrap_records
from scioc.models.delayed import innovations, sample_delayed
from scioc.models.delayed.bootstrap import DelayedChain, delayed_records
from scioc.models.design import ENCODER_STEP, WheelParameters
from scioc.models.lq import lq_policy
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.reconstruct import apply_reconstruction, fixed_reconstruction
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Feedback, planning_plant, prepare_batch
from scioc.models.simulate import quantize

#: False-failure budget of each seeded statistical test in this module.
FALSE_FAILURE = 0.001
THETA = np.array([400.0, 0.0, 20.0])
#: The `combined` human's magnitudes (models.humans): delay 0.12 s, lag 0.06 s, motor noise 0.25 N·m.
DELAY, TAU_NM, SIGMA_M = 12, 0.06, 0.25
K, M = 300, 100


@pytest.fixture(scope="module")
def setting():
    plant = discretize(DT_HUMAN)
    ref = reference_trajectory(DT_HUMAN * (K + M + 400)).angle[400:]  # a stretch of the run, not its start
    fb = human_feedback(design_assistant(), reference_trajectory(DT_HUMAN * (K + M + 800)).angle)
    return plant, ref, Feedback(fb.gain, fb.feedforward[400 : 400 + K + M])


def _window(plant, ref, rng, *, feedback=None, u_A=None, x0=(0.05, -0.1), tau0=0.2, **model):
    """One window drawn from the delayed human, planning over the window and M preview steps."""
    kw = dict(tau_nm=TAU_NM, sigma_m=SIGMA_M, delay=DELAY) | model
    return sample_delayed(THETA, np.array(x0), ref, plant, rng, feedback=feedback, u_A=u_A, tau0=tau0, n_obs=K, **kw)


def _chain(plant, ref, draw, *, feedback=None, u_A=None, recon=None, tau0=0.2, **model) -> DelayedChain:
    """The chain of a window whose span is the window (w0 = 0); with ``recon``, the encoder angle is reconstructed."""
    kw = dict(tau_nm=TAU_NM, sigma_m=SIGMA_M, delay=DELAY) | model
    gain = np.zeros(2) if feedback is None else feedback.gain
    known = feedback.feedforward if feedback is not None else (np.zeros(K + M) if u_A is None else u_A)
    angle, x0w = draw.x[:, 0], draw.x[0]
    ua = np.append(draw.u_A, 0.0)
    if recon is not None:
        angle = quantize(angle)
        ang, vel, _ = apply_reconstruction(*(recon.F, recon.b, recon.A, recon.Kg, recon.Sv, recon.C), angle, ua)
        x0w = np.array([ang[0], vel[0]])  # the recorded row starts where its own reconstruction says
    return DelayedChain(plant=plant, params=WheelParameters(), theta=THETA, tau0=tau0, gain=gain,
                        feedback=feedback is not None, known=np.asarray(known, float), ref=ref, x0=draw.x[0],
                        x0_window=x0w, angle=angle, velocity=draw.x[:, 1], u_H=np.append(draw.u_H, 0.0), u_A=ua,
                        w0=0, K=K, M=M, recon=None if recon is None else tuple(recon[i] for i in (0, 3, 4, 5)),
                        resolution=ENCODER_STEP, **kw)


@pytest.mark.parametrize("assistant", ["none", "feedback", "exogenous"])
def test_the_recorded_rows_residuals_are_the_likelihoods_innovations(setting, assistant):
    plant, ref, fb = setting
    rng = np.random.default_rng(1)
    kw = {"feedback": fb} if assistant == "feedback" else {"u_A": fb.feedforward} if assistant == "exogenous" else {}
    draw = _window(plant, ref, rng, **kw)
    rec = delayed_records(_chain(plant, ref, draw, **kw), 3, rng)
    seg = draw.segments[0]
    z = innovations(THETA, prepare_batch(plant, [seg]), plant, tau_nm=TAU_NM, sigma_m=SIGMA_M, delay=DELAY, tau0=0.2)
    np.testing.assert_allclose(rec.z[0], z[0], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rec.torque[0], draw.u_H)


@pytest.mark.parametrize("assistant", ["none", "feedback"])
def test_without_delay_lag_and_motor_noise_it_is_the_maxent_bootstrap(setting, assistant):
    """Same random draws: equal records to rounding (the 3-state plan on the lagged wheel and the innovations
    kernel sum in other orders than the max-ent plan and residual pass), hence the same p-values."""
    plant, ref, fb = setting
    feedback = fb if assistant == "feedback" else None
    rng = np.random.default_rng(2)
    draw = _window(plant, ref, rng, feedback=feedback, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0)
    dc = _chain(plant, ref, draw, feedback=feedback, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0)
    gain = np.zeros(2) if feedback is None else fb.gain
    pol = lq_policy(planning_plant(plant, gain), THETA, ref, dc.known)
    mc = Chain(A=plant.A, b=plant.b, gain=gain, known=dc.known[:K], L=pol.L[:K], f=pol.f[:K], S=pol.S[:K],
               x0=dc.x0, angle=dc.angle, velocity=dc.velocity, u_H=dc.u_H, u_A=dc.u_A, ref=ref[: K + 1], w0=0, K=K,
               recon=None, resolution=0.0, noise_scale=0.8)
    a = bootstrap_records(mc, 19, np.random.default_rng(3))
    b = delayed_records(dc._replace(noise_scale=0.8), 19, np.random.default_rng(3))
    for name, x, y in zip(a._fields, a, b):
        np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-9 * np.max(np.abs(x)), err_msg=name)
    sa, sb = adq.segment_adequacy(a, DT_HUMAN), adq.segment_adequacy(b, DT_HUMAN)
    assert sa.p == sb.p and sa.p_segment == sb.p_segment


def test_same_seed_same_bits(setting):
    plant, ref, fb = setting
    draw = _window(plant, ref, np.random.default_rng(4), feedback=fb)
    chain = _chain(plant, ref, draw, feedback=fb)
    a = delayed_records(chain, 5, np.random.default_rng(5))
    b = delayed_records(chain, 5, np.random.default_rng(5))
    for x, y in zip(a, b):
        assert x.tobytes() == y.tobytes()


def _pvalues(setting, n_windows, B, rng, *, recon, judged_delay=DELAY):
    """Per-statistic and min-P p-values of windows drawn from the model, judged at ``judged_delay``."""
    plant, ref, fb = setting
    fixed = fixed_reconstruction(plant, K + 1, 0.1, 1e-4) if recon else None
    P = []
    for i in range(n_windows):
        feedback = fb if i % 2 else None  # MC and SC windows alternate
        draw = _window(plant, ref, rng, feedback=feedback)
        chain = _chain(plant, ref, draw, feedback=feedback, recon=fixed, delay=judged_delay)
        res = adq.segment_adequacy(delayed_records(chain, B, rng), DT_HUMAN)
        P.append([res.p[k] for k in adq.STATISTICS] + [res.p_segment])
    return np.array(P)


@pytest.mark.parametrize("recon", [False, True], ids=["measured", "reconstructed"])
def test_pvalues_exactly_uniform_when_data_and_replicates_share_the_model(setting, recon):
    """Windows drawn from the delayed human itself, judged at the true parameters over the same plan and
    acquisition: the recorded row is exchangeable with the replicates, so every p-value is uniform on
    {1/20, ..., 1}. χ² goodness of fit per statistic, false-failure budget FALSE_FAILURE per test (7 tests
    per acquisition: ≤ 0.7 %)."""
    B, n = 19, 120
    P = _pvalues(setting, n, B, np.random.default_rng(6 + recon), recon=recon)
    grid = np.arange(1, B + 2) / (B + 1)
    for j in range(P.shape[1]):
        counts = np.array([np.sum(np.isclose(P[:, j], g)) for g in grid])
        assert counts.sum() == n  # ties (encoder angles, coverage) could only raise a p-value; none here
        assert sps.chisquare(counts).pvalue > FALSE_FAILURE, (j, counts)


def test_negative_control_a_wrong_delay_is_flagged(setting):
    """Windows with a true delay of 12 samples judged with d = 0. Measured on these 3-s windows: 21 of 40
    flagged at 5 % (53 %; 3 of 40 with the true delay). The test asks for at least 9 of 40: a rate of 53 %
    falls below with probability 2e-5, a valid check at 5 % reaches it with probability 1.3e-4."""
    P = _pvalues(setting, 40, 19, np.random.default_rng(8), recon=True, judged_delay=0)
    assert np.sum(P[:, -1] <= adq.SEGMENT_ALPHA) >= 9


def test_invalid_chains_are_refused(setting):
    plant, ref, fb = setting
    chain = _chain(plant, ref, _window(plant, ref, np.random.default_rng(9)))
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="at least one replicate"):
        delayed_records(chain, 0, rng)
    with pytest.raises(ValueError, match="does not fit"):
        delayed_records(chain._replace(K=K + 5), 3, rng)
    with pytest.raises(ValueError, match="cover the span and the plan"):
        delayed_records(chain._replace(known=chain.known[:K]), 3, rng)
    with pytest.raises(ValueError, match="whole delay"):
        delayed_records(chain._replace(delay=-1), 3, rng)
