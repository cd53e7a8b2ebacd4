"""The arm torque at a window's start from the torques before it: the simulator's arm torque recovered, its
tangents, and the whole likelihood's τ_nm-derivative with τ_0 recomputed at each τ_nm."""

import numpy as np
import pytest

from scioc.models.delayed import loglik_grad, sample_delayed
from scioc.models.delayed.lag import Warmup, arm_torque, lag_coefficients, window_tau0
from scioc.models.segment import Feedback, Segment, prepare_batch


def run(rng, plant, n, mode, *, tau_nm, sigma_m, delay, theta=(300.0, 0.2, 10.0)):
    """A drawn run of n steps (plus 30 preview) from rest; the assistant's law in ``SC``."""
    t = np.arange(n + 31) * plant.dt
    ref = 0.3 * np.sin(2 * np.pi * 0.4 * t) + 0.1 * np.sin(2 * np.pi * 1.1 * t + 1.0)
    kw = {}
    if mode == "SC":
        kw["feedback"] = Feedback(np.array([3.0, 0.3]), rng.normal(0.0, 0.2, n + 30))
    return sample_delayed(np.array(theta), [0.0, 0.0], ref, plant, rng, tau_nm=tau_nm, sigma_m=sigma_m, delay=delay,
                          n_obs=n, **kw)


def window_of(draw, start: int) -> Segment:
    """The run's steps from ``start`` on as a window of its own (initial state, reference, assistant cut there)."""
    seg = draw.segments[0]
    fb = seg.feedback
    return Segment(draw.x[start].copy(), seg.angle_ref[start:], seg.u_H[start:], seg.u_A[start:],
                   None if fb is None else fb.window(start, seg.u_A.shape[0] - start))


@pytest.mark.parametrize("tau_nm", [0.02, 0.06, 0.3])
def test_the_arm_torque_follows_from_the_observed_torques(plant, tau_nm):
    rng = np.random.default_rng([31, int(tau_nm * 100)])
    draw = run(rng, plant, 3000, "MC", tau_nm=tau_nm, sigma_m=0.25, delay=8)
    lag = lag_coefficients(tau_nm)
    res = arm_torque(draw.u_H, lag.a, lag.alpha)
    # the simulator's arm torque (its state z[2]) from the torques alone, from rest; rounding grows at most
    # by 1/(1 - |p|) = 1/(1 - 0.97) through the recursion's pole
    np.testing.assert_allclose(res.tau, draw.tau, rtol=0, atol=1e-12)


def test_from_a_wrong_start_the_error_decays_with_the_pole(plant):
    rng = np.random.default_rng(32)
    draw = run(rng, plant, 400, "MC", tau_nm=0.06, sigma_m=0.25, delay=8)
    lag = lag_coefficients(0.06)
    p = lag.a - (1 - lag.a) * lag.alpha / (1 - lag.alpha)
    res = arm_torque(draw.u_H, lag.a, lag.alpha, tau_start=1.0)
    err = res.tau - draw.tau
    np.testing.assert_allclose(err, p ** np.arange(401), rtol=1e-9, atol=1e-14)  # linear: the error is p^k


@pytest.mark.parametrize("tau_nm", [0.01, 0.06, 0.5])
def test_tangents_match_central_differences(tau_nm):
    rng = np.random.default_rng(33)
    u = rng.normal(0.0, 0.5, 700)
    lag = lag_coefficients(tau_nm)
    res = arm_torque(u, lag.a, lag.alpha, tau_start=0.3)
    # Steps relative to 1 - a and 1 - α: the pole p moves by (1 - a)/(1 - α)² per unit of α, and p^k's
    # truncation error, about (k h dp/dα)², must stay below 1e-8 over the 700 steps.
    for j, (a, al) in enumerate(((1e-7 * (1 - lag.a), 0.0), (0.0, 1e-7 * (1 - lag.alpha)))):
        up = arm_torque(u, lag.a + a, lag.alpha + al, tau_start=0.3).tau
        down = arm_torque(u, lag.a - a, lag.alpha - al, tau_start=0.3).tau
        fd = (up - down) / (2 * (a + al))
        scale = np.max(np.abs(res.dtau[:, j]))
        np.testing.assert_allclose(res.dtau[:, j], fd, rtol=0, atol=1e-7 * scale)
        assert np.all(res.dtau[0] == 0.0)  # the start is fixed


