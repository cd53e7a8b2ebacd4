"""Reconstruct velocity and human torque from the encoder angle (paper Section IV-E).

Inverting the sampled plant rings (a sampling zero near -1) and amplifies quantization, so a
Kalman/Rauch-Tung-Striebel smoother estimates the torque ``u_H,k = s_k + ε_k``, ``s_{k+1} = s_k + w_k``
(w ~ N(0, q), ε ~ N(0, σ_ε²): a smooth optimal part plus white deviations, as the max-ent human's), from
``angle_k = φ_k + n_k``, n ~ N(0, Δ²/12); q and σ_ε maximize the angles' marginal likelihood (empirical
Bayes). The smoothed means satisfy the plant equation exactly; variability below the encoder's
resolution is shrunk, so the reconstructed torque is less variable than the true one.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize

from scioc.models.design import ENCODER_STEP
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit

#: Encoder increment of the study's wheel (:data:`scioc.models.design.ENCODER_STEP`), rad.
DEFAULT_RESOLUTION = ENCODER_STEP


class Reconstruction(NamedTuple):
    """Smoothed ``angle``, ``velocity``, ``u_H`` (K + 1,; last u_H unused), the chosen ``sigma_eps`` and ``q``,
    the angles' marginal ``loglik``, and the ``smoother`` at those variances."""

    angle: np.ndarray
    velocity: np.ndarray
    u_H: np.ndarray
    sigma_eps: float
    q: float
    loglik: float
    smoother: "FixedReconstruction"


def _transition(A, b, var_eps, q):
    """State transition F and process noise of z = (φ, φ̇, s) over one sample."""
    F = np.zeros((3, 3))
    F[:2, :2] = A
    F[0, 2], F[1, 2], F[2, 2] = b[0], b[1], 1.0
    Qn = np.zeros((3, 3))
    Qn[:2, :2] = np.outer(b, b) * var_eps
    Qn[2, 2] = q
    return F, Qn


@njit(cache=True, fastmath=False, error_model="python")
def _gains(F, Qn, r, n, smooth):
    """The angle-independent half of the filter and smoother: Kalman gains ``Kg`` (n, 3), innovation
    variances ``Sv`` (n,) and smoother gains ``C`` (n, 3, 3), ``Pf[k] Fᵀ Pp[k+1]⁻¹`` (zeros unless ``smooth``)."""
    Kg = np.empty((n, 3))
    Sv = np.empty(n)
    C = np.zeros((n, 3, 3))
    Pf = np.empty((n, 3, 3))
    Pp = np.empty((n, 3, 3))
    P = np.zeros((3, 3))
    P[0, 0] = r
    P[1, 1] = 1.0  # rad/s: a wheel at rest or turning slowly
    P[2, 2] = 1.0  # N·m
    for k in range(n):
        if k > 0:
            FP = np.zeros((3, 3))
            for i in range(3):
                for j in range(3):
                    for m in range(3):
                        FP[i, j] += F[i, m] * P[m, j]
            Pn = Qn.copy()
            for i in range(3):
                for j in range(3):
                    for m in range(3):
                        Pn[i, j] += FP[i, m] * F[j, m]
            P = Pn
        Pp[k] = P
        S = P[0, 0] + r
        Sv[k] = S
        for i in range(3):
            Kg[k, i] = P[i, 0] / S
        Pnew = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                Pnew[i, j] = P[i, j] - Kg[k, i] * P[0, j]
        P = 0.5 * (Pnew + Pnew.T)
        Pf[k] = P
    if smooth:
        for k in range(n - 2, -1, -1):
            PFt = np.zeros((3, 3))
            for i in range(3):
                for j in range(3):
                    for m in range(3):
                        PFt[i, j] += Pf[k, i, m] * F[j, m]
            C[k] = PFt @ np.linalg.inv(Pp[k + 1])
    return Kg, Sv, C


