"""The Kalman filter of the encoder's angles (:mod:`.angles`) and its reverse sweep (numba).

State ``s_k = (z_k, m_{k-1}, ..., m_{k-d})``, n = 3 + d. A step is ``s⁻ = F_k s + e_k``,
``F_k = [[M_k, b_c h_kᵀ], [0, 0], [I, 0]]`` (M_k = Ā - b_c L_kᵀ, h_{k,j} = L_k Ā^{j-1} b_c, the
history shifted by one lag), mean offset ``b_c f_k + b_a κ_k``, noise ``b_c (ε_k + m_k)`` on z and
m_k in the first lag; then the update by ``y_{k+1} = s⁻[0] + v``. F_k's structure makes a step
O(n²). Once the covariance is stationary and while the plan is (:data:`FREEZE_RTOL`), the
filter is held: the gain, the innovation variance, M and h of the step that held it.

Reverse mode (:func:`angle_filter_reverse`) runs the same steps backward from the tape the
forward sweep records: with x̄ = ∂ log p / ∂x, P̄ symmetric, c = P⁻[:, 0], s = c_0 + σ_y²,

    update:  ḡ = μ̄ ν,  c̄ = ḡ / s - 2 P̄ c / s,  s̄ = ν²/(2 s²) - 1/(2 s) - ḡ·c / s² + cᵀ P̄ c / s²,
             P̄⁻ = P̄ + sym(c̄ e_0ᵀ) + s̄ e_0 e_0ᵀ,  μ̄⁻ = μ̄ - e_0 (c·μ̄ / s - ν / s)
    predict: F̄ = μ̄⁻ μᵀ + 2 P̄⁻ F P,  μ̄ = Fᵀ μ̄⁻,  P̄ = Fᵀ P̄⁻ F,  and the noise's b_c, S_k, σ_m²
    F_k:     Ā̄ += M̄,  b̄_c -= M̄ L_k,  L̄_k = -M̄ᵀ b_c + sum_j h̄_j Ā^{j-1} b_c  (b_c also in the noise and offset)

A held run's gain, s, M and h collect their adjoints over the run and hand them to the step that
held it. The tape holds μ_k and ν_k of every step and P_k, c and s of the steps not held:
O(K n) plus O(n²) per step not held.
"""

from __future__ import annotations

import numpy as np

from scioc.models.maxent import HALF_LOG_2PI
from scioc.models.runtime import FASTMATH, njit

