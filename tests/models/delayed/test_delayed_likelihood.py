"""The linear-time ``delayed`` likelihood against the dense joint Gaussian, the max-ent kernel,
finite differences and itself (held steady state or not)."""

import numpy as np
import pytest

from scioc.models.delayed import loglik, loglik_dense, loglik_grad, sample_delayed
from scioc.models.maxent import loglik_grad as maxent_loglik_grad
from scioc.models.segment import Segment, prepare_batch
from tests.conftest import random_segment, random_theta, random_window_inputs

MODES = ("MC", "SC feedback", "SC exogenous")


def window(rng, plant, K, M, mode, *, drawn, theta=None, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0):
    """A window of K observed steps and M preview steps.

    ``drawn``: torques drawn from the model itself; otherwise arbitrary torques. With the
    assistant's law, the recorded u_A follows it on the states the torques drive (the
    likelihood's states come from the recorded u_A, the dense reference's from the law).
    """
    ref, x0, fb, u_A, kw = random_window_inputs(rng, plant, K, M, mode)
    if drawn:
        return sample_delayed(theta, x0, ref, plant, rng, tau_nm=tau_nm, sigma_m=sigma_m, delay=delay, tau0=tau0,
                              n_obs=K, physical=False, **kw).segments[0]  # the likelihood's convention
    u_H = rng.normal(0.0, 0.5, K)
    if mode == "MC":
        return Segment(x0, ref, u_H, np.zeros(K + M))
    if mode == "SC exogenous":
        return Segment(x0, ref, u_H, u_A)
    x, rec = x0.copy(), fb.feedforward.copy()
    for k in range(K):
        rec[k] = fb.feedforward[k] - fb.gain @ x
        x = plant.A @ x + plant.b * (u_H[k] + rec[k])
    return Segment(x0, ref, u_H, rec, fb)


def _random_case(i):
    rng = np.random.default_rng([21, i])
    return dict(K=int(rng.integers(40, 201)), M=int(rng.choice([0, 25, 120])), mode=MODES[i % 3],
                delay=int(rng.integers(0, 31)), tau_nm=float(rng.choice([0.0, 0.05, 0.1])),
                sigma_m=float(rng.choice([0.0, 0.1, 0.3])), drawn=bool(i % 2), tau0=float(rng.normal(0, 0.2)))


CASES = [_random_case(i) for i in range(24)] + [
    dict(K=40, M=0, mode="SC feedback", delay=30, tau_nm=0.1, sigma_m=0.3, drawn=True, tau0=0.1),
    dict(K=20, M=10, mode="MC", delay=30, tau_nm=0.05, sigma_m=0.3, drawn=False, tau0=0.0),  # delay longer than K
    dict(K=1, M=5, mode="SC exogenous", delay=12, tau_nm=0.1, sigma_m=0.1, drawn=False, tau0=0.3),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c['mode']}-K{c['K']}-M{c['M']}-d{c['delay']}-"
                                                      f"tau{c['tau_nm']}-sig{c['sigma_m']}")
def test_linear_time_equals_dense(plant, case):
    rng = np.random.default_rng([22, case["K"], case["delay"]])
    theta = random_theta(rng, False)
    par = {k: case[k] for k in ("tau_nm", "sigma_m", "delay", "tau0")}
    seg = window(rng, plant, case["K"], case["M"], case["mode"], drawn=case["drawn"], theta=theta, **par)
    dense = loglik_dense(theta, seg, plant, **par)
    batch = prepare_batch(plant, [seg])
    for freeze in (True, False):
        fast = loglik_grad(theta, batch, plant, freeze=freeze, **par)
        assert abs(fast.loglik[0] - dense.loglik) <= 1e-9 * abs(dense.loglik)


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("K, M", [(60, 0), (400, 50)])
def test_without_delay_lag_and_motor_noise_it_is_the_maxent_likelihood(plant, mode, K, M):
    rng = np.random.default_rng([23, K, MODES.index(mode)])
    seg = window(rng, plant, K, M, mode, drawn=False)
    batch = prepare_batch(plant, [seg])
    for q22_zero in (True, False):
        theta = random_theta(rng, q22_zero)
        ref = maxent_loglik_grad(theta, batch, plant)
        res = loglik_grad(theta, batch, plant)
        assert abs(res.loglik[0] - ref.loglik[0]) <= 1e-12 * abs(ref.loglik[0])
        # q11, q22, R: the same gradient, to rounding relative to its size
        assert np.max(np.abs(res.grad[:3, 0] - ref.grad[:, 0])) <= 1e-10 * np.max(np.abs(ref.grad))
        assert res.grad[4, 0] == 0.0  # the likelihood depends on σ_m²


