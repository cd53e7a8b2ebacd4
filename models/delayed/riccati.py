"""The ``delayed`` human's plan: the 3-state LQ recursion and its reverse-mode derivative in q11, q22, a, α (numba).

:func:`scioc.models.lq.lq_tracking_policy`'s recursion on :func:`.lag.lagged_planning_plant`
(P = P_{k+1}; P_{K+M} = Q, s_{K+M} = Q x_ref)::

    S_k = R + b_cᵀ P b_c,  L_k = b_cᵀ P A / S_k,  w = s_{k+1} - P b_a a_k,  f_k = b_cᵀ w / S_k,
    M_k = A - b_c L_k,  s_k = Q x_ref_k + M_kᵀ w,  P_k = Q + R L_kᵀ L_k + M_kᵀ P M_k.

:func:`plan_recursion` records each step (the tape) until P is stationary to
:data:`scioc.models.maxent.FREEZE_RTOL` at step k_z, then runs the s-recursion only. Reverse
mode: :func:`plan_adjoint` over the stationary steps, :func:`.reverse.plan_reverse` over the
recorded ones; by the envelope theorem the P-update's derivative in L vanishes.
"""

from __future__ import annotations

from scioc.models.maxent import FREEZE_RTOL
from scioc.models.runtime import FASTMATH, njit

