"""Parametric bootstrap through the acquisition chain, drawing from a fitted ``delayed`` human.

:mod:`scioc.models.bootstrap` for the ``delayed`` human: the statistics are shared
(:mod:`scioc.models.adequacy`). Replicates run :func:`.sample.closed_loop` over the chain's
span at the fitted parameters, on the physically lagged wheel. Every data set then passes the
same encoder and reconstruction (:func:`scioc.models.bootstrap.measure_span`), and its z is the
delayed model's standardized innovations (:func:`.likelihood.innovations`), from
``τ_0,i = tau0 + T(u_i) - T(u_rec)``, T the lag recursion over the span before the window.
See docs/decisions/delayed-bootstrap-replicates.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.bootstrap import Records, measure_span
from scioc.models.cost import validate_theta
from scioc.models.delayed.lag import arm_torque, arm_torque_recursion, lag_coefficients, lagged_planning_plant
from scioc.models.delayed.likelihood import innovations
from scioc.models.delayed.sample import closed_loop
from scioc.models.design import WheelParameters
from scioc.models.lq import lq_tracking_policy
from scioc.models.plant import DiscretePlant, discretize_lagged
from scioc.models.runtime import njit
from scioc.models.segment import SegmentBatch
from scioc.models.simulate import quantize


class DelayedChain(NamedTuple):
    """A segment fitted with the ``delayed`` human and how its data were acquired.

    Times are samples of the span (row 0 its first); the window starts at ``w0`` and has ``K``
    steps, the plan ``M`` more. The fit: ``theta``, ``tau_nm`` (s), ``sigma_m`` (N·m), ``delay``
    (samples), and ``tau0`` (N·m), the recorded likelihood's arm torque at the window's start. The
    assistant's feedback ``gain`` acts on the true state if ``feedback``, else its recorded u_A is
    replayed. ``known`` (N·m) and ``ref`` (rad) cover the span and the plan from the span's start.
    ``x0``: the state at the span's start; ``x0_window``: where the recorded likelihood starts.
    ``angle``, ``velocity``, ``u_H``, ``u_A``: as in :class:`scioc.models.bootstrap.Chain`.
    ``recon``: ``(F, Kg, Sv, C)`` of a :class:`scioc.models.reconstruct.FixedReconstruction` or None,
    then replicates are quantized by ``resolution`` (rad). Max-ent noise: ``noise_scale / √(2 S_k)``.
    """

    plant: DiscretePlant
    params: WheelParameters
    theta: np.ndarray
    tau_nm: float
    sigma_m: float
    delay: int
    tau0: float
    gain: np.ndarray
    feedback: bool
    known: np.ndarray
    ref: np.ndarray
    x0: np.ndarray
    x0_window: np.ndarray
    angle: np.ndarray
    velocity: np.ndarray | None
    u_H: np.ndarray | None
    u_A: np.ndarray
    w0: int
    K: int
    M: int
    recon: tuple | None
    resolution: float
    noise_scale: float = 1.0


@njit(cache=True, fastmath=False, error_model="python")
def _window_states(A, b, x1, x2, u, a, w0, K, x1_out, x2_out):
    """States over the window from (x1, x2) at w0, driven by the measured torque plus u_A (as prepare_batch)."""
    x1_out[0] = x1
    x2_out[0] = x2
    for k in range(K):
        tot = u[w0 + k] + a[w0 + k]
        x1_out[k + 1] = A[0, 0] * x1_out[k] + A[0, 1] * x2_out[k] + b[0] * tot
        x2_out[k + 1] = A[1, 0] * x1_out[k] + A[1, 1] * x2_out[k] + b[1] * tot


@njit(cache=True, fastmath=False, error_model="python")
def _measure_rows(A, b, Y, V, UH, UA, ref, recon_on, F, Kg, Sv, C, w0, K, a, al, angle_out, err_out, u_out, x1_out,
                  x2_out, arm_out):
    """Every replicate row through the chain: the statistics' inputs, the window states, T(u) from 0."""
    tau = np.empty(w0 + 1)
    dtau = np.zeros((w0 + 1, 2))  # tangents unused here
    dct = np.empty((w0, 2))
    for i in range(Y.shape[0]):
        ang, v, u = measure_span(A, b, Y[i], V[i], UH[i], UA[i], ref, recon_on, F, Kg, Sv, C, w0, K, angle_out[i],
                                 err_out[i], u_out[i])
        _window_states(A, b, ang[w0], v[w0], u, UA[i], w0, K, x1_out[i], x2_out[i])
        tau[0] = 0.0
        arm_torque_recursion(u[:w0], a, al, tau, dtau, dct)
        arm_out[i] = tau[w0]


