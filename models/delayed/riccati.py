"""The ``delayed`` human's plan: the 3-state LQ recursion with tangents in q11, q22, a and α (numba).

The same recursion as :func:`models.lq.lq_tracking_policy` (P_{K+M} = Q, s_{K+M} = Q x_ref,
``S_k = R + b_cᵀ P b_c``, ``L_k = b_cᵀ P A / S_k``, ``w = s_{k+1} - P b_a a_k``,
``f_k = b_cᵀ w / S_k``, ``M_k = A - b_c L_k``, ``s_k = Q x_ref_k + M_kᵀ w``,
``P_k = Q + R L_kᵀ L_k + M_kᵀ P M_k``) on the plant of
:func:`models.delayed.lag.lagged_planning_plant`, with forward-mode tangents in four
directions: q11, q22 (through Q) and the lag's a and α (through A and b_c). The
R-direction follows from homogeneity (L and f do not change when θ is scaled, S scales
with it), so it is not carried.

By the envelope theorem (L minimizes the Joseph-form bracket for every state) the
tangent of P is ``dP_k = dQ + M_kᵀ dP M_k + D_kᵀ P M_k + M_kᵀ P D_k`` with
``D_k = dA - db_c L_kᵀ`` at fixed L.

As in :mod:`models.maxent`, P and its tangents become stationary some hundred steps
from the end (step k_z); from there on S, L, M, P b_a and their tangents are constants
and only the s-recursion (which carries the reference and the known input) runs,
without tangents: the derivative of ``sum_k ω_k f_k`` over those steps, all the
likelihood needs of them, comes from one forward adjoint sweep
(:func:`plan_adjoint`) once ω is known.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from models.maxent import FREEZE_RTOL

#: Tangent directions carried through the recursion, in this order.
DIRECTIONS = ("q11", "q22", "a", "alpha")


def _layout(*sizes):
    """Offsets of consecutive blocks of the given sizes in one flat buffer, and its size."""
    offsets = np.cumsum((0,) + sizes)
    return tuple(int(o) for o in offsets)


# Phase 1's flat buffer: A, b_c, b_a, dA, db_c, P, dP, Pb, L, M, PM, dPb, dS, dL, D, dM, X, Y,
# P b_a, d(P b_a), s, ds, w, dw, and four 4-vectors; tangent blocks have the directions last.
(_AB, _BC, _BA, _DAB, _DBC, _P, _DP, _PB, _L, _M, _PM, _DPB, _DS, _DL, _DK, _DM, _X, _Y, _PBA, _DPBA, _S, _DSV, _W,
 _DW, _NUM, _DEN, _T4, _SIZE) = _layout(9, 3, 3, 36, 12, 9, 36, 3, 3, 9, 9, 12, 4, 12, 36, 36, 36, 36, 3, 12, 3, 12,
                                        3, 12, 4, 4, 4)


@njit(cache=True, error_model="numpy")
def plan_recursion(Ab, bc, ba, dAb, dbc, q11, q22, R, r, ua, K_obs, freeze, f, df, S_t, L_t, dS_t, dL_t, cst, adj, W):
    """Run the recursion backward over the plan's K + M steps; return (k_R, k_z).

    Tangent arrays carry the four :data:`DIRECTIONS` on their last axis (contiguous, so
    that each tangent operation is one short vector operation).

    Parameters
    ----------
    Ab, bc, ba : ndarray, shapes (3, 3), (3,), (3,)
        The planning plant (closed by the assistant's feedback), command and known-input
        vectors; ``ba[2]`` must be 0.
    dAb, dbc : ndarray, shapes (3, 3, 4), (3, 4)
        Their derivatives in the :data:`DIRECTIONS` (zero for q11 and q22).
    q11, q22, R : float
    r : ndarray, shape (K + M + 1,)
        Angle reference, rad.
    ua : ndarray, shape (K + M,)
        Known input, N·m.
    K_obs : int
        Observed steps K.
    freeze : bool
        Hold the step quantities once stationary (see the module docstring).
    f, df : ndarray, shapes (K,), (K, 4)
        Out: feedforward f_k for the observed steps, and its tangents for the observed
        steps k >= k_z (the others come from :func:`plan_adjoint`).
    S_t, L_t, dS_t, dL_t : ndarray, shapes (K,), (K, 3), (K, 4), (K, 3, 4)
        Out: S_k, L_k and their tangents, written for the observed steps k > k_R only.
    cst : ndarray, shape (20,)
        Out: the constants of steps k <= k_R: S, L (3), dS (4), dL (3 × 4).
    adj : tuple of ndarray
        Out, for :func:`plan_adjoint`: M (3, 3), P b_a (3,), dM (3, 3, 4), d(P b_a) (3, 4)
        and the tangents of s_{k_z} (3, 4).
    W : ndarray, shape (K + M, 3)
        Out: ``w_k = s_{k+1} - P b_a a_k`` of the steps k < k_z.

    Returns
    -------
    (int, int)
        k_R: every observed step k <= k_R has the constant S, L of ``cst`` (-1: none;
        K - 1: all); k_z: the steps k < k_z have constant step quantities (0: none).
    """
    M, pba, dM, dpba, ds = adj
    K = ua.shape[0]
    # Everything phase 1 touches lives in one flat buffer at fixed offsets (see _layout):
    # LLVM can then tell every load and store apart and keep values in registers, which
    # separate small arrays (any of which might alias another) do not allow.
    T = np.zeros(_SIZE)
    for i in range(3):
        T[_BC + i] = bc[i]
        T[_BA + i] = ba[i]
        for j in range(3):
            T[_AB + 3 * i + j] = Ab[i, j]
            for p in range(4):
                T[_DAB + 12 * i + 4 * j + p] = dAb[i, j, p]
        for p in range(4):
            T[_DBC + 4 * i + p] = dbc[i, p]
    T[_P + 0] = q11
    T[_P + 4] = q22
    T[_DP + 0] = 1.0  # dP[0, 0, q11]
    T[_DP + 16 + 1] = 1.0  # dP[1, 1, q22]
    T[_S] = q11 * r[K]
    T[_DSV] = r[K]  # ds[0, q11]
    S = 0.0
    k_R = -1
    k = K - 1
    stationary = False
    # ---- phase 1: Riccati with tangents, data step with tangents
    while k >= 0 and not stationary:
        for i in range(3):
            T[_PB + i] = T[_P + 3 * i] * T[_BC] + T[_P + 3 * i + 1] * T[_BC + 1] + T[_P + 3 * i + 2] * T[_BC + 2]
            T[_PBA + i] = T[_P + 3 * i] * T[_BA] + T[_P + 3 * i + 1] * T[_BA + 1]
        S = R + T[_BC] * T[_PB] + T[_BC + 1] * T[_PB + 1] + T[_BC + 2] * T[_PB + 2]
        iS = 1.0 / S
        for j in range(3):
            T[_L + j] = (T[_PB] * T[_AB + j] + T[_PB + 1] * T[_AB + 3 + j] + T[_PB + 2] * T[_AB + 6 + j]) * iS
        for i in range(3):
            for j in range(3):
                T[_M + 3 * i + j] = T[_AB + 3 * i + j] - T[_BC + i] * T[_L + j]
        for p in range(4):
            T[_DS + p] = 0.0
        for i in range(3):
            for p in range(4):
                v = (T[_DP + 12 * i + p] * T[_BC] + T[_DP + 12 * i + 4 + p] * T[_BC + 1]
                     + T[_DP + 12 * i + 8 + p] * T[_BC + 2] + T[_P + 3 * i] * T[_DBC + p]
                     + T[_P + 3 * i + 1] * T[_DBC + 4 + p] + T[_P + 3 * i + 2] * T[_DBC + 8 + p])
                T[_DPB + 4 * i + p] = v
                T[_DPBA + 4 * i + p] = T[_DP + 12 * i + p] * T[_BA] + T[_DP + 12 * i + 4 + p] * T[_BA + 1]
                T[_DS + p] += T[_DBC + 4 * i + p] * T[_PB + i] + T[_BC + i] * v  # db_cᵀ Pb + b_cᵀ dPb
        for j in range(3):
            for p in range(4):
                T[_DL + 4 * j + p] = (T[_DPB + p] * T[_AB + j] + T[_DPB + 4 + p] * T[_AB + 3 + j]
                                      + T[_DPB + 8 + p] * T[_AB + 6 + j] + T[_PB] * T[_DAB + 4 * j + p]
                                      + T[_PB + 1] * T[_DAB + 12 + 4 * j + p] + T[_PB + 2] * T[_DAB + 24 + 4 * j + p]
                                      - T[_L + j] * T[_DS + p]) * iS
        for i in range(3):
            for j in range(3):
                for p in range(4):
                    v = T[_DAB + 12 * i + 4 * j + p] - T[_DBC + 4 * i + p] * T[_L + j]
                    T[_DK + 12 * i + 4 * j + p] = v
                    T[_DM + 12 * i + 4 * j + p] = v - T[_BC + i] * T[_DL + 4 * j + p]
        # P_k and its tangents (Joseph form, symmetric; envelope theorem for the tangents:
        # dP_k = dQ + Mᵀ dP M + Dᵀ P M + Mᵀ P D with D = dA - db_c Lᵀ)
        for i in range(3):
            for j in range(3):
                T[_PM + 3 * i + j] = (T[_P + 3 * i] * T[_M + j] + T[_P + 3 * i + 1] * T[_M + 3 + j]
                                      + T[_P + 3 * i + 2] * T[_M + 6 + j])
        for i in range(3):
            for j in range(3):
                for p in range(4):
                    T[_X + 12 * i + 4 * j + p] = (T[_DP + 12 * i + p] * T[_M + j] + T[_DP + 12 * i + 4 + p] * T[_M + 3 + j]
                                                  + T[_DP + 12 * i + 8 + p] * T[_M + 6 + j])
                    T[_Y + 12 * i + 4 * j + p] = (T[_DK + 4 * i + p] * T[_PM + j] + T[_DK + 12 + 4 * i + p] * T[_PM + 3 + j]
                                                  + T[_DK + 24 + 4 * i + p] * T[_PM + 6 + j])
        pn = 0.0
        pd = 0.0
        for p in range(4):
            T[_NUM + p] = 0.0
            T[_DEN + p] = 0.0
        for i in range(3):
            for j in range(i, 3):
                v = (R * T[_L + i] * T[_L + j] + T[_M + i] * T[_PM + j] + T[_M + 3 + i] * T[_PM + 3 + j]
                     + T[_M + 6 + i] * T[_PM + 6 + j])
                if i == j and i < 2:
                    v += q11 if i == 0 else q22
                pn += abs(v - T[_P + 3 * i + j])
                pd += abs(v)
                T[_P + 3 * i + j] = v
                T[_P + 3 * j + i] = v
                for p in range(4):
                    v = (T[_M + i] * T[_X + 4 * j + p] + T[_M + 3 + i] * T[_X + 12 + 4 * j + p]
                         + T[_M + 6 + i] * T[_X + 24 + 4 * j + p] + T[_Y + 12 * i + 4 * j + p] + T[_Y + 12 * j + 4 * i + p])
                    if p == i and p == j and p < 2:
                        v += 1.0  # dQ
                    T[_NUM + p] += abs(v - T[_DP + 12 * i + 4 * j + p])
                    T[_DEN + p] += abs(v)
                    T[_DP + 12 * i + 4 * j + p] = v
                    T[_DP + 12 * j + 4 * i + p] = v
        stationary = freeze and pn <= FREEZE_RTOL * pd
        for p in range(4):
            stationary = stationary and T[_NUM + p] <= FREEZE_RTOL * T[_DEN + p]
        # data step k with tangents
        ak = ua[k]
        for i in range(3):
            T[_W + i] = T[_S + i] - T[_PBA + i] * ak
        fk = (T[_BC] * T[_W] + T[_BC + 1] * T[_W + 1] + T[_BC + 2] * T[_W + 2]) * iS
        for i in range(3):
            for p in range(4):
                T[_DW + 4 * i + p] = T[_DSV + 4 * i + p] - T[_DPBA + 4 * i + p] * ak
        for p in range(4):
            T[_T4 + p] = (T[_DBC + p] * T[_W] + T[_DBC + 4 + p] * T[_W + 1] + T[_DBC + 8 + p] * T[_W + 2]
                          + T[_BC] * T[_DW + p] + T[_BC + 1] * T[_DW + 4 + p] + T[_BC + 2] * T[_DW + 8 + p]
                          - fk * T[_DS + p]) * iS
        for j in range(3):
            for p in range(4):
                T[_DSV + 4 * j + p] = (T[_DM + 4 * j + p] * T[_W] + T[_DM + 12 + 4 * j + p] * T[_W + 1]
                                       + T[_DM + 24 + 4 * j + p] * T[_W + 2] + T[_M + j] * T[_DW + p]
                                       + T[_M + 3 + j] * T[_DW + 4 + p] + T[_M + 6 + j] * T[_DW + 8 + p])
        T[_DSV] += r[k]
        for j in range(3):
            T[_S + j] = T[_M + j] * T[_W] + T[_M + 3 + j] * T[_W + 1] + T[_M + 6 + j] * T[_W + 2]
        T[_S] += q11 * r[k]
        if k < K_obs:  # outputs last: their stores might alias the buffer as far as LLVM knows
            f[k] = fk
            S_t[k] = S
            for p in range(4):
                df[k, p] = T[_T4 + p]
                dS_t[k, p] = T[_DS + p]
            for j in range(3):
                L_t[k, j] = T[_L + j]
                for p in range(4):
                    dL_t[k, j, p] = T[_DL + 4 * j + p]
        k -= 1
    for i in range(3):
        pba[i] = T[_PBA + i]
        for j in range(3):
            M[i, j] = T[_M + 3 * i + j]
            for p in range(4):
                dM[i, j, p] = T[_DM + 12 * i + 4 * j + p]
        for p in range(4):
            dpba[i, p] = T[_DPBA + 4 * i + p]
            ds[i, p] = T[_DSV + 4 * i + p]
    s = np.empty(3)
    for i in range(3):
        s[i] = T[_S + i]
    L = T[_L:_L + 3]
    dS = T[_DS:_DS + 4]
    dL = T[_DL:_DL + 12].reshape((3, 4))
    k_z = k + 1 if stationary else 0
    if stationary:
        k_R = min(k, K_obs - 1)
        cst[0] = S
        for j in range(3):
            cst[1 + j] = L[j]
            for p in range(4):
                cst[8 + 4 * j + p] = dL[j, p]
        for p in range(4):
            cst[4 + p] = dS[p]
    # ---- phase 2: constant step quantities; the primal s-recursion only (tangents by plan_adjoint)
    iS = 1.0 / S
    b0, b1, b2 = bc[0] * iS, bc[1] * iS, bc[2] * iS
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = (M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0],
                                                   M[2, 1], M[2, 2])
    p0, p1, p2 = pba[0], pba[1], pba[2]
    s0, s1, s2 = s[0], s[1], s[2]
    while k >= 0:
        ak = ua[k]
        w0 = s0 - p0 * ak
        w1 = s1 - p1 * ak
        w2 = s2 - p2 * ak
        W[k, 0] = w0
        W[k, 1] = w1
        W[k, 2] = w2
        if k < K_obs:
            f[k] = b0 * w0 + b1 * w1 + b2 * w2
        s0 = m00 * w0 + m10 * w1 + m20 * w2 + q11 * r[k]
        s1 = m01 * w0 + m11 * w1 + m21 * w2
        s2 = m02 * w0 + m12 * w1 + m22 * w2
        k -= 1
    return k_R, k_z


@njit(cache=True, error_model="numpy")
def plan_adjoint(bc, dbc, S, dS, r, ua, om, K_obs, k_z, adj, W, G):
    """Add ``sum_{k < k_z, k < K} om_k df_k / d(direction)`` to G (4,), by one forward adjoint sweep.

    For the steps k < k_z the step quantities are constants, ``f_k = βᵀ w_k`` with
    β = b_c / S, ``w_k = s_{k+1} - P b_a a_k``, ``s_k = Q x_ref_k + Mᵀ w_k``. With
    λ_k = ∂F/∂s_k (λ_0 = 0) the adjoint runs forward: ``o_k = ρ_k β + M λ_k``,
    ``λ_{k+1} = o_k``, and F's derivatives with respect to the constants are sums over k;
    λ_{k_z} meets the tangent of s_{k_z} carried by :func:`plan_recursion`. ``om`` is
    ρ over the observed steps (ρ_k = 0 in the preview).
    """
    M, pba, dM, dpba, ds = adj
    iS = 1.0 / S
    b0, b1, b2 = bc[0] * iS, bc[1] * iS, bc[2] * iS
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = (M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0],
                                                   M[2, 1], M[2, 2])
    l0 = l1 = l2 = 0.0
    gb0 = gb1 = gb2 = 0.0  # ∂F/∂β
    g00 = g01 = g02 = g10 = g11 = g12 = g20 = g21 = g22 = 0.0  # ∂F/∂M_ij = sum w_i λ_j
    gp0 = gp1 = gp2 = 0.0  # ∂F/∂(P b_a)
    gq = 0.0  # ∂F/∂q11 through Q x_ref
    for k in range(k_z):
        rho = om[k] if k < K_obs else 0.0
        w0 = W[k, 0]
        w1 = W[k, 1]
        w2 = W[k, 2]
        gb0 += rho * w0
        gb1 += rho * w1
        gb2 += rho * w2
        g00 += w0 * l0
        g01 += w0 * l1
        g02 += w0 * l2
        g10 += w1 * l0
        g11 += w1 * l1
        g12 += w1 * l2
        g20 += w2 * l0
        g21 += w2 * l1
        g22 += w2 * l2
        gq += l0 * r[k]
        o0 = rho * b0 + m00 * l0 + m01 * l1 + m02 * l2
        o1 = rho * b1 + m10 * l0 + m11 * l1 + m12 * l2
        o2 = rho * b2 + m20 * l0 + m21 * l1 + m22 * l2
        ak = ua[k]
        gp0 -= ak * o0
        gp1 -= ak * o1
        gp2 -= ak * o2
        l0, l1, l2 = o0, o1, o2
    for p in range(4):
        # β = b_c / S: dβ = (db_c - β dS) / S
        G[p] += (gb0 * (dbc[0, p] - b0 * dS[p]) + gb1 * (dbc[1, p] - b1 * dS[p])
                 + gb2 * (dbc[2, p] - b2 * dS[p])) * iS
        G[p] += (g00 * dM[0, 0, p] + g01 * dM[0, 1, p] + g02 * dM[0, 2, p] + g10 * dM[1, 0, p]
                 + g11 * dM[1, 1, p] + g12 * dM[1, 2, p] + g20 * dM[2, 0, p] + g21 * dM[2, 1, p]
                 + g22 * dM[2, 2, p])
        G[p] += gp0 * dpba[0, p] + gp1 * dpba[1, p] + gp2 * dpba[2, p]
        G[p] += l0 * ds[0, p] + l1 * ds[1, p] + l2 * ds[2, p]
    G[0] += gq


__all__ = ["DIRECTIONS", "plan_adjoint", "plan_recursion"]