GRAD_CASES = [
    dict(K=300, M=200, mode="MC", delay=12, tau_nm=0.06, sigma_m=0.25),
    dict(K=250, M=0, mode="SC feedback", delay=25, tau_nm=0.1, sigma_m=0.1),
    dict(K=200, M=30, mode="SC exogenous", delay=4, tau_nm=0.05, sigma_m=0.3),
    dict(K=900, M=200, mode="SC feedback", delay=10, tau_nm=0.06, sigma_m=0.25),  # a held steady state and a tail
    dict(K=150, M=450, mode="MC", delay=8, tau_nm=0.08, sigma_m=0.2),  # steady within the preview: every row held
]


@pytest.mark.parametrize("case", GRAD_CASES, ids=lambda c: f"{c['mode']}-K{c['K']}-d{c['delay']}")
def test_gradient_matches_central_differences(plant, case):
    rng = np.random.default_rng([24, case["K"]])
    theta = np.array([rng.uniform(50.0, 400.0), rng.uniform(0.1, 1.0), rng.uniform(1.0, 20.0)])
    par = dict(tau_nm=case["tau_nm"], sigma_m=case["sigma_m"], delay=case["delay"], tau0=0.1)
    seg = window(rng, plant, case["K"], case["M"], case["mode"], drawn=True, theta=theta, **par)
    batch = prepare_batch(plant, [seg])
    p0 = np.array([*theta, case["tau_nm"], case["sigma_m"]])

    def ll(p):
        return loglik_grad(p[:3], batch, plant, tau_nm=p[3], sigma_m=p[4], delay=case["delay"], tau0=0.1).loglik[0]

    grad = loglik_grad(theta, batch, plant, **par).grad[:, 0]
    for j in range(5):
        h = 1e-5 * p0[j]
        up, down = p0.copy(), p0.copy()
        up[j] += h
        down[j] -= h
        fd = (ll(up) - ll(down)) / (2 * h)
        # O(h²) truncation and eps·|ll|/h rounding are both below 1e-7 relative here
        assert abs(fd - grad[j]) <= 1e-6 * abs(grad[j]), (j, fd, grad[j])


def test_tau_derivative_at_zero_is_one_sided(plant):
    rng = np.random.default_rng(25)
    theta = np.array([200.0, 0.3, 5.0])
    seg = window(rng, plant, 150, 20, "SC feedback", drawn=True, theta=theta, delay=8, sigma_m=0.2)
    batch = prepare_batch(plant, [seg])

    def ll(tau):
        return loglik_grad(theta, batch, plant, tau_nm=tau, sigma_m=0.2, delay=8).loglik[0]

    # second-order one-sided difference; exp(-dt/h) underflows, only α moves. The likelihood
    # bends strongly in τ_nm near 0 (the error is 1e-3 relative at h = 1e-4, 1e-7 here).
    h = 3e-7
    fd = (-3 * ll(0.0) + 4 * ll(h) - ll(2 * h)) / (2 * h)
    g = loglik_grad(theta, batch, plant, sigma_m=0.2, delay=8).grad[3, 0]
    assert g == pytest.approx(fd, rel=1e-6)


