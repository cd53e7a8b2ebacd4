"""The ``delayed`` human seen through the encoder: the exact likelihood of the recorded angles.

Why a second likelihood
-----------------------
:mod:`scioc.models.delayed.likelihood` is the density of the human's *torques*. The paper's rig
records only the wheel angle (an encoder of q rad per count); scioc then reconstructs the
torque, and that reconstruction smooths it. The delayed model reads the smoothing as
neuromuscular lag (on angle-only ``kbl`` data τ_nm ran to its 1-s bound in 81 of 84 units,
README "Human models"), and it cannot be undone: inverting the lag turns torque noise into
command noise ×1/(1 - α), about ×12 at τ_nm = 60 ms. So for angle-only data the model must
describe the angles themselves, with the encoder inside it. This module does that.

The model
---------
The closed loop of :func:`scioc.models.delayed.sample.closed_loop` (physically lagged wheel, as
:func:`scioc.models.delayed.sample.sample_delayed` draws it), with z = (angle, velocity, arm
torque), the human's plan (L_k, f_k, S_k) for the command cost θ on its planning plant
(Ā, b_c, b_a) (:func:`scioc.models.delayed.sample.delayed_setup`; with the assistant's law Ā
contains it), white policy noise ε_k ~ N(0, 1/(2 S_k)) and white motor noise
m_k ~ N(0, σ_m²) that the human does not know. The truth moves as
``z_{k+1} = Ā z_k + b_c (c_k + m_k) + b_a κ_k`` (κ the known input: the assistant's
feedforward with its law, or its recorded torque), and the human, seeing z_{k-d} and
predicting with its own commands, acts on ``ẑ_k = z_k - e_k``,
``e_k = Σ_{j=1..d} G_j m_{k-j}``, ``G_j = Ā^{j-1} b_c`` (derived in
:mod:`scioc.models.delayed.likelihood`). With ``c_k = -L_k ẑ_k + f_k + ε_k``::

    z_{k+1} = (Ā - b_c L_k) z_k + b_c (Σ_{j=1..d} h_{k,j} m_{k-j} + ε_k + m_k + f_k) + b_a κ_k,
    h_{k,j} = L_k G_j   (the MA coefficients of the torque likelihood).

The encoder reads ``y_k = angle_k + v_k``, k = 0..K, with v_k ~ N(0, σ_y²) white: the
quantization of a step q as noise of variance q²/12 (Widrow's model; exact in the
second moments when the angle moves over many counts between samples, as on the study
reference, and an approximation of the quantizer's distribution otherwise).

So ``s_k = (z_k, m_{k-1}, ..., m_{k-d})`` (3 + d states) is a linear Gaussian state-space
model in the noises (ε_k, m_k, v_k), and ``log p(y_1..y_K | y_0)`` is the sum of the Kalman
filter's innovation terms. What is conditioned on: the reference, the known input and the
parameters; z_0 has the Gaussian prior N(``z0_mean``, ``z0_cov``) (the caller's: e.g. the
angle and velocity the recording gives at the window's start and the arm torque that the
torques before it imply, with their uncertainty) and is updated by y_0, which is not
scored; the pre-window motor noises have their prior N(0, σ_m²), independent of z_0 (the
torque likelihood's convention).

Computation
-----------
The filter's covariance is (3 + d)², but the transition is sparse: the z-block depends on
the history only through the scalar Σ_j h_{k,j} m_{k-j}, and the history only shifts. One
prediction costs O(d²) (the product of the history block with h, and the shift) and the
scalar update O((3 + d)²). The covariance does not depend on the data, and where the plan
is stationary (all of a window but its last steps when the plan looks past it) it
converges: once it moves by at most :data:`FREEZE_RTOL` in a step, it and the filter's
gain are held and only the mean moves, O(d) per step, until the plan moves again (tested:
equal to the unheld filter to rounding). Against O(K³) for the dense joint Gaussian
(:func:`scioc.models.delayed.dense.angle_loglik_dense`, the reference of the tests).
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
    """log p(y_1..y_K | y_0) of one window's recorded angles under the ``delayed`` human.

    Attributes
    ----------
    loglik : float
        Nats.
    innovations : ndarray, shape (K,)
        The filter's standardized innovations of y_1..y_K: iid N(0, 1) under the model.
    """

    loglik: float
    innovations: np.ndarray


#: The filter is held (:func:`angle_filter`) once its covariance after an update moves by at most this,
#: relative to its largest entry, in one step, while the plan's gain and S_k move by at most this too.
FREEZE_RTOL = 1e-13


@njit(cache=True, error_model="numpy", fastmath=False)
def angle_filter(Ab, bc, ba, L, f, S, known, d, s2m, s2y, y, mu0, P0, inn, freeze):
    """The Kalman filter of the module docstring; returns log p(y_1..y_K | y_0), fills ``inn`` (K,).

    State (z_k, m_{k-1}, ..., m_{k-d}), the history in lag order (it shifts every step). With
    ``freeze``, once the covariance is stationary (:data:`FREEZE_RTOL`) and while the plan is,
    only the mean moves, with the held gain: O(d) per step instead of O(d²).
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
    # y_0: conditioned on, not scored
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
    """The plan and the loop of one window (:func:`scioc.models.delayed.sample.delayed_setup`, physically lagged)."""
    return delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                         physical=True)