@njit(cache=True, fastmath=False, error_model="python")
def smooth_means(F, b, y, a, Kg, Sv, C, smooth):
    """Marginal log-likelihood of the angles ``y`` and the smoothed (or filtered) means (n, 3), from precomputed
    gains; no allocation per step, as the bootstrap runs it per replicate."""
    n = y.shape[0]
    zf = np.empty((n, 3))
    zp = np.empty((n, 3))
    z0 = y[0]
    z1 = 0.0
    z2 = 0.0
    ll = 0.0
    for k in range(n):
        if k > 0:
            n0 = F[0, 0] * z0 + F[0, 1] * z1 + F[0, 2] * z2 + b[0] * a[k - 1]
            n1 = F[1, 0] * z0 + F[1, 1] * z1 + F[1, 2] * z2 + b[1] * a[k - 1]
            n2 = F[2, 0] * z0 + F[2, 1] * z1 + F[2, 2] * z2
            z0, z1, z2 = n0, n1, n2
        zp[k, 0], zp[k, 1], zp[k, 2] = z0, z1, z2
        S = Sv[k]
        nu = y[k] - z0
        ll += -0.5 * (math.log(2.0 * math.pi * S) + nu * nu / S)
        z0 += Kg[k, 0] * nu
        z1 += Kg[k, 1] * nu
        z2 += Kg[k, 2] * nu
        zf[k, 0], zf[k, 1], zf[k, 2] = z0, z1, z2
    zs = zf.copy()
    if smooth:
        for k in range(n - 2, -1, -1):
            d0 = zs[k + 1, 0] - zp[k + 1, 0]
            d1 = zs[k + 1, 1] - zp[k + 1, 1]
            d2 = zs[k + 1, 2] - zp[k + 1, 2]
            for i in range(3):
                zs[k, i] = zf[k, i] + C[k, i, 0] * d0 + C[k, i, 1] * d1 + C[k, i, 2] * d2
    return ll, zs


def _filter(A, b, y, a, var_eps, q, r, smooth):
    """Kalman filter (and RTS smoother means) for z = (φ, φ̇, s): marginal log-likelihood and means."""
    F, Qn = _transition(A, b, var_eps, q)
    Kg, Sv, C = _gains(F, Qn, r, y.shape[0], smooth)
    return smooth_means(F, b, y, a, Kg, Sv, C, smooth)


class FixedReconstruction(NamedTuple):
    """The reconstruction at fixed variances: a linear filter for records of one length."""

    F: np.ndarray
    b: np.ndarray
    A: np.ndarray
    Kg: np.ndarray
    Sv: np.ndarray
    C: np.ndarray


def fixed_reconstruction(plant: DiscretePlant, n: int, sigma_eps: float, q: float, *,
                         resolution: float = DEFAULT_RESOLUTION) -> FixedReconstruction:
    """The smoother of :func:`reconstruct` for records of ``n`` angles at ``sigma_eps`` (N·m), ``q``
    ((N·m)² per sample) and encoder ``resolution`` (rad)."""
    F, Qn = _transition(plant.A, plant.b, sigma_eps**2, q)
    Kg, Sv, C = _gains(F, Qn, resolution**2 / 12.0, int(n), True)
    return FixedReconstruction(F, np.asarray(plant.b, dtype=float), np.asarray(plant.A, dtype=float), Kg, Sv, C)


@njit(cache=True, fastmath=False, error_model="python")
def torque_from_means(A, b, zs, a):
    """u_H from smoothed means: smooth torque plus the white part from the velocity row (b2 > 0)."""
    n = zs.shape[0]
    u = np.empty(n)
    for k in range(n - 1):
        pred = A[1, 0] * zs[k, 0] + A[1, 1] * zs[k, 1] + b[1] * (zs[k, 2] + a[k])
        u[k] = zs[k, 2] + (zs[k + 1, 1] - pred) / b[1]
    u[n - 1] = zs[n - 1, 2]
    return u


