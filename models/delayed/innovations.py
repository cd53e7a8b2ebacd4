"""Exact Gaussian log-density of a residual sequence with banded covariance, and its reverse mode (numba).

The residuals r of the ``delayed`` model (:mod:`models.delayed.likelihood`) are Gaussian
with a covariance Σ of bandwidth d. Its factorization ``Σ = L D Lᵀ`` (L unit lower
triangular, bandwidth d) gives the innovations ``y = L⁻¹ r`` with variances D:
these are exactly the innovations and innovation variances of the Kalman filter over
the motor noises (m_k, ..., m_{k-d}) (the factorization is unique), computed in
d²/2 operations per row instead of the filter's (d+1)² and without its state::

    log N(r; 0, Σ) = -½ sum_k y_k² / D_k - ½ sum_k log D_k - K/2 log 2π.

Σ is Toeplitz up to row k_R (the policy is stationary there) and arbitrary after it
(the plan's last steps). Row i of L follows from the d rows before it, so once d
consecutive rows agree to :data:`models.maxent.FREEZE_RTOL` (the filter's steady state)
every later Toeplitz row is the same row: it is stored once (row i_f) and rows
i_f + 1 .. k_R are aliases of it. Only the rows before the steady state and after k_R
cost O(d²); the others cost O(d) (the two triangular solves and the reverse pass).

Reverse mode. With ``ω = Σ⁻¹ r = L⁻ᵀ D⁻¹ y``::

    ∂/∂r = -ω,   ∂/∂L_ij = ω_i y_j,   ∂/∂D_i = ½ (y_i² / D_i - 1) / D_i,

and the adjoint of the row recursion maps these to ∂/∂Σ_ij, row by row backward. An
alias row has no Σ of its own: its adjoint adds to row i_f's, so the result is the exact
derivative of the computation with the steady state held (equal to the derivative
without it to about the steady state's tolerance times the transient's length; tested).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from models.maxent import FREEZE_RTOL, HALF_LOG_2PI


@njit(cache=True, inline="always")
def _row(j, i_f, i_e):
    """Where row j of L is stored: aliases of the steady-state row map to it."""
    if i_f < j <= i_e:
        return i_f
    return j


@njit(cache=True, inline="always")
def _sigma(i, t, k_R, gam, tailS):
    if i <= k_R:
        return gam[t]
    return tailS[i, t]


@njit(cache=True, fastmath={"contract", "reassoc"}, error_model="numpy")
def _schur_step(x, y, xn, yn):
    """One step of the Schur algorithm: the generator of the next Schur complement (returns ρ)."""
    d = x.shape[0] - 1
    rho = y[1] / x[0] if d > 0 else 0.0
    c = math.sqrt(1.0 - rho * rho)
    ic = 1.0 / c
    for j in range(d):
        xn[j] = (x[j] - rho * y[j + 1]) * ic
    xn[d] = x[d] * ic
    yn[0] = 0.0
    for j in range(1, d):
        yn[j] = c * y[j + 1] - rho * xn[j]
    if d > 0:
        yn[d] = -rho * xn[d]
    return rho


@njit(cache=True, fastmath={"contract", "reassoc"}, error_model="numpy")
def _schur_step_adjoint(x, y, xn, yn, xbn, ybn, xb, yb):
    """Reverse of :func:`_schur_step`: from the adjoints (xbn, ybn) of (xn, yn) to (xb, yb) (overwritten)."""
    d = x.shape[0] - 1
    if d == 0:
        xb[0] = xbn[0]
        yb[0] = 0.0
        return
    rho = y[1] / x[0]
    c = math.sqrt(1.0 - rho * rho)
    ic = 1.0 / c
    cb = 0.0
    rb = 0.0
    # y'_j = c ỹ_j - ρ x'_j (j >= 1; y'_0 = 0 is a constant), ỹ_j = y_{j+1}, ỹ_d = 0
    for j in range(d + 1):
        xb[j] = 0.0
        yb[j] = 0.0
    for j in range(1, d + 1):
        g = ybn[j]
        yt = y[j + 1] if j < d else 0.0
        cb += g * yt
        rb -= g * xn[j]
        if j < d:
            yb[j + 1] += c * g
    # x'_j = (x_j - ρ ỹ_j) / c
    for j in range(d + 1):
        g = xbn[j] - rho * (ybn[j] if j > 0 else 0.0)
        yt = y[j + 1] if j < d else 0.0
        xb[j] += g * ic
        if j < d:
            yb[j + 1] -= rho * g * ic
        rb -= g * yt * ic
        cb -= g * xn[j] * ic
    rb -= cb * rho * ic  # c = sqrt(1 - ρ²)
    yb[1] += rb / x[0]  # ρ = y_1 / x_0
    xb[0] -= rb * rho / x[0]


@njit(cache=True, fastmath={"contract", "reassoc"}, error_model="numpy")
def banded_loglik(d, gam, k_R, tailS, r, freeze, Lr, D, y, om, q, Lbar, Dbar, Sbar, w, wb, XY, gbar):
    """log N(r; 0, Σ), ω = Σ⁻¹ r and ∂/∂Σ (band), for Σ of bandwidth d.

    Parameters
    ----------
    d : int
        Bandwidth (the delay in samples).
    gam : ndarray, shape (d + 1,)
        ``Σ_{i, i-t}`` for rows i <= k_R (Toeplitz).
    k_R : int
        Last Toeplitz row (-1: none).
    tailS : ndarray, shape (K, d + 1)
        ``Σ_{i, i-t}`` for rows i > k_R (only those rows are read).
    r : ndarray, shape (K,)
    freeze : bool
        Hold the factorization once stationary (module docstring).
    Lr, D, y, om, q, Lbar, Dbar, w, wb : ndarray
        Scratch of shapes (K, dd), (K,), (K,), (K,), (K,), (K, dd), (K,), (dd + 1,),
        (dd + 1,) with dd = max(d, 1); ``om`` holds ω on return.
    Sbar : ndarray, shape (K, d + 1)
        Out: ``∂ log N / ∂Σ_{i, i-t}`` for the rows i > k_R (Σ_{i, i-t} = Σ_{i-t, i} is
        one number).
    XY : ndarray, shape (K + 1, 4, d + 1)
        Scratch: the Schur generators, and their adjoints.
    gbar : ndarray, shape (d + 1,)
        Out: ``∂ log N / ∂γ_t`` through the Toeplitz rows.

    Returns
    -------
    (float, int, int)
        The log-density and the alias range (i_f, i_e]; i_f = i_e = -1 without aliases.
    """
    K = r.shape[0]
    nA = min(k_R + 1, K)
    i_f = -1
    i_e = -1
    k_f = nA  # first step whose generator is the steady one
    # ---- phase A: Toeplitz rows 0..nA-1 by the Schur algorithm on the generators
    if nA > 0:
        s = 1.0 / math.sqrt(gam[0])
        for j in range(d + 1):
            XY[0, 0, j] = gam[j] * s
            XY[0, 1, j] = gam[j] * s
        XY[0, 1, 0] = 0.0
        for k in range(nA):
            src = min(k, k_f)
            x = XY[src, 0]
            x0 = x[0]
            D[k] = x0 * x0
            for t in range(1, min(d, nA - 1 - k) + 1):
                Lr[k + t, t - 1] = x[t] / x0
            if k_f < nA and k >= k_f + d:
                break  # all later rows are the steady row
            if k + 1 < nA and k < k_f:
                _schur_step(XY[k, 0], XY[k, 1], XY[k + 1, 0], XY[k + 1, 1])
                if freeze:
                    num = 0.0
                    den = 0.0
                    for j in range(d + 1):
                        num += abs(XY[k + 1, 0, j] - XY[k, 0, j]) + abs(XY[k + 1, 1, j] - XY[k, 1, j])
                        den += abs(XY[k + 1, 0, j]) + abs(XY[k + 1, 1, j])
                    if num <= FREEZE_RTOL * den:
                        k_f = k + 1
        if k_f + d < nA - 1:
            i_f = k_f + d
            i_e = nA - 1
    # ---- phase B: rows after k_R, L D Lᵀ row by row
    for i in range(nA, K):
        nt = min(i, d)
        for t in range(nt, 0, -1):
            rj = _row(i - t, i_f, i_e)
            acc = tailS[i, t]
            for s in range(t + 1, nt + 1):
                acc -= w[s] * Lr[rj, s - t - 1]
            w[t] = acc
            Lr[i, t - 1] = acc / D[rj]
        acc = tailS[i, 0]
        for t in range(1, nt + 1):
            acc -= w[t] * Lr[i, t - 1]
        D[i] = acc
    for i in range(K):
        if not (i_f < i <= i_e):
            for t in range(min(i, d)):
                Lbar[i, t] = 0.0
            Dbar[i] = 0.0
    # ---- innovations y = L⁻¹ r, log-density
    quad = 0.0
    logs = 0.0
    for i in range(K):
        ri = _row(i, i_f, i_e)
        nt = min(i, d)
        acc = r[i]
        for t in range(1, nt + 1):
            acc -= Lr[ri, t - 1] * y[i - t]
        y[i] = acc
        quad += acc * acc / D[ri]
        if ri == i:
            logs += math.log(D[i])
    if i_f >= 0:
        logs += (i_e - i_f) * math.log(D[i_f])
    ll = -0.5 * quad - 0.5 * logs - K * HALF_LOG_2PI
    # ---- ω = L⁻ᵀ D⁻¹ y (q accumulates the subtracted terms)
    for i in range(K):
        q[i] = 0.0
    for i in range(K - 1, -1, -1):
        ri = _row(i, i_f, i_e)
        o = y[i] / D[ri] - q[i]
        om[i] = o
        for t in range(1, min(i, d) + 1):
            q[i - t] += Lr[ri, t - 1] * o
    # ---- reverse pass: rows (phase B rows through their recursion)
    for i in range(K - 1, -1, -1):
        ri = _row(i, i_f, i_e)
        nt = min(i, d)
        o = om[i]
        for t in range(1, nt + 1):
            Lbar[ri, t - 1] += o * y[i - t]
        Dr = D[ri]
        Dbar[ri] += 0.5 * (y[i] * y[i] / Dr - 1.0) / Dr
        if i < nA:
            continue
        db = Dbar[i]
        Sbar[i, 0] = db
        for t in range(1, nt + 1):
            rj = _row(i - t, i_f, i_e)
            lt = Lr[i, t - 1]
            Dj = D[rj]
            w[t] = lt * Dj
            wb[t] = Lbar[i, t - 1] / Dj - 2.0 * lt * db
            Dbar[rj] += lt * lt * db - Lbar[i, t - 1] * lt / Dj
        for t in range(1, nt + 1):
            rj = _row(i - t, i_f, i_e)
            g = wb[t]
            Sbar[i, t] = g
            for s in range(t + 1, nt + 1):
                wb[s] -= g * Lr[rj, s - t - 1]
                Lbar[rj, s - t - 1] -= g * w[s]
    # ---- reverse pass: phase A columns, then the Schur steps back to the initial generator
    for j in range(d + 1):
        gbar[j] = 0.0
    if nA > 0:
        last = min(nA - 1, k_f)
        for j in range(d + 1):
            XY[last, 2, j] = 0.0
            XY[last, 3, j] = 0.0
        top = min(nA - 1, i_f) if i_f >= 0 else nA - 1
        for k in range(top, -1, -1):
            # column k's entries: L_{k+t,k} = x_t / x_0 (rows k + t <= top), D_k = x_0²
            kk = min(k, k_f)
            x = XY[kk, 0]
            x0 = x[0]
            xb = XY[kk, 2]
            acc = 2.0 * x0 * Dbar[k]
            for t in range(1, min(d, top - k) + 1):
                lb = Lbar[k + t, t - 1]
                xb[t] += lb / x0
                acc -= lb * x[t] / (x0 * x0)
            xb[0] += acc
            if 0 < k <= k_f:
                _schur_step_adjoint(XY[k - 1, 0], XY[k - 1, 1], XY[k, 0], XY[k, 1], XY[k, 2], XY[k, 3],
                                    XY[k - 1, 2], XY[k - 1, 3])
        s = 1.0 / math.sqrt(gam[0])
        acc = 0.0
        for j in range(d + 1):
            g = XY[0, 2, j] + (XY[0, 3, j] if j > 0 else 0.0)
            gbar[j] += g * s
            acc += g * gam[j]
        gbar[0] -= 0.5 * s * s * s * acc
    return ll, i_f, i_e


__all__ = ["banded_loglik"]