def _span_policy(chain: DelayedChain, n: int, pp):
    """The fitted plan over the span: the likelihood's horizon, then a plan ending with the span."""
    c = chain
    q11, q22, R = validate_theta(c.theta)
    Q = np.diag([q11, q22, 0.0])
    end = c.w0 + c.K + c.M

    def plan(m):
        x_ref = np.zeros((m + 1, 3))
        x_ref[:, 0] = c.ref[: m + 1]
        return lq_tracking_policy(pp.A, pp.b_c, pp.b_a, Q, R, x_ref, c.known[:m])

    pol = plan(end)
    L, f, S = pol.L, pol.f, pol.S
    if end < n - 1:  # the span reaches past the plan: its last steps follow a plan that ends with the span
        tail = plan(n - 1)
        L, f, S = (np.concatenate([x, y[end:]]) for x, y in ((L, tail.L), (f, tail.f), (S, tail.S)))
    return np.ascontiguousarray(L[: n - 1]), np.ascontiguousarray(f[: n - 1]), np.ascontiguousarray(S[: n - 1])


def _check(c: DelayedChain, n_boot: int) -> int:
    n = c.angle.shape[0]
    if n_boot < 1:
        raise ValueError(f"the bootstrap needs at least one replicate; got {n_boot!r}")
    if c.w0 < 0 or c.K < 1 or c.M < 0 or c.w0 + c.K > n - 1:
        raise ValueError(f"window {c.w0}..{c.w0 + c.K} (preview {c.M}) does not fit a span of {n} samples")
    end = c.w0 + c.K + c.M
    if c.known.shape[0] < max(end, n - 1) or c.ref.shape[0] < max(end + 1, n):
        raise ValueError(f"known input and reference must cover the span and the plan ({max(end, n - 1)} and "
                         f"{max(end + 1, n)} samples); got {c.known.shape[0]} and {c.ref.shape[0]}")
    if int(c.delay) != c.delay or c.delay < 0 or not (np.isfinite(c.sigma_m) and c.sigma_m >= 0):
        raise ValueError(f"need a whole delay >= 0 samples and sigma_m >= 0; got {c.delay!r}, {c.sigma_m!r}")
    return n


