"""Parametric bootstrap through the acquisition chain, drawing from a fitted ``delayed`` human.

The adequacy checks (:mod:`scioc.models.adequacy`) compare a segment's recorded data with ``B``
data sets drawn from the fitted human model through the *same* chain. This module is
:mod:`scioc.models.bootstrap` for the ``delayed`` human (:mod:`scioc.models.delayed.likelihood`):
the statistics, their calibration, min-P and Fisher are those of every human model; what
changes is where the replicates come from and what the residual series z is.

What is drawn
-------------
Each replicate runs the delayed human's closed loop (:func:`scioc.models.delayed.sample.closed_loop`)
over the chain's span (the reconstruction span where the torque is reconstructed from the
angle, else the window) at the fitted θ, τ_nm, σ_m and delay d: the human plans on the
lagged wheel (closed by the assistant's law with ``feedback``, else with the recorded
u_A as a known input), sees the state d samples late and predicts it with its own
commands; max-ent noise ``ε_k ~ N(0, 1 / (2 S_k))`` (times ``noise_scale``) and motor
noise ``m_k ~ N(0, σ_m²)`` enter the command; the assistant acts on the true state every
sample (``u_A = -gain·x + feedforward``) or plays the recorded u_A. The plan's horizon is
the likelihood's (window plus preview), as in :mod:`scioc.models.bootstrap`. The motor noises
before the span are drawn from their prior, as the likelihood assumes before its window.
Replicates start at the span's first state: the reconstructed (or measured) angle and
velocity, and the arm torque τ_s below. The true state moves on the physically lagged
wheel (the arm torque acts continuously within each sample, :func:`scioc.models.plant.discretize_lagged`),
as a real arm's does, and the replicate's u_H is its ZOH-equivalent torque; the likelihood
moves the angle with that torque held over the sample, about 1e-5 rad per step apart
(:mod:`scioc.models.humans`). Replicates in the likelihood's convention instead made segments of
the physically lagged ``kbl`` and ``combined`` humans at their true parameters look unlike
their replicates once the angle-only data had passed the reconstruction (16-20 of 84
flagged; 9 and 6 of 84 with physical replicates).

What is measured
----------------
Every data set, the recorded one included, goes through the same encoder (replicates
are quantized when the torque is reconstructed) and the same fixed reconstruction
filter (:func:`scioc.models.bootstrap.measure_span`), and its z is the standardized
innovations of the delayed model at the fitted parameters over the window
(:func:`scioc.models.delayed.likelihood.innovations`, iid N(0, 1) under the model for the true
torque): the analogue of the max-ent residuals. The recorded row's window starts at
``x0_window``, the state its likelihood starts from; replicates start at their own
measured state at the window start.

The arm torque at the window start, τ_0
---------------------------------------
The likelihood conditions on τ_0, which the identification supplies for the recorded
data (``tau0``). Each replicate needs its own, estimated the way the recorded one was.
The arm torque after the span's first w0 torques is the recursion
``τ_{k+1} = a τ_k + (1 - a) (u_k - α τ_k) / (1 - α)`` (:func:`scioc.models.delayed.lag.arm_torque`), affine
in the torques with the same coefficient ``p^{w0}``, p = (a - α) / (1 - α), on its start for
every data set. So
the replicates get ``τ_0,i = tau0 + T(u_i) - T(u_rec)``, T the recursion over the span
before the window from any common start: if the recorded tau0 is that recursion from the
arm torque at the span start (a :class:`scioc.models.delayed.lag.Warmup` of the span's torques), every
replicate gets the same recursion from the same start, whatever that start was; the
difference does not depend on it. A measured torque's span is the window (w0 = 0): every
data set then has τ_0 = tau0, and the replicates start there, exactly the conditioning of
the likelihood. With a reconstructed torque the replicates start the span at
τ_s = the recorded (reconstructed) torque at the span's first sample, the arm torque of
a torque held steady. The closed loop forgets it slowly but well enough: after the 1-s
margin about 1e-3 of an error in τ_s remains in the torque (measured at d = 30,
τ_nm = 0.06-0.1 s, MC and SC), against a policy noise of about 0.15 N·m.

Noise scale with a reconstructed torque
---------------------------------------
The max-ent bootstrap replaces its fitted policy noise by the reconstruction's σ_ε,
because the max-ent R fitted to reconstructed torques is biased (the smoother removes
variability). That fix is specific to the max-ent model, where σ_ε and 1/√(2S) measure
the same white torque. In the delayed model the torque's white part is
``(1 - α)(ε + m)``, about a twelfth of the command noise at τ_nm = 60 ms, the rest
passing the lag, so σ_ε measures something else: rescaling ε by it (to about a tenth)
makes the replicates far smoother than data from the model (measured on the model's own
data at the true parameters: 17 of 20 segments flagged at 5 %, against 3 of 80 without
the rescaling; tests/pipelines/test_adequacy_delayed.py). Here the replicates are drawn
at the fitted parameters as given (``noise_scale`` = 1): exchangeable with the recorded
data when they come from the delayed model at those parameters. Measured false alarms,
true parameters as the fit, 15-s windows, B = 49, 200 segments each (MC and SC): 3.5 %
angle only, 2.0 % with an exogenous assistant, 4.5 % with a torque sensor, 3.5 % with
both; 27 of 800 in all, 3.4 % (95 % CI 2.2-4.9 %), within the 5 % budget. Whether the
delayed fit on reconstructed torques is itself biased is the identification's question;
if it is, the same measurement with fitted instead of true parameters shows it.

With delay, lag and motor noise at zero the replicates are the max-ent bootstrap's on the
same random draws and the statistics agree with :func:`scioc.models.bootstrap.bootstrap_records`'
to rounding (the two plans and residual passes sum in different orders; tested).

numba caches :func:`_measure_rows` with the code of what it calls from other files
(:func:`scioc.models.bootstrap.measure_span`, :func:`scioc.models.delayed.lag.arm_torque_recursion`)
and does not see their changes: after editing those, delete this module's cache files in
``models/delayed/__pycache__``.
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

    Times are samples of the span (row 0 = its first sample); the window starts at ``w0``
    and has K steps, the plan M more.

    Attributes
    ----------
    plant : DiscretePlant
        The wheel at the human's sample time.
    params : WheelParameters
        The wheel ``plant`` was discretized from (the lag needs it).
    theta : ndarray, shape (3,)
        Fitted command cost [q11, q22, R].
    tau_nm, sigma_m : float
        Fitted neuromuscular time constant (s) and motor-noise SD (N·m per sample).
    delay : int
        Fitted perceptual delay, samples.
    tau0 : float
        Arm torque at the window's start the recorded data's likelihood uses, N·m.
    gain : ndarray, shape (2,)
        The assistant's state feedback.
    feedback : bool
        The human plans with the assistant's law and the assistant acts on the true
        state; otherwise the recorded u_A is a known input and is replayed.
    known : ndarray, shape (>= w0 + K + M and >= n - 1,)
        The plan's known input from the span's start: feedforward or recorded u_A, N·m.
    ref : ndarray, shape (>= w0 + K + M + 1 and >= n,)
        Angle reference from the span's start, rad.
    x0 : ndarray, shape (2,)
        State at the span's start (reconstructed or measured), rad, rad/s.
    x0_window : ndarray, shape (2,)
        State the recorded window's likelihood starts from.
    angle, velocity, u_H, u_A : ndarray, shape (n,)
        The recorded span as in :class:`scioc.models.bootstrap.Chain` (velocity and u_H only
        without reconstruction; u_A's last entry unused).
    w0, K, M : int
    recon : tuple or None
        ``(F, Kg, Sv, C)`` of a :class:`scioc.models.reconstruct.FixedReconstruction`, or None.
    resolution : float
        Encoder increment, rad (applied to replicates only with ``recon``).
    noise_scale : float
        The replicates' max-ent noise is ``noise_scale / √(2 S_k)`` (module docstring: 1).
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
    """Every replicate row through the chain: window statistics' inputs, window states, T(u) from 0."""
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
    """The fitted plan over the span: the likelihood's horizon (window + preview), then a plan ending with the span."""
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
    """The recorded segment (row 0) and ``n_boot`` draws of the fitted delayed human, through the same chain.

    Parameters
    ----------
    chain : DelayedChain
    n_boot : int
        B >= 1.
    rng : numpy.random.Generator
        The replicates' only source of randomness: the max-ent noises (shape (B, n - 1),
        drawn first, as :func:`scioc.models.bootstrap.bootstrap_records` draws its noise), then
        the motor noises m_{-d}..m_{n-2} (shape (B, n - 1 + d)).

    Returns
    -------
    Records
        ``n_boot + 1`` rows; ``z`` is the standardized innovations of the delayed model.
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
    # ---- the recorded data set
    _, _, u_rec = measure_span(A, b, np.ascontiguousarray(c.angle, dtype=float), vel, uh, ua0, ref, recon_on, F, Kg,
                               Sv, Cm, w0, K, angle[0], err[0], torque[0])
    xw = np.asarray(c.x0_window, dtype=float)
    _window_states(A, b, float(xw[0]), float(xw[1]), u_rec, ua0, w0, K, x1[0], x2[0])
    arm[0] = arm_torque(u_rec[:w0], lag.a, lag.alpha).tau[-1]
    # ---- replicates: the delayed human's closed loop over the span
    eps = rng.standard_normal((n_boot, n - 1))
    mot = rng.standard_normal((n_boot, n - 1 + d))
    eps_cols = np.ascontiguousarray((float(c.noise_scale) * eps / np.sqrt(2.0 * S)).T)
    mot_cols = np.ascontiguousarray((float(c.sigma_m) * mot).T)
    tau_s = float(c.tau0) if w0 == 0 else float(u_rec[0])
    z0 = np.array([c.x0[0], c.x0[1], tau_s], dtype=float)
    known = np.ascontiguousarray(c.known[: n - 1], dtype=float)
    # The replicates' arm acts on the physically lagged wheel, as a real arm (and models.humans) does.
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
    # ---- residuals: the innovations of every data set at the fitted parameters
    tau0 = float(c.tau0) + (arm - arm[0])
    batch = SegmentBatch(x1, x2, np.tile(c.ref[w0 : w0 + K + M + 1], (rows, 1)), torque,
                         np.tile(c.known[w0 : w0 + K + M], (rows, 1)), np.tile(gain, (rows, 1)))
    zs = innovations(c.theta, batch, c.plant, tau_nm=float(c.tau_nm), sigma_m=float(c.sigma_m), delay=d, tau0=tau0,
                     params=c.params)
    return Records(angle, err, torque, zs)


__all__ = ["DelayedChain", "delayed_records"]
