"""The ``delayed`` sampler: its draws have the likelihood's distribution, and it keeps the data convention."""

import numpy as np
import pytest
from scipy import stats

from scioc.models.delayed import closed_loop, forward_delayed, innovations, lag_coefficients, sample_delayed
from scioc.models.delayed.sample import delayed_setup
from scioc.models.maxent import forward_optimal_control, sample_maxent
from scioc.models.plant import propagate
from scioc.models.segment import Feedback, plan_inputs, prepare_batch

#: False-failure budget of each seeded statistical check below (two-sided z-tests and a KS test).
ALPHA = 1e-3
Z_CRIT = stats.norm.isf(ALPHA / 2)

THETA = np.array([300.0, 0.2, 5.0])
K, M, N_DRAWS = 120, 30, 400
PAR = dict(tau_nm=0.06, sigma_m=0.25, delay=12, tau0=0.1)


def _draws(plant, mode, seed, **par):
    """N_DRAWS windows drawn from the delayed human, as one batch."""
    rng = np.random.default_rng(seed)
    t = np.arange(K + M + 1) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    kw = {}
    if mode == "SC feedback":
        kw["feedback"] = Feedback(np.array([2.0, 0.2]), 0.1 * np.sin(t[:-1]))
    elif mode == "SC exogenous":
        kw["u_A"] = 0.2 * np.cos(2 * np.pi * 0.3 * t[:-1])
    draw = sample_delayed(THETA, [0.05, 0.0], ref, plant, rng, n_obs=K, size=N_DRAWS, **kw, **par)
    return prepare_batch(plant, draw.segments)


def _z_statistics(e):
    """z-scores of the pooled mean, variance and lag-1..3 autocorrelations of iid N(0, 1) innovations (n, K)."""
    n = e.size
    z = {"mean": e.mean() * np.sqrt(n), "variance": (np.mean(e * e) - 1.0) / np.sqrt(2.0 / n)}
    for lag in (1, 2, 3):
        prods = e[:, lag:] * e[:, :-lag]
        z[f"lag {lag}"] = prods.mean() * np.sqrt(prods.size)
    return z


@pytest.mark.parametrize("mode", ["MC", "SC feedback", "SC exogenous"])
def test_draws_have_the_likelihoods_distribution(plant, mode):
    # Under the model the standardized innovations of every window are iid N(0, 1).
    batch = _draws(plant, mode, [31, len(mode)], **PAR)
    e = innovations(THETA, batch, plant, **PAR)
    for name, z in _z_statistics(e).items():
        assert abs(z) < Z_CRIT, (name, z)
    assert stats.kstest(e.ravel(), "norm").pvalue > ALPHA


def test_the_check_catches_a_wrong_delay(plant):
    # Negative control: the same draws read with no delay (the paper's human) must fail.
    batch = _draws(plant, "SC feedback", 32, **PAR)
    e = innovations(THETA, batch, plant, **{**PAR, "delay": 0})
    z = _z_statistics(e)
    assert max(abs(v) for v in z.values()) > Z_CRIT, z


def test_without_motor_noise_the_delay_is_invisible(plant):
    # The prediction from d samples ago is exact when nothing unknown enters the loop.
    t = np.arange(201) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    fb = Feedback(np.array([2.0, 0.2]), 0.1 * np.sin(t[:-1]))
    a = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(33), feedback=fb, tau_nm=0.06, delay=0)
    b = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(33), feedback=fb, tau_nm=0.06, delay=17)
    np.testing.assert_allclose(b.u_H, a.u_H, rtol=0, atol=1e-12)


@pytest.mark.parametrize("shared", [False, True])
def test_without_delay_lag_and_motor_noise_it_is_the_maxent_sampler(plant, shared):
    t = np.arange(151) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    u_A = 0.2 * np.cos(2 * np.pi * 0.3 * t[:-1]) if shared else np.zeros(150)
    ours = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(34), u_A=u_A)
    theirs = sample_maxent(THETA, [0.05, 0.0], ref, u_A, plant, np.random.default_rng(34))
    np.testing.assert_allclose(ours.u_H, theirs.u_H, rtol=0, atol=1e-11)
    np.testing.assert_allclose(ours.x, theirs.x, rtol=0, atol=1e-11)


