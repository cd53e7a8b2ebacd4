"""Parametric bootstrap through the acquisition chain: data sets drawn from a fitted max-ent model.

For the adequacy checks (:mod:`scioc.models.adequacy`) a segment's recorded data and ``B`` data
sets drawn from the fitted model must pass through the *same* chain: the same reference
and assistant (in closed loop: the assistant reacts to each replicate's own state), the
same encoder and the same reconstruction (or, for a recorded torque, the same exact
measurement), and the same residual pass of the likelihood. :func:`bootstrap_records`
returns what the statistics see of all ``B + 1`` data sets.

Shortcuts, and why the null stays honest
----------------------------------------
* θ is not refitted on each replicate (plug-in). The recorded data were used to choose θ
  and the replicates were not, so the recorded data look, if anything, a little better
  than the replicates: the test is conservative, by about 3 parameters in 1500 samples.
* The reconstruction's two variances are held at the values chosen for the recorded
  segment; with them fixed the Kalman/RTS smoother is a linear filter whose gains are
  computed once per segment and applied to every replicate. The recorded segment passes
  through exactly the same filter.
* Replicates start at the reconstructed state at the start of the reconstruction span.
* For a reconstructed torque the fitted R is biased upward (the smoother removes torque
  variability below the encoder's resolution, so the torque looks less variable), and
  replicates drawn with it would be smoother still after their own reconstruction. They
  are therefore drawn with the fitted θ1 and θ2 but with the policy noise the
  reconstruction measured (its white-torque SD σ_ε, within 2 % of the true policy noise
  on the default study; ``noise_scale``), and they are standardized with the fitted S
  like the recorded data. Recorded torques use the fitted R as it is.

These shortcuts are checked where it matters, by the false-alarm rate measured on data from the
model (``scioc power``, README).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.reconstruct import apply_reconstruction
from scioc.models.runtime import njit


class Records(NamedTuple):
    """What the statistics see of B + 1 data sets of one segment (row 0: the recorded one).

    Attributes
    ----------
    angle : ndarray, shape (n, K + 1)
        Recorded (encoder) angle over the window, rad.
    error : ndarray, shape (n, K + 1)
        Tracking error of the angle the likelihood uses (smoothed if reconstructed), rad.
    torque : ndarray, shape (n, K)
        Human torque the likelihood uses, N·m.
    z : ndarray, shape (n, K)
        Standardized policy residuals.
    """

    angle: np.ndarray
    error: np.ndarray
    torque: np.ndarray
    z: np.ndarray


class Chain(NamedTuple):
    """A fitted segment and how its data were acquired, for :func:`bootstrap_records`.

    Times are samples of the reconstruction span (row 0 = its first sample); the window
    starts at ``w0`` and has K steps.

    Attributes
    ----------
    A, b : ndarray
        The wheel (2, 2), (2,).
    gain : ndarray, shape (2,)
        The assistant's state feedback the human plans with (zeros: none).
    known : ndarray, shape (n - 1,)
        The known input of the plan over the span: the assistant's feedforward (with a
        gain) or the recorded u_A, N·m.
    L, f, S : ndarray, shapes (n - 1, 2), (n - 1,), (n - 1,)
        The fitted model's policy over the span (its plan within the window).
    x0 : ndarray, shape (2,)
        State at the span's start, rad, rad/s.
    angle, velocity, u_H, u_A : ndarray, shape (n,)
        The recorded span: angle (encoder), and, without reconstruction, the recorded
        velocity and u_H (else unused); u_A's last entry is unused.
    ref : ndarray, shape (n,)
        Angle reference, rad.
    w0, K : int
    recon : tuple or None
        ``(F, Kg, Sv, C)`` of a :class:`scioc.models.reconstruct.FixedReconstruction`, or None
        when velocity and u_H were recorded.
    resolution : float
        Encoder increment, rad (0: not quantized).
    noise_scale : float
        The replicates' policy noise is ``noise_scale / √(2 S_k)`` (1: the fitted model's).
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


# --------------------------------------------------------------------------- the chain


@njit(cache=True, fastmath=False, error_model="python")
def measure_span(A, b, y, vel, uh, a, ref, recon_on, F, Kg, Sv, C, w0, K, angle_out, err_out, u_out):
    """One data set of a span through the acquisition chain: what the statistics see of its window.

    With ``recon_on`` the angle ``y`` (encoder) goes through the reconstruction with its
    variances fixed (:func:`scioc.models.reconstruct.apply_reconstruction`, a linear smoother);
    otherwise ``y``, ``vel`` and ``uh`` are the measured angle, velocity and torque. Writes
    the window's encoder angle, tracking error and torque into the out rows and returns
    ``(angle, velocity, u_H)`` over the whole span (shape (n,) each), from which a human
    model's residual pass starts. ``a`` is the assistant's torque over the span.
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
            # The assistant reacts to the actual state; the human's plan knows its law.
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
    """The recorded segment (row 0) and ``n_boot`` draws of the fitted model, through the same chain.

    Parameters
    ----------
    chain : Chain
    n_boot : int
        B >= 1.
    rng : numpy.random.Generator
        The replicates' only source of randomness.

    Returns
    -------
    Records
        ``n_boot + 1`` rows.
    """
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
        # Unused placeholders of the right types (numba compiles one signature).
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
