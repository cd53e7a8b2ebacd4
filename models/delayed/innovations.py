"""Exact Gaussian log-density of a residual sequence with banded covariance, and its reverse mode (numba).

The residuals r of :mod:`.likelihood` have a covariance Σ of bandwidth d, factored
``Σ = L D Lᵀ`` (L unit lower triangular); ``y = L⁻¹ r`` are the innovations of the Kalman
filter over the motor noises, D their variances, and
``log N(r; 0, Σ) = -½ sum_k (y_k² / D_k + log D_k) - K/2 log 2π``.

* Rows 0..k_R (the plan stationary, Σ Toeplitz): the Schur algorithm by columns, O(d) each.
  The displacement ``Σ - Z Σ Zᵀ = x xᵀ - y yᵀ`` has rank 2; column k is
  ``L_{k+t,k} = x_t / x_0``, ``D_k = x_0²``, and a hyperbolic rotation zeroing y's leading entry
  gives the next generator (:mod:`.schur`). y decays and moves x only at second order, so
  once d + 1 columns agree to :data:`scioc.models.maxent.FREEZE_RTOL` and |y| <= Y_RTOL |x|
  (column k_f) the later columns are held; their solves carry the neighbouring row's term in a
  register, one multiplication and one subtraction per step on the dependency chain.
* Later rows: L D Lᵀ row by row from the d rows before, O(d²) each.

Reverse mode, with ``ω = Σ⁻¹ r``: ``∂/∂r = -ω``, ``∂/∂L_ij = ω_i y_j``,
``∂/∂D_i = ½ (y_i² / D_i - 1) / D_i``, back through the later rows (∂/∂Σ) and the Schur steps
to the first generator ``x = y = γ / sqrt(γ_0)`` (∂/∂γ); the held columns add their adjoints
to the steady column's, so the gradient is that of the held computation.
"""

from __future__ import annotations

import math

from scioc.models.delayed.schur import U, schur_step, schur_step_adjoint
from scioc.models.maxent import FREEZE_RTOL, HALF_LOG_2PI, PROD_HUGE, PROD_TINY
from scioc.models.runtime import FASTMATH, njit

#: The Schur columns are stationary once d + 1 consecutive steps change x by at most FREEZE_RTOL
#: relative and y, which drives every later change of x, is below this fraction of x.
Y_RTOL = 1e-7

