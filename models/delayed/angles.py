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
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.delayed.lag import Warmup, lag_coefficients, window_tau0
from scioc.models.delayed.sample import delayed_setup
from scioc.models.design import WheelParameters
from scioc.models.maxent import HALF_LOG_2PI
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit
from scioc.models.segment import Feedback


class AngleLoglik(NamedTuple):
    """log p(y_1..y_K | y_0) of one window's angles (nats), and the filter's standardized innovations (K,)."""

    loglik: float
    innovations: np.ndarray


#: The filter is held once its covariance, the plan's gain and S_k move by at most this, relative, in a step.
FREEZE_RTOL = 1e-13


@njit(cache=True, error_model="numpy", fastmath=False)
def angle_filter(Ab, bc, ba, L, f, S, known, d, s2m, s2y, y, mu0, P0, inn, freeze):
    """The Kalman filter of the module docstring; returns log p(y_1..y_K | y_0), fills ``inn`` (K,).

    State (z_k, m_{k-1}, ..., m_{k-d}), history in lag order. With ``freeze``, once the
    covariance is stationary and while the plan is, only the mean moves, with the held gain.
    """
    K = y.shape[0] - 1
    n = 3 + d
    mu = np.zeros(n)
    P = np.zeros((n, n))
    Q = np.zeros((n, n))  # the covariance being built, then the previous step's (swapped)
    for i in range(3):
        mu[i] = mu0[i]
        for j in range(3):
            P[i, j] = P0[i, j]
    for j in range(d):
        P[3 + j, 3 + j] = s2m
    G = np.zeros((max(d, 1), 3))  # G[j - 1] = Ā^{j-1} b_c
    for j in range(d):
        for i in range(3):
            if j == 0:
                G[0, i] = bc[i]
            else:
                G[j, i] = Ab[i, 0] * G[j - 1, 0] + Ab[i, 1] * G[j - 1, 1] + Ab[i, 2] * G[j - 1, 2]
    h = np.zeros(max(d, 1))  # h[j - 1] = L_k G_j, the coefficient of m_{k-j}
    wm = np.zeros(max(d, 1))
    wz = np.zeros(3)
    M = np.zeros((3, 3))
    MP = np.zeros((3, n))
    Mw = np.zeros(3)
    gain = np.zeros(n)
    ll = 0.0
    s = P[0, 0] + s2y
    if s > 0.0:
        nu = y[0] - mu[0]
        for i in range(n):
            gain[i] = P[i, 0] / s
        for i in range(n):
            mu[i] += gain[i] * nu
            for j in range(n):
                P[i, j] -= gain[i] * gain[j] * s
    held = False
    s_held = 0.0
    L_held = np.zeros(3)
    S_held = 0.0
    for k in range(K):
        if held:  # the plan as when the filter was held
            same = abs(S[k] - S_held) <= FREEZE_RTOL * S_held
            for j in range(3):
                same = same and abs(L[k, j] - L_held[j]) <= FREEZE_RTOL * abs(L_held[j])
            if not same:
                held = False  # P is the stationary covariance after the last update: go on from it
        if not held:
            for j in range(d):
                h[j] = L[k, 0] * G[j, 0] + L[k, 1] * G[j, 1] + L[k, 2] * G[j, 2]
            for i in range(3):
                for j in range(3):
                    M[i, j] = Ab[i, j] - bc[i] * L[k, j]
        # ---- the mean
        g = 0.0
        for j in range(d):
            g += h[j] * mu[3 + j]
        z0_ = mu[0]
        z1_ = mu[1]
        z2_ = mu[2]
        for i in range(3):
            mu[i] = M[i, 0] * z0_ + M[i, 1] * z1_ + M[i, 2] * z2_ + bc[i] * (g + f[k]) + ba[i] * known[k]
        for j in range(d - 1, 0, -1):
            mu[3 + j] = mu[2 + j]
        if d > 0:
            mu[3] = 0.0
        if held:
            nu = y[k + 1] - mu[0]
            ll -= 0.5 * nu * nu / s_held + 0.5 * np.log(s_held) + HALF_LOG_2PI
            inn[k] = nu / np.sqrt(s_held)
            for i in range(n):
                mu[i] += gain[i] * nu
            continue
        # ---- the covariance: predict into Q
        hph = 0.0
        for a in range(d):
            acc = 0.0
            for t in range(d):
                acc += P[3 + a, 3 + t] * h[t]
            wm[a] = acc
            hph += h[a] * acc
        for i in range(3):
            acc = 0.0
            for t in range(d):
                acc += P[i, 3 + t] * h[t]
            wz[i] = acc
        for i in range(3):
            for j in range(n):
                MP[i, j] = M[i, 0] * P[0, j] + M[i, 1] * P[1, j] + M[i, 2] * P[2, j]
            Mw[i] = M[i, 0] * wz[0] + M[i, 1] * wz[1] + M[i, 2] * wz[2]
        var_u = hph + 0.5 / S[k] + s2m
        for i in range(3):
            for j in range(3):
                Q[i, j] = (MP[i, 0] * M[j, 0] + MP[i, 1] * M[j, 1] + MP[i, 2] * M[j, 2] + Mw[i] * bc[j]
                           + bc[i] * Mw[j] + bc[i] * bc[j] * var_u)
        if d > 0:
            for i in range(3):
                Q[i, 3] = bc[i] * s2m  # Cov(z_{k+1}, m_k)
                Q[3, i] = Q[i, 3]
            Q[3, 3] = s2m
            for j in range(1, d):
                Q[3, 3 + j] = 0.0
                Q[3 + j, 3] = 0.0
                for i in range(3):  # Cov(z_{k+1}, m_{k-j}), m_{k-j} in the old lag j - 1
                    v = MP[i, 2 + j] + bc[i] * wm[j - 1]
                    Q[i, 3 + j] = v
                    Q[3 + j, i] = v
                for t in range(1, d):
                    Q[3 + j, 3 + t] = P[2 + j, 2 + t]
        # ---- observe y_{k+1}
        s = Q[0, 0] + s2y
        nu = y[k + 1] - mu[0]
        if not s > 0.0:
            if nu != 0.0:
                return -np.inf
            inn[k] = 0.0
            P, Q = Q, P
            continue
        ll -= 0.5 * nu * nu / s + 0.5 * np.log(s) + HALF_LOG_2PI
        inn[k] = nu / np.sqrt(s)
        for i in range(n):
            gain[i] = Q[i, 0] / s
        for i in range(n):
            mu[i] += gain[i] * nu
        big = 0.0
        moved = 0.0
        for i in range(n):
            for j in range(i, n):
                v = Q[i, j] - gain[i] * gain[j] * s
                Q[i, j] = v
                Q[j, i] = v
                big = max(big, abs(v))
                moved = max(moved, abs(v - P[i, j]))
        P, Q = Q, P
        if freeze and k > 0 and moved <= FREEZE_RTOL * big:
            stationary = abs(S[k] - S[k - 1]) <= FREEZE_RTOL * S[k]
            for j in range(3):
                stationary = stationary and abs(L[k, j] - L[k - 1, j]) <= FREEZE_RTOL * abs(L[k, j])
            if stationary:
                held = True
                s_held = s
                S_held = S[k]
                for j in range(3):
                    L_held[j] = L[k, j]
    return ll


