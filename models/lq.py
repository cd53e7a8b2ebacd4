"""Finite-horizon LQ tracking with a known affine input: the one home of the backward Riccati recursion.

The human (θ on the 0.01-s plant) and the MPC assistant (θ_A on the 0.02-s plant) both solve::

    min_u  sum_{k=1..K} e_kᵀ Q e_k + sum_{k=0..K-1} R u_k²
    s.t.   x_{k+1} = A x_k + b (u_k + a_k),   e_k = x_k - (r_k, 0)

with ``a_k`` a known torque (u_A, to the human). With the cost-to-go ``xᵀ P_k x - 2 s_kᵀ x + const``,
``P_K = Q``, ``s_K = Q (r_K, 0)``, one step back is

* ``S_k = R + bᵀ P_{k+1} b``,  ``L_k = bᵀ P_{k+1} A / S_k``,  ``M_k = A - b L_k``
* ``f_k = bᵀ (s_{k+1} - P_{k+1} b a_k) / S_k``
* ``P_k = Q + Aᵀ P_{k+1} A - S_k L_kᵀ L_k``,  ``s_k = Q (r_k, 0) + M_kᵀ (s_{k+1} - P_{k+1} b a_k)``

and ``u_k = -L_k x_k + f_k``. Completing the square gives ``J(u) - min J = sum_k S_k (u_k + L_k x_k - f_k)²``
at the states driven by ``u``, which makes the max-ent likelihood linear in K (:mod:`scioc.models.maxent`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.cost import validate_theta
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit


@njit(cache=True, inline="always", error_model="numpy", fastmath=False)
def riccati_gains(p11, p12, p22, a11, a12, a21, a22, b1, b2, R):
    """``(S, 1/S, L1, L2, pb1, pb2, m11, m12, m21, m22)`` of a backward step from ``P_{k+1}``; M = A - b L."""
    pb1 = p11 * b1 + p12 * b2
    pb2 = p12 * b1 + p22 * b2
    S = R + b1 * pb1 + b2 * pb2
    invS = 1.0 / S
    L1 = (pb1 * a11 + pb2 * a21) * invS
    L2 = (pb1 * a12 + pb2 * a22) * invS
    m11 = a11 - b1 * L1
    m12 = a12 - b1 * L2
    m21 = a21 - b2 * L1
    m22 = a22 - b2 * L2
    return S, invS, L1, L2, pb1, pb2, m11, m12, m21, m22


@njit(cache=True, inline="always", fastmath=False, error_model="numpy")
def riccati_update(p11, p12, p22, q11, q22, R, L1, L2, m11, m12, m21, m22):
    """``P_k = Q + Lᵀ R L + Mᵀ P_{k+1} M`` (Joseph form), and by the envelope theorem also its tangent
    ``dP_k = dQ + Lᵀ dR L + Mᵀ dP_{k+1} M``."""
    x11 = p11 * m11 + p12 * m21
    x12 = p11 * m12 + p12 * m22
    x21 = p12 * m11 + p22 * m21
    x22 = p12 * m12 + p22 * m22
    n11 = q11 + R * L1 * L1 + (m11 * x11 + m21 * x21)
    n12 = R * L1 * L2 + (m11 * x12 + m21 * x22)
    n22 = q22 + R * L2 * L2 + (m12 * x12 + m22 * x22)
    return n11, n12, n22


class Policy(NamedTuple):
    """Optimal policy ``u_k = -L[k] @ x_k + f[k]``: ``L`` (K, 2), N·m per (rad, rad/s); ``f`` (K,), N·m;
    ``S`` (K,), 1/(N·m)², the max-ent precision: u_k | x_k has variance ``1 / (2 S_k)``."""

    L: np.ndarray
    f: np.ndarray
    S: np.ndarray


@njit(cache=True, fastmath=False, error_model="python")
def _policy_kernel(A, b, q11, q22, R, r, a):
    K = a.shape[0]
    a11, a12, a21, a22 = A[0, 0], A[0, 1], A[1, 0], A[1, 1]
    b1, b2 = b[0], b[1]
    L = np.empty((K, 2))
    f = np.empty(K)
    Sv = np.empty(K)
    p11, p12, p22 = q11, 0.0, q22
    s1, s2 = q11 * r[K], 0.0
    for k in range(K - 1, -1, -1):
        S, invS, L1, L2, pb1, pb2, m11, m12, m21, m22 = riccati_gains(p11, p12, p22, a11, a12, a21, a22, b1, b2, R)
        w1 = s1 - pb1 * a[k]
        w2 = s2 - pb2 * a[k]
        f[k] = (b1 * w1 + b2 * w2) * invS
        L[k, 0] = L1
        L[k, 1] = L2
        Sv[k] = S
        s1 = q11 * r[k] + m11 * w1 + m21 * w2
        s2 = m12 * w1 + m22 * w2
        p11, p12, p22 = riccati_update(p11, p12, p22, q11, q22, R, L1, L2, m11, m12, m21, m22)
    return L, f, Sv


def lq_policy(plant: DiscretePlant, theta, angle_ref, u_A) -> Policy:
    """Optimal tracking :class:`Policy` for θ = [q11, q22, R] on ``plant``.

    ``angle_ref`` (K + 1,), rad (r_0 unused); ``u_A`` (K,), the known torque, N·m (zeros in MC).
    """
    q11, q22, R = validate_theta(theta)
    r = np.ascontiguousarray(angle_ref, dtype=float)
    a = np.ascontiguousarray(u_A, dtype=float)
    if r.ndim != 1 or a.ndim != 1 or r.shape[0] != a.shape[0] + 1:
        raise ValueError(f"angle_ref must have K + 1 entries and u_A K entries; got {r.shape} and {a.shape}")
    L, f, S = _policy_kernel(plant.A, plant.b, q11, q22, R, r, a)
    return Policy(L=L, f=f, S=S)


@njit(cache=True, fastmath=False, error_model="python")
def rollout(A, b, L, f, x0, a, noise):
    """``(x, u)``, shapes (K + 1, 2) and (K,), of ``u_k = -L_k x_k + f_k + noise_k`` with extra torque ``a``."""
    K = a.shape[0]
    x = np.empty((K + 1, 2))
    u = np.empty(K)
    x[0, 0] = x0[0]
    x[0, 1] = x0[1]
    for k in range(K):
        u[k] = -(L[k, 0] * x[k, 0] + L[k, 1] * x[k, 1]) + f[k] + noise[k]
        tot = u[k] + a[k]
        x[k + 1, 0] = A[0, 0] * x[k, 0] + A[0, 1] * x[k, 1] + b[0] * tot
        x[k + 1, 1] = A[1, 0] * x[k, 0] + A[1, 1] * x[k, 1] + b[1] * tot
    return x, u


@njit(cache=True, fastmath=False, error_model="python")
def _general_policy_kernel(A, b_c, b_a, Q, R, x_ref, a):
    n = A.shape[0]
    K = a.shape[0]
    L = np.empty((K, n))
    f = np.empty(K)
    Sv = np.empty(K)
    P = Q.copy()
    s = np.zeros(n)
    for i in range(n):
        for j in range(n):
            s[i] += Q[i, j] * x_ref[K, j]
    Pb = np.empty(n)
    Pa = np.empty(n)
    w = np.empty(n)
    M = np.empty((n, n))
    PM = np.empty((n, n))
    for k in range(K - 1, -1, -1):
        for i in range(n):
            Pb[i] = 0.0
            Pa[i] = 0.0
            for j in range(n):
                Pb[i] += P[i, j] * b_c[j]
                Pa[i] += P[i, j] * b_a[j]
        S = R
        for i in range(n):
            S += b_c[i] * Pb[i]
        fk = 0.0
        for i in range(n):
            w[i] = s[i] - Pa[i] * a[k]
            fk += b_c[i] * w[i]
        f[k] = fk / S
        Sv[k] = S
        for j in range(n):
            acc = 0.0
            for i in range(n):
                acc += Pb[i] * A[i, j]
            L[k, j] = acc / S
        for i in range(n):
            for j in range(n):
                M[i, j] = A[i, j] - b_c[i] * L[k, j]
        # s_k = Q x_ref_k + Mᵀ w;  P_k = Q + R L Lᵀ + Mᵀ P M (Joseph form)
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += Q[i, j] * x_ref[k, j] + M[j, i] * w[j]
            s[i] = acc
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for m in range(n):
                    acc += P[i, m] * M[m, j]
                PM[i, j] = acc
        for i in range(n):
            for j in range(i, n):
                acc = Q[i, j] + R * L[k, i] * L[k, j]
                for m in range(n):
                    acc += M[m, i] * PM[m, j]
                P[i, j] = acc
                P[j, i] = acc
    return L, f, Sv


def lq_tracking_policy(A, b_c, b_a, Q, R: float, x_ref, a) -> Policy:
    """The recursion of :func:`lq_policy` for an n-state plant whose command and known input enter apart::

        min_c  sum_{k=1..K} e_kᵀ Q e_k + sum_{k=0..K-1} R c_k²
        s.t.   z_{k+1} = A z_k + b_c c_k + b_a a_k,   e_k = z_k - x_ref_k

    For the human with a neuromuscular lag (:func:`scioc.models.plant.discretize_lagged`, n = 3). ``Q``
    (n, n) symmetric PSD; ``R`` > 0, 1/(N·m)²; ``x_ref`` (K + 1, n), row 0 unused; ``a`` (K,), N·m.
    Returns a :class:`Policy` with ``L`` of shape (K, n).
    """
    A = np.ascontiguousarray(A, dtype=float)
    n = A.shape[0] if A.ndim == 2 else -1
    b_c = np.ascontiguousarray(b_c, dtype=float)
    b_a = np.ascontiguousarray(b_a, dtype=float)
    Q = np.ascontiguousarray(Q, dtype=float)
    x_ref = np.ascontiguousarray(x_ref, dtype=float)
    a = np.ascontiguousarray(a, dtype=float)
    if A.shape != (n, n) or b_c.shape != (n,) or b_a.shape != (n,) or Q.shape != (n, n):
        raise ValueError(f"A must be (n, n), b_c and b_a (n,), Q (n, n); got {A.shape}, {b_c.shape}, {b_a.shape}, "
                         f"{Q.shape}")
    if a.ndim != 1 or x_ref.shape != (a.shape[0] + 1, n):
        raise ValueError(f"x_ref must have shape (K + 1, {n}) and a shape (K,); got {x_ref.shape} and {a.shape}")
    if not np.allclose(Q, Q.T) or np.linalg.eigvalsh(Q).min() < -1e-12 * max(1.0, np.abs(Q).max()):
        raise ValueError("Q must be symmetric positive semi-definite")
    if not (np.isfinite(R) and R > 0):
        raise ValueError(f"R must be > 0; got {R!r}")
    L, f, S = _general_policy_kernel(A, b_c, b_a, Q, float(R), x_ref, a)
    return Policy(L=L, f=f, S=S)