#: The filter is held once its covariance, the plan's gain and S_k move by at most this, relative, in a step.
FREEZE_RTOL = 1e-13


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def step_gains(Ab, bc, d):
    """G (max(d, 1), 3): G[j - 1] = Ā^{j-1} b_c, j = 1..d."""
    G = np.zeros((max(d, 1), 3))
    for j in range(d):
        for i in range(3):
            if j == 0:
                G[0, i] = bc[i]
            else:
                G[j, i] = Ab[i, 0] * G[j - 1, 0] + Ab[i, 1] * G[j - 1, 1] + Ab[i, 2] * G[j - 1, 2]
    return G


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def angle_filter(Ab, bc, ba, L, f, S, known, d, s2m, s2y, y, mu0, P0, inn, freeze, record, t_mu, t_nu, slot, t_P,
                 t_c, t_s):
    """The filter of the module docstring; returns log p(y_1..y_K | y_0), fills ``inn`` (K,).

    ``Ab``, ``bc``, ``ba``: the plant the human moves and plans on; ``L`` (K, 3), ``f``, ``S`` (K,):
    the plan; ``known`` (>= K,) N·m; ``s2m``, ``s2y``: σ_m², σ_y²; ``y`` (K + 1,) rad; ``mu0`` (3,),
    ``P0`` (3, 3): z_0's prior. With ``record`` the tape: ``t_mu`` (K, n) the mean entering each
    step, ``t_nu`` (K,) the innovations, ``slot`` (K,) the row of ``t_P`` (K + 1, n, n), ``t_c`` (K, n),
    ``t_s`` (K,) of a step not held, or -1 - (the step that held it); ``t_P``'s rows are the filter's
    covariances, in order.
    """
    K = y.shape[0] - 1
    n = 3 + d
    mu = np.zeros(n)
    P = np.zeros((n, n))
    Q = np.zeros((n, n))  # the covariance being built, then the previous step's (swapped)
    if record:
        P = t_P[0]
        for i in range(n):
            for j in range(n):
                P[i, j] = 0.0
    for i in range(3):
        mu[i] = mu0[i]
        for j in range(3):
            P[i, j] = P0[i, j]
    for j in range(d):
        P[3 + j, 3 + j] = s2m
    G = step_gains(Ab, bc, d)
    h = np.zeros(max(d, 1))  # h[j - 1] = L_k G_j, the coefficient of m_{k-j}
    wm = np.zeros(max(d, 1))
    wz = np.zeros(3)
    M = np.zeros((3, 3))
    MP = np.zeros((3, n))
    Mw = np.zeros(3)
    gain = np.zeros(n)
    ll = 0.0
    s = P[0, 0] + s2y
    if s > 0.0:
        nu = y[0] - mu[0]
        for i in range(n):
            gain[i] = P[i, 0] / s
        for i in range(n):
            mu[i] += gain[i] * nu
            for j in range(n):
                P[i, j] -= gain[i] * gain[j] * s
    held = False
    s_held = 0.0
    k_held = 0
    L_held = np.zeros(3)
    S_held = 0.0
    row = 0
    for k in range(K):
        if held:  # the plan as when the filter was held
            same = abs(S[k] - S_held) <= FREEZE_RTOL * S_held
            for j in range(3):
                same = same and abs(L[k, j] - L_held[j]) <= FREEZE_RTOL * abs(L_held[j])
            if not same:
                held = False  # P is the stationary covariance after the last update: go on from it
        if not held:
            for j in range(d):
                h[j] = L[k, 0] * G[j, 0] + L[k, 1] * G[j, 1] + L[k, 2] * G[j, 2]
            for i in range(3):
                for j in range(3):
                    M[i, j] = Ab[i, j] - bc[i] * L[k, j]
        if record:
            for i in range(n):
                t_mu[k, i] = mu[i]
        # ---- the mean
        g = 0.0
        for j in range(d):
            g += h[j] * mu[3 + j]
        z0_ = mu[0]
        z1_ = mu[1]
        z2_ = mu[2]
        for i in range(3):
            mu[i] = M[i, 0] * z0_ + M[i, 1] * z1_ + M[i, 2] * z2_ + bc[i] * (g + f[k]) + ba[i] * known[k]
        for j in range(d - 1, 0, -1):
            mu[3 + j] = mu[2 + j]
        if d > 0:
            mu[3] = 0.0
        if held:
            nu = y[k + 1] - mu[0]
            ll -= 0.5 * nu * nu / s_held + 0.5 * np.log(s_held) + HALF_LOG_2PI
            inn[k] = nu / np.sqrt(s_held)
            for i in range(n):
                mu[i] += gain[i] * nu
            if record:
                t_nu[k] = nu
                slot[k] = -1 - k_held
            continue
        if record:  # P is the tape's row; the prediction and update go to the next
            slot[k] = row
            Q = t_P[row + 1]
        # ---- the covariance: predict into Q
        hph = 0.0
        for a in range(d):
            acc = 0.0
            for t in range(d):
                acc += P[3 + a, 3 + t] * h[t]
            wm[a] = acc
            hph += h[a] * acc
        for i in range(3):
            acc = 0.0
            for t in range(d):
                acc += P[i, 3 + t] * h[t]
            wz[i] = acc
        for i in range(3):
            for j in range(n):
                MP[i, j] = M[i, 0] * P[0, j] + M[i, 1] * P[1, j] + M[i, 2] * P[2, j]
            Mw[i] = M[i, 0] * wz[0] + M[i, 1] * wz[1] + M[i, 2] * wz[2]
        var_u = hph + 0.5 / S[k] + s2m
        for i in range(3):
            for j in range(3):
                Q[i, j] = (MP[i, 0] * M[j, 0] + MP[i, 1] * M[j, 1] + MP[i, 2] * M[j, 2] + Mw[i] * bc[j]
                           + bc[i] * Mw[j] + bc[i] * bc[j] * var_u)
        if d > 0:
            for i in range(3):
                Q[i, 3] = bc[i] * s2m  # Cov(z_{k+1}, m_k)
                Q[3, i] = Q[i, 3]
            Q[3, 3] = s2m
            for j in range(1, d):
                Q[3, 3 + j] = 0.0
                Q[3 + j, 3] = 0.0
                for i in range(3):  # Cov(z_{k+1}, m_{k-j}), m_{k-j} in the old lag j - 1
                    v = MP[i, 2 + j] + bc[i] * wm[j - 1]
                    Q[i, 3 + j] = v
                    Q[3 + j, i] = v
                for t in range(1, d):
                    Q[3 + j, 3 + t] = P[2 + j, 2 + t]
        # ---- observe y_{k+1}
        s = Q[0, 0] + s2y
        nu = y[k + 1] - mu[0]
        if record:
            t_nu[k] = nu
            t_s[row] = s
            for i in range(n):
                t_c[row, i] = Q[i, 0]
            row += 1
        if not s > 0.0:
            if nu != 0.0:
                return -np.inf
            inn[k] = 0.0
            P, Q = Q, P
            continue
        ll -= 0.5 * nu * nu / s + 0.5 * np.log(s) + HALF_LOG_2PI
        inn[k] = nu / np.sqrt(s)
        for i in range(n):
            gain[i] = Q[i, 0] / s
        for i in range(n):
            mu[i] += gain[i] * nu
        big = 0.0
        moved = 0.0
        for i in range(n):
            for j in range(i, n):
                v = Q[i, j] - gain[i] * gain[j] * s
                Q[i, j] = v
                Q[j, i] = v
                big = max(big, abs(v))
                moved = max(moved, abs(v - P[i, j]))
        P, Q = Q, P
        if freeze and k > 0 and moved <= FREEZE_RTOL * big:
            stationary = abs(S[k] - S[k - 1]) <= FREEZE_RTOL * S[k]
            for j in range(3):
                stationary = stationary and abs(L[k, j] - L[k - 1, j]) <= FREEZE_RTOL * abs(L[k, j])
            if stationary:
                held = True
                s_held = s
                k_held = k
                S_held = S[k]
                for j in range(3):
                    L_held[j] = L[k, j]
    return ll


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _step_matrices(Ab, bc, L, G, k, d, M, h):
    for j in range(d):
        h[j] = L[k, 0] * G[j, 0] + L[k, 1] * G[j, 1] + L[k, 2] * G[j, 2]
    for i in range(3):
        for j in range(3):
            M[i, j] = Ab[i, j] - bc[i] * L[k, j]


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def _mean_reverse(M, h, bc, mu, fk, d, mub, Mb, hb, bcb):
    """The mean's prediction backward: μ̄⁻ in ``mub`` becomes μ̄; F's adjoints added; returns f̄_k."""
    m0 = mub[0]
    m1 = mub[1]
    m2 = mub[2]
    bm = bc[0] * m0 + bc[1] * m1 + bc[2] * m2
    hm = 0.0
    for j in range(d):
        hm += h[j] * mu[3 + j]
        hb[j] += mu[3 + j] * bm
    bcb[0] += (fk + hm) * m0
    bcb[1] += (fk + hm) * m1
    bcb[2] += (fk + hm) * m2
    for j in range(3):
        Mb[0, j] += m0 * mu[j]
        Mb[1, j] += m1 * mu[j]
        Mb[2, j] += m2 * mu[j]
    for j in range(3):
        mub[j] = M[0, j] * m0 + M[1, j] * m1 + M[2, j] * m2
    for j in range(d):
        mub[3 + j] = h[j] * bm + (mub[4 + j] if j + 1 < d else 0.0)
    return bm


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def angle_filter_reverse(Ab, bc, L, f, S, d, s2m, s2y, y, mu0, P0, t_mu, t_nu, slot, t_P, t_c, t_s, Lbar, fbar, Sbar,
                         Abar, bcbar, mubar0):
    """The reverse sweep of :func:`angle_filter` from its tape; returns ∂ log p / ∂σ_m².

    Fills ``Lbar`` (K, 3), ``fbar``, ``Sbar`` (K,): the adjoints of the plan, zero on held steps;
    adds to ``Abar`` (3, 3) and ``bcbar`` (3,) those of Ā and b_c; ``mubar0`` (3,): of z_0's mean.
    """
    K = y.shape[0] - 1
    n = 3 + d
    G = step_gains(Ab, bc, d)
    Gb = np.zeros((max(d, 1), 3))
    mub = np.zeros(n)
    Pb = np.zeros((n, n))  # P̄ of the covariance after the current step's update
    Y = np.zeros((3, n))
    FP = np.zeros((3, n))
    xb = np.zeros(n)
    yb = np.zeros(n)
    wP = np.zeros(n)
    Pc = np.zeros(n)
    cb = np.zeros(n)
    gb = np.zeros(n)
    M = np.zeros((3, 3))
    Mb = np.zeros((3, 3))
    h = np.zeros(max(d, 1))
    hb = np.zeros(max(d, 1))
    # a held run's constants and their adjoints
    k_run = -1
    Mr = np.zeros((3, 3))
    hr = np.zeros(max(d, 1))
    gr = np.zeros(n)
    sr = 0.0
    Mrb = np.zeros((3, 3))
    hrb = np.zeros(max(d, 1))
    grb = np.zeros(n)
    srb = 0.0
    s2mb = 0.0
    for k in range(K - 1, -1, -1):
        nu = t_nu[k]
        mu = t_mu[k]
        sl = slot[k]
        if sl < 0:
            kh = -1 - sl
            if kh != k_run:  # the last step of a held run: its constants are those of step kh
                k_run = kh
                _step_matrices(Ab, bc, L, G, kh, d, Mr, hr)
                r = slot[kh]
                sr = t_s[r]
                for i in range(n):
                    gr[i] = t_c[r, i] / sr
                    grb[i] = 0.0
                for i in range(3):
                    for j in range(3):
                        Mrb[i, j] = 0.0
                for j in range(d):
                    hrb[j] = 0.0
                srb = 0.0
            cm = 0.0
            for i in range(n):
                cm += gr[i] * mub[i]
                grb[i] += mub[i] * nu
            srb += 0.5 * nu * nu / (sr * sr) - 0.5 / sr
            mub[0] -= cm - nu / sr
            fbar[k] = _mean_reverse(Mr, hr, bc, mu, f[k], d, mub, Mrb, hrb, bcbar)
            Sbar[k] = 0.0
            for j in range(3):
                Lbar[k, j] = 0.0
            continue
        _step_matrices(Ab, bc, L, G, k, d, M, h)
        P = t_P[sl]
        c = t_c[sl]
        s = t_s[sl]
        for i in range(3):
            for j in range(3):
                Mb[i, j] = 0.0
        for j in range(d):
            hb[j] = 0.0
        for i in range(n):
            gb[i] = 0.0
        sb = 0.0
        if k_run == k:  # this step held the run that follows: its adjoints join this step's
            for i in range(3):
                for j in range(3):
                    Mb[i, j] = Mrb[i, j]
            for j in range(d):
                hb[j] = hrb[j]
            for i in range(n):
                gb[i] = grb[i]
            sb = srb
            k_run = -1
        # ---- the update, backward: Pb becomes P̄⁻
        if s > 0.0:
            cm = 0.0
            gc = 0.0
            for i in range(n):
                cm += c[i] * mub[i]
                gb[i] += mub[i] * nu
                gc += gb[i] * c[i]
            cPc = 0.0
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += Pb[i, j] * c[j]
                Pc[i] = acc
                cPc += c[i] * acc
            for i in range(n):
                cb[i] = (gb[i] - 2.0 * Pc[i]) / s
            sb += 0.5 * nu * nu / (s * s) - 0.5 / s - gc / (s * s) + cPc / (s * s)
            for i in range(n):
                Pb[i, 0] += 0.5 * cb[i]
                Pb[0, i] += 0.5 * cb[i]
            Pb[0, 0] += sb
            mub[0] -= cm / s - nu / s
        # ---- the mean's prediction
        fbar[k] = _mean_reverse(M, h, bc, mu, f[k], d, mub, Mb, hb, bcbar)
        # ---- the noise: b_c b_cᵀ (1/(2 S_k) + σ_m²) on z, b_c σ_m² between z and the first lag, σ_m² there
        v = 0.5 / S[k] + s2m
        vb = 0.0
        for i in range(3):
            acc = Pb[i, 0] * bc[0] + Pb[i, 1] * bc[1] + Pb[i, 2] * bc[2]
            vb += bc[i] * acc
            bcbar[i] += 2.0 * v * acc
        Sbar[k] = -0.5 * vb / (S[k] * S[k])
        s2mb += vb
        if d > 0:
            for i in range(3):
                bcbar[i] += 2.0 * s2m * Pb[i, 3]
                s2mb += 2.0 * bc[i] * Pb[i, 3]
            s2mb += Pb[3, 3]
        # ---- F P Fᵀ: F̄ = 2 P̄⁻ F P on F's z-rows, reduced to M̄, b̄_c and h̄ (O(n d)); P̄ = Fᵀ P̄⁻ F
        for i in range(n):  # xb = P̄⁻[:, :3] b_c, wP = P[:, 3:] h
            xb[i] = Pb[i, 0] * bc[0] + Pb[i, 1] * bc[1] + Pb[i, 2] * bc[2]
            acc = 0.0
            for t in range(d):
                acc += P[i, 3 + t] * h[t]
            wP[i] = acc
        for t in range(3):  # (F P)[t, :3] and (F P h̃)[t], h̃ = (0, h)
            acc = 0.0
            for j in range(d):
                acc += h[j] * wP[3 + j]
            for j in range(3):
                FP[t, j] = M[t, 0] * P[0, j] + M[t, 1] * P[1, j] + M[t, 2] * P[2, j] + bc[t] * wP[j]
            Pc[t] = M[t, 0] * wP[0] + M[t, 1] * wP[1] + M[t, 2] * wP[2] + bc[t] * acc
        for i in range(3):
            for j in range(3):
                acc = Pb[i, 0] * FP[0, j] + Pb[i, 1] * FP[1, j] + Pb[i, 2] * FP[2, j]
                for t in range(1, d):
                    acc += Pb[i, 3 + t] * P[2 + t, j]
                Mb[i, j] += 2.0 * acc
            acc = Pb[i, 0] * Pc[0] + Pb[i, 1] * Pc[1] + Pb[i, 2] * Pc[2]
            for t in range(1, d):
                acc += Pb[i, 3 + t] * wP[2 + t]
            bcbar[i] += 2.0 * acc
        bx = bc[0] * xb[0] + bc[1] * xb[1] + bc[2] * xb[2]
        for r in range(3):  # yb = Fᵀ xb
            yb[r] = M[0, r] * xb[0] + M[1, r] * xb[1] + M[2, r] * xb[2]
        for j in range(d):
            yb[3 + j] = h[j] * bx + (xb[4 + j] if j + 1 < d else 0.0)
        for j in range(d):
            acc = 0.0
            for m in range(n):
                acc += P[3 + j, m] * yb[m]
            hb[j] += 2.0 * acc
        for t in range(3):  # FP's rows become (P̄⁻ F)[:3, :]
            for c in range(3):
                Y[t, c] = Pb[t, 0] * M[0, c] + Pb[t, 1] * M[1, c] + Pb[t, 2] * M[2, c]
            for j in range(d):
                Y[t, 3 + j] = xb[t] * h[j] + (Pb[t, 4 + j] if j + 1 < d else 0.0)
        for c in range(n):
            yb[c] = bc[0] * Y[0, c] + bc[1] * Y[1, c] + bc[2] * Y[2, c]
            for r in range(3):
                Pb[r, c] = M[0, r] * Y[0, c] + M[1, r] * Y[1, c] + M[2, r] * Y[2, c]
        for i in range(d):  # the history block: P̄⁻'s shifted, in place (row i + 1 is read before it is written)
            for j in range(d):
                v = h[i] * yb[3 + j]
                if i + 1 < d:
                    v += xb[4 + i] * h[j] + (Pb[4 + i, 4 + j] if j + 1 < d else 0.0)
                Pb[3 + i, 3 + j] = v
            for r in range(3):
                Pb[3 + i, r] = Pb[r, 3 + i]
        # ---- F_k from the plan: M = Ā - b_c L_kᵀ, h_j = L_k Ā^{j-1} b_c
        for i in range(3):
            for j in range(3):
                Abar[i, j] += Mb[i, j]
            bcbar[i] -= Mb[i, 0] * L[k, 0] + Mb[i, 1] * L[k, 1] + Mb[i, 2] * L[k, 2]
        for j in range(3):
            acc = -(Mb[0, j] * bc[0] + Mb[1, j] * bc[1] + Mb[2, j] * bc[2])
            for t in range(d):
                acc += hb[t] * G[t, j]
                Gb[t, j] += hb[t] * L[k, j]
            Lbar[k, j] = acc
    # ---- the update by y_0 (z_0's prior; the history starts at its prior σ_m² I, apart from z_0)
    s = P0[0, 0] + s2y
    cm = P0[0, 0] * mub[0] + P0[1, 0] * mub[1] + P0[2, 0] * mub[2]
    for i in range(3):
        mubar0[i] = mub[i]
    if s > 0.0:
        mubar0[0] -= cm / s
    for j in range(d):
        s2mb += Pb[3 + j, 3 + j]
    # ---- G_j = Ā G_{j-1}, G_0 = b_c
    for j in range(d - 1, 0, -1):
        for i in range(3):
            for m in range(3):
                Abar[i, m] += Gb[j, i] * G[j - 1, m]
        for m in range(3):
            Gb[j - 1, m] += Ab[0, m] * Gb[j, 0] + Ab[1, m] * Gb[j, 1] + Ab[2, m] * Gb[j, 2]
    if d > 0:
        for i in range(3):
            bcbar[i] += Gb[0, i]
    return s2mb


__all__ = ["FREEZE_RTOL", "angle_filter", "angle_filter_reverse", "step_gains"]