def angle_setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params):
    """The plan and the loop of one window (:func:`.sample.delayed_setup`, physically lagged)."""
    return delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                         physical=True)


def check_angles(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov):
    """:func:`angle_loglik`'s arguments checked: (y, d, z0 mean, z0 covariance); ValueError otherwise."""
    y = np.ascontiguousarray(angles, dtype=float)
    n_plan = setup.known.shape[0]
    if y.ndim != 1 or not 2 <= y.shape[0] <= n_plan + 1:
        raise ValueError(f"angles must be a vector of K + 1 samples, 2 <= K + 1 <= {n_plan + 1} (the plan's length "
                         f"+ 1); got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError("angles must be finite")
    d = int(delay)
    if d != delay or d < 0:
        raise ValueError(f"delay must be a whole number of samples >= 0; got {delay!r}")
    for name, v in (("sigma_m", sigma_m), ("sigma_y", sigma_y)):
        if not (np.isfinite(v) and v >= 0):
            raise ValueError(f"{name} must be a finite number >= 0; got {v!r}")
    mu0 = np.ascontiguousarray(z0_mean, dtype=float).reshape(3)
    P0 = np.ascontiguousarray(z0_cov, dtype=float).reshape(3, 3)
    if not (np.all(np.isfinite(mu0)) and np.all(np.isfinite(P0)) and np.allclose(P0, P0.T)
            and np.all(np.linalg.eigvalsh(P0) >= -1e-12 * max(1.0, np.abs(P0).max()))):
        raise ValueError("z0_mean must be 3 finite numbers and z0_cov a symmetric positive semi-definite 3 × 3 matrix")
    return y, d, mu0, P0


def angle_loglik(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                 tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0, sigma_y: float, z0_mean, z0_cov,
                 params: WheelParameters = WheelParameters(), freeze: bool = True) -> AngleLoglik:
    """log p(y_1..y_K | y_0) of one window's recorded angles ``angles`` (K + 1,), rad, under the ``delayed`` human.

    ``theta``, ``angle_ref``, ``plant``, ``u_A``, ``feedback``, ``tau_nm``, ``sigma_m``, ``delay``
    and ``params`` as :func:`.sample.sample_delayed`'s. ``sigma_y``: the angle's noise SD, rad
    (encoder step q: q / sqrt(12)). ``z0_mean`` (3,), ``z0_cov`` (3, 3): the prior of (angle,
    velocity, arm torque) at the window's start. ``freeze``: hold the filter once stationary.
    """
    setup = angle_setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params)
    y, d, mu0, P0 = check_angles(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov)
    K = y.shape[0] - 1
    inn = np.zeros(K)
    pol = setup.policy
    ll = angle_filter(setup.A, setup.b_c, setup.b_a, pol.L, pol.f, pol.S, setup.known, d, float(sigma_m) ** 2,
                      float(sigma_y) ** 2, y, mu0, P0, inn, bool(freeze))
    return AngleLoglik(float(ll), inn)


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


def window_loglik(theta, tau_nm: float, sigma_m: float, delay: int, w: AngleWindow, plant: DiscretePlant, *,
                  sigma_y: float, params: WheelParameters = WheelParameters()) -> AngleLoglik:
    """:func:`angle_loglik` of a recorded window, its start's prior from the data (:data:`START_SD`)."""
    lag = lag_coefficients(float(tau_nm), plant.dt, params)
    tau0 = float(window_tau0([w.warmup], lag.a, lag.alpha)[0][0])
    mean = np.array([w.angles[0], w.velocity0, tau0])
    cov = np.diag([float(sigma_y) ** 2, START_SD[0] ** 2, START_SD[1] ** 2])
    return angle_loglik(theta, w.angles, w.angle_ref, plant, u_A=w.u_A, feedback=w.feedback, tau_nm=tau_nm,
                        sigma_m=sigma_m, delay=delay, sigma_y=sigma_y, z0_mean=mean, z0_cov=cov, params=params)


__all__ = ["FREEZE_RTOL", "START_SD", "AngleLoglik", "AngleWindow", "angle_filter", "angle_loglik", "angle_setup",
           "check_angles", "window_loglik"]
