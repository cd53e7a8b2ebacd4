"""The ``delayed`` human seen through the encoder: the exact likelihood of the recorded angles.

Why a second likelihood
-----------------------
:mod:`models.delayed.likelihood` is the density of the human's *torques*. The paper's rig
records only the wheel angle (an encoder of q rad per count); scioc then reconstructs the
torque, and that reconstruction smooths it. The delayed model reads the smoothing as
neuromuscular lag (on angle-only ``kbl`` data τ_nm ran to its 1-s bound in 81 of 84 units,
README "Human models"), and it cannot be undone: inverting the lag turns torque noise into
command noise ×1/(1 - α), about ×12 at τ_nm = 60 ms. So for angle-only data the model must
describe the angles themselves, with the encoder inside it. This module does that.

The model
---------
The closed loop of :func:`models.delayed.sample.closed_loop` (physically lagged wheel, as
:func:`models.delayed.sample.sample_delayed` draws it), with z = (angle, velocity, arm
torque), the human's plan (L_k, f_k, S_k) for the command cost θ on its planning plant
(Ā, b_c, b_a) (:func:`models.delayed.sample.delayed_setup`; with the assistant's law Ā
contains it), white policy noise ε_k ~ N(0, 1/(2 S_k)) and white motor noise
m_k ~ N(0, σ_m²) that the human does not know. The truth moves as
``z_{k+1} = Ā z_k + b_c (c_k + m_k) + b_a κ_k`` (κ the known input: the assistant's
feedforward with its law, or its recorded torque), and the human, seeing z_{k-d} and
predicting with its own commands, acts on ``ẑ_k = z_k - e_k``,
``e_k = Σ_{j=1..d} G_j m_{k-j}``, ``G_j = Ā^{j-1} b_c`` (derived in
:mod:`models.delayed.likelihood`). With ``c_k = -L_k ẑ_k + f_k + ε_k``::

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
the history only through the scalar Σ_j h_{k,j} m_{k-j}, and the history shifts (kept in a
ring buffer, so the shift costs nothing). One prediction costs O(d²) (the product of the
history block with h) and the scalar update O((3 + d)²): O(K d²) per window, against O(K³)
for the dense joint Gaussian (:func:`angle_loglik_dense`, the reference of the tests).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.linalg import cho_factor, cho_solve

from models.delayed.sample import closed_loop, delayed_setup
from models.design import WheelParameters
from models.maxent import HALF_LOG_2PI
from models.plant import DiscretePlant
from models.segment import Feedback


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


@njit(cache=True, error_model="numpy")
def angle_filter(Ab, bc, ba, L, f, S, known, d, s2m, s2y, y, mu0, P0, inn):
    """The Kalman filter of the module docstring; returns log p(y_1..y_K | y_0), fills ``inn`` (K,)."""
    K = y.shape[0] - 1
    n = 3 + d
    mu = np.zeros(n)
    P = np.zeros((n, n))
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
    h = np.zeros(max(d, 1))  # h[s]: the coefficient of the noise held in history slot s
    wm = np.zeros(max(d, 1))
    wz = np.zeros(3)
    M = np.zeros((3, 3))
    MP = np.zeros((3, n))
    Pzz = np.zeros((3, 3))
    pcol = np.zeros(n)
    ll = 0.0
    # y_0: conditioned on, not scored
    s = P[0, 0] + s2y
    if s > 0.0:
        nu = y[0] - mu[0]
        for i in range(n):
            pcol[i] = P[i, 0]
        for i in range(n):
            mu[i] += pcol[i] * nu / s
            for j in range(n):
                P[i, j] -= pcol[i] * pcol[j] / s
    for k in range(K):
        # ---- predict z_{k+1}; the history slot of m_{k-j} is (k - j) mod d
        for j in range(1, d + 1):
            h[(k - j) % d] = L[k, 0] * G[j - 1, 0] + L[k, 1] * G[j - 1, 1] + L[k, 2] * G[j - 1, 2]
        for i in range(3):
            for j in range(3):
                M[i, j] = Ab[i, j] - bc[i] * L[k, j]
        g = 0.0
        for s_ in range(d):
            g += h[s_] * mu[3 + s_]
        hph = 0.0
        for s_ in range(d):
            acc = 0.0
            for t in range(d):
                acc += P[3 + s_, 3 + t] * h[t]
            wm[s_] = acc
            hph += h[s_] * acc
        for i in range(3):
            acc = 0.0
            for t in range(d):
                acc += P[i, 3 + t] * h[t]
            wz[i] = acc
        # M P[:3, :] (rows of the z-block against everything)
        for i in range(3):
            for j in range(n):
                MP[i, j] = M[i, 0] * P[0, j] + M[i, 1] * P[1, j] + M[i, 2] * P[2, j]
        var_u = hph + 0.5 / S[k] + s2m
        for i in range(3):
            for j in range(3):
                Pzz[i, j] = (MP[i, 0] * M[j, 0] + MP[i, 1] * M[j, 1] + MP[i, 2] * M[j, 2]
                             + (M[i, 0] * wz[0] + M[i, 1] * wz[1] + M[i, 2] * wz[2]) * bc[j]
                             + bc[i] * (M[j, 0] * wz[0] + M[j, 1] * wz[1] + M[j, 2] * wz[2])
                             + bc[i] * bc[j] * var_u)
        z0_ = mu[0]
        z1_ = mu[1]
        z2_ = mu[2]
        for i in range(3):
            mu[i] = M[i, 0] * z0_ + M[i, 1] * z1_ + M[i, 2] * z2_ + bc[i] * (g + f[k]) + ba[i] * known[k]
        new = k % d if d > 0 else -1  # m_k takes the slot of m_{k-d}
        for s_ in range(d):
            if s_ == new:
                continue
            for i in range(3):
                v = MP[i, 3 + s_] + bc[i] * wm[s_]
                P[i, 3 + s_] = v
                P[3 + s_, i] = v
        for i in range(3):
            for j in range(3):
                P[i, j] = Pzz[i, j]
        if d > 0:
            mu[3 + new] = 0.0
            for j in range(n):
                P[3 + new, j] = 0.0
                P[j, 3 + new] = 0.0
            P[3 + new, 3 + new] = s2m
            for i in range(3):
                P[i, 3 + new] = bc[i] * s2m
                P[3 + new, i] = bc[i] * s2m
        # ---- observe y_{k+1}
        s = P[0, 0] + s2y
        nu = y[k + 1] - mu[0]
        if not s > 0.0:
            if nu != 0.0:
                return -np.inf
            inn[k] = 0.0
            continue
        ll -= 0.5 * nu * nu / s + 0.5 * np.log(s) + HALF_LOG_2PI
        inn[k] = nu / np.sqrt(s)
        for i in range(n):
            pcol[i] = P[i, 0]
        for i in range(n):
            mu[i] += pcol[i] * nu / s
            for j in range(i, n):
                v = P[i, j] - pcol[i] * pcol[j] / s
                P[i, j] = v
                P[j, i] = v
    return ll


def _setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params):
    return delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                         physical=True)


def _check(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov):
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
                 params: WheelParameters = WheelParameters()) -> AngleLoglik:
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

    Returns
    -------
    AngleLoglik
    """
    setup = _setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params)
    y, d, mu0, P0 = _check(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov)
    K = y.shape[0] - 1
    inn = np.zeros(K)
    pol = setup.policy
    ll = angle_filter(setup.A, setup.b_c, setup.b_a, pol.L, pol.f, pol.S, setup.known, d, float(sigma_m) ** 2,
                      float(sigma_y) ** 2, y, mu0, P0, inn)
    return AngleLoglik(float(ll), inn)


