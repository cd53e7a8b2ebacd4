"""The exact gradient of the angle likelihood (models.delayed.angles.angle_loglik_grad, window_loglik_grad): its
value against the dense joint Gaussians, its gradient against central differences of the filter and of the dense
reference, the held filter against the full one, the one-sided derivatives at zero lag and noise, and the
max-ent limit.

Central differences are Richardson-extrapolated, ``(4 D(h/2) - D(h)) / 3``, in coordinates where each parameter
moves by O(1) over its range (log q11, log q22, log R, τ_nm in 0.1 s, σ_m in 0.1 N·m), with h = 1e-3. Their
truncation error is O(h⁴) ≈ 1e-12; their rounding error about 3 ε / h, ε the filter's rounding of log p (about
1e-12 nats on these windows of K = 60, log p ≈ 600), so 3e-9 nats per unit of a coordinate (measured <= 7e-9).
A component of at least MIN_GRAD = 0.01 nats per unit is thus resolved to the 1e-6 relative tolerance with a
margin; a smaller one, which would measure the differences' rounding, to 1e-6 × MIN_GRAD absolute.
"""

import numpy as np
import pytest

from scioc.models.delayed.angles import (
    AngleWindow,
    angle_loglik,
    angle_loglik_grad,
    window_loglik,
    window_loglik_grad,
)
from scioc.models.delayed.dense import angle_loglik_dense, maxent_angle_loglik_dense
from scioc.models.delayed.lag import Warmup
from tests.models.delayed.test_angles import MODES, Q, window

DELAYS = (0, 1, 5, 30)
#: The relative tolerance of the central differences (module docstring).
FD_RTOL = 1e-6
#: The smallest gradient component, nats per unit of the scaled coordinates, that the differences resolve to FD_RTOL.
MIN_GRAD = 0.01
SCALE = np.array([1.0, 1.0, 1.0, 0.1, 0.1])  # the scaled coordinates' units for τ_nm and σ_m


def to_params(u):
    """(θ, τ_nm, σ_m) of the scaled coordinates u = (log q11, log q22, log R, τ_nm / 0.1, σ_m / 0.1)."""
    return np.exp(u[:3]), u[3] * SCALE[3], u[4] * SCALE[4]


def scaled_grad(g, u):
    """The gradient in PARAMETERS order (q11, q22, R, τ_nm, σ_m) carried to u."""
    return np.concatenate([g[:3] * np.exp(u[:3]), g[3:] * SCALE[3:]])


def richardson(f, u, j, h=1e-3, one_sided=False):
    """∂f/∂u_j by Richardson-extrapolated central differences (forward ones if ``one_sided``)."""
    def diff(step):
        e = np.zeros_like(u)
        e[j] = step
        if one_sided:  # (-3 f0 + 4 f1 - f2) / 2h, O(h²)
            return (-3 * f(u) + 4 * f(u + e) - f(u + 2 * e)) / (2 * step)
        return (f(u + e) - f(u - e)) / (2 * step)

    return (4 * diff(h / 2) - diff(h)) / 3


def case(plant, mode, d, K=60, M=20, seed=0):
    """A window of the delayed human (τ_nm = 0.06 s, σ_m = 0.25 N·m, delay d) and the filter's keywords."""
    rng = np.random.default_rng([51, MODES.index(mode), d, seed])
    theta = np.array([300.0, 0.3, 20.0])
    y, ref, kw, z0 = window(rng, plant, K, M, mode, theta=theta, tau_nm=0.06, sigma_m=0.25, delay=d,
                            tau0=0.1)
    par = dict(delay=d, sigma_y=Q / np.sqrt(12), z0_mean=z0 + np.array([1e-4, 0.02, 0.05]),
               z0_cov=np.array([[1e-8, 0, 0], [0, 0.01, 0.002], [0, 0.002, 0.04]]), **kw)
    # evaluated away from the truth, where every component of the gradient is well away from 0
    u = np.array([np.log(240.0), np.log(0.3), np.log(26.0), 0.72, 3.0])
    return y, ref, par, u