def delayed_records(chain: DelayedChain, n_boot: int, rng: np.random.Generator) -> Records:
    """The recorded segment (row 0) and ``n_boot`` >= 1 draws of the fitted delayed human, through the same chain.

    ``rng`` draws the max-ent noises (B, n - 1) first, as
    :func:`scioc.models.bootstrap.bootstrap_records` does, then the motor noises m_{-d}..m_{n-2}
    (B, n - 1 + d). Returns :class:`scioc.models.bootstrap.Records` of ``n_boot + 1`` rows whose
    ``z`` is the delayed model's standardized innovations.
    """
    c = chain
    n = _check(c, n_boot)
    d, K, M, w0 = int(c.delay), int(c.K), int(c.M), int(c.w0)
    A, b = np.ascontiguousarray(c.plant.A), np.ascontiguousarray(c.plant.b)
    lag = lag_coefficients(float(c.tau_nm), c.plant.dt, c.params)
    gain = np.asarray(c.gain, dtype=float).reshape(2) if c.feedback else np.zeros(2)
    pp = lagged_planning_plant(c.plant, lag.a, lag.alpha, gain)
    L, f, S = _span_policy(c, n, pp)
    rows = n_boot + 1
    angle, err = np.empty((rows, K + 1)), np.empty((rows, K + 1))
    torque, x1, x2 = np.empty((rows, K)), np.empty((rows, K + 1)), np.empty((rows, K + 1))
    arm = np.empty(rows)
    if c.recon is None:
        # Unused placeholders of the right types (numba compiles one signature).
        F, Kg, Sv, Cm = np.zeros((3, 3)), np.zeros((1, 3)), np.zeros(1), np.zeros((1, 3, 3))
    else:
        F, Kg, Sv, Cm = (np.asarray(x, dtype=float) for x in c.recon)
    recon_on = c.recon is not None
    ref = np.ascontiguousarray(c.ref[:n], dtype=float)
    ua0 = np.ascontiguousarray(c.u_A, dtype=float)
    vel = np.zeros(n) if c.velocity is None else np.ascontiguousarray(c.velocity, dtype=float)
    uh = np.zeros(n) if c.u_H is None else np.ascontiguousarray(c.u_H, dtype=float)
    _, _, u_rec = measure_span(A, b, np.ascontiguousarray(c.angle, dtype=float), vel, uh, ua0, ref, recon_on, F, Kg,
                               Sv, Cm, w0, K, angle[0], err[0], torque[0])
    xw = np.asarray(c.x0_window, dtype=float)
    _window_states(A, b, float(xw[0]), float(xw[1]), u_rec, ua0, w0, K, x1[0], x2[0])
    arm[0] = arm_torque(u_rec[:w0], lag.a, lag.alpha).tau[-1]
    eps = rng.standard_normal((n_boot, n - 1))
    mot = rng.standard_normal((n_boot, n - 1 + d))
    eps_cols = np.ascontiguousarray((float(c.noise_scale) * eps / np.sqrt(2.0 * S)).T)
    mot_cols = np.ascontiguousarray((float(c.sigma_m) * mot).T)
    tau_s = float(c.tau0) if w0 == 0 else float(u_rec[0])
    z0 = np.array([c.x0[0], c.x0[1], tau_s], dtype=float)
    known = np.ascontiguousarray(c.known[: n - 1], dtype=float)
    physical = float(c.tau_nm) > 0.0
    lp = discretize_lagged(float(c.tau_nm), c.plant.dt, c.params) if physical else None
    At, bt = (np.ascontiguousarray(lp.A), np.ascontiguousarray(lp.b_c)) if physical else (np.zeros((3, 3)), np.zeros(3))
    z, uH, uA = closed_loop(A, b, lag.a, lag.alpha, pp.A, pp.b_c, pp.b_a, gain, bool(c.feedback), known, L, f, z0,
                            eps_cols, mot_cols, d, At, bt, physical)
    Y = np.ascontiguousarray(z[:, 0, :].T)
    if recon_on:
        Y = quantize(Y, float(c.resolution))
    V = np.ascontiguousarray(z[:, 1, :].T)
    UH, UA = np.zeros((n_boot, n)), np.zeros((n_boot, n))
    UH[:, : n - 1], UA[:, : n - 1] = uH.T, uA.T
    _measure_rows(A, b, Y, V, UH, UA, ref, recon_on, F, Kg, Sv, Cm, w0, K, lag.a, lag.alpha, angle[1:], err[1:],
                  torque[1:], x1[1:], x2[1:], arm[1:])
    tau0 = float(c.tau0) + (arm - arm[0])
    batch = SegmentBatch(x1, x2, np.tile(c.ref[w0 : w0 + K + M + 1], (rows, 1)), torque,
                         np.tile(c.known[w0 : w0 + K + M], (rows, 1)), np.tile(gain, (rows, 1)))
    zs = innovations(c.theta, batch, c.plant, tau_nm=float(c.tau_nm), sigma_m=float(c.sigma_m), delay=d, tau0=tau0,
                     params=c.params)
    return Records(angle, err, torque, zs)


__all__ = ["DelayedChain", "delayed_records"]