def test_holding_the_steady_state_changes_nothing_but_rounding(plant):
    rng = np.random.default_rng(26)
    K, M = 1500, 200
    segs, thetas, delays = [], [], [0, 10, 30, 30, 10, 0]
    for i, d in enumerate(delays):
        theta = np.array([rng.uniform(100.0, 600.0), rng.uniform(0.0, 0.5), rng.uniform(5.0, 30.0)])
        segs.append(window(rng, plant, K, M, MODES[i % 3], drawn=True, theta=theta, tau_nm=0.06, sigma_m=0.25,
                           delay=d))
        thetas.append(theta)
    batch = prepare_batch(plant, segs)
    par = dict(tau_nm=0.06, sigma_m=0.25, delay=delays)
    held = loglik_grad(np.column_stack(thetas), batch, plant, **par)
    full = loglik_grad(np.column_stack(thetas), batch, plant, freeze=False, **par)
    # the held quantities differ from the moving ones by <= FREEZE_RTOL relative; over 1500
    # steps and a few hundred transient rows that adds up to about 1e-13 of the gradient
    np.testing.assert_allclose(held.loglik, full.loglik, rtol=1e-12)
    for i in range(len(delays)):
        np.testing.assert_allclose(held.grad[:, i], full.grad[:, i], rtol=0,
                                   atol=1e-10 * np.abs(full.grad[:, i]).max())


def test_a_segments_result_does_not_depend_on_its_batch(plant):
    rng = np.random.default_rng(27)
    segs = [window(rng, plant, 300, 40, MODES[i % 3], drawn=False) for i in range(5)]
    thetas = np.column_stack([random_theta(rng, False) for _ in range(5)])
    par = dict(tau_nm=[0.0, 0.05, 0.1, 0.06, 0.06], sigma_m=[0.1, 0.0, 0.3, 0.25, 0.2], delay=[0, 3, 30, 12, 12],
               tau0=[0.0, 0.1, -0.1, 0.0, 0.2])
    together = loglik_grad(thetas, prepare_batch(plant, segs), plant, **par)
    for i, s in enumerate(segs):
        alone = loglik_grad(thetas[:, i], prepare_batch(plant, [s]), plant, **{k: v[i] for k, v in par.items()})
        assert alone.loglik[0] == together.loglik[i]
        assert np.array_equal(alone.grad[:, 0], together.grad[:, i])


def test_invalid_arguments_are_refused(plant):
    rng = np.random.default_rng(28)
    batch = prepare_batch(plant, [random_segment(rng, 30, False), random_segment(rng, 30, True)])
    theta = [10.0, 0.0, 1.0]
    bad = [
        (dict(delay=-1), "delay must be >= 0"),
        (dict(delay=2.5), "whole number"),
        (dict(delay=[1, 2, 3]), r"delay must be a scalar or have shape \(2,\)"),
        (dict(tau_nm=-0.01), "tau_nm must be >= 0"),
        (dict(tau_nm=np.nan), "tau_nm must be finite"),
        (dict(sigma_m=-0.1), "sigma_m must be >= 0"),
        (dict(tau0=np.inf), "tau0 must be finite"),
    ]
    for kw, msg in bad:
        with pytest.raises(ValueError, match=msg):
            loglik_grad(theta, batch, plant, **kw)
    with pytest.raises(ValueError, match=r"theta must have shape \(3,\) or \(3, 2\)"):
        loglik_grad(np.ones((3, 3)), batch, plant)
    with pytest.raises(ValueError, match="R must be > 0"):
        loglik_grad([10.0, 0.0, 0.0], batch, plant)
    with pytest.raises(ValueError, match="WheelParameters"):
        from scioc.models.design import WheelParameters

        loglik_grad(theta, batch, plant, tau_nm=0.06, params=WheelParameters(inertia=0.05))
    with pytest.raises(TypeError, match="SegmentBatch"):
        loglik_grad(theta, [random_segment(rng, 30, False)], plant)