class AngleDense(NamedTuple):
    """The joint Gaussian of one window's recorded angles y_0..y_K and log p(y_1..y_K | y_0).

    Attributes
    ----------
    loglik : float
    mean : ndarray, shape (K + 1,)
    cov : ndarray, shape (K + 1, K + 1)
    """

    loglik: float
    mean: np.ndarray
    cov: np.ndarray


def angle_loglik_dense(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None,
                       feedback: Feedback | None = None, tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0,
                       sigma_y: float, z0_mean, z0_cov, params: WheelParameters = WheelParameters()) -> AngleDense:
    """The dense reference of :func:`angle_loglik`: the angles' joint Gaussian from the generative loop.

    The loop (:func:`models.delayed.sample.closed_loop`, physically lagged) is affine in
    z_0 and the noises: its mean is the loop at z0_mean with every noise zero, and its
    covariance comes from the loop with every offset zero driven by the columns of
    z0_cov's square root, by each ε_k and each m_k (k = -d..K-1) as unit impulses; the
    encoder's noise adds σ_y² on the diagonal. Then log N(y) - log N(y_0). O(K²) memory
    and O(K³) time: for tests only.
    """
    setup = _setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params)
    y, d, mu0, P0 = _check(angles, setup, delay, sigma_m, sigma_y, z0_mean, z0_cov)
    K = y.shape[0] - 1
    pol = setup.policy

    def run(z0, known, f, eps, m):
        return closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                           setup.feedback, known, pol.L, f, z0, eps, m, d, setup.true_A, setup.true_b,
                           setup.physical)[0][:, 0, :]

    mean = run(mu0, setup.known, pol.f, np.zeros((K, 1)), np.zeros((K + d, 1)))[:, 0]
    zero = np.zeros_like(setup.known)
    w, V = np.linalg.eigh(P0)
    root = V * np.sqrt(np.clip(w, 0.0, None))
    cols = [run(root[:, i], zero, zero, np.zeros((K, 1)), np.zeros((K + d, 1))) for i in range(3)]
    eps = np.diag(np.sqrt(0.5 / pol.S[:K]))
    m = float(sigma_m) * np.eye(K + d)
    cols.append(run(np.zeros(3), zero, zero, eps, np.zeros((K + d, K))))
    cols.append(run(np.zeros(3), zero, zero, np.zeros((K, K + d)), m))
    Gm = np.hstack(cols)
    cov = Gm @ Gm.T + float(sigma_y) ** 2 * np.eye(K + 1)
    c = cho_factor(cov, lower=True)
    e = y - mean
    ll_all = -0.5 * e @ cho_solve(c, e) - np.sum(np.log(np.diag(c[0]))) - (K + 1) * HALF_LOG_2PI
    ll0 = -0.5 * e[0] ** 2 / cov[0, 0] - 0.5 * np.log(cov[0, 0]) - HALF_LOG_2PI
    return AngleDense(float(ll_all - ll0), mean, cov)


__all__ = ["AngleDense", "AngleLoglik", "angle_filter", "angle_loglik", "angle_loglik_dense"]