#: Directions of the plan's derivative, in this order.
DIRECTIONS = ("q11", "q22", "a", "alpha")
#: Columns of the tape, per recorded step: P_{k+1} (upper triangle, 6), P b_c (3), S, L (3), w (3), f.
TAPE = 17
#: Entries of the stationary constants' adjoints (:func:`plan_adjoint`): ∂F/∂β (β = b_c / S, 3),
#: ∂F/∂M (9, row-major), ∂F/∂(P b_a) (3), ∂F/∂q11 through Q x_ref, ∂F/∂s_{k_z} (3).
SEED = 19


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def plan_recursion(Ab, bc, ba, q11, q22, R, r, ua, K_obs, freeze, f, S_t, L_t, cst, frozen, W, tape):
    """Run the recursion backward over the plan's K + M steps; return (k_R, k_z).

    ``Ab``, ``bc``, ``ba``: the planning plant closed by the assistant's feedback (``ba[2]`` = 0);
    ``r`` (K + M + 1,) the angle reference, rad; ``ua`` (K + M,) the known input, N·m; ``K_obs`` = K.
    Out: ``f`` (K,); ``S_t``, ``L_t`` (K,), (K, 3) of the observed steps k > k_R; ``cst`` (4,) the
    stationary S and L; ``frozen`` the stationary M (3, 3) and P b_a (3,); ``W`` (K + M, 3) the w_k
    of the steps k < k_z; ``tape`` (K + M, :data:`TAPE`) the recorded steps k >= k_z. The
    observed steps k <= k_R (-1: none) have the stationary S and L; the steps k < k_z (0: none)
    all stationary step quantities.
    """
    M, pba = frozen
    K = ua.shape[0]
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = (Ab[0, 0], Ab[0, 1], Ab[0, 2], Ab[1, 0], Ab[1, 1], Ab[1, 2], Ab[2, 0],
                                                   Ab[2, 1], Ab[2, 2])
    b0, b1, b2 = bc[0], bc[1], bc[2]
    e0, e1 = ba[0], ba[1]
    # P = P_{k+1} (symmetric), s = s_{k+1}; M and P b_a of the last step run
    p00, p01, p02, p11, p12, p22 = q11, 0.0, 0.0, q22, 0.0, 0.0
    s0, s1, s2 = q11 * r[K], 0.0, 0.0
    S = 0.0
    L0 = L1 = L2 = 0.0
    m00 = m01 = m02 = m10 = m11 = m12 = m20 = m21 = m22 = 0.0
    g0 = g1 = g2 = 0.0
    k = K - 1
    stationary = False
    while k >= 0 and not stationary:
        pb0 = p00 * b0 + p01 * b1 + p02 * b2
        pb1 = p01 * b0 + p11 * b1 + p12 * b2
        pb2 = p02 * b0 + p12 * b1 + p22 * b2
        S = R + b0 * pb0 + b1 * pb1 + b2 * pb2
        iS = 1.0 / S
        L0 = (pb0 * a00 + pb1 * a10 + pb2 * a20) * iS
        L1 = (pb0 * a01 + pb1 * a11 + pb2 * a21) * iS
        L2 = (pb0 * a02 + pb1 * a12 + pb2 * a22) * iS
        m00 = a00 - b0 * L0
        m01 = a01 - b0 * L1
        m02 = a02 - b0 * L2
        m10 = a10 - b1 * L0
        m11 = a11 - b1 * L1
        m12 = a12 - b1 * L2
        m20 = a20 - b2 * L0
        m21 = a21 - b2 * L1
        m22 = a22 - b2 * L2
        g0 = p00 * e0 + p01 * e1
        g1 = p01 * e0 + p11 * e1
        g2 = p02 * e0 + p12 * e1
        ak = ua[k]
        w0 = s0 - g0 * ak
        w1 = s1 - g1 * ak
        w2 = s2 - g2 * ak
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
        s0 = m00 * w0 + m10 * w1 + m20 * w2 + q11 * r[k]
        s1 = m01 * w0 + m11 * w1 + m21 * w2
        s2 = m02 * w0 + m12 * w1 + m22 * w2
        # P_k = Q + R L Lᵀ + Mᵀ P M (Joseph form, symmetric)
        h00 = p00 * m00 + p01 * m10 + p02 * m20
        h01 = p00 * m01 + p01 * m11 + p02 * m21
        h02 = p00 * m02 + p01 * m12 + p02 * m22
        h10 = p01 * m00 + p11 * m10 + p12 * m20
        h11 = p01 * m01 + p11 * m11 + p12 * m21
        h12 = p01 * m02 + p11 * m12 + p12 * m22
        h20 = p02 * m00 + p12 * m10 + p22 * m20
        h21 = p02 * m01 + p12 * m11 + p22 * m21
        h22 = p02 * m02 + p12 * m12 + p22 * m22
        n00 = R * L0 * L0 + m00 * h00 + m10 * h10 + m20 * h20 + q11
        n01 = R * L0 * L1 + m00 * h01 + m10 * h11 + m20 * h21
        n02 = R * L0 * L2 + m00 * h02 + m10 * h12 + m20 * h22
        n11 = R * L1 * L1 + m01 * h01 + m11 * h11 + m21 * h21 + q22
        n12 = R * L1 * L2 + m01 * h02 + m11 * h12 + m21 * h22
        n22 = R * L2 * L2 + m02 * h02 + m12 * h12 + m22 * h22
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
    M[0, 0], M[0, 1], M[0, 2], M[1, 0], M[1, 1], M[1, 2], M[2, 0], M[2, 1], M[2, 2] = (m00, m01, m02, m10, m11, m12,
                                                                                      m20, m21, m22)
    pba[0], pba[1], pba[2] = g0, g1, g2
    # ---- constant step quantities: the s-recursion only
    iS = 1.0 / S
    c0, c1, c2 = b0 * iS, b1 * iS, b2 * iS
    while k >= 0:
        ak = ua[k]
        w0 = s0 - g0 * ak
        w1 = s1 - g1 * ak
        w2 = s2 - g2 * ak
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


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def plan_adjoint(bc, S, r, ua, om, K_obs, k_z, frozen, W, seed):
    """F's adjoints of the stationary constants into ``seed`` (:data:`SEED`), F = sum_{k < k_z, K} om_k f_k.

    For k < k_z, ``f_k = βᵀ w_k`` (β = b_c / S), ``w_k = s_{k+1} - P b_a a_k``,
    ``s_k = Q x_ref_k + Mᵀ w_k``. λ_k = ∂F/∂s_k runs forward from λ_0 = 0,
    ``λ_{k+1} = ρ_k β + M λ_k`` (ρ = ``om``, 0 in the preview); the derivatives in β, M, P b_a and
    q11 are sums over k, and λ_{k_z} is that in s_{k_z}.
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


__all__ = ["DIRECTIONS", "SEED", "TAPE", "plan_adjoint", "plan_recursion"]
