"""The dense K×K reference of the max-ent likelihood: paper Eq. 8 with Eq. 11-16 literally.

With the lifted system ``x = Φ x0 + Γ (u_H + u_A)`` (Eq. 11-12), g from Eq. 15 and
H = 2 (ΓᵀQΓ + R I) (Eq. 16), ``log p(u) = -½ gᵀ H⁻¹ g + ½ log|H| - K/2 log 2π`` (Eq. 8), by a Cholesky
factorization of H: O(K³). Only the tests and the benchmark use it, as the reference for the linear-time
kernel of :mod:`scioc.models.maxent`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular

from scioc.models.cost import validate_theta
from scioc.models.maxent import HALF_LOG_2PI
from scioc.models.plant import DiscretePlant
from scioc.models.segment import Segment, check_segment, plan_inputs


def lifted_matrices(plant: DiscretePlant, K: int) -> tuple[np.ndarray, np.ndarray]:
    """``Phi`` (2K, 2) and ``Gamma`` (2K, K) of Eq. 11-12: ``x = Φ x0 + Γ (u_H + u_A)`` for x_1..x_K."""
    A, b = plant.A, plant.b
    Phi = np.empty((2 * K, 2))
    Gamma = np.zeros((2 * K, K))
    powers_b = np.empty((K, 2))  # A^j b
    Ak = np.eye(2)
    for j in range(K):
        powers_b[j] = Ak @ b
        Ak = A @ Ak
        Phi[2 * j : 2 * j + 2] = Ak
    for i in range(K):  # block row i is x_{i+1}
        for j in range(i + 1):
            Gamma[2 * i : 2 * i + 2, j] = powers_b[i - j]
    return Phi, Gamma


class DenseResult(NamedTuple):
    """Eq. 8 and its ingredients: ``g`` (Eq. 15), ``H`` (Eq. 16), ``u_opt = u - H⁻¹ g``."""

    loglik: float
    grad: np.ndarray
    g: np.ndarray
    H: np.ndarray
    u_opt: np.ndarray


def loglik_dense(theta, segment: Segment, plant: DiscretePlant, *, with_grad: bool = True) -> DenseResult:
    """Max-ent log-likelihood by Eq. 8 with Eq. 11-16 literally (Cholesky of the K×K Hessian).

    With a :class:`Feedback` it plans on the closed wheel and also propagates the states that way, so it
    equals :func:`scioc.models.maxent.loglik_grad` when the recorded u_A follows the law exactly.
    ``grad`` (3,) is NaN unless ``with_grad``.
    """
    q11, q22, R = validate_theta(theta)
    seg = check_segment(segment)
    if seg.feedback is not None:
        plant, known = plan_inputs(seg, plant)
        seg = Segment(seg.x0, seg.angle_ref, seg.u_H, known)
    if seg.preview > 0:
        return _loglik_dense_marginal(q11, q22, R, seg, plant)
    K = seg.K
    Phi, Gamma = lifted_matrices(plant, K)
    x = Phi @ seg.x0 + Gamma @ (seg.u_H + seg.u_A)
    xref = np.zeros(2 * K)
    xref[0::2] = seg.angle_ref[1:]
    e = x - xref
    qdiag = np.tile([q11, q22], K)
    g = 2.0 * Gamma.T @ (qdiag * e) + 2.0 * R * seg.u_H
    GtQG = Gamma.T @ (qdiag[:, None] * Gamma)
    H = 2.0 * GtQG + 2.0 * R * np.eye(K)
    c = cho_factor(H, lower=True)
    y = cho_solve(c, g)
    logdet = 2.0 * np.sum(np.log(np.diag(c[0])))
    ll = -0.5 * g @ y + 0.5 * logdet - K * HALF_LOG_2PI
    grad = np.full(3, np.nan)
    if with_grad:
        # d log p = -yᵀ dg + ½ yᵀ dH y + ½ tr(H⁻¹ dH), y = H⁻¹ g; dH/dq_ii = 2 Γᵀ E_ii Γ, dH/dR = 2 I,
        # so the traces are column norms of L⁻¹ Γᵀ and the Frobenius norm of L⁻¹ (H = L Lᵀ).
        Lc = np.tril(c[0])
        W = solve_triangular(Lc, Gamma.T, lower=True)
        col2 = np.sum(W * W, axis=0)  # diag(Γ H⁻¹ Γᵀ)
        Linv = solve_triangular(Lc, np.eye(K), lower=True)
        Gy = Gamma @ y
        for j in range(2):
            dg = 2.0 * Gamma[j::2].T @ e[j::2]
            grad[j] = -dg @ y + Gy[j::2] @ Gy[j::2] + np.sum(col2[j::2])
        grad[2] = -2.0 * seg.u_H @ y + y @ y + np.sum(Linv * Linv)
    return DenseResult(float(ll), grad, g, H, seg.u_H - y)


def _loglik_dense_marginal(q11, q22, R, seg: Segment, plant: DiscretePlant) -> DenseResult:
    """With preview: Eq. 8 over all K + M controls, marginalized to the K observed ones (value only)."""
    K, Kt = seg.K, seg.u_A.shape[0]
    Phi, Gamma = lifted_matrices(plant, Kt)
    xref = np.zeros(2 * Kt)
    xref[0::2] = seg.angle_ref[1:]
    qdiag = np.tile([q11, q22], Kt)
    g0 = 2.0 * Gamma.T @ (qdiag * (Phi @ seg.x0 + Gamma @ seg.u_A - xref))  # g at u_H = 0
    H = 2.0 * Gamma.T @ (qdiag[:, None] * Gamma) + 2.0 * R * np.eye(Kt)
    Sigma = np.linalg.inv(H)
    u_opt = -Sigma @ g0
    c = cho_factor(Sigma[:K, :K], lower=True)
    d = seg.u_H - u_opt[:K]
    ll = -0.5 * d @ cho_solve(c, d) - np.sum(np.log(np.diag(c[0]))) - K * HALF_LOG_2PI
    return DenseResult(float(ll), np.full(3, np.nan), g0 + H @ np.concatenate([seg.u_H, u_opt[K:]]), H, u_opt)


__all__ = ["DenseResult", "lifted_matrices", "loglik_dense"]
