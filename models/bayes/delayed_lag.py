"""The neuromuscular lag's coefficients in numba: :func:`scioc.models.delayed.lag.lag_coefficients` for compiled code.

:func:`lag_nb` gives the pole a = e^{-μ dt} (μ = 1/τ_nm), the mixing α = v_1 / b_1 and their τ_nm-derivatives from
the wheel's constants: where every wheel pole is at relative distance > 5 % from -μ, in closed form,
``v = (A_c + μ I)⁻¹ (Φ - a I) b_w``, ``dv/dμ = (A_c + μ I)⁻¹ (dt a b_w - v)``; otherwise (a real pole near -μ)
by entire functions of X = (A_c + μ I) dt, with scaling and squaring (``φ1(2Z) = ½ (I + e^Z) φ1(Z)``,
``ψ(2Z) = ¼ (ψ(Z) + e^Z (φ1(Z) + ψ(Z)))``)::

    v = a dt φ1(X) b_w,   dv/dμ = -dt v + a dt² ψ(X) b_w,   φ1(X) = ∫_0^1 e^{X s} ds,   ψ(X) = ∫_0^1 s e^{X s} ds
"""

from __future__ import annotations

import math

import numpy as np

from scioc.models.design import WheelParameters
from scioc.models.plant import continuous_matrices, discretize
from scioc.models.runtime import njit

#: Taylor terms of the series branch (at norm <= 1/2: 0.5^24 / 24! is far below rounding).
_TERMS = 24
#: τ_nm (s) below which α is its first-order expansion (a sampler can propose τ_nm = 1e-200).
TAU_TINY = 1e-9


def wheel_constants(dt: float, params: WheelParameters = WheelParameters()) -> tuple:
    """``(dt, A_c, b_w, Φ b_w, b_1, poles)`` for :func:`lag_nb`: the continuous wheel, its ZOH step, its poles."""
    A_c, b_w = continuous_matrices(params)
    wheel = discretize(float(dt), params)
    return (float(dt), np.ascontiguousarray(A_c), np.ascontiguousarray(b_w), np.ascontiguousarray(wheel.A @ b_w),
            float(wheel.b[1]), np.linalg.eigvals(A_c).astype(np.complex128))


@njit(cache=True, fastmath=False, error_model="python")
def _mm(X, Y):
    Z = np.empty((2, 2))
    for i in range(2):
        for j in range(2):
            Z[i, j] = X[i, 0] * Y[0, j] + X[i, 1] * Y[1, j]
    return Z


@njit(cache=True, fastmath=False, error_model="python")
def _phi_series(X):
    """(φ1(X), ψ(X)) of a 2 × 2 matrix by scaling and squaring (module docstring)."""
    norm = max(abs(X[0, 0]) + abs(X[1, 0]), abs(X[0, 1]) + abs(X[1, 1]))
    s = 0
    while norm > 0.5:
        norm *= 0.5
        s += 1
    Y = X / 2.0**s
    E = np.eye(2)
    P1 = np.eye(2)
    P2 = 0.5 * np.eye(2)
    term = np.eye(2)  # Y^k / k!
    for k in range(1, _TERMS):
        term = _mm(term, Y) / k
        E += term
        P1 += term / (k + 1)
        P2 += term / (k + 2)
    eye = np.eye(2)
    for _ in range(s):
        P2 = 0.25 * (P2 + _mm(E, P1 + P2))
        P1 = 0.5 * _mm(eye + E, P1)
        E = _mm(E, E)
    return P1, P2