def test_window_tau0_is_the_last_arm_torque_and_rest_is_zero():
    rng = np.random.default_rng(34)
    u = rng.normal(0.0, 0.5, 50)
    lag = lag_coefficients(0.06)
    t0, dt0 = window_tau0([None, Warmup(u), Warmup(u[:0], 0.2)], lag.a, lag.alpha)
    res = arm_torque(u, lag.a, lag.alpha)
    assert t0[0] == 0.0 and np.all(dt0[0] == 0.0)
    assert t0[1] == res.tau[-1] and np.all(dt0[1] == res.dtau[-1])
    assert t0[2] == 0.2 and np.all(dt0[2] == 0.0)  # no torques before: the start itself


def whole_loglik(p, batch, warm, plant, delay):
    """The likelihood with τ_0 recomputed from the warm-up at p's τ_nm."""
    lag = lag_coefficients(p[3])
    t0, _ = window_tau0([warm], lag.a, lag.alpha)
    return loglik_grad(p[:3], batch, plant, tau_nm=p[3], sigma_m=p[4], delay=delay, tau0=t0).loglik[0]


@pytest.mark.parametrize("mode", ["MC", "SC"])
@pytest.mark.parametrize("delay", [0, 5, 12])
def test_the_tau_derivative_includes_the_warm_up(plant, mode, delay):
    rng = np.random.default_rng([35, delay, mode == "SC"])
    theta = np.array([300.0, 0.2, 10.0])
    tau_nm, sigma_m = 0.06, 0.25
    draw = run(rng, plant, 700, mode, tau_nm=tau_nm, sigma_m=sigma_m, delay=delay, theta=theta)
    start = 400
    batch = prepare_batch(plant, [window_of(draw, start)])
    warm = Warmup(draw.u_H[:start])
    lag = lag_coefficients(tau_nm)
    t0, dt0 = window_tau0([warm], lag.a, lag.alpha)
    assert t0[0] == pytest.approx(draw.tau[start], abs=1e-12)
    # evaluated away from the data's own parameters, where no gradient component is near 0 (rounding of
    # the differences, eps·|ll|/h, is then far below 1e-6 of each)
    p0 = np.array([1.5 * theta[0], 3.0 * theta[1], 0.7 * theta[2], 0.08, 0.2])
    lag = lag_coefficients(p0[3])
    t0, dt0 = window_tau0([warm], lag.a, lag.alpha)
    res = loglik_grad(p0[:3], batch, plant, tau_nm=p0[3], sigma_m=p0[4], delay=delay, tau0=t0, dtau0=dt0)
    for j in range(5):
        h = 1e-5 * p0[j]
        up, down = p0.copy(), p0.copy()
        up[j] += h
        down[j] -= h
        fd = (whole_loglik(up, batch, warm, plant, delay) - whole_loglik(down, batch, warm, plant, delay)) / (2 * h)
        # O(h²) truncation and eps·|ll|/h rounding are both below 1e-7 relative here
        assert abs(fd - res.grad[j, 0]) <= 1e-6 * abs(res.grad[j, 0]), (j, fd, res.grad[j, 0])
    # negative control: with τ_0 held fixed the τ_nm-derivative misses the warm-up's part by more than ten times
    # the tolerance above
    fixed = loglik_grad(p0[:3], batch, plant, tau_nm=p0[3], sigma_m=p0[4], delay=delay, tau0=t0).grad[3, 0]
    assert abs(fixed - res.grad[3, 0]) > 1e-5 * abs(res.grad[3, 0]), (fixed, res.grad[3, 0])


def test_dtau0_is_checked(plant):
    rng = np.random.default_rng(36)
    draw = run(rng, plant, 60, "MC", tau_nm=0.06, sigma_m=0.1, delay=2)
    batch = prepare_batch(plant, draw.segments)
    with pytest.raises(ValueError, match="dtau0"):
        loglik_grad([10.0, 0.0, 1.0], batch, plant, tau_nm=0.06, dtau0=np.zeros(3))
    with pytest.raises(ValueError, match="dtau0"):
        loglik_grad([10.0, 0.0, 1.0], batch, plant, tau_nm=0.06, dtau0=[np.nan, 0.0])
    with pytest.raises(ValueError, match="alpha"):
        arm_torque(np.ones(3), 0.5, 1.0)