@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def banded_loglik(d, gam, k_R, tailS, r, freeze, grad, Lr, D, yb_, ob_, q, Lbar, Dbar, Sbar, w, wb, XY, gbar):
    """Return (log N(r; 0, Σ), k_f) and fill ω = Σ⁻¹ r, ∂/∂γ (Toeplitz rows) and ∂/∂Σ (later rows).

    Σ has bandwidth ``d``: ``gam`` (d + 1,) holds ``Σ_{i, i-t}`` of the rows i <= ``k_R`` (-1: none),
    ``tailS`` (K, d + 1) that of the later rows. ``r`` (K,). ``grad`` False stops after the
    log-density. Out: ``D`` (K,), y in ``yb_[d:K + d]``, ω in ``ob_[d:K + d]`` (padded with d leading
    zeros), ∂/∂Σ_{i, i-t} of the later rows in ``Sbar``, ∂/∂γ_t in ``gbar``. Scratch: ``Lr``,
    ``Lbar`` (K, >= d; ``Lr[i, s] = L_{i, i-d+s}``), ``Dbar``, ``q``, ``w``, ``wb``, ``XY`` (the Schur
    generators and their adjoints). k_f is the first steady column (min(k_R + 1, K) if none).
    """
    K = r.shape[0]
    ud = U(d)
    nA = min(k_R + 1, K)
    k_f = nA  # first column whose generator is the steady one
    count = 0
    lo_r = max(0, nA - d)  # Toeplitz rows written out as rows for the rows after k_R
    for i in range(lo_r, min(lo_r + d, K)):  # the padding before column 0
        for s in range(U(max(0, d - i))):
            Lr[i, s] = 0.0
    for i in range(K + d):
        q[i] = 0.0
    for s in range(ud):
        yb_[s] = 0.0
        ob_[s] = 0.0
        w[s] = 0.0
    quad = 0.0
    logs = 0.0
    prod = 1.0
    # ---- Toeplitz rows 0..nA-1: the Schur algorithm by columns, and y = L⁻¹ r by columns
    if nA > 0:
        sc = 1.0 / math.sqrt(gam[0])
        for j in range(ud + U(1)):
            XY[0, 0, j] = gam[j] * sc
            XY[0, 1, j] = gam[j] * sc
        XY[0, 1, 0] = 0.0
        k = 0
        while k < nA:  # the columns up to the first steady one
            kx = U(min(k, k_f))
            x0 = XY[kx, 0, 0]
            ix0 = 1.0 / x0  # off the recursion's critical path, as the rest but y_k and the update
            Dk = x0 * x0
            D[k] = Dk
            yk = r[k] - q[k + d]
            yb_[k + d] = yk
            f = yk * ix0
            quad += f * f
            if k <= k_f:
                prod *= Dk
                # one log per 16 columns, or sooner before the product over- or underflows
                if k % 16 == 15 or not (PROD_TINY < prod < PROD_HUGE):
                    logs += math.log(prod)
                    prod = 1.0
            uk = U(k + d)
            for t in range(U(1), U(min(d, nA - 1 - k) + 1)):
                q[uk + t] += XY[kx, 0, t] * f
            if k + 1 < nA and k < k_f:
                schur_step(XY, k, d)
                if freeze:
                    a = U(k)
                    b = U(k + 1)
                    num = 0.0
                    den = 0.0
                    ny = 0.0
                    for j in range(ud + U(1)):
                        num += abs(XY[b, 0, j] - XY[a, 0, j])
                        den += abs(XY[b, 0, j])
                        ny += abs(XY[b, 1, j])
                    count = count + 1 if num <= FREEZE_RTOL * den else 0
                    if count > d and ny <= Y_RTOL * den:
                        k_f = k + 1
            k += 1
            if k > k_f:
                break
        if k < nA:
            # the held columns share x: l_t = x_t / x_0 in w; l_1 y_{k-1} is carried in a register (module docstring)
            ix0 = 1.0 / XY[k_f, 0, 0]
            Dk = D[k_f]
            for t in range(ud + U(1)):
                w[t] = XY[k_f, 0, t] * ix0
            l1 = w[1] if d > 0 else 0.0
            carry = 0.0
            for k in range(k, nA):
                yk = r[k] - q[k + d] - carry
                D[k] = Dk
                yb_[k + d] = yk
                quad += yk * yk / Dk
                carry = l1 * yk
                uk = U(k + d)
                for t in range(U(2), U(min(d, nA - 1 - k) + 1)):
                    q[uk + t] += w[t] * yk
            for s in range(ud):
                w[s] = 0.0
        logs += math.log(prod)
        if k_f < nA - 1:
            logs += (nA - 1 - k_f) * math.log(D[k_f])
        # the last d Toeplitz rows as rows: L_{i, i-d+s} = column (i-d+s)'s entry d - s
        for i in range(lo_r, nA):
            for s in range(max(0, d - i), d):
                c = min(i - d + s, k_f)
                Lr[i, s] = XY[c, 0, d - s] / XY[c, 0, 0]
    # ---- rows after k_R: L D Lᵀ row by row (Lr[i, s] = L_{i, j}, j = i - d + s), and y
    for i in range(nA, K):
        ui = U(i)
        s0 = max(0, d - i)
        for s in range(s0, d):
            rj = U(i - d + s)
            o = U(d - s)
            acc = tailS[ui, o]
            for u in range(U(s)):
                acc -= w[u] * Lr[rj, o + u]
            w[s] = acc
            Lr[ui, s] = acc / D[rj]
        acc = tailS[ui, 0]
        for s in range(ud):
            acc -= w[s] * Lr[ui, s]
        D[i] = acc
        acc = r[i]
        for s in range(ud):
            acc -= Lr[ui, s] * yb_[ui + s]
        yb_[i + d] = acc
        quad += acc * acc / D[i]
        logs += math.log(D[i])
    ll = -0.5 * quad - 0.5 * logs - K * HALF_LOG_2PI
    if not grad:
        return ll, k_f
    # ---- ω = L⁻ᵀ D⁻¹ y: rows after k_R by rows, then the Toeplitz rows by columns
    for i in range(K + d):
        q[i] = 0.0
    for i in range(K - 1, nA - 1, -1):
        ui = U(i)
        o = yb_[i + d] / D[i] - q[i + d]
        ob_[i + d] = o
        for s in range(ud):
            q[ui + s] += Lr[ui, s] * o
    hi = min(nA, k_f + d)  # rows hi.. are the steady row: by rows (a short recursion) ...
    if hi < nA:
        for s in range(d):
            w[s] = XY[k_f, 0, d - s] / XY[k_f, 0, 0]
        iD = 1.0 / D[k_f]
        wl = w[d - 1] if d > 0 else 0.0
        carry = 0.0  # as in the forward recursion: the nearest term in a register, not through q
        for i in range(nA - 1, hi - 1, -1):
            ui = U(i)
            o = yb_[i + d] * iD - q[i + d] - carry
            ob_[i + d] = o
            carry = wl * o
            for s in range(U(max(d - 1, 0))):
                q[ui + s] += w[s] * o
        if hi > 0:
            q[hi - 1 + d] += carry
        for s in range(d):
            w[s] = 0.0
    for k in range(hi - 1, -1, -1):  # ... the columns before by columns
        kx = U(min(k, k_f))
        uk = U(k + d)
        head = yb_[k + d] / D[k] - q[k + d]  # off the recursion's critical path
        ix0 = 1.0 / XY[kx, 0, 0]
        acc = 0.0
        for t in range(U(1), U(min(d, hi - 1 - k) + 1)):
            acc += XY[kx, 0, t] * ob_[uk + t]
        ob_[k + d] = head - acc * ix0
    # ---- reverse: rows after k_R through their recursion (they add to the d rows before them)
    for i in range(lo_r, K):
        for s in range(ud):
            Lbar[i, s] = 0.0
        Dbar[i] = 0.0
    for i in range(K - 1, nA - 1, -1):
        ui = U(i)
        o = ob_[i + d]
        for s in range(ud):
            Lbar[ui, s] += o * yb_[ui + s]
        Dr = D[i]
        yi = yb_[i + d]
        db = Dbar[i] + 0.5 * (yi * yi / Dr - 1.0) / Dr
        Sbar[ui, 0] = db
        s0 = max(0, d - i)
        for s in range(s0, d):
            rj = i - d + s
            lt = Lr[ui, s]
            Dj = D[rj]
            lb = Lbar[ui, s]
            w[s] = lt * Dj
            wb[s] = lb / Dj - 2.0 * lt * db
            Dbar[rj] += lt * lt * db - lb * lt / Dj
        for s in range(d - 1, s0 - 1, -1):
            rj = U(i - d + s)
            o = U(d - s)
            g = wb[s]
            Sbar[ui, o] = g
            for u in range(U(s)):
                wb[u] -= g * Lr[rj, o + u]
            for u in range(U(s)):
                Lbar[rj, o + u] -= g * w[u]
    # ---- reverse: the Toeplitz columns, then the Schur steps back to the first generator
    for j in range(d + 1):
        gbar[j] = 0.0
    if nA > 0:
        last = min(nA - 1, k_f)
        for j in range(ud + U(1)):
            XY[last, 2, j] = 0.0
            XY[last, 3, j] = 0.0
        top = nA - 1
        if k_f < nA:  # the held columns k_f .. nA - 1 share one x: their adjoints add up
            uf = U(k_f)
            x0 = XY[uf, 0, 0]
            ix0 = 1.0 / x0
            iD = 1.0 / D[k_f]
            yy = 0.0
            for m in range(U(k_f + d), U(nA + d)):
                yy += yb_[m] * yb_[m]
            db = 0.5 * (yy * iD - (nA - k_f)) * iD
            for k in range(max(lo_r, k_f), nA):
                db += Dbar[k]
            a = U(k_f + d)
            for t in range(U(1), U(min(d, nA - 1 - k_f) + 1)):  # ∂/∂L_{k+t,k} = ω_{k+t} y_k, summed
                acc = 0.0
                for m in range(U(nA - k_f) - t):
                    acc += ob_[a + t + m] * yb_[a + m]
                XY[uf, 2, t] += acc * ix0
            for i in range(max(lo_r, k_f + 1), nA):  # what the rows after k_R added to these rows
                for t in range(1, min(d, i - k_f) + 1):
                    XY[uf, 2, t] += Lbar[i, d - t] * ix0
            acc = 2.0 * x0 * db
            for t in range(1, d + 1):
                acc -= XY[uf, 2, t] * XY[uf, 0, t] * ix0
            XY[uf, 2, 0] += acc
            if k_f > 0:
                schur_step_adjoint(XY, k_f, d)
            top = k_f - 1
        for k in range(top, -1, -1):
            # column k: L_{k+t,k} = x_t / x_0 (rows k + t < nA), D_k = x_0²
            kx = U(k)
            uk = U(k + d)
            x0 = XY[kx, 0, 0]
            ix0 = 1.0 / x0
            yk = yb_[k + d]
            Dk = D[k]
            db = 0.5 * (yk * yk / Dk - 1.0) / Dk
            if k >= lo_r:
                db += Dbar[k]
            acc = 2.0 * x0 * db
            f = yk * ix0
            tmax = min(d, nA - 1 - k)
            for t in range(U(1), U(tmax + 1)):  # ∂/∂L_{k+t,k} = ω_{k+t} y_k
                lb = ob_[uk + t] * f
                XY[kx, 2, t] += lb
                acc -= lb * XY[kx, 0, t] * ix0
            if k + tmax >= lo_r:  # rows written out as rows: what the rows after k_R added
                for t in range(max(1, lo_r - k), tmax + 1):
                    lb = Lbar[k + t, d - t] * ix0
                    XY[kx, 2, t] += lb
                    acc -= lb * XY[kx, 0, t] * ix0
            XY[kx, 2, 0] += acc
            if k > 0:
                schur_step_adjoint(XY, k, d)
        sc = 1.0 / math.sqrt(gam[0])
        acc = 0.0
        for j in range(d + 1):
            g = XY[0, 2, j] + (XY[0, 3, j] if j > 0 else 0.0)
            gbar[j] = g * sc
            acc += g * gam[j]
        gbar[0] -= 0.5 * sc * sc * sc * acc
    return ll, k_f


__all__ = ["U", "banded_loglik"]