def test_draws_keep_the_data_convention(plant):
    t = np.arange(K + M + 1) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    fb = Feedback(np.array([2.0, 0.2]), 0.1 * np.sin(t[:-1]))
    draw = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(35), feedback=fb, n_obs=K,
                          physical=False, **PAR)
    # the wheel moves with the recorded torques; the assistant's law acts on the true state
    np.testing.assert_allclose(propagate(plant, draw.x[0], draw.u_H + draw.u_A), draw.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(draw.u_A, fb.feedforward[:K] - draw.x[:-1] @ fb.gain, rtol=0, atol=1e-13)
    # the arm torque follows the lag of the effective command recovered from u_H
    lag = lag_coefficients(PAR["tau_nm"])
    c = (draw.u_H - lag.alpha * draw.tau[:-1]) / (1 - lag.alpha)
    np.testing.assert_allclose(draw.tau[1:], lag.a * draw.tau[:-1] + (1 - lag.a) * c, rtol=0, atol=1e-12)
    assert draw.tau[0] == PAR["tau0"]
    seg = draw.segments[0]
    assert seg.K == K and seg.preview == M and seg.feedback is fb
    assert np.array_equal(plan_inputs(seg, plant)[1], fb.feedforward)


def test_shapes(plant):
    ref = np.zeros(51)
    one = sample_delayed(THETA, [0.0, 0.0], ref, plant, np.random.default_rng(36), n_obs=40)
    many = sample_delayed(THETA, [0.0, 0.0], ref, plant, np.random.default_rng(36), n_obs=40, size=3)
    assert (one.x.shape, one.u_H.shape, one.u_A.shape, one.tau.shape) == ((41, 2), (40,), (40,), (41,))
    assert (many.x.shape, many.u_H.shape, many.tau.shape) == ((41, 2, 3), (40, 3), (41, 3))
    assert len(many.segments) == 3 and many.segments[2].u_A.shape == (50,)


def test_invalid_arguments_are_refused(plant):
    rng = np.random.default_rng(37)
    ref = np.zeros(11)
    with pytest.raises(ValueError, match="either"):
        sample_delayed(THETA, [0, 0], ref, plant, rng, u_A=np.zeros(10), feedback=Feedback(np.zeros(2), np.zeros(10)))
    with pytest.raises(ValueError, match="10 samples"):
        sample_delayed(THETA, [0, 0], ref, plant, rng, u_A=np.zeros(9))
    for kw in (dict(delay=-1), dict(delay=1.5), dict(sigma_m=-1.0), dict(n_obs=11), dict(n_obs=0)):
        with pytest.raises(ValueError, match="n_obs"):
            sample_delayed(THETA, [0, 0], ref, plant, rng, **kw)
    with pytest.raises(ValueError, match="tau_nm"):
        sample_delayed(THETA, [0, 0], ref, plant, rng, tau_nm=-0.1)


def test_physical_draws_move_on_the_lagged_wheel(plant):
    # A physical arm: u_H is the ZOH-equivalent torque (the velocity row is exact), the angle differs from
    # the held-torque convention by the torque's shape within the sample; without a lag both are one thing.
    t = np.arange(K + M + 1) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    fb = Feedback(np.array([2.0, 0.2]), 0.1 * np.sin(t[:-1]))
    draw = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(35), feedback=fb, n_obs=K, **PAR)
    held = np.empty_like(draw.x)
    held[0] = draw.x[0]
    for k in range(K):  # one step from the true state with the recorded torques held
        held[k + 1] = plant.A @ draw.x[k] + plant.b * (draw.u_H[k] + draw.u_A[k])
    np.testing.assert_allclose(held[1:, 1], draw.x[1:, 1], rtol=0, atol=1e-12)
    step = np.abs(held[1:, 0] - draw.x[1:, 0])
    assert 1e-8 < np.max(step) < 5e-5  # rad per step: present, and small
    np.testing.assert_allclose(draw.u_A, fb.feedforward[:K] - draw.x[:-1] @ fb.gain, rtol=0, atol=1e-13)
    no_lag = {**PAR, "tau_nm": 0.0}
    a = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(35), feedback=fb, n_obs=K, **no_lag)
    b = sample_delayed(THETA, [0.05, 0.0], ref, plant, np.random.default_rng(35), feedback=fb, n_obs=K,
                       physical=False, **no_lag)
    assert np.array_equal(a.u_H, b.u_H) and np.array_equal(a.x, b.x)


@pytest.mark.parametrize("mode", ["MC", "SC feedback", "SC exogenous"])
def test_the_mean_behaviour_is_the_mean_of_the_draws(plant, mode):
    # The loop is affine in its noises: a draw and its mirror (every noise negated) average to the noise-free run.
    t = np.arange(K + M + 1) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    kw = {"feedback": Feedback(np.array([2.0, 0.2]), 0.1 * np.sin(t[:-1]))} if mode == "SC feedback" else \
        {"u_A": 0.2 * np.cos(2 * np.pi * 0.3 * t[:-1])} if mode == "SC exogenous" else {}
    mean = forward_delayed(THETA, [0.05, 0.0], ref, plant, tau_nm=PAR["tau_nm"], tau0=PAR["tau0"], n_obs=K, **kw)
    setup = delayed_setup(THETA, ref, plant, tau_nm=PAR["tau_nm"], physical=True, **kw)
    rng = np.random.default_rng(36)
    eps = rng.standard_normal((K, 1)) / np.sqrt(2.0 * setup.policy.S[:K, None])
    m = rng.standard_normal((K + PAR["delay"], 1)) * PAR["sigma_m"]
    z0 = np.array([0.05, 0.0, PAR["tau0"]])
    runs = [closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                        setup.feedback, setup.known, setup.policy.L, setup.policy.f, z0, s * eps, s * m, PAR["delay"],
                        setup.true_A, setup.true_b, setup.physical) for s in (1.0, -1.0)]
    assert np.abs(runs[0][1] - mean.u_H[:, None]).max() > 1e-2  # the noises matter
    np.testing.assert_allclose((runs[0][0][:, :2, 0] + runs[1][0][:, :2, 0]) / 2, mean.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose((runs[0][1][:, 0] + runs[1][1][:, 0]) / 2, mean.u_H, rtol=0, atol=1e-12)


@pytest.mark.parametrize("shared", [False, True])
def test_without_lag_the_mean_behaviour_is_the_maxent_humans(plant, shared):
    t = np.arange(151) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t)
    u_A = 0.2 * np.cos(2 * np.pi * 0.3 * t[:-1]) if shared else np.zeros(150)
    ours = forward_delayed(THETA, [0.05, 0.0], ref, plant, u_A=u_A)
    theirs = forward_optimal_control(THETA, [0.05, 0.0], ref, u_A, plant)
    np.testing.assert_allclose(ours.u_H, theirs.u_H, rtol=0, atol=1e-11)
    np.testing.assert_allclose(ours.x, theirs.x, rtol=0, atol=1e-11)
    lagged = forward_delayed(THETA, [0.05, 0.0], ref, plant, u_A=u_A, tau_nm=0.08)
    assert np.abs(lagged.u_H - theirs.u_H).max() > 1e-2  # the lag is not ignored