@pytest.mark.parametrize("d", DELAYS)
@pytest.mark.parametrize("mode", MODES)
def test_value_with_gradient_is_the_dense_joint_gaussian(plant, mode, d):
    y, ref, par, u = case(plant, mode, d)
    th, tau, sig = to_params(u)
    res = angle_loglik_grad(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par)
    dense = angle_loglik_dense(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par)
    # the dense Cholesky of a K × K covariance and the filter agree to rounding (as test_angles.py)
    assert res.loglik == pytest.approx(dense.loglik, rel=1e-9, abs=1e-9)
    assert res.loglik == angle_loglik(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par).loglik  # bit for bit
    assert res.grad.shape == (5,) and res.grad_z0_mean.shape == (3,)


@pytest.mark.parametrize("d", DELAYS)
@pytest.mark.parametrize("mode", MODES)
def test_gradient_is_the_central_differences_of_the_filter(plant, mode, d):
    y, ref, par, u = case(plant, mode, d)

    def f(v):
        th, tau, sig = to_params(v)
        return angle_loglik(th, y, ref, plant, tau_nm=tau, sigma_m=sig, freeze=False, **par).loglik

    th, tau, sig = to_params(u)
    g = scaled_grad(angle_loglik_grad(th, y, ref, plant, tau_nm=tau, sigma_m=sig, freeze=False, **par).grad, u)
    fd = np.array([richardson(f, u, j) for j in range(5)])
    assert np.sum(np.abs(fd) >= MIN_GRAD) >= 4, fd  # a well-scaled point (module docstring)
    np.testing.assert_allclose(g, fd, rtol=FD_RTOL, atol=FD_RTOL * MIN_GRAD)


@pytest.mark.parametrize("mode, d", [("MC", 5), ("SC feedback", 1), ("SC exogenous", 30)])
def test_gradient_is_the_central_differences_of_the_dense_reference(plant, mode, d):
    # The dense joint Gaussian shares no code with the filter, its plan or its reverse sweeps. Its Cholesky factor
    # rounds to about cond(Σ) ε: with the encoder's σ_y (cond ≈ 1e7) its differences would measure that; an angle
    # noise of 1 mrad (cond ≈ 1e4) keeps them at the filter's.
    y, ref, par, u = case(plant, mode, d, K=40, M=10, seed=1)
    par["sigma_y"] = 1e-3

    def f(v):
        th, tau, sig = to_params(v)
        return angle_loglik_dense(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par).loglik

    th, tau, sig = to_params(u)
    g = scaled_grad(angle_loglik_grad(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par).grad, u)
    fd = np.array([richardson(f, u, j) for j in range(5)])
    assert np.sum(np.abs(fd) >= MIN_GRAD) >= 4, fd
    np.testing.assert_allclose(g, fd, rtol=FD_RTOL, atol=FD_RTOL * MIN_GRAD)


@pytest.mark.parametrize("mode", MODES)
def test_holding_the_stationary_filter_changes_the_gradient_only_by_rounding(plant, mode):
    # The held covariance, gain and plan differ from the moving ones by <= FREEZE_RTOL (1e-13) relative; their
    # effect on a gradient summed over 1500 steps stays below 1e-9 relative (measured <= 3e-12).
    for d in (0, 12, 30):
        y, ref, par, u = case(plant, mode, d, K=1500, M=200)
        th, tau, sig = to_params(u)
        held = angle_loglik_grad(th, y, ref, plant, tau_nm=tau, sigma_m=sig, **par)
        full = angle_loglik_grad(th, y, ref, plant, tau_nm=tau, sigma_m=sig, freeze=False, **par)
        assert held.loglik == pytest.approx(full.loglik, rel=1e-11)
        np.testing.assert_allclose(held.grad, full.grad, rtol=1e-9, atol=1e-9 * np.abs(full.grad).max())
        np.testing.assert_allclose(held.grad_z0_mean, full.grad_z0_mean, rtol=1e-9,
                                   atol=1e-9 * np.abs(full.grad_z0_mean).max())