def check_angles(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov):
    """The arguments of :func:`angle_loglik` checked: (y, d, z0 mean, z0 covariance); ValueError otherwise."""
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
    """log p(y_1..y_K | y_0) of one window's recorded angles under the ``delayed`` human (module docstring).

    Parameters
    ----------
    theta : array_like, shape (3,)
        Command cost [q11, q22, R].
    angles : array_like, shape (K + 1,)
        The recorded angles y_0..y_K, rad.
    angle_ref : array_like, shape (K + M + 1,)
        The reference over the plan, rad.
    plant : DiscretePlant
    u_A : array_like, shape (K + M,), optional
        The assistant's recorded torque (the human knows it).
    feedback : Feedback, optional
        The assistant's law, acting on the true state; the human plans with it.
    tau_nm, sigma_m, delay : float, float, int
        Lag time constant (s), motor-noise SD (N·m per sample), delay (samples).
    sigma_y : float
        SD of the angle's measurement noise, rad (an encoder step q: q / sqrt(12)).
    z0_mean, z0_cov : array_like, shapes (3,), (3, 3)
        Prior of (angle, velocity, arm torque) at the window's start.
    params : WheelParameters
    freeze : bool
        Hold the filter's covariance once it is stationary (:func:`angle_filter`; the result
        equals the unheld filter's to rounding, tested).

    Returns
    -------
    AngleLoglik
    """
    setup = angle_setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params)
    y, d, mu0, P0 = check_angles(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov)
    K = y.shape[0] - 1
    inn = np.zeros(K)
    pol = setup.policy
    ll = angle_filter(setup.A, setup.b_c, setup.b_a, pol.L, pol.f, pol.S, setup.known, d, float(sigma_m) ** 2,
                      float(sigma_y) ** 2, y, mu0, P0, inn, bool(freeze))
    return AngleLoglik(float(ll), inn)


#: Prior SDs of the velocity (rad/s) and the arm torque (N·m) at a recorded window's start
#: (:func:`window_loglik`): the reconstruction's velocity and the arm torque its torques imply are
#: the means, and these SDs are wide against what the first samples' angles then tell (a torque
#: moves the angle by about 1e-4 rad within 0.05 s, some counts of the encoder).
START_SD = (0.05, 0.1)


class AngleWindow(NamedTuple):
    """One recorded window for :func:`window_loglik`.

    Attributes
    ----------
    angles : ndarray, shape (K + 1,)
        The encoder's angles y_0..y_K, rad.
    angle_ref : ndarray, shape (K + M + 1,)
    u_A : ndarray or None, shape (K + M,)
        The assistant's recorded torque, when it is a given input (None with ``feedback``).
    feedback : Feedback or None
    velocity0 : float
        The velocity at the window's start the angle implies (the reconstruction's), rad/s.
    warmup : Warmup or None
        The (reconstructed) torques before the window: the arm torque at the start follows
        from them at each τ_nm (None: at rest).
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
