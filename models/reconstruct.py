"""Reconstruct velocity and human torque from the encoder angle (paper Section IV-E).

Only the angle is measured. Inverting the sampled plant step by step is nearly unstable
(the zero-order-hold plant has a sampling zero at -0.976 at 100 Hz, so the inverse rings)
and it amplifies quantization: one encoder increment (1.6e-4 rad) is worth about
0.13 N·m of torque in a single step. We therefore estimate the torque statistically, as
a Kalman/Rauch-Tung-Striebel smoother of the plant driven by

    u_H,k = s_k + ε_k,   s_{k+1} = s_k + w_k,   w_k ~ N(0, q),   ε_k ~ N(0, σ_ε²)

(a slowly wandering torque plus white torque variability, which is what the max-ent
human produces: an optimal part that changes smoothly and Gaussian deviations around
it), observed through ``angle_k = φ_k + n_k`` with the quantization error
``n_k ~ N(0, Δ²/12)``. The two variances are chosen by maximizing the marginal
likelihood of the recorded angles (empirical Bayes), per segment.

The smoothed means satisfy the plant equation exactly: with ``û_H,k = ŝ_k + ε̂_k``,
``x̂_{k+1} = A x̂_k + b (û_H,k + u_A,k)``. What cannot be recovered is the part of the
torque variability whose effect on the angle stays below the encoder's resolution;
the smoother shrinks it toward the smooth torque, which makes the reconstructed torque
less variable than the true one (measured by ``scioc identify`` on simulated data and
shown in the report).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.optimize import minimize

from models.plant import DiscretePlant

#: Encoder increment of the paper's wheel (40000 per revolution), rad.
DEFAULT_RESOLUTION = 2.0 * math.pi / 40000


class Reconstruction(NamedTuple):
    """Velocity and torque reconstructed from the angle.

    Attributes
    ----------
    angle : ndarray, shape (K + 1,)
        Smoothed angle, rad.
    velocity : ndarray, shape (K + 1,)
        rad/s.
    u_H : ndarray, shape (K + 1,)
        N·m; the last entry is the smooth torque at the last sample (unused downstream).
    sigma_eps : float
        Chosen SD of the white torque component, N·m.
    q : float
        Chosen random-walk variance of the smooth torque, (N·m)² per sample.
    loglik : float
        Marginal log-likelihood of the angles at the chosen variances.
    """

    angle: np.ndarray
    velocity: np.ndarray
    u_H: np.ndarray
    sigma_eps: float
    q: float
    loglik: float


@njit(cache=True)
def _filter(A, b, y, a, var_eps, q, r, smooth):
    """Kalman filter (and RTS smoother means) for z = (φ, φ̇, s)."""
    n = y.shape[0]
    F = np.zeros((3, 3))
    F[0, 0], F[0, 1], F[1, 0], F[1, 1] = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    F[0, 2], F[1, 2], F[2, 2] = b[0], b[1], 1.0
    Qn = np.zeros((3, 3))
    Qn[0, 0] = b[0] * b[0] * var_eps
    Qn[0, 1] = Qn[1, 0] = b[0] * b[1] * var_eps
    Qn[1, 1] = b[1] * b[1] * var_eps
    Qn[2, 2] = q
    zf = np.empty((n, 3))
    Pf = np.empty((n, 3, 3))
    zp = np.empty((n, 3))
    Pp = np.empty((n, 3, 3))
    z = np.array([y[0], 0.0, 0.0])
    P = np.zeros((3, 3))
    P[0, 0] = r
    P[1, 1] = 1.0  # rad/s: a wheel at rest or turning slowly
    P[2, 2] = 1.0  # N·m
    ll = 0.0
    for k in range(n):
        if k > 0:
            zn = np.zeros(3)
            for i in range(3):
                for j in range(3):
                    zn[i] += F[i, j] * z[j]
            zn[0] += b[0] * a[k - 1]
            zn[1] += b[1] * a[k - 1]
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
            z = zn
            P = Pn
        zp[k] = z
        Pp[k] = P
        S = P[0, 0] + r
        nu = y[k] - z[0]
        ll += -0.5 * (math.log(2.0 * math.pi * S) + nu * nu / S)
        Kg = P[:, 0] / S
        z = z + Kg * nu
        Pnew = np.empty((3, 3))
        for i in range(3):
            for j in range(3):
                Pnew[i, j] = P[i, j] - Kg[i] * P[0, j]
        P = 0.5 * (Pnew + Pnew.T)
        zf[k] = z
        Pf[k] = P
    zs = zf.copy()
    if smooth:
        for k in range(n - 2, -1, -1):
            # C = Pf[k] Fᵀ Pp[k+1]⁻¹
            PFt = np.zeros((3, 3))
            for i in range(3):
                for j in range(3):
                    for m in range(3):
                        PFt[i, j] += Pf[k, i, m] * F[j, m]
            C = PFt @ np.linalg.inv(Pp[k + 1])
            d = zs[k + 1] - zp[k + 1]
            for i in range(3):
                acc = 0.0
                for j in range(3):
                    acc += C[i, j] * d[j]
                zs[k, i] = zf[k, i] + acc
    return ll, zs


def reconstruct(
    angle,
    u_A,
    plant: DiscretePlant,
    *,
    resolution: float = DEFAULT_RESOLUTION,
    sigma_eps: float | None = None,
    q: float | None = None,
) -> Reconstruction:
    """Reconstruct velocity and u_H of one segment from its encoder angle and u_A.

    Parameters
    ----------
    angle : array_like, shape (K + 1,)
        Recorded angle, rad.
    u_A : array_like, shape (K + 1,) or (K,)
        Assistant torque, N·m (zeros in MC); entries beyond K are ignored.
    plant : DiscretePlant
        The 0.01-s wheel.
    resolution : float
        Encoder increment, rad; sets the measurement variance resolution²/12.
    sigma_eps, q : float, optional
        Fix the white-torque SD (N·m) and the smooth-torque random-walk variance
        ((N·m)² per sample) instead of maximizing the marginal likelihood.

    Returns
    -------
    Reconstruction
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

        # Nelder-Mead on log-SDs: two smooth parameters, each evaluation an O(K) filter.
        res = minimize(f, start[free], method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-6, "maxiter": 400})
        z = [fixed[0], fixed[1]]
        for i, v in zip(free, res.x):
            z[i] = v
        sigma_eps, q = math.exp(z[0]), math.exp(2 * z[1])
    ll, zs = _filter(plant.A, plant.b, y, a, sigma_eps**2, q, r, True)
    # White torque component from the smoothed transition (velocity row; b2 > 0).
    x = zs[:, :2]
    pred = x[:-1] @ plant.A.T + np.outer(zs[:-1, 2] + a, plant.b)
    eps = (x[1:, 1] - pred[:, 1]) / plant.b[1]
    u_H = np.append(zs[:-1, 2] + eps, zs[-1, 2])
    return Reconstruction(zs[:, 0].copy(), zs[:, 1].copy(), u_H, float(sigma_eps), float(q), float(ll))