@njit(cache=True, fastmath=False, error_model="python")
def _response(mu, a, dt, A_c, b_w, Pb, poles):
    """(v0, v1, dv0/dμ, dv1/dμ) at μ = 1/τ_nm > 0, a = e^{-μ dt} (module docstring)."""
    dist = np.inf
    for lam in poles:
        dist = min(dist, abs(mu + lam) / (mu + abs(lam)))
    if dist > 0.05:
        m00, m01, m10, m11 = A_c[0, 0] + mu, A_c[0, 1], A_c[1, 0], A_c[1, 1] + mu
        det = m00 * m11 - m01 * m10
        r0, r1 = Pb[0] - a * b_w[0], Pb[1] - a * b_w[1]
        v0, v1 = (m11 * r0 - m01 * r1) / det, (m00 * r1 - m10 * r0) / det
        s0, s1 = dt * a * b_w[0] - v0, dt * a * b_w[1] - v1
        return v0, v1, (m11 * s0 - m01 * s1) / det, (m00 * s1 - m10 * s0) / det
    X = (A_c + mu * np.eye(2)) * dt
    P1, P2 = _phi_series(X)
    v0 = a * dt * (P1[0, 0] * b_w[0] + P1[0, 1] * b_w[1])
    v1 = a * dt * (P1[1, 0] * b_w[0] + P1[1, 1] * b_w[1])
    return (v0, v1, -dt * v0 + a * dt * dt * (P2[0, 0] * b_w[0] + P2[0, 1] * b_w[1]),
            -dt * v1 + a * dt * dt * (P2[1, 0] * b_w[0] + P2[1, 1] * b_w[1]))


@njit(cache=True, fastmath=False, error_model="python")
def lag_nb(tau_nm, dt, A_c, b_w, Pb, b1, poles):
    """``(a, α, da/dτ_nm, dα/dτ_nm)`` of one τ_nm >= 0 (s); the wheel's constants from :func:`wheel_constants`."""
    if tau_nm < TAU_TINY:
        # a = e^{-dt/τ} is 0 here and α = τ (Φ b_w)_1 / b_1 + O(τ²) to rounding; μ² would overflow.
        return 0.0, tau_nm * Pb[1] / b1, 0.0, Pb[1] / b1
    mu = 1.0 / tau_nm
    a = math.exp(-dt * mu)
    _, v1, _, dv1 = _response(mu, a, dt, A_c, b_w, Pb, poles)
    return a, v1 / b1, a * dt * mu * mu, -mu * mu * dv1 / b1


@njit(cache=True, fastmath=False, error_model="python")
def lagged_wheel_nb(tau_nm, dt, A_c, b_w, Phi, b, poles):
    """(A (3, 3), b_c (3,), dA/dτ_nm, db_c/dτ_nm) of the physically lagged wheel at τ_nm >= 0 (s)
    (:func:`scioc.models.delayed.angles.lagged_wheel`): ``A = [[Φ, v], [0, a]]``, ``b_c = (b - v, 1 - a)``, v the
    wheel's response over a sample to an arm torque decaying from 1; ``Phi``, ``b``: the wheel's ZOH step."""
    Pb = Phi @ b_w
    if tau_nm < TAU_TINY:  # v = τ Φ b_w + O(τ²) to rounding
        a, da = 0.0, 0.0
        v0, v1, dv0, dv1 = tau_nm * Pb[0], tau_nm * Pb[1], Pb[0], Pb[1]
    else:
        mu = 1.0 / tau_nm
        a = math.exp(-dt * mu)
        da = a * dt * mu * mu
        v0, v1, dv0, dv1 = _response(mu, a, dt, A_c, b_w, Pb, poles)
        dv0, dv1 = -mu * mu * dv0, -mu * mu * dv1
    A = np.zeros((3, 3))
    dA = np.zeros((3, 3))
    A[:2, :2] = Phi
    A[0, 2], A[1, 2], A[2, 2] = v0, v1, a
    dA[0, 2], dA[1, 2], dA[2, 2] = dv0, dv1, da
    b_c = np.array([b[0] - v0, b[1] - v1, 1.0 - a])
    db_c = np.array([-dv0, -dv1, -da])
    return A, b_c, dA, db_c


__all__ = ["TAU_TINY", "lag_nb", "lagged_wheel_nb", "wheel_constants"]