@njit(cache=True, fastmath=False, error_model="python")
def apply_reconstruction(F, b, A, Kg, Sv, C, y, a):
    """``(angle, velocity, u_H)``, each (n,), of one record through a :class:`FixedReconstruction`'s arrays."""
    _, zs = smooth_means(F, b, y, a, Kg, Sv, C, True)
    return zs[:, 0].copy(), zs[:, 1].copy(), torque_from_means(A, b, zs, a)


#: Seconds of recorded angle :func:`initial_state` fits the initial state to.
INITIAL_STATE_SECONDS = 0.5


def initial_state(angle, u, plant: DiscretePlant, seconds: float = INITIAL_STATE_SECONDS) -> np.ndarray:
    """x_0 (2,) of a record with measured total torque ``u``: least squares of the angles, linear in x_0, over
    the first ``seconds`` (at least 3 samples), which averages the quantization instead of differencing."""
    y = np.asarray(angle, dtype=float)
    uu = np.asarray(u, dtype=float)
    n = min(y.shape[0], uu.shape[0] + 1, max(3, int(round(seconds / plant.dt)) + 1))
    if n < 2:
        raise ValueError("initial_state needs at least two angle samples")
    rows = np.empty((n, 2))
    forced = np.zeros(n)
    Ak = np.eye(2)
    x = np.zeros(2)  # the torques' part of the state
    for k in range(n):
        rows[k] = Ak[0]
        forced[k] = x[0]
        if k + 1 < n:
            Ak = plant.A @ Ak
            x = plant.A @ x + plant.b * uu[k]
    sol, *_ = np.linalg.lstsq(rows, y[:n] - forced, rcond=None)
    return sol


def reconstruct(
    angle,
    u_A,
    plant: DiscretePlant,
    *,
    resolution: float = DEFAULT_RESOLUTION,
    sigma_eps: float | None = None,
    q: float | None = None,
) -> Reconstruction:
    """Reconstruct velocity (rad/s) and u_H (N·m) of one segment from its encoder ``angle`` (K + 1,), rad.

    ``u_A`` (K,) or longer, N·m; ``resolution``, the encoder increment, rad; ``sigma_eps`` (N·m) and ``q``
    ((N·m)² per sample) are fitted unless given.
    """
    y = np.ascontiguousarray(angle, dtype=float)
    a = np.ascontiguousarray(u_A, dtype=float)[: y.shape[0] - 1]
    if y.ndim != 1 or y.shape[0] < 3 or a.shape[0] != y.shape[0] - 1:
        raise ValueError("reconstruct needs at least 3 angle samples and one u_A per step")
    if not resolution > 0:
        raise ValueError(f"encoder resolution must be > 0 rad; got {resolution!r}")
    r = resolution**2 / 12.0

    def negll(z):
        ll, _ = _filter(plant.A, plant.b, y, a, math.exp(2 * z[0]), math.exp(2 * z[1]), r, False)
        return -ll

    if sigma_eps is None or q is None:
        fixed = [None if sigma_eps is None else math.log(sigma_eps), None if q is None else 0.5 * math.log(q)]
        free = [i for i in range(2) if fixed[i] is None]
        start = np.array([math.log(0.1), 0.5 * math.log(1e-4)])

        def f(zfree):
            z = [fixed[0], fixed[1]]
            for i, v in zip(free, zfree):
                z[i] = v
            return negll(z)

        res = minimize(f, start[free], method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 400})
        z = [fixed[0], fixed[1]]
        for i, v in zip(free, res.x):
            z[i] = v
        sigma_eps, q = math.exp(z[0]), math.exp(2 * z[1])
    fixed = fixed_reconstruction(plant, y.shape[0], float(sigma_eps), float(q), resolution=resolution)
    ll, zs = smooth_means(fixed.F, fixed.b, y, a, fixed.Kg, fixed.Sv, fixed.C, True)
    u_H = torque_from_means(fixed.A, fixed.b, zs, a)
    return Reconstruction(zs[:, 0].copy(), zs[:, 1].copy(), u_H, float(sigma_eps), float(q), float(ll), fixed)
