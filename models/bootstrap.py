"""Parametric bootstrap through the acquisition chain: data sets drawn from a fitted max-ent model.

The recorded segment and B replicates pass the same chain: assistant in closed loop, encoder, fixed
reconstruction (or exact measurement), residual pass. Why its shortcuts keep the null honest:
docs/decisions/maxent-adequacy-bootstrap.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.reconstruct import apply_reconstruction
from scioc.models.runtime import njit


class Records(NamedTuple):
    """What the statistics see of B + 1 data sets of one segment (row 0: the recorded one).

    ``angle`` (n, K + 1), the encoder angle, and ``error`` (n, K + 1), the tracking error of the angle the
    likelihood uses, rad; ``torque`` (n, K), the u_H it uses, N·m; ``z`` (n, K), standardized residuals.
    """

    angle: np.ndarray
    error: np.ndarray
    torque: np.ndarray
    z: np.ndarray


class Chain(NamedTuple):
    """A fitted segment over a span of n samples (window ``w0 .. w0 + K``) and how its data were acquired.

    The plan's feedback ``gain`` and ``known`` input; the fitted policy ``L``, ``f``, ``S`` from ``x0``; the
    recorded span (velocity, u_H used without reconstruction only); ``recon``, a ``FixedReconstruction``'s
    arrays or None; the replicates' policy noise ``noise_scale / √(2 S_k)``.
    """

    A: np.ndarray
    b: np.ndarray
    gain: np.ndarray
    known: np.ndarray
    L: np.ndarray
    f: np.ndarray
    S: np.ndarray
    x0: np.ndarray
    angle: np.ndarray
    velocity: np.ndarray
    u_H: np.ndarray
    u_A: np.ndarray
    ref: np.ndarray
    w0: int
    K: int
    recon: tuple | None
    resolution: float
    noise_scale: float = 1.0



@njit(cache=True, fastmath=False, error_model="python")
def measure_span(A, b, y, vel, uh, a, ref, recon_on, F, Kg, Sv, C, w0, K, angle_out, err_out, u_out):
    """One data set of a span through the acquisition chain; writes the window into the out rows.

    With ``recon_on`` the encoder angle ``y`` passes the fixed reconstruction, else ``y``, ``vel``, ``uh``
    are measured. Returns ``(angle, velocity, u_H)`` over the span, where a residual pass starts.
    """
    if recon_on:
        ang, v, u = apply_reconstruction(F, b, A, Kg, Sv, C, y, a)
    else:
        ang = y
        v = vel
        u = uh
    for k in range(K + 1):
        angle_out[k] = y[w0 + k]
        err_out[k] = ang[w0 + k] - ref[w0 + k]
    for k in range(K):
        u_out[k] = u[w0 + k]
    return ang, v, u


@njit(cache=True, fastmath=False, error_model="python")
def _measure(A, b, y, vel, uh, a, ref, recon_on, F, Kg, Sv, C, w0, K, L, f, S, angle_out, err_out, u_out, z_out):
    """One data set through the acquisition chain and the max-ent residual pass (writes the out rows)."""
    ang, v, u = measure_span(A, b, y, vel, uh, a, ref, recon_on, F, Kg, Sv, C, w0, K, angle_out, err_out, u_out)
    x1 = ang[w0]
    x2 = v[w0]
    for k in range(K):
        j = w0 + k
        uk = u[j]
        dev = uk + L[j, 0] * x1 + L[j, 1] * x2 - f[j]
        z_out[k] = dev * np.sqrt(2.0 * S[j])
        tot = uk + a[j]
        n1 = A[0, 0] * x1 + A[0, 1] * x2 + b[0] * tot
        x2 = A[1, 0] * x1 + A[1, 1] * x2 + b[1] * tot
        x1 = n1


@njit(cache=True, fastmath=False, error_model="python")
def _replicates(A, b, gain, known, L, f, S, x0, ref, noise, scale, step, recon_on, F, Kg, Sv, C, w0, K,
                angle_out, err_out, u_out, z_out):
    """Draw B data sets from the fitted model in closed loop and measure each (rows 1..B of the outs)."""
    B, m = noise.shape
    n = m + 1
    y = np.empty(n)
    vel = np.empty(n)
    uh = np.empty(n)
    ua = np.empty(n)
    for i in range(B):
        x1 = x0[0]
        x2 = x0[1]
        for k in range(m):
            y[k] = x1
            vel[k] = x2
            ua[k] = known[k] - (gain[0] * x1 + gain[1] * x2)
            uh[k] = -(L[k, 0] * x1 + L[k, 1] * x2) + f[k] + scale * noise[i, k] / np.sqrt(2.0 * S[k])
            tot = uh[k] + ua[k]
            n1 = A[0, 0] * x1 + A[0, 1] * x2 + b[0] * tot
            x2 = A[1, 0] * x1 + A[1, 1] * x2 + b[1] * tot
            x1 = n1
        y[m] = x1
        vel[m] = x2
        uh[m] = 0.0
        ua[m] = 0.0
        if step > 0.0:
            for k in range(n):
                y[k] = np.round(y[k] / step) * step
        _measure(A, b, y, vel, uh, ua, ref, recon_on, F, Kg, Sv, C, w0, K, L, f, S,
                 angle_out[i + 1], err_out[i + 1], u_out[i + 1], z_out[i + 1])


def bootstrap_records(chain: Chain, n_boot: int, rng: np.random.Generator) -> Records:
    """:class:`Records` of the recorded segment (row 0) and ``n_boot`` >= 1 draws of the fitted model,
    through the same chain; ``rng`` is the replicates' only source of randomness."""
    c = chain
    n = c.angle.shape[0]
    if n_boot < 1:
        raise ValueError(f"the bootstrap needs at least one replicate; got {n_boot!r}")
    if c.w0 < 0 or c.w0 + c.K > n - 1:
        raise ValueError(f"window {c.w0}..{c.w0 + c.K} does not fit a span of {n} samples")
    rows = n_boot + 1
    angle = np.empty((rows, c.K + 1))
    err = np.empty((rows, c.K + 1))
    torque = np.empty((rows, c.K))
    z = np.empty((rows, c.K))
    if c.recon is None:
        # Placeholders of the right types: numba compiles one signature.
        F, Kg, Sv, Cm = np.zeros((3, 3)), np.zeros((1, 3)), np.zeros(1), np.zeros((1, 3, 3))
        recon_on = False
    else:
        F, Kg, Sv, Cm = c.recon
        recon_on = True
    args = (np.asarray(F, dtype=float), np.asarray(Kg, dtype=float), np.asarray(Sv, dtype=float),
            np.asarray(Cm, dtype=float), int(c.w0), int(c.K), c.L, c.f, c.S)
    vel = c.velocity if c.velocity is not None else np.zeros(n)
    uh = c.u_H if c.u_H is not None else np.zeros(n)
    _measure(c.A, c.b, c.angle, vel, uh, c.u_A, c.ref, recon_on, *args, angle[0], err[0], torque[0], z[0])
    noise = rng.standard_normal((n_boot, n - 1))
    step = float(c.resolution) if recon_on else 0.0
    F, Kg, Sv, Cm = args[:4]
    _replicates(c.A, c.b, c.gain, c.known, c.L, c.f, c.S, c.x0, c.ref, noise, float(c.noise_scale), step, recon_on, F, Kg, Sv, Cm,
                int(c.w0), int(c.K), angle, err, torque, z)
    return Records(angle, err, torque, z)
