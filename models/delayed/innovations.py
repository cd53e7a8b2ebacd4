"""Exact Gaussian log-density of a residual sequence with banded covariance, and its reverse mode (numba).

The residuals r of the ``delayed`` model (:mod:`scioc.models.delayed.likelihood`) are Gaussian
with a covariance Σ of bandwidth d. Its factorization ``Σ = L D Lᵀ`` (L unit lower
triangular, bandwidth d) gives the innovations ``y = L⁻¹ r`` with variances D: these
are exactly the innovations and innovation variances of the Kalman filter over the
motor noises (m_k, ..., m_{k-d}) (the factorization is unique)::

    log N(r; 0, Σ) = -½ sum_k y_k² / D_k - ½ sum_k log D_k - K/2 log 2π.

Rows 0..k_R of Σ are Toeplitz (the plan is stationary there), the rows after k_R are
not (the plan's last steps).

* Toeplitz rows: the Schur algorithm, by columns. The displacement
  ``Σ - Z Σ Zᵀ = x xᵀ - y yᵀ`` (Z the shift) has rank 2; step k reads the Cholesky
  column x (``L_{k+t,k} = x_t / x_0``, ``D_k = x_0²``) and passes to the generator of
  the next Schur complement by a hyperbolic rotation that zeroes y's leading entry (in
  mixed form): O(d) per column instead of the d²/2 of a row of Cholesky (it is the
  Chandrasekhar form of the Kalman filter). The generator is all the state there is. Its
  y part decays (the reflection coefficients ρ = y_1 / x_0 of a moving average go to
  zero) and changes x only at second order (``x' - x = O(ρ²) x + O(ρ) y``), so once
  d + 1 consecutive columns agree to :data:`scioc.models.maxent.FREEZE_RTOL` and
  ``|y| <= Y_RTOL |x|`` (the filter's steady state, at step k_f) every later column is
  the same to rounding and is not computed again. The solves run by columns there; in both
  solves (y = L⁻¹ r forward, ω backward) the term of the neighbouring row is carried in a
  register rather than added into the accumulator q and read back, so that each step's
  dependence on the last is one multiplication and one subtraction (the rest of the row is
  not on that path). ``scioc bench --parts delayed``, run twice before (642b0ad) and twice
  after, alternating, 2026-12-06 (one thread, min): delay 10, 7.82 and 8.01 ms before, 7.60
  and 7.60 after; delay 30, 17.05 and 17.03, 16.37 and 16.97; delay 0 unchanged.
* Rows after k_R: L D Lᵀ row by row, O(d²) each, from the d rows before (the last
  Toeplitz rows are written out as rows for them).

Reverse mode. With ``ω = Σ⁻¹ r = L⁻ᵀ D⁻¹ y``::

    ∂/∂r = -ω,   ∂/∂L_ij = ω_i y_j,   ∂/∂D_i = ½ (y_i² / D_i - 1) / D_i;

the rows after k_R are reversed row by row (giving ∂/∂Σ for their entries), the
Toeplitz columns one by one and through the Schur steps back to the first generator,
``x = y = γ / sqrt(γ_0)`` (giving ∂/∂γ_t). The held columns add their adjoints to the
steady column's, so the gradient is the exact derivative of the computation with the
steady state held (equal to the one without it to about the tolerance times the
transient's length; tested).

Storage: row i of L (rows after k_R and the d before) is ``Lr[i, s] = L_{i, i-d+s}``,
s = 0..d-1 (zero before column 0); y, ω and the solves' accumulators are padded with d
leading zeros (row i at i + d), so every inner loop runs over contiguous memory. Inner
loops index with unsigned integers (``U``) and never slice: numba then needs neither
wraparound checks nor reference counts there, and LLVM vectorizes them.
"""

from __future__ import annotations

import math

from scioc.models.delayed.schur import U, schur_step, schur_step_adjoint
from scioc.models.maxent import FREEZE_RTOL, HALF_LOG_2PI, PROD_HUGE, PROD_TINY
from scioc.models.runtime import FASTMATH, njit

#: The Schur columns count as stationary once d + 1 consecutive steps change x by at most
#: FREEZE_RTOL relative and y (which drives every later change of x, to second order) is below
#: this fraction of x.
Y_RTOL = 1e-7

@njit(cache=True, fastmath=FASTMATH, error_model="numpy")
def banded_loglik(d, gam, k_R, tailS, r, freeze, grad, Lr, D, yb_, ob_, q, Lbar, Dbar, Sbar, w, wb, XY, gbar):
    """log N(r; 0, Σ), ω = Σ⁻¹ r, ∂/∂γ (Toeplitz rows) and ∂/∂Σ (the other rows), Σ of bandwidth d.

    Parameters
    ----------
    d : int
        Bandwidth (the delay in samples).
    gam : ndarray, shape (d + 1,)
        ``γ_t = Σ_{i, i-t}`` of the rows i <= k_R.
    k_R : int
        Last Toeplitz row (-1: none).
    tailS : ndarray, shape (K, d + 1)
        ``Σ_{i, i-t}`` for the rows i > k_R (only those rows are read).
    r : ndarray, shape (K,)
    freeze : bool
        Hold the factorization once stationary (module docstring).
    grad : bool
        False: stop after the log-density (y and D are written; ω, Sbar and gbar are not).
    Lr, D, Lbar, Dbar : ndarray, shapes (K, >= d), (K,), (K, >= d), (K,)
        Scratch: rows of L (module docstring), D (returned: every row's), and adjoints.
    yb_, ob_, q : ndarray, shape (>= K + d,)
        Scratch, padded: the innovations y (returned: ``yb_[d:K + d]``), ω (returned:
        ``ob_[d:K + d]``), the solves' accumulator.
    Sbar : ndarray, shape (K, >= d + 1)
        Out: ``∂ log N / ∂Σ_{i, i-t}`` for the rows i > k_R (Σ_{i, i-t} = Σ_{i-t, i} is one number).
    w, wb : ndarray, shape (>= d + 1,)
        Scratch.
    XY : ndarray, shape (K + 1, 4, >= d + 1)
        Scratch: the Schur generators and their adjoints.
    gbar : ndarray, shape (>= d + 1,)
        Out: ``∂ log N / ∂γ_t``, t = 0..d.

    Returns
    -------
    (float, int)
        The log-density and k_f, the first column of the steady state (nA = min(k_R + 1, K)
        if the columns never became steady).
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
            # the columns after the first steady one share its x: l_t = x_t / x_0 in w; the term of the column just
            # before (l_1 y_{k-1}) is carried in a register, not through q, so that the recursion's path from y_{k-1}
            # to y_k is one multiply and one subtraction (module docstring)
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