def test_a_lag_whose_alpha_rounds_to_one_gives_minus_infinity_not_an_exception(plant):
    # NUTS once proposed log τ_nm = 34 (τ_nm = 6e14 s) in the unit SBC; in the numba-compiled model
    # α rounded to 1 and the division 1 / (1 - α) raised ZeroDivisionError, which stopped the
    # whole calibration run. A density of 0 (-inf) lets the sampler reject the point instead.
    from scioc.models.delayed.kernel import batch_kernel_serial
    from scioc.models.delayed.lag import arm_torque_recursion

    rng = np.random.default_rng(29)
    batch = prepare_batch(plant, [window(rng, plant, 60, 10, mode, drawn=False) for mode in MODES])
    n = batch.n
    theta = np.ascontiguousarray(np.column_stack([random_theta(rng, False) for _ in range(n)]))
    lag = np.zeros((4, n))
    lag[0], lag[1] = 1.0, 1.0  # a = α = 1
    out = np.empty((6, n))
    batch_kernel_serial(plant.A, plant.b, batch.fb, theta, lag, np.full(n, 0.2), np.array([0, 5, 12]),
                        np.zeros(n), np.zeros((n, 2)), batch.x1, batch.x2, batch.r, batch.u, batch.a, True, True,
                        1, out, np.empty((n, 0)))
    assert np.all(out[0] == -np.inf)
    assert np.all(out[1:] == 0.0)
    # the warm-up's arm-torque recursion, which runs before the kernel, does not raise either
    u = rng.normal(0.0, 0.3, 20)
    tau, dtau, dct = np.zeros(21), np.zeros((21, 2)), np.zeros((20, 2))
    arm_torque_recursion(u, 1.0, 1.0, tau, dtau, dct)
    assert not np.all(np.isfinite(tau[1:]))
    # a lag just short of α = 1 still gives a finite (very small) density
    lag[1] = 1.0 - 1e-15
    batch_kernel_serial(plant.A, plant.b, batch.fb, theta, lag, np.full(n, 0.2), np.array([0, 5, 12]),
                        np.zeros(n), np.zeros((n, 2)), batch.x1, batch.x2, batch.r, batch.u, batch.a, True, True,
                        1, out, np.empty((n, 0)))
    assert np.all(np.isfinite(out[0]))


@pytest.mark.parametrize("sigma_m", [1e10, 1e14, 1e20, 1e-12, 1e-30])
def test_extreme_motor_noise_equals_dense(plant, sigma_m):
    # The innovations' running product of D_k (variances ~ sigma_m²) is logged before it
    # over- or underflows: with 16 factors per log, sigma_m = 1e10, 1e14 and 1e20 gave a
    # non-finite or wrong density on this 400-step window; 1e-12 and 1e-30 did not.
    rng = np.random.default_rng(43)
    theta = random_theta(rng, False)
    par = dict(tau_nm=0.05, sigma_m=sigma_m, delay=5, tau0=0.0)
    seg = window(rng, plant, 400, 200, "MC", drawn=False, **par)
    dense = loglik_dense(theta, seg, plant, **par)
    for freeze in (True, False):  # unheld, every column's D_k enters the product
        fast = loglik_grad(theta, prepare_batch(plant, [seg]), plant, freeze=freeze, **par)
        assert np.isfinite(fast.loglik[0]) and abs(fast.loglik[0] - dense.loglik) <= 1e-9 * abs(dense.loglik)


@pytest.mark.parametrize("delay", [0, 7])
def test_the_log_likelihood_alone_is_the_one_with_the_gradient_bit_for_bit(plant, delay):
    rng = np.random.default_rng([31, delay])
    segs = [window(rng, plant, 200, 30, mode, drawn=False) for mode in MODES]
    batch = prepare_batch(plant, segs)
    theta = np.column_stack([random_theta(rng, False) for _ in segs])
    par = dict(tau_nm=0.06, sigma_m=0.2, delay=delay)
    for freeze in (True, False):
        both = loglik_grad(theta, batch, plant, freeze=freeze, **par)
        assert np.array_equal(loglik(theta, batch, plant, freeze=freeze, **par), both.loglik)
        assert np.all(np.isfinite(both.grad))
