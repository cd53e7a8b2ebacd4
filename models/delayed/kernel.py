"""The ``delayed`` likelihood of one segment and of a batch: assembly and chain rule (numba).

Per segment (the model in :mod:`.likelihood`): the plan (:func:`.riccati.plan_recursion`); τ_k,
c̃_k and their (a, α) tangents (:func:`.lag.arm_torque_recursion`); the residual
``r_k = c̃_k + L_k z_k - f_k``; the MA coefficients ``c_{k,0} = 1``, ``c_{k,j} = L_k Ā^{j-1} b_c``
and the band ``Σ_{i, i-t} = [t = 0] / (2 S_i) + σ_m² sum_{j=t..d} c_{i,j} c_{i-t, j-t}``;
log N(r; 0, Σ) (:func:`.innovations.banded_loglik`); then the chain rule back through the MA
coefficients, the data and the plan (:mod:`.riccati`, :mod:`.reverse`). R follows from
homogeneity: L and f are unchanged when θ is scaled and S scales with it, so
``θ · ∇_θ log p = sum_k S_k ∂/∂S_k``. A segment's result does not depend on its batch.
See docs/decisions/delayed-kernel.md.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from scioc.models.delayed.innovations import U, banded_loglik
from scioc.models.delayed.lag import arm_torque_recursion
from scioc.models.delayed.reverse import plan_reverse
from scioc.models.delayed.riccati import SEED, TAPE, plan_adjoint, plan_recursion
from scioc.models.runtime import FASTMATH, njit


@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def segment_kernel(A, b, fb, q11, q22, R, a, al, da, dal, sig, d, tau0, dtau0_a, dtau0_al, x1, x2, r, u, ua, freeze,
                   grad, sc, out, inn):
    """Log-likelihood and gradient of one segment into ``out`` (8,): ll, d/d[q11, q22, R, τ_nm, σ_m], k_R, k_f.

    ``dtau0_a``, ``dtau0_al``: d tau0 / d[a, α]; ``sc``: :func:`make_scratch`'s tuple; ``inn`` (K or
    0,) receives the standardized innovations. ``grad`` False leaves the gradient NaN.
    """
    (f, Sbk, S_t, L_t, tape, seed, cst, tau, dtau, dct, rr, g, dg, cs, ctail, tailS, Lr, D, y, om, q, Lbar, Dbar,
     Sbar, w, wb, cbt, cbs, gb, Lbt, XY, gbar, tailP, W, frozen) = sc
    K = u.shape[0]
    if not al < 1.0:
        # α rounds to 1 (a huge τ_nm): u -> c̃ is singular, the density 0; -inf lets a sampler reject the point
        out[0] = -np.inf
        for m in range(1, 8):
            out[m] = 0.0
        return
    # ---- planning plant and its derivatives in (q11, q22, a, α)
    Ab = np.zeros((3, 3))
    for i in range(2):
        for j in range(2):
            Ab[i, j] = A[i, j] - b[i] * fb[j]
        Ab[i, 2] = al * b[i]
    Ab[2, 2] = a
    bc = np.array([(1.0 - al) * b[0], (1.0 - al) * b[1], 1.0 - a])
    ba = np.array([b[0], b[1], 0.0])
    dAb = np.zeros((3, 3, 4))  # directions last: q11, q22, a, α
    dbc = np.zeros((3, 4))
    dAb[2, 2, 2] = 1.0
    dbc[2, 2] = -1.0
    dAb[0, 2, 3] = b[0]
    dAb[1, 2, 3] = b[1]
    dbc[0, 3] = -b[0]
    dbc[1, 3] = -b[1]
    k_R, k_z = plan_recursion(Ab, bc, ba, q11, q22, R, r, ua, K, freeze, f, S_t, L_t, cst, frozen, W, tape)
    Sc = cst[0]
    # ---- data: arm torque, effective command, residual
    tau[0] = tau0
    dtau[0, 0] = dtau0_a  # τ_0's own dependence on the lag (a warm-up over the torques before the window)
    dtau[0, 1] = dtau0_al
    arm_torque_recursion(u, a, al, tau, dtau, dct)
    om1 = 1.0 - al
    iom1 = 1.0 / om1
    for k in range(K):
        tk = tau[k]
        c = (u[k] - al * tk) * iom1
        if k <= k_R:
            rr[k] = c + cst[1] * x1[k] + cst[2] * x2[k] + cst[3] * tk - f[k]
        else:
            rr[k] = c + L_t[k, 0] * x1[k] + L_t[k, 1] * x2[k] + L_t[k, 2] * tk - f[k]
    # ---- g_j = Ā^{j-1} b_c and its (a, α) tangents; MA coefficients
    for j in range(d):
        for i in range(3):
            if j == 0:
                g[0, i] = bc[i]
                dg[0, 0, i] = dbc[i, 2]
                dg[0, 1, i] = dbc[i, 3]
            else:
                g[j, i] = Ab[i, 0] * g[j - 1, 0] + Ab[i, 1] * g[j - 1, 1] + Ab[i, 2] * g[j - 1, 2]
                for p in range(2):
                    dg[j, p, i] = (dAb[i, 0, 2 + p] * g[j - 1, 0] + dAb[i, 1, 2 + p] * g[j - 1, 1]
                                   + dAb[i, 2, 2 + p] * g[j - 1, 2] + Ab[i, 0] * dg[j - 1, p, 0]
                                   + Ab[i, 1] * dg[j - 1, p, 1] + Ab[i, 2] * dg[j - 1, p, 2])
    s2 = sig * sig
    cs[0] = 1.0
    for j in range(1, d + 1):
        cs[j] = cst[1] * g[j - 1, 0] + cst[2] * g[j - 1, 1] + cst[3] * g[j - 1, 2]
    gam = np.empty(d + 1)
    for t in range(d + 1):
        acc = 0.0
        for j in range(t, d + 1):
            acc += cs[j] * cs[j - t]
        gam[t] = s2 * acc
    if k_R >= 0:
        gam[0] += 0.5 / Sc
    # rows k_R - d + 1 .. k_R are the tail rows' partners: give them the stationary coefficients
    lo_t = max(0, k_R - d + 1)
    for i in range(lo_t, min(k_R + 1, K)):
        for j in range(d + 1):
            ctail[i, j] = cs[j]
    for i in range(k_R + 1, K):
        ctail[i, 0] = 1.0
        for j in range(1, d + 1):
            ctail[i, j] = L_t[i, 0] * g[j - 1, 0] + L_t[i, 1] * g[j - 1, 1] + L_t[i, 2] * g[j - 1, 2]
    for i in range(k_R + 1, K):
        ui = U(i)
        for t in range(min(i, d) + 1):
            up = U(i - t)
            ut = U(t)
            acc = 0.0
            for j in range(U(d + 1 - t)):
                acc += ctail[ui, ut + j] * ctail[up, j]
            tailP[ui, ut] = acc
            tailS[ui, ut] = s2 * acc
        tailS[ui, 0] += 0.5 / S_t[i]
    # ---- Gaussian log-density of the residuals and ∂/∂Σ
    ll, k_f = banded_loglik(d, gam, k_R, tailS, rr, freeze, grad, Lr[:, :d], D, y[:K + d], om[:K + d], q[:K + d],
                            Lbar[:, :d], Dbar, Sbar, w, wb, XY[:, :, :d + 1], gbar[:d + 1])
    if inn.shape[0] == K:
        for k in range(K):
            inn[k] = y[d + k] / math.sqrt(D[k])
    if not grad:
        out[0] = ll - K * math.log(om1)  # as below
        for m in range(1, 6):
            out[m] = np.nan
        out[6] = k_R
        out[7] = k_f
        return
    # ---- adjoints of the MA coefficients, of 1/(2S) and of σ_m²
    s2bar = 0.0
    for j in range(d + 1):
        cbs[j] = 0.0
        gam[j] = gbar[j]  # now ∂/∂γ_t through the Toeplitz rows
    vbar_s = gam[0]
    for t in range(d + 1):
        acc = 0.0
        for j in range(t, d + 1):
            acc += cs[j] * cs[j - t]
            cbs[j] += s2 * gam[t] * cs[j - t]
            cbs[j - t] += s2 * gam[t] * cs[j]
        s2bar += gam[t] * acc
    for i in range(lo_t, K):
        for j in range(d + 1):
            cbt[i, j] = 0.0
    for i in range(k_R + 1, K):
        ui = U(i)
        for t in range(min(i, d) + 1):
            up = U(i - t)
            ut = U(t)
            sb = Sbar[ui, ut]
            fs = s2 * sb
            n = U(d + 1 - t)
            for j in range(n):
                cbt[ui, ut + j] += fs * ctail[up, j]
            for j in range(n):
                cbt[up, j] += fs * ctail[ui, ut + j]
            s2bar += sb * tailP[ui, ut]
    for i in range(lo_t, min(k_R + 1, K)):
        for j in range(d + 1):
            cbs[j] += cbt[i, j]
    # c̄ -> L̄ (per tail row, summed over the stationary rows) and ḡ
    for j in range(d):
        for i in range(3):
            gb[j, i] = cbs[j + 1] * cst[1 + i]
    Lbs0 = Lbs1 = Lbs2 = 0.0
    for j in range(d):
        Lbs0 += cbs[j + 1] * g[j, 0]
        Lbs1 += cbs[j + 1] * g[j, 1]
        Lbs2 += cbs[j + 1] * g[j, 2]
    for i in range(k_R + 1, K):
        for m in range(3):
            Lbt[i, m] = 0.0
        for j in range(d):
            cb = cbt[i, j + 1]
            for m in range(3):
                Lbt[i, m] += cb * g[j, m]
                gb[j, m] += cb * L_t[i, m]
    # ---- the residual's path: r̄ = -ω; chain to the lag's tangents and the plan's adjoints
    G = np.zeros(4)
    if k_z > 0:  # f_k of the stationary plan: one adjoint sweep
        plan_adjoint(bc, Sc, r, ua, om[d:d + K], K, k_z, frozen, W, seed)
    hom = 0.0  # sum_k S_k ∂/∂S_k
    for k in range(K):
        o = om[d + k]
        G[2] -= o * dct[k, 0]
        G[3] -= o * dct[k, 1]
        if k <= k_R:
            Lbs0 -= o * x1[k]
            Lbs1 -= o * x2[k]
            Lbs2 -= o * tau[k]
            G[2] -= o * cst[3] * dtau[k, 0]
            G[3] -= o * cst[3] * dtau[k, 1]
        else:
            Lbt[k, 0] -= o * x1[k]
            Lbt[k, 1] -= o * x2[k]
            Lbt[k, 2] -= o * tau[k]
            G[2] -= o * L_t[k, 2] * dtau[k, 0]
            G[3] -= o * L_t[k, 2] * dtau[k, 1]
            Sk = S_t[k]
            Sb = -0.5 * Sbar[k, 0] / (Sk * Sk)
            hom += Sb * Sk
            Sbk[k] = Sb
    Scb = 0.0
    if k_R >= 0:
        Scb = -0.5 * vbar_s / (Sc * Sc)
        hom += Scb * Sc
    Lbs = np.array([Lbs0, Lbs1, Lbs2])
    # the plan in reverse: f_k, S_k, L_k of the recorded steps, and the held ones' constants
    plan_reverse(Ab, bc, ba, dAb, dbc, r, ua, K, k_z, tape, om[d:d + K], Sbk, Lbt, Scb, Lbs, seed, G)
    for j in range(d):
        for p in range(2):
            G[2 + p] += gb[j, 0] * dg[j, p, 0] + gb[j, 1] * dg[j, p, 1] + gb[j, 2] * dg[j, p, 2]
    # u -> c̃ is triangular with diagonal 1/(1 - α): log p(u) = log p(c̃) - K log(1 - α)
    out[0] = ll - K * math.log(om1)
    G[3] += K / om1
    out[1] = G[0]
    out[2] = G[1]
    out[3] = (hom - q11 * G[0] - q22 * G[1]) / R
    out[4] = G[2] * da + G[3] * dal
    out[5] = 2.0 * sig * s2bar
    out[6] = k_R
    out[7] = k_f


@njit(cache=True, fastmath=False, error_model="python")
def make_scratch(K, KM, dmax):
    """Scratch arrays for :func:`segment_kernel`: K observed steps, K + M planned, delays <= dmax."""
    dd = max(dmax, 1)
    return (np.empty(K), np.empty(K), np.empty(K), np.empty((K, 3)), np.empty((KM, TAPE)), np.zeros(SEED),
            np.zeros(4), np.empty(K + 1), np.empty((K + 1, 2)), np.empty((K, 2)), np.empty(K),
            np.empty((dd, 3)), np.empty((dd, 2, 3)), np.empty(dmax + 1), np.empty((K, dmax + 1)),
            np.empty((K, dmax + 1)), np.empty((K, dd)), np.empty(K), np.empty(K + dmax), np.empty(K + dmax),
            np.empty(K + dmax), np.empty((K, dd)), np.empty(K), np.empty((K, dmax + 1)), np.empty(dd + 1), np.empty(dd + 1),
            np.empty((K, dmax + 1)), np.empty(dmax + 1), np.empty((dd, 3)), np.empty((K, 3)),
            np.empty((K + 1, 4, dmax + 1)), np.empty(dmax + 1), np.empty((K, dmax + 1)), np.empty((KM, 3)),
            (np.empty((3, 3)), np.empty(3)))


@njit(cache=True, fastmath=False, error_model="python")
def _chunk(A, b, fb, th, lag, sig, delay, tau0, dtau0, x1, x2, r, u, ua, freeze, grad, c, nchunks, dmax, out,
           inn):
    """Segments c, c + nchunks, c + 2 nchunks, ... of a batch (:func:`batch_kernel`), with their own scratch."""
    n = u.shape[0]
    sc = make_scratch(u.shape[1], ua.shape[1], dmax)
    res = np.empty(8)
    for i in range(c, n, nchunks):
        segment_kernel(A, b, fb[i], th[0, i], th[1, i], th[2, i], lag[0, i], lag[1, i], lag[2, i], lag[3, i],
                       sig[i], delay[i], tau0[i], dtau0[i, 0], dtau0[i, 1], x1[i], x2[i], r[i], u[i], ua[i],
                       freeze, grad, sc, res, inn[i])
        for m in range(6):
            out[m, i] = res[m]


@njit(cache=True, fastmath=False, error_model="python")
def _max_delay(delay):
    dmax = 0
    for i in range(delay.shape[0]):
        dmax = max(dmax, delay[i])
    return dmax


@njit(cache=True, parallel=True, fastmath=False, error_model="python")
def batch_kernel(A, b, fb, th, lag, sig, delay, tau0, dtau0, x1, x2, r, u, ua, freeze, grad, nchunks, out, inn):
    """Every segment of a batch, each on its own, in ``nchunks`` parallel chunks (``prange``).

    C-contiguous float64 arguments (``delay`` int64): the wheel ``A``, ``b``; ``fb`` (n, 2);
    ``th`` (3, n) q11, q22, R; ``lag`` (4, n) a, α, da/dτ_nm, dα/dτ_nm; ``sig``, ``delay``, ``tau0``
    (n,), ``dtau0`` (n, 2); a :class:`scioc.models.segment.SegmentBatch`'s arrays. Out: ``out`` (6, n),
    the log-likelihood and the gradient in q11, q22, R, τ_nm, σ_m (NaN unless ``grad``); ``inn``
    (n, K) the standardized innovations, or (n, 0) to skip them.
    """
    dmax = _max_delay(delay)
    for c in prange(nchunks):
        _chunk(A, b, fb, th, lag, sig, delay, tau0, dtau0, x1, x2, r, u, ua, freeze, grad, c, nchunks, dmax, out,
               inn)


@njit(cache=True, fastmath=False, error_model="python")
def batch_kernel_serial(A, b, fb, th, lag, sig, delay, tau0, dtau0, x1, x2, r, u, ua, freeze, grad, nchunks, out, inn):
    """:func:`batch_kernel` in the calling thread, for a batch too small to pay for a parallel region.

    A separate function, not a second dispatcher of one: numba's cache keys a function by file,
    name and first line (docs/decisions/delayed-kernel.md).
    """
    dmax = _max_delay(delay)
    for c in range(nchunks):
        _chunk(A, b, fb, th, lag, sig, delay, tau0, dtau0, x1, x2, r, u, ua, freeze, grad, c, nchunks, dmax, out,
               inn)


__all__ = ["batch_kernel", "batch_kernel_serial", "make_scratch", "segment_kernel"]
