"""The reverse sweep of the ``delayed`` human's plan: F's derivative in q11, q22, a and α (numba).

Step 3 of :mod:`.riccati`, one step of its recursion backward (P = P_{k+1}, s' = s_{k+1},
x̄ = ∂F/∂x), in this order, P̄ kept symmetric as only symmetric perturbations of P exist::

    s_k:  w̄ = M s̄_k,  M̄ = w s̄_kᵀ,  q̄11 += r_k s̄_k[0]
    f_k:  w̄ += b_c f̄ / S,  b̄ += w f̄ / S,  S̄ -= f_k f̄ / S
    P_k:  q̄11 += P̄_k[0, 0], q̄22 += P̄_k[1, 1];  Ā += V, b̄ -= V L with V = 2 P M P̄_k (L held:
          the envelope theorem); P̄ = M P̄_k Mᵀ
    w:    s̄' = w̄;  P̄ += sym((-a_k w̄) b_aᵀ)
    M:    Ā += M̄,  b̄ -= M̄ L,  L̄ -= M̄ᵀ b_c
    L, S: S̄ -= Lᵀ L̄ / S;  c = A L̄ / S + b_c S̄;  Ā += (P b_c) L̄ᵀ / S;  b̄ += (P b_c) S̄ + P c;
          P̄ += sym(c b_cᵀ)

At step k_z the held steps' constants add their adjoints and s̄_{k_z} starts from
:func:`.riccati.plan_adjoint`'s λ; at the end P_N = Q, s_N = q11 r_N e_0, and
``G[p] += Āᵢⱼ ∂Aᵢⱼ/∂p + b̄ᵢ ∂bᵢ/∂p``. Written with scalars: LLVM keeps small arrays in memory.
"""

from __future__ import annotations