@pytest.mark.parametrize("mode", MODES)
def test_window_gradient_follows_the_start_arm_torque(plant, mode):
    # the prior mean of the arm torque follows the torques before the window through the lag: ∂/∂τ_nm has that term
    y, ref, par, u = case(plant, mode, 5, K=50)
    rng = np.random.default_rng(52)
    w = AngleWindow(y, ref, par.get("u_A"), par.get("feedback"), 0.1, Warmup(rng.normal(0.0, 0.5, 200), 0.2))
    sy = par["sigma_y"]

    def f(v):
        th, tau, sig = to_params(v)
        return window_loglik(th, tau, sig, 5, w, plant, sigma_y=sy).loglik

    th, tau, sig = to_params(u)
    res = window_loglik_grad(th, tau, sig, 5, w, plant, sigma_y=sy)
    assert res.loglik == f(u)
    fd = richardson(f, u, 3)
    assert abs(scaled_grad(res.grad, u)[3] - fd) <= FD_RTOL * abs(fd)
    # negative control: without the start's term the τ_nm-derivative is another number
    no_warm = window_loglik_grad(th, tau, sig, 5, w._replace(warmup=None), plant, sigma_y=sy)
    assert abs(scaled_grad(no_warm.grad, u)[3] - fd) > 1e3 * FD_RTOL * abs(fd)


@pytest.mark.parametrize("mode", MODES)
def test_derivatives_at_zero_lag_are_one_sided_and_at_zero_motor_noise_vanish(plant, mode):
    y, ref, par, u = case(plant, mode, 5, K=50)
    u = u.copy()
    u[3] = 0.0

    def f(v):
        th, tau, sig = to_params(v)
        return angle_loglik(th, y, ref, plant, tau_nm=tau, sigma_m=sig, freeze=False, **par).loglik

    th, _, sig = to_params(u)
    g = scaled_grad(angle_loglik_grad(th, y, ref, plant, tau_nm=0.0, sigma_m=sig, freeze=False, **par).grad, u)
    # The likelihood bends sharply as the lag appears (a plain forward difference with h = 1e-3 is 60 % off);
    # the extrapolated one-sided stencil's error is O(h³), about 1e-8 relative at h = 2e-5, rounding 1e-7 nats.
    fd = richardson(f, u, 3, h=2e-5, one_sided=True)
    assert abs(g[3] - fd) <= FD_RTOL * abs(fd)
    at_zero = angle_loglik_grad(th, y, ref, plant, tau_nm=0.0, sigma_m=0.0, **par)
    assert at_zero.grad[4] == 0.0  # σ_m enters as σ_m²


@pytest.mark.parametrize("mode", MODES)
def test_without_delay_lag_or_motor_noise_the_angles_are_the_max_ent_human_through_the_encoder(plant, mode):
    y, ref, par, u = case(plant, mode, 0, K=80)
    th = np.exp(u[:3])
    par = {**par, "delay": 0}
    fast = angle_loglik_grad(th, y, ref, plant, tau_nm=0.0, sigma_m=0.0, **par)
    dense = maxent_angle_loglik_dense(th, y, ref, plant, u_A=par.get("u_A"), feedback=par.get("feedback"),
                                      sigma_y=par["sigma_y"], x0_mean=par["z0_mean"][:2],
                                      x0_cov=par["z0_cov"][:2, :2])
    assert fast.loglik == pytest.approx(dense.loglik, rel=1e-9, abs=1e-9)
    # negative control: with motor noise the delayed human is another one
    other = angle_loglik(th, y, ref, plant, tau_nm=0.0, sigma_m=0.2, **par)
    assert abs(other.loglik - dense.loglik) > 1.0
