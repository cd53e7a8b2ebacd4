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
from the end; from there on S, L, M, P b_a and their tangents are constants and only
the s-recursion (which carries the reference and the known input) runs, with its four
tangents, so that every observed step gets f_k and df_k.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from models.maxent import FREEZE_RTOL

#: Tangent directions carried through the recursion, in this order.
DIRECTIONS = ("q11", "q22", "a", "alpha")


@njit(cache=True, inline="always")
def _rel_change(new, old):
    num = 0.0
    den = 0.0
    for i in range(3):
        for j in range(3):
            num += abs(new[i, j] - old[i, j])
            den += abs(new[i, j])
    return num <= FREEZE_RTOL * den


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def plan_recursion(Ab, bc, ba, dAb, dbc, q11, q22, R, r, ua, K_obs, freeze, f, df, S_t, L_t, dS_t, dL_t, cst):
    """Run the recursion backward over the plan's K + M steps; return k_R.

    Parameters
    ----------
    Ab, bc, ba : ndarray, shapes (3, 3), (3,), (3,)
        The planning plant (closed by the assistant's feedback), command and known-input vectors.
    dAb, dbc : ndarray, shapes (4, 3, 3), (4, 3)
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
        Out: feedforward f_k and its tangents for the observed steps.
    S_t, L_t, dS_t, dL_t : ndarray, shapes (K,), (K, 3), (K, 4), (K, 4, 3)
        Out: S_k, L_k and their tangents, written for the observed steps k > k_R only.
    cst : ndarray, shape (20,)
        Out: the constants of steps k <= k_R: S, L (3), dS (4), dL (4 × 3).

    Returns
    -------
    int
        k_R: every observed step k <= k_R has the constant S, L of ``cst``
        (-1: none; K - 1: all).
    """
    K = ua.shape[0]
    P = np.zeros((3, 3))
    P[0, 0] = q11
    P[1, 1] = q22
    dP = np.zeros((4, 3, 3))
    dP[0, 0, 0] = 1.0
    dP[1, 1, 1] = 1.0
    s = np.zeros(3)
    s[0] = q11 * r[K]
    ds = np.zeros((4, 3))
    ds[0, 0] = r[K]
    Pb = np.empty(3)
    L = np.empty(3)
    M = np.empty((3, 3))
    PM = np.empty((3, 3))
    pba = np.empty(3)
    dPb = np.empty(3)
    dS = np.empty(4)
    dL = np.empty((4, 3))
    dM = np.empty((4, 3, 3))
    dpba = np.empty((4, 3))
    Dk = np.empty((3, 3))
    X = np.empty((3, 3))
    nP = np.empty((3, 3))
    ndP = np.empty((4, 3, 3))
    w = np.empty(3)
    dw = np.empty(3)
    ns = np.empty(3)
    S = 0.0
    k = K - 1
    k_R = -1
    stationary = False
    while k >= 0:
        if not stationary:
            # ---- step quantities from P_{k+1} and their tangents
            for i in range(3):
                Pb[i] = P[i, 0] * bc[0] + P[i, 1] * bc[1] + P[i, 2] * bc[2]
                pba[i] = P[i, 0] * ba[0] + P[i, 1] * ba[1] + P[i, 2] * ba[2]
            S = R + bc[0] * Pb[0] + bc[1] * Pb[1] + bc[2] * Pb[2]
            for j in range(3):
                L[j] = (Pb[0] * Ab[0, j] + Pb[1] * Ab[1, j] + Pb[2] * Ab[2, j]) / S
            for i in range(3):
                for j in range(3):
                    M[i, j] = Ab[i, j] - bc[i] * L[j]
            for p in range(4):
                t = 0.0
                for i in range(3):
                    dPb[i] = (dP[p, i, 0] * bc[0] + dP[p, i, 1] * bc[1] + dP[p, i, 2] * bc[2]
                              + P[i, 0] * dbc[p, 0] + P[i, 1] * dbc[p, 1] + P[i, 2] * dbc[p, 2])
                    dpba[p, i] = dP[p, i, 0] * ba[0] + dP[p, i, 1] * ba[1] + dP[p, i, 2] * ba[2]
                    t += dbc[p, i] * Pb[i] + bc[i] * dPb[i]
                dS[p] = t  # d(b_cᵀ P b_c) = 2 db_cᵀ P b_c + b_cᵀ dP b_c = db_cᵀ Pb + b_cᵀ dPb
                for j in range(3):
                    dL[p, j] = (dPb[0] * Ab[0, j] + dPb[1] * Ab[1, j] + dPb[2] * Ab[2, j]
                                + Pb[0] * dAb[p, 0, j] + Pb[1] * dAb[p, 1, j] + Pb[2] * dAb[p, 2, j]
                                - L[j] * dS[p]) / S
                for i in range(3):
                    for j in range(3):
                        dM[p, i, j] = dAb[p, i, j] - dbc[p, i] * L[j] - bc[i] * dL[p, j]
            # ---- P_k and its tangents (Joseph form; envelope theorem for the tangents)
            for i in range(3):
                for j in range(3):
                    PM[i, j] = P[i, 0] * M[0, j] + P[i, 1] * M[1, j] + P[i, 2] * M[2, j]
            for i in range(3):
                for j in range(3):
                    nP[i, j] = R * L[i] * L[j] + M[0, i] * PM[0, j] + M[1, i] * PM[1, j] + M[2, i] * PM[2, j]
            nP[0, 0] += q11
            nP[1, 1] += q22
            for p in range(4):
                for i in range(3):
                    for j in range(3):
                        Dk[i, j] = dAb[p, i, j] - dbc[p, i] * L[j]
                        X[i, j] = dP[p, i, 0] * M[0, j] + dP[p, i, 1] * M[1, j] + dP[p, i, 2] * M[2, j]
                for i in range(3):
                    for j in range(3):
                        ndP[p, i, j] = M[0, i] * X[0, j] + M[1, i] * X[1, j] + M[2, i] * X[2, j]
                if p >= 2:
                    for i in range(3):
                        for j in range(3):
                            X[i, j] = Dk[0, i] * PM[0, j] + Dk[1, i] * PM[1, j] + Dk[2, i] * PM[2, j]
                    for i in range(3):
                        for j in range(3):
                            ndP[p, i, j] += X[i, j] + X[j, i]
            ndP[0, 0, 0] += 1.0
            ndP[1, 1, 1] += 1.0
            if freeze:
                stationary = _rel_change(nP, P)
                for p in range(4):
                    stationary = stationary and _rel_change(ndP[p], dP[p])
            P[:, :] = nP
            dP[:, :, :] = ndP
            if k < K_obs:
                S_t[k] = S
                for j in range(3):
                    L_t[k, j] = L[j]
                for p in range(4):
                    dS_t[k, p] = dS[p]
                    for j in range(3):
                        dL_t[k, p, j] = dL[p, j]
            if stationary:
                k_R = min(k, K_obs - 1)
                cst[0] = S
                cst[1:4] = L
                cst[4:8] = dS
                for p in range(4):
                    cst[8 + 3 * p:11 + 3 * p] = dL[p]
        # ---- the data step: f_k and s_k with tangents
        ak = ua[k]
        for i in range(3):
            w[i] = s[i] - pba[i] * ak
        fk = (bc[0] * w[0] + bc[1] * w[1] + bc[2] * w[2]) / S
        for p in range(4):
            for i in range(3):
                dw[i] = ds[p, i] - dpba[p, i] * ak
            if k < K_obs:
                df[k, p] = (dbc[p, 0] * w[0] + dbc[p, 1] * w[1] + dbc[p, 2] * w[2]
                            + bc[0] * dw[0] + bc[1] * dw[1] + bc[2] * dw[2] - fk * dS[p]) / S
            for j in range(3):
                ds[p, j] = (dM[p, 0, j] * w[0] + dM[p, 1, j] * w[1] + dM[p, 2, j] * w[2]
                            + M[0, j] * dw[0] + M[1, j] * dw[1] + M[2, j] * dw[2])
            if p == 0:
                ds[0, 0] += r[k]
        if k < K_obs:
            f[k] = fk
        for j in range(3):
            ns[j] = M[0, j] * w[0] + M[1, j] * w[1] + M[2, j] * w[2]
        ns[0] += q11 * r[k]
        s[:] = ns
        k -= 1
    return k_R


__all__ = ["DIRECTIONS", "plan_recursion"]
