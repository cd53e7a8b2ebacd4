"""The ``delayed`` human's plan: the 3-state LQ recursion, and its reverse-mode derivative in q11, q22, a and α (numba).

The same recursion as :func:`models.lq.lq_tracking_policy` (P_{K+M} = Q, s_{K+M} = Q x_ref,
``S_k = R + b_cᵀ P b_c``, ``L_k = b_cᵀ P A / S_k``, ``w = s_{k+1} - P b_a a_k``,
``f_k = b_cᵀ w / S_k``, ``M_k = A - b_c L_k``, ``s_k = Q x_ref_k + M_kᵀ w``,
``P_k = Q + R L_kᵀ L_k + M_kᵀ P M_k``, P = P_{k+1}) on the plant of
:func:`models.delayed.lag.lagged_planning_plant`. The likelihood needs the derivative of a
scalar F (its log-density) that depends on the plan through f_k, S_k and L_k; it gets it in
reverse mode, once F's adjoints of those are known (:mod:`models.delayed.kernel`):

1. :func:`plan_recursion` runs the recursion backward and records each step's P, P b_c,
   S, L, w and f (the tape) until P is stationary (step k_z, some hundred steps from the
   end); from there on S, L, M and P b_a are constants and only the s-recursion runs (it
   carries the reference and the known input), recording its w_k.
2. :func:`plan_adjoint` sweeps the stationary steps forward with the adjoint of s and
   returns F's adjoints of the constants and of s_{k_z}.
3. :func:`plan_reverse` sweeps the recorded steps forward, from k_z to the end, with the
   adjoints of P and s, and contracts the adjoints of A and b_c it collects with their
   derivatives in the :data:`DIRECTIONS`. The R-direction follows from homogeneity (L and f
   do not change when θ is scaled, S scales with it), so it is not needed.

Reverse through P_k. By the envelope theorem (L minimizes the Joseph-form bracket for every
state) the P-update's derivative in L is zero at the optimal L, so P_k's adjoint P̄ flows to
P_{k+1} as ``M P̄ Mᵀ``, to M (at fixed L, so on to A and b_c but not to L) as ``P M (P̄ + P̄ᵀ)``
and to Q as itself. Every other use of L (in M of the s-recursion, and F's own) goes
through ``L = Aᵀ P b_c / S``. Per step this costs about a fifth of carrying forward tangents
in four directions, which the plan did before (measured: README "Speed").

Holding the stationary part is exact to rounding: P stops changing at the last bit
(:data:`models.maxent.FREEZE_RTOL`) and the derivative is that of the held computation; its
tangents, which converge at the same geometric rate, differ from their limits by about the
number of recorded steps times the last bit, about 1e-13 relative (``freeze=False`` records
every step; tested equal).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from models.maxent import FREEZE_RTOL

#: Directions of the plan's derivative, in this order.
DIRECTIONS = ("q11", "q22", "a", "alpha")
#: Columns of the tape, per recorded step: P_{k+1} (upper triangle, 6), P b_c (3), S, L (3), w (3), f.
TAPE = 17
#: Entries of the stationary constants' adjoints (:func:`plan_adjoint`): ∂F/∂β (β = b_c / S, 3),
#: ∂F/∂M (9, row-major), ∂F/∂(P b_a) (3), ∂F/∂q11 through Q x_ref, ∂F/∂s_{k_z} (3).
SEED = 19


@njit(cache=True, error_model="numpy")
def plan_recursion(Ab, bc, ba, q11, q22, R, r, ua, K_obs, freeze, f, S_t, L_t, cst, frozen, W, tape):
    """Run the recursion backward over the plan's K + M steps; return (k_R, k_z).

    Parameters
    ----------
    Ab, bc, ba : ndarray, shapes (3, 3), (3,), (3,)
        The planning plant (closed by the assistant's feedback), command and known-input
        vectors; ``ba[2]`` must be 0.
    q11, q22, R : float
    r : ndarray, shape (K + M + 1,)
        Angle reference, rad.
    ua : ndarray, shape (K + M,)
        Known input, N·m.
    K_obs : int
        Observed steps K.
    freeze : bool
        Hold the step quantities once P is stationary (module docstring).
    f, S_t, L_t : ndarray, shapes (K,), (K,), (K, 3)
        Out: f_k for the observed steps; S_k, L_k for the observed steps k > k_R.
    cst : ndarray, shape (4,)
        Out: S and L of the stationary steps (those of step k_z).
    frozen : tuple of ndarray
        Out: M (3, 3) and P b_a (3,) of the stationary steps.
    W : ndarray, shape (K + M, 3)
        Out: ``w_k = s_{k+1} - P b_a a_k`` of the steps k < k_z.
    tape : ndarray, shape (K + M, TAPE)
        Out: the recorded steps k >= k_z (:data:`TAPE`).

    Returns
    -------
    (int, int)
        k_R: every observed step k <= k_R has the constant S, L of ``cst`` (-1: none);
        k_z: the steps k < k_z have constant step quantities (0: none).
    """
    M, pba = frozen
    K = ua.shape[0]
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = Ab[i, j]
    b0, b1, b2 = bc[0], bc[1], bc[2]
    a0, a1 = ba[0], ba[1]
    # P = P_{k+1} (symmetric), s = s_{k+1}
    p00, p01, p02, p11, p12, p22 = q11, 0.0, 0.0, q22, 0.0, 0.0
    s0, s1, s2 = q11 * r[K], 0.0, 0.0
    S = 0.0
    L0 = L1 = L2 = 0.0
    PM = np.empty((3, 3))
    k = K - 1
    stationary = False
    while k >= 0 and not stationary:
        pb0 = p00 * b0 + p01 * b1 + p02 * b2
        pb1 = p01 * b0 + p11 * b1 + p12 * b2
        pb2 = p02 * b0 + p12 * b1 + p22 * b2
        S = R + b0 * pb0 + b1 * pb1 + b2 * pb2
        iS = 1.0 / S
        L0 = (pb0 * A[0, 0] + pb1 * A[1, 0] + pb2 * A[2, 0]) * iS
        L1 = (pb0 * A[0, 1] + pb1 * A[1, 1] + pb2 * A[2, 1]) * iS
        L2 = (pb0 * A[0, 2] + pb1 * A[1, 2] + pb2 * A[2, 2]) * iS
        for j in range(3):
            Lj = L0 if j == 0 else (L1 if j == 1 else L2)
            M[0, j] = A[0, j] - b0 * Lj
            M[1, j] = A[1, j] - b1 * Lj
            M[2, j] = A[2, j] - b2 * Lj
        pba[0] = p00 * a0 + p01 * a1
        pba[1] = p01 * a0 + p11 * a1
        pba[2] = p02 * a0 + p12 * a1
        ak = ua[k]
        w0 = s0 - pba[0] * ak
        w1 = s1 - pba[1] * ak
        w2 = s2 - pba[2] * ak
        fk = (b0 * w0 + b1 * w1 + b2 * w2) * iS
        tape[k, 0] = p00
        tape[k, 1] = p01
        tape[k, 2] = p02
        tape[k, 3] = p11
        tape[k, 4] = p12
        tape[k, 5] = p22
        tape[k, 6] = pb0
        tape[k, 7] = pb1
        tape[k, 8] = pb2
        tape[k, 9] = S
        tape[k, 10] = L0
        tape[k, 11] = L1
        tape[k, 12] = L2
        tape[k, 13] = w0
        tape[k, 14] = w1
        tape[k, 15] = w2
        tape[k, 16] = fk
        s0 = M[0, 0] * w0 + M[1, 0] * w1 + M[2, 0] * w2 + q11 * r[k]
        s1 = M[0, 1] * w0 + M[1, 1] * w1 + M[2, 1] * w2
        s2 = M[0, 2] * w0 + M[1, 2] * w1 + M[2, 2] * w2
        # P_k = Q + R L Lᵀ + Mᵀ P M (Joseph form, symmetric)
        for j in range(3):
            PM[0, j] = p00 * M[0, j] + p01 * M[1, j] + p02 * M[2, j]
            PM[1, j] = p01 * M[0, j] + p11 * M[1, j] + p12 * M[2, j]
            PM[2, j] = p02 * M[0, j] + p12 * M[1, j] + p22 * M[2, j]
        n00 = q11 + R * L0 * L0 + M[0, 0] * PM[0, 0] + M[1, 0] * PM[1, 0] + M[2, 0] * PM[2, 0]
        n01 = R * L0 * L1 + M[0, 0] * PM[0, 1] + M[1, 0] * PM[1, 1] + M[2, 0] * PM[2, 1]
        n02 = R * L0 * L2 + M[0, 0] * PM[0, 2] + M[1, 0] * PM[1, 2] + M[2, 0] * PM[2, 2]
        n11 = q22 + R * L1 * L1 + M[0, 1] * PM[0, 1] + M[1, 1] * PM[1, 1] + M[2, 1] * PM[2, 1]
        n12 = R * L1 * L2 + M[0, 1] * PM[0, 2] + M[1, 1] * PM[1, 2] + M[2, 1] * PM[2, 2]
        n22 = R * L2 * L2 + M[0, 2] * PM[0, 2] + M[1, 2] * PM[1, 2] + M[2, 2] * PM[2, 2]
        if freeze:
            num = (abs(n00 - p00) + abs(n01 - p01) + abs(n02 - p02) + abs(n11 - p11) + abs(n12 - p12)
                   + abs(n22 - p22))
            den = abs(n00) + abs(n01) + abs(n02) + abs(n11) + abs(n12) + abs(n22)
            stationary = num <= FREEZE_RTOL * den
        p00, p01, p02, p11, p12, p22 = n00, n01, n02, n11, n12, n22
        if k < K_obs:
            f[k] = fk
            S_t[k] = S
            L_t[k, 0] = L0
            L_t[k, 1] = L1
            L_t[k, 2] = L2
        k -= 1
    k_z = k + 1 if stationary else 0
    k_R = min(k, K_obs - 1) if stationary else -1
    cst[0] = S
    cst[1] = L0
    cst[2] = L1
    cst[3] = L2
    # ---- constant step quantities: the s-recursion only
    iS = 1.0 / S
    c0, c1, c2 = b0 * iS, b1 * iS, b2 * iS
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = (M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0],
                                                   M[2, 1], M[2, 2])
    e0, e1, e2 = pba[0], pba[1], pba[2]
    while k >= 0:
        ak = ua[k]
        w0 = s0 - e0 * ak
        w1 = s1 - e1 * ak
        w2 = s2 - e2 * ak
        W[k, 0] = w0
        W[k, 1] = w1
        W[k, 2] = w2
        if k < K_obs:
            f[k] = c0 * w0 + c1 * w1 + c2 * w2
        s0 = m00 * w0 + m10 * w1 + m20 * w2 + q11 * r[k]
        s1 = m01 * w0 + m11 * w1 + m21 * w2
        s2 = m02 * w0 + m12 * w1 + m22 * w2
        k -= 1
    return k_R, k_z


@njit(cache=True, error_model="numpy")
def plan_adjoint(bc, S, r, ua, om, K_obs, k_z, frozen, W, seed):
    """F's adjoints of the stationary constants, from ``F = sum_{k < k_z, k < K} om_k f_k``, into ``seed`` (:data:`SEED`).

    For the steps k < k_z the step quantities are constants, ``f_k = βᵀ w_k`` with
    β = b_c / S, ``w_k = s_{k+1} - P b_a a_k``, ``s_k = Q x_ref_k + Mᵀ w_k``. With
    λ_k = ∂F/∂s_k (λ_0 = 0) the adjoint runs forward: ``o_k = ρ_k β + M λ_k``,
    ``λ_{k+1} = o_k``; F's derivatives with respect to β, M, P b_a and q11 (through Q x_ref)
    are sums over k, and λ_{k_z} is its derivative with respect to s_{k_z}. ``om`` is ρ over
    the observed steps (ρ_k = 0 in the preview).
    """
    M = frozen[0]
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
    seed[0], seed[1], seed[2] = gb0, gb1, gb2
    seed[3], seed[4], seed[5], seed[6], seed[7], seed[8], seed[9], seed[10], seed[11] = (g00, g01, g02, g10, g11, g12,
                                                                                         g20, g21, g22)
    seed[12], seed[13], seed[14] = gp0, gp1, gp2
    seed[15] = gq
    seed[16], seed[17], seed[18] = l0, l1, l2


@njit(cache=True, error_model="numpy")
def plan_reverse(Ab, bc, ba, dAb, dbc, r, ua, K_obs, k_z, tape, fbar, Sbar, Lbar, Sc_bar, Lc_bar, seed, G):
    """Add F's derivative in the :data:`DIRECTIONS` through the recorded steps (module docstring, step 3) to G (4,).

    ``fbar``, ``Sbar``, ``Lbar`` (K,), (K,), (K, 3): F's adjoints of f_k, S_k and L_k, read for the observed
    steps k >= k_z. If k_z > 0, ``Sc_bar`` and ``Lc_bar`` (3,) are F's adjoints of the stationary S and L
    (``cst`` of :func:`plan_recursion`, through the stationary observed rows) and ``seed`` those of
    :func:`plan_adjoint`; they belong to step k_z, whose quantities the stationary steps hold.
    ``dAb``, ``dbc``: the derivatives of Ab and bc in the directions (3, 3, 4), (3, 4).
    """
    N = ua.shape[0]
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = Ab[i, j]
    b = np.empty(3)
    for i in range(3):
        b[i] = bc[i]
    Abar = np.zeros((3, 3))
    bbar = np.zeros(3)
    Pbar = np.zeros((3, 3))  # adjoint of P_k (none for P_{k_z}: the held steps use P_{k_z + 1})
    Pn = np.zeros((3, 3))  # adjoint of P_{k+1}, being collected
    P = np.empty((3, 3))
    M = np.empty((3, 3))
    Mbar = np.empty((3, 3))
    MP = np.empty((3, 3))
    X = np.empty((3, 3))
    L = np.empty(3)
    Lb = np.empty(3)
    pb = np.empty(3)
    pbb = np.empty(3)
    w = np.empty(3)
    wb = np.empty(3)
    sb = np.zeros(3)
    qb0 = 0.0
    qb1 = 0.0
    held = k_z > 0
    if held:
        for i in range(3):
            sb[i] = seed[16 + i]
        qb0 = seed[15]
    for k in range(k_z, N):
        P[0, 0] = tape[k, 0]
        P[0, 1] = P[1, 0] = tape[k, 1]
        P[0, 2] = P[2, 0] = tape[k, 2]
        P[1, 1] = tape[k, 3]
        P[1, 2] = P[2, 1] = tape[k, 4]
        P[2, 2] = tape[k, 5]
        S = tape[k, 9]
        iS = 1.0 / S
        fk = tape[k, 16]
        for i in range(3):
            pb[i] = tape[k, 6 + i]
            L[i] = tape[k, 10 + i]
            w[i] = tape[k, 13 + i]
        for i in range(3):
            for j in range(3):
                M[i, j] = A[i, j] - b[i] * L[j]
        obs = k < K_obs
        fb_ = fbar[k] if obs else 0.0
        Sb = Sbar[k] if obs else 0.0
        for j in range(3):
            Lb[j] = Lbar[k, j] if obs else 0.0
        for i in range(3):
            for j in range(3):
                Mbar[i, j] = w[i] * sb[j]  # s_k = Mᵀ w + q11 r_k e_0
        qb0 += r[k] * sb[0]
        for i in range(3):
            wb[i] = M[i, 0] * sb[0] + M[i, 1] * sb[1] + M[i, 2] * sb[2] + b[i] * fb_ * iS  # and f_k = b_cᵀ w / S
            bbar[i] += w[i] * fb_ * iS
        Sb -= fk * fb_ * iS
        if held and k == k_z:  # the held steps' constants are this step's
            for i in range(3):
                Lb[i] += Lc_bar[i]
                bbar[i] += seed[i] * iS  # β = b_c / S
                Sb -= seed[i] * b[i] * iS * iS
                for j in range(3):
                    Mbar[i, j] += seed[3 + 3 * i + j]
            Sb += Sc_bar
        # P_k = Q + R L Lᵀ + Mᵀ P M at fixed L (envelope theorem): to Q, P_{k+1}, and A, b_c through M
        qb0 += Pbar[0, 0]
        qb1 += Pbar[1, 1]
        for i in range(3):
            for j in range(3):
                X[i, j] = Pbar[i, j] + Pbar[j, i]
                MP[i, j] = M[i, 0] * Pbar[0, j] + M[i, 1] * Pbar[1, j] + M[i, 2] * Pbar[2, j]
        for i in range(3):
            for j in range(3):
                Pn[i, j] = MP[i, 0] * M[j, 0] + MP[i, 1] * M[j, 1] + MP[i, 2] * M[j, 2]
        for i in range(3):
            for j in range(3):  # P M (P̄ + P̄ᵀ), with P M in MP's place
                MP[i, j] = P[i, 0] * M[0, j] + P[i, 1] * M[1, j] + P[i, 2] * M[2, j]
        for i in range(3):
            for j in range(3):
                v = MP[i, 0] * X[0, j] + MP[i, 1] * X[1, j] + MP[i, 2] * X[2, j]
                Abar[i, j] += v
                bbar[i] -= v * L[j]
        # w = s_{k+1} - P b_a a_k, P b_a from P_{k+1}
        ak = ua[k]
        if held and k == k_z:
            for i in range(3):
                for j in range(3):
                    Pn[i, j] -= (ak * wb[i] - seed[12 + i]) * ba[j]
        else:
            for i in range(3):
                for j in range(3):
                    Pn[i, j] -= ak * wb[i] * ba[j]
        # M = A - b_c Lᵀ (the s-recursion's M, and the held steps')
        for i in range(3):
            for j in range(3):
                Abar[i, j] += Mbar[i, j]
                bbar[i] -= Mbar[i, j] * L[j]
                Lb[j] -= b[i] * Mbar[i, j]
        # L = Aᵀ P b_c / S, S = R + b_cᵀ P b_c, P b_c from P_{k+1}
        Sb -= (L[0] * Lb[0] + L[1] * Lb[1] + L[2] * Lb[2]) * iS
        for i in range(3):
            pbb[i] = (A[i, 0] * Lb[0] + A[i, 1] * Lb[1] + A[i, 2] * Lb[2]) * iS + b[i] * Sb
            for j in range(3):
                Abar[i, j] += pb[i] * Lb[j] * iS
            bbar[i] += pb[i] * Sb
        for i in range(3):
            bbar[i] += P[i, 0] * pbb[0] + P[i, 1] * pbb[1] + P[i, 2] * pbb[2]
            for j in range(3):
                Pn[i, j] += pbb[i] * b[j]
        for i in range(3):
            sb[i] = wb[i]
            for j in range(3):
                Pbar[i, j] = Pn[i, j]
    # P_N = Q, s_N = Q x_ref_N
    qb0 += Pbar[0, 0] + r[N] * sb[0]
    qb1 += Pbar[1, 1]
    G[0] += qb0
    G[1] += qb1
    for p in range(4):
        acc = 0.0
        for i in range(3):
            acc += bbar[i] * dbc[i, p]
            for j in range(3):
                acc += Abar[i, j] * dAb[i, j, p]
        G[p] += acc


__all__ = ["DIRECTIONS", "SEED", "TAPE", "plan_adjoint", "plan_recursion", "plan_reverse"]
