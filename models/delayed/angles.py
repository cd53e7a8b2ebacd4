"""The ``delayed`` human seen through the encoder: the exact likelihood of the recorded angles.

For recordings without a torque sensor (docs/decisions/delayed-angle-likelihood.md). On the
physically lagged wheel, with ``c_k = -L_k ẑ_k + f_k + ε_k`` (:mod:`.likelihood`), the loop is::

    z_{k+1} = (Ā - b_c L_k) z_k + b_c (sum_{j=1..d} h_{k,j} m_{k-j} + ε_k + m_k + f_k) + b_a κ_k,

κ the known input, and the encoder reads ``y_k = angle_k + v_k``, v_k ~ N(0, σ_y²).
``s_k = (z_k, m_{k-1}, ..., m_{k-d})`` is a linear Gaussian state, and ``log p(y_1..y_K | y_0)``
the sum of its Kalman filter's innovation terms, given z_0's prior N(``z0_mean``, ``z0_cov``)
(updated by y_0, not scored) and the pre-window noises'. A step costs O((3 + d)²): the z-block
sees the history only through ``sum_j h_{k,j} m_{k-j}``, which shifts. Where the plan is
stationary the covariance converges and is held (:data:`FREEZE_RTOL`): O(d) per step.

The plan is :mod:`.riccati`'s, the filter :mod:`.kalman`'s, one window's kernel :mod:`.angle_kernel`'s;
:func:`angle_loglik_grad` and :func:`window_loglik_grad` add the exact gradient by their reverse sweeps.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.linalg import expm_frechet

from scioc.models.cost import validate_theta
from scioc.models.delayed.angle_kernel import OUT, window_kernel
from scioc.models.delayed.kalman import FREEZE_RTOL, angle_filter
from scioc.models.delayed.lag import Warmup, check_wheel, lag_coefficients, window_tau0
from scioc.models.delayed.sample import delayed_setup, known_inputs
from scioc.models.design import WheelParameters
from scioc.models.plant import DiscretePlant, continuous_matrices, discretize, discretize_lagged
from scioc.models.segment import Feedback


class AngleLoglik(NamedTuple):
    """log p(y_1..y_K | y_0) of one window's angles (nats), and the filter's standardized innovations (K,)."""

    loglik: float
    innovations: np.ndarray


class AngleLoglikGrad(NamedTuple):
    """log p(y_1..y_K | y_0) (nats); its gradient (5,) in :data:`.likelihood.PARAMETERS` order (q11, q22, R,
    τ_nm in s, σ_m in N·m); in the prior mean of z_0 (3,) (rad, rad/s, N·m); the innovations (K,)."""

    loglik: float
    grad: np.ndarray
    grad_z0_mean: np.ndarray
    innovations: np.ndarray


class LaggedWheel(NamedTuple):
    """The physically lagged wheel (:func:`scioc.models.plant.discretize_lagged`) and its τ_nm-derivatives (1/s)."""

    A: np.ndarray
    b_c: np.ndarray
    dA: np.ndarray
    db_c: np.ndarray


@lru_cache(maxsize=64)
def lagged_wheel(tau_nm: float, dt: float, params: WheelParameters) -> LaggedWheel:
    """The wheel behind the lag τ_nm (s) at sample time ``dt`` (s) and its derivative in τ_nm (Fréchet).

    At τ_nm = 0 the lag is gone (A's torque column 0, b_c = (b, 1)) and the derivative one-sided:
    the torque decays within the sample, ``A[:2, 2] ≈ τ_nm Φ b_w`` and ``b_c[:2] ≈ b - τ_nm Φ b_w``.
    Cached: a search asks once per τ_nm for all its windows.
    """
    A_c, b_w = continuous_matrices(params)
    if tau_nm == 0.0:
        wheel = discretize(dt, params)
        A = np.zeros((3, 3))
        A[:2, :2] = wheel.A
        dA = np.zeros((3, 3))
        dA[:2, 2] = wheel.A @ b_w
        return LaggedWheel(A, np.array([wheel.b[0], wheel.b[1], 1.0]), dA, np.array([-dA[0, 2], -dA[1, 2], 0.0]))
    M = np.zeros((4, 4))
    M[:2, :2] = A_c
    M[:2, 2] = b_w
    M[2, 2], M[2, 3] = -1.0 / tau_nm, 1.0 / tau_nm
    dM = np.zeros((4, 4))
    dM[2, 2], dM[2, 3] = 1.0 / tau_nm ** 2, -1.0 / tau_nm ** 2
    _, dE = expm_frechet(M * dt, dM * dt)
    lp = discretize_lagged(tau_nm, dt, params)
    return LaggedWheel(lp.A, lp.b_c, np.ascontiguousarray(dE[:3, :3]), np.ascontiguousarray(dE[:3, 3]))


def planning_plant(tau_nm: float, plant: DiscretePlant, params: WheelParameters, gain):
    """(Ā, b_c, b_a, dĀ (3, 3, 4), db_c (3, 4)) of :func:`.angle_kernel.window_kernel`: the lagged wheel closed
    by the assistant's ``gain`` (2,), derivatives in direction 2 (τ_nm)."""
    lw = lagged_wheel(float(tau_nm), float(plant.dt), params)
    ba = np.array([plant.b[0], plant.b[1], 0.0])
    Ab = lw.A.copy()
    Ab[:, 0] -= ba * gain[0]
    Ab[:, 1] -= ba * gain[1]
    dAb = np.zeros((3, 3, 4))
    dAb[:, :, 2] = lw.dA
    dbc = np.zeros((3, 4))
    dbc[:, 2] = lw.db_c
    return Ab, lw.b_c, ba, dAb, dbc


def angle_setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params):
    """The plan and the loop of one window (:func:`.sample.delayed_setup`, physically lagged)."""
    return delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                         physical=True)