from scioc.models.runtime import FASTMATH, njit


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def plan_reverse(Ab, bc, ba, dAb, dbc, r, ua, K_obs, k_z, tape, fbar, Sbar, Lbar, Sc_bar, Lc_bar, seed, G):
    """Add F's derivative in :data:`.riccati.DIRECTIONS` through the recorded steps to G (4,).

    ``fbar``, ``Sbar``, ``Lbar`` (K,), (K,), (K, 3): F's adjoints of f_k, S_k, L_k of the observed
    steps. If k_z > 0, ``Sc_bar`` and ``Lc_bar`` are F's adjoints of the stationary S and L
    (through the stationary observed rows) and ``seed`` :func:`.riccati.plan_adjoint`'s; they
    belong to step k_z. ``dAb`` (3, 3, 4), ``dbc`` (3, 4): Ab's and bc's derivatives in the directions.
    """
    N = ua.shape[0]
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = (Ab[0, 0], Ab[0, 1], Ab[0, 2], Ab[1, 0], Ab[1, 1], Ab[1, 2], Ab[2, 0],
                                                   Ab[2, 1], Ab[2, 2])
    b0, b1, b2 = bc[0], bc[1], bc[2]
    e0, e1 = ba[0], ba[1]
    # adjoints: of A (x), of b_c (bb), of q11 and q22 (qb); carried: of P_k (u, symmetric) and of s_k (sb)
    x00 = x01 = x02 = x10 = x11 = x12 = x20 = x21 = x22 = 0.0
    bb0 = bb1 = bb2 = 0.0
    qb0 = qb1 = 0.0
    u00 = u01 = u02 = u11 = u12 = u22 = 0.0  # none for P_{k_z}: the held steps use P_{k_z + 1}
    sb0 = sb1 = sb2 = 0.0
    if k_z > 0:
        sb0, sb1, sb2 = seed[16], seed[17], seed[18]
        qb0 = seed[15]
    for k in range(k_z, N):
        p00 = tape[k, 0]
        p01 = tape[k, 1]
        p02 = tape[k, 2]
        p11 = tape[k, 3]
        p12 = tape[k, 4]
        p22 = tape[k, 5]
        pb0 = tape[k, 6]
        pb1 = tape[k, 7]
        pb2 = tape[k, 8]
        S = tape[k, 9]
        iS = 1.0 / S
        L0 = tape[k, 10]
        L1 = tape[k, 11]
        L2 = tape[k, 12]
        w0 = tape[k, 13]
        w1 = tape[k, 14]
        w2 = tape[k, 15]
        fk = tape[k, 16]
        m00 = a00 - b0 * L0
        m01 = a01 - b0 * L1
        m02 = a02 - b0 * L2
        m10 = a10 - b1 * L0
        m11 = a11 - b1 * L1
        m12 = a12 - b1 * L2
        m20 = a20 - b2 * L0
        m21 = a21 - b2 * L1
        m22 = a22 - b2 * L2
        if k < K_obs:
            fbk = fbar[k]
            Sb = Sbar[k]
            lb0 = Lbar[k, 0]
            lb1 = Lbar[k, 1]
            lb2 = Lbar[k, 2]
        else:
            fbk = 0.0
            Sb = 0.0
            lb0 = lb1 = lb2 = 0.0
        # s_k = Mᵀ w + q11 r_k e_0, f_k = b_cᵀ w / S
        n00 = w0 * sb0
        n01 = w0 * sb1
        n02 = w0 * sb2
        n10 = w1 * sb0
        n11 = w1 * sb1
        n12 = w1 * sb2
        n20 = w2 * sb0
        n21 = w2 * sb1
        n22 = w2 * sb2
        qb0 += r[k] * sb0
        ff = fbk * iS
        wb0 = m00 * sb0 + m01 * sb1 + m02 * sb2 + b0 * ff
        bb0 += w0 * ff
        wb1 = m10 * sb0 + m11 * sb1 + m12 * sb2 + b1 * ff
        bb1 += w1 * ff
        wb2 = m20 * sb0 + m21 * sb1 + m22 * sb2 + b2 * ff
        bb2 += w2 * ff
        Sb -= fk * ff
        ga0 = ga1 = ga2 = 0.0
        if k == k_z and k_z > 0:  # the held steps' constants are this step's
            lb0 += Lc_bar[0]
            lb1 += Lc_bar[1]
            lb2 += Lc_bar[2]
            bb0 += seed[0] * iS  # β = b_c / S
            bb1 += seed[1] * iS  # β = b_c / S
            bb2 += seed[2] * iS  # β = b_c / S
            Sb += Sc_bar - (seed[0] * b0 + seed[1] * b1 + seed[2] * b2) * iS * iS
            n00 += seed[3]
            n01 += seed[4]
            n02 += seed[5]
            n10 += seed[6]
            n11 += seed[7]
            n12 += seed[8]
            n20 += seed[9]
            n21 += seed[10]
            n22 += seed[11]
            ga0 = seed[12]
            ga1 = seed[13]
            ga2 = seed[14]
        # P_k = Q + R L Lᵀ + Mᵀ P M at fixed L (envelope theorem): to Q, to A and b_c through M, to P_{k+1}
        qb0 += u00
        qb1 += u11
        h00 = p00 * m00 + p01 * m10 + p02 * m20
        h01 = p00 * m01 + p01 * m11 + p02 * m21
        h02 = p00 * m02 + p01 * m12 + p02 * m22
        h10 = p01 * m00 + p11 * m10 + p12 * m20
        h11 = p01 * m01 + p11 * m11 + p12 * m21
        h12 = p01 * m02 + p11 * m12 + p12 * m22
        h20 = p02 * m00 + p12 * m10 + p22 * m20
        h21 = p02 * m01 + p12 * m11 + p22 * m21
        h22 = p02 * m02 + p12 * m12 + p22 * m22
        v = 2.0 * (h00 * u00 + h01 * u01 + h02 * u02)
        x00 += v
        bb0 -= v * L0
        v = 2.0 * (h00 * u01 + h01 * u11 + h02 * u12)
        x01 += v
        bb0 -= v * L1
        v = 2.0 * (h00 * u02 + h01 * u12 + h02 * u22)
        x02 += v
        bb0 -= v * L2
        v = 2.0 * (h10 * u00 + h11 * u01 + h12 * u02)
        x10 += v
        bb1 -= v * L0
        v = 2.0 * (h10 * u01 + h11 * u11 + h12 * u12)
        x11 += v
        bb1 -= v * L1
        v = 2.0 * (h10 * u02 + h11 * u12 + h12 * u22)
        x12 += v
        bb1 -= v * L2
        v = 2.0 * (h20 * u00 + h21 * u01 + h22 * u02)
        x20 += v
        bb2 -= v * L0
        v = 2.0 * (h20 * u01 + h21 * u11 + h22 * u12)
        x21 += v
        bb2 -= v * L1
        v = 2.0 * (h20 * u02 + h21 * u12 + h22 * u22)
        x22 += v
        bb2 -= v * L2
        h00 = m00 * u00 + m01 * u01 + m02 * u02
        h01 = m00 * u01 + m01 * u11 + m02 * u12
        h02 = m00 * u02 + m01 * u12 + m02 * u22
        h10 = m10 * u00 + m11 * u01 + m12 * u02
        h11 = m10 * u01 + m11 * u11 + m12 * u12
        h12 = m10 * u02 + m11 * u12 + m12 * u22
        h20 = m20 * u00 + m21 * u01 + m22 * u02
        h21 = m20 * u01 + m21 * u11 + m22 * u12
        h22 = m20 * u02 + m21 * u12 + m22 * u22
        t00 = h00 * m00 + h01 * m01 + h02 * m02
        t01 = h00 * m10 + h01 * m11 + h02 * m12
        t02 = h00 * m20 + h01 * m21 + h02 * m22
        t11 = h10 * m10 + h11 * m11 + h12 * m12
        t12 = h10 * m20 + h11 * m21 + h12 * m22
        t22 = h20 * m20 + h21 * m21 + h22 * m22
        # w = s_{k+1} - P b_a a_k (P b_a from P_{k+1}, b_a[2] = 0)
        ak = ua[k]
        ga0 -= ak * wb0
        ga1 -= ak * wb1
        ga2 -= ak * wb2
        t00 += ga0 * e0
        t01 += 0.5 * (ga0 * e1 + e0 * ga1)
        t02 += 0.5 * (e0 * ga2)
        t11 += ga1 * e1
        t12 += 0.5 * (e1 * ga2)
        # M = A - b_c Lᵀ (the s-recursion's M, and the held steps')
        x00 += n00
        x01 += n01
        x02 += n02
        x10 += n10
        x11 += n11
        x12 += n12
        x20 += n20
        x21 += n21
        x22 += n22
        bb0 -= n00 * L0 + n01 * L1 + n02 * L2
        bb1 -= n10 * L0 + n11 * L1 + n12 * L2
        bb2 -= n20 * L0 + n21 * L1 + n22 * L2
        lb0 -= b0 * n00 + b1 * n10 + b2 * n20
        lb1 -= b0 * n01 + b1 * n11 + b2 * n21
        lb2 -= b0 * n02 + b1 * n12 + b2 * n22
        # L = Aᵀ P b_c / S, S = R + b_cᵀ P b_c (P b_c from P_{k+1})
        Sb -= (L0 * lb0 + L1 * lb1 + L2 * lb2) * iS
        c0 = (a00 * lb0 + a01 * lb1 + a02 * lb2) * iS + b0 * Sb
        c1 = (a10 * lb0 + a11 * lb1 + a12 * lb2) * iS + b1 * Sb
        c2 = (a20 * lb0 + a21 * lb1 + a22 * lb2) * iS + b2 * Sb
        x00 += pb0 * lb0 * iS
        x01 += pb0 * lb1 * iS
        x02 += pb0 * lb2 * iS
        bb0 += pb0 * Sb + p00 * c0 + p01 * c1 + p02 * c2
        x10 += pb1 * lb0 * iS
        x11 += pb1 * lb1 * iS
        x12 += pb1 * lb2 * iS
        bb1 += pb1 * Sb + p01 * c0 + p11 * c1 + p12 * c2
        x20 += pb2 * lb0 * iS
        x21 += pb2 * lb1 * iS
        x22 += pb2 * lb2 * iS
        bb2 += pb2 * Sb + p02 * c0 + p12 * c1 + p22 * c2
        u00 = t00 + c0 * b0
        u01 = t01 + 0.5 * (c0 * b1 + b0 * c1)
        u02 = t02 + 0.5 * (c0 * b2 + b0 * c2)
        u11 = t11 + c1 * b1
        u12 = t12 + 0.5 * (c1 * b2 + b1 * c2)
        u22 = t22 + c2 * b2
        sb0 = wb0
        sb1 = wb1
        sb2 = wb2
    # P_N = Q, s_N = Q x_ref_N
    qb0 += u00 + r[N] * sb0
    qb1 += u11
    G[0] += qb0
    G[1] += qb1
    for p in range(4):
        G[p] += (bb0 * dbc[0, p] + bb1 * dbc[1, p] + bb2 * dbc[2, p]
                 + x00 * dAb[0, 0, p] + x01 * dAb[0, 1, p] + x02 * dAb[0, 2, p]
                 + x10 * dAb[1, 0, p] + x11 * dAb[1, 1, p] + x12 * dAb[1, 2, p]
                 + x20 * dAb[2, 0, p] + x21 * dAb[2, 1, p] + x22 * dAb[2, 2, p])


__all__ = ["plan_reverse"]