def _check_window(angles, n_plan: int, delay, sigma_m, sigma_y) -> tuple[np.ndarray, int]:
    y = np.ascontiguousarray(angles, dtype=float)
    if y.ndim != 1 or not 2 <= y.shape[0] <= n_plan + 1:
        raise ValueError(f"angles must be a vector of K + 1 samples, 2 <= K + 1 <= {n_plan + 1} (the plan's length "
                         f"+ 1); got shape {y.shape}")
    if not np.isfinite(y).all():
        raise ValueError("angles must be finite")
    d = int(delay)
    if d != delay or d < 0:
        raise ValueError(f"delay must be a whole number of samples >= 0; got {delay!r}")
    for name, v in (("sigma_m", sigma_m), ("sigma_y", sigma_y)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0; got {v!r}")
    return y, d


def check_angles(angles, n_plan: int, delay, sigma_m, sigma_y, z0_mean, z0_cov):
    """:func:`angle_loglik`'s arguments checked against a plan of ``n_plan`` steps: (y, d, z0 mean, z0
    covariance); ValueError otherwise."""
    y, d = _check_window(angles, n_plan, delay, sigma_m, sigma_y)
    mu0 = np.ascontiguousarray(z0_mean, dtype=float).reshape(3)
    P0 = np.ascontiguousarray(z0_cov, dtype=float).reshape(3, 3)
    if not (np.all(np.isfinite(mu0)) and np.all(np.isfinite(P0)) and np.allclose(P0, P0.T)
            and np.all(np.linalg.eigvalsh(P0) >= -1e-12 * max(1.0, np.abs(P0).max()))):
        raise ValueError("z0_mean must be 3 finite numbers and z0_cov a symmetric positive semi-definite 3 × 3 matrix")
    return y, d, mu0, P0


def _run(theta, y, ref, known, gain, plant, params, tau_nm, sigma_m, d, sigma_y, mu0, P0, freeze, grad):
    """:func:`.angle_kernel.window_kernel` on checked arguments: (out (:data:`.angle_kernel.OUT`,), innovations)."""
    q11, q22, R = (float(v) for v in validate_theta(theta))
    if not (np.isfinite(tau_nm) and tau_nm >= 0):
        raise ValueError(f"tau_nm must be a finite number of seconds >= 0; got {tau_nm!r}")
    check_wheel(plant, params)
    Ab, bc, ba, dAb, dbc = planning_plant(tau_nm, plant, params, gain)
    out = np.empty(OUT)
    inn = np.zeros(y.shape[0] - 1)
    window_kernel(Ab, bc, ba, dAb, dbc, q11, q22, R, ref, known, d, float(sigma_m) ** 2, float(sigma_y) ** 2, y, mu0,
                  P0, bool(freeze), bool(grad), inn, out)
    return out, inn


def _gradient(out, sigma_m: float, dmu0_dtau) -> tuple[np.ndarray, np.ndarray]:
    """(∂/∂[q11, q22, R, τ_nm, σ_m], ∂/∂z0_mean) of the kernel's ``out``; z0's mean moves with τ_nm as ``dmu0_dtau``."""
    gz0 = out[6:9].copy()
    return np.array([out[1], out[2], out[3], out[4] + gz0 @ dmu0_dtau, 2.0 * float(sigma_m) * out[5]]), gz0


def _angle_args(theta, angles, angle_ref, u_A, feedback, delay, sigma_m, sigma_y, z0_mean, z0_cov):
    ref, known, gain = known_inputs(angle_ref, u_A, feedback)
    y, d, mu0, P0 = check_angles(angles, known.shape[0], delay, sigma_m, sigma_y, z0_mean, z0_cov)
    return y, ref, known, gain, d, mu0, P0


def angle_loglik(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                 tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0, sigma_y: float, z0_mean, z0_cov,
                 params: WheelParameters = WheelParameters(), freeze: bool = True) -> AngleLoglik:
    """log p(y_1..y_K | y_0) of one window's recorded angles ``angles`` (K + 1,), rad, under the ``delayed`` human.

    ``theta``, ``angle_ref``, ``plant``, ``u_A``, ``feedback``, ``tau_nm``, ``sigma_m``, ``delay``
    and ``params`` as :func:`.sample.sample_delayed`'s. ``sigma_y``: the angle's noise SD, rad
    (encoder step q: q / sqrt(12)). ``z0_mean`` (3,), ``z0_cov`` (3, 3): the prior of (angle,
    velocity, arm torque) at the window's start. ``freeze``: hold the plan and the filter once stationary.
    """
    y, ref, known, gain, d, mu0, P0 = _angle_args(theta, angles, angle_ref, u_A, feedback, delay, sigma_m, sigma_y,
                                                  z0_mean, z0_cov)
    out, inn = _run(theta, y, ref, known, gain, plant, params, float(tau_nm), sigma_m, d, sigma_y, mu0, P0, freeze,
                    False)
    return AngleLoglik(float(out[0]), inn)


def angle_loglik_grad(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                      tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0, sigma_y: float, z0_mean, z0_cov,
                      params: WheelParameters = WheelParameters(), freeze: bool = True) -> AngleLoglikGrad:
    """:func:`angle_loglik` and its exact gradient, by a reverse sweep through the filter and the plan.

    Parameters
    ----------
    theta : array_like, shape (3,)
        ``[q11, q22, R]``.
    angles, angle_ref : array_like, shapes (K + 1,) and (K + M + 1,)
        The recorded angles and the reference, rad.
    plant : DiscretePlant
        The wheel at the human's sample time.
    u_A, feedback, tau_nm, sigma_m, delay, sigma_y, z0_mean, z0_cov, params, freeze
        As :func:`angle_loglik`'s; ``z0_mean`` is held fixed (its gradient is returned apart).

    Returns
    -------
    AngleLoglikGrad
        The value as :func:`angle_loglik`'s, bit for bit; the gradient in q11, q22, R, τ_nm (one-sided
        at 0) and σ_m (0 at σ_m = 0), and in ``z0_mean``. O(K (3 + d)²) where the filter is not held,
        O(K (3 + d)) where it is.
    """
    y, ref, known, gain, d, mu0, P0 = _angle_args(theta, angles, angle_ref, u_A, feedback, delay, sigma_m, sigma_y,
                                                  z0_mean, z0_cov)
    out, inn = _run(theta, y, ref, known, gain, plant, params, float(tau_nm), sigma_m, d, sigma_y, mu0, P0, freeze,
                    True)
    g, gz0 = _gradient(out, sigma_m, np.zeros(3))
    return AngleLoglikGrad(float(out[0]), g, gz0, inn)


#: Prior SDs of velocity (rad/s) and arm torque (N·m) at a window's start: wide against what its first angles tell.
START_SD = (0.05, 0.1)


class AngleWindow(NamedTuple):
    """One recorded window for :func:`window_loglik`.

    ``angles`` (K + 1,) rad; ``angle_ref`` (K + M + 1,); ``u_A`` (K + M,), the assistant's recorded
    torque when it is a given input (None with ``feedback``); ``velocity0``, the reconstruction's
    velocity at the start, rad/s; ``warmup``, the reconstructed torques before the window
    (:class:`.lag.Warmup`, None: at rest).
    """

    angles: np.ndarray
    angle_ref: np.ndarray
    u_A: np.ndarray | None
    feedback: Feedback | None
    velocity0: float
    warmup: Warmup | None


def _window(theta, tau_nm, sigma_m, delay, w: AngleWindow, plant, sigma_y, params, grad):
    """(out, innovations, dτ_0/dτ_nm) of a recorded window, its start's prior from the data (:data:`START_SD`)."""
    tau_nm = float(tau_nm)
    lag = lag_coefficients(tau_nm, plant.dt, params)
    tau0, dtau0 = window_tau0([w.warmup], lag.a, lag.alpha)
    ref, known, gain = known_inputs(w.angle_ref, w.u_A, w.feedback)
    y, d = _check_window(w.angles, known.shape[0], delay, sigma_m, sigma_y)
    mu0 = np.array([y[0], w.velocity0, tau0[0]])
    P0 = np.diag([float(sigma_y) ** 2, START_SD[0] ** 2, START_SD[1] ** 2])
    out, inn = _run(theta, y, ref, known, gain, plant, params, tau_nm, sigma_m, d, sigma_y, mu0, P0, True, grad)
    return out, inn, float(dtau0[0, 0] * lag.da + dtau0[0, 1] * lag.dalpha)


def window_loglik(theta, tau_nm: float, sigma_m: float, delay: int, w: AngleWindow, plant: DiscretePlant, *,
                  sigma_y: float, params: WheelParameters = WheelParameters()) -> AngleLoglik:
    """:func:`angle_loglik` of a recorded window, its start's prior from the data (:data:`START_SD`)."""
    out, inn, _ = _window(theta, tau_nm, sigma_m, delay, w, plant, sigma_y, params, False)
    return AngleLoglik(float(out[0]), inn)


def window_loglik_grad(theta, tau_nm: float, sigma_m: float, delay: int, w: AngleWindow, plant: DiscretePlant, *,
                       sigma_y: float, params: WheelParameters = WheelParameters()) -> AngleLoglikGrad:
    """:func:`window_loglik` and its exact gradient (:func:`angle_loglik_grad`).

    Parameters
    ----------
    theta : array_like, shape (3,)
        ``[q11, q22, R]``.
    tau_nm, sigma_m, delay : float, float, int
        Lag (s), motor-noise SD per sample (N·m), delay (samples).
    w : AngleWindow
        The recorded window; its start's prior comes from the data (:data:`START_SD`).
    plant, sigma_y, params
        As :func:`window_loglik`'s.

    Returns
    -------
    AngleLoglikGrad
        The gradient in τ_nm includes the start's arm torque, which follows from the torques before
        the window through the lag (:func:`.lag.window_tau0`).
    """
    out, inn, dtau0 = _window(theta, tau_nm, sigma_m, delay, w, plant, sigma_y, params, True)
    g, gz0 = _gradient(out, sigma_m, np.array([0.0, 0.0, dtau0]))
    return AngleLoglikGrad(float(out[0]), g, gz0, inn)


__all__ = ["FREEZE_RTOL", "START_SD", "AngleLoglik", "AngleLoglikGrad", "AngleWindow", "LaggedWheel", "angle_filter",
           "angle_loglik", "angle_loglik_grad", "angle_setup", "check_angles", "lagged_wheel", "planning_plant",
           "window_loglik", "window_loglik_grad"]
