"""The ``delayed`` human as a generative closed loop: exact draws, and the affine map the dense reference uses.

:func:`closed_loop` runs the model of :mod:`scioc.models.delayed.likelihood` forward, literally:
at step k the human takes the state it saw d samples ago, z_{k-d} (angle, velocity and
arm torque), runs its internal model Ā forward with its own past commands and the known
input (the assistant's feedforward with its law, or the recorded u_A), and commands
``c_k = -L_k ẑ_k + f_k + ε_k``; the motor noise m_k joins the command
(``c̃_k = c_k + m_k``), the arm torque lags it, the wheel moves with the ZOH-equivalent
torque ``u_H,k = α τ_k + (1 - α) c̃_k`` plus the assistant's torque (its law on the true
state, or the given sequence). Nothing here uses the MA coefficients or the
innovations of the likelihood.

Before the window (k < d) the state seen, z_{k-d}, lies before z_0. The true
dynamics from it to z_0 differ from the human's prediction only by the motor noises
m_{k-d}..m_{-1}, so the human's view of z_0 is ``z_0 - sum_{i=1..d-k} Ā^{i-1} b_c m_{-i}``,
run forward from there with its commands since t_0. The pre-window noises are drawn
from their prior, independent of z_0: the conditioning the likelihood states.

The loop is affine in the noises (ε_0..ε_{K-1}, m_{-d}..m_{K-1}): with every offset
zero (initial state, feedforward, known input, reference) it is their linear map, which
:func:`scioc.models.delayed.dense.loglik_dense` evaluates on unit impulses.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from scioc.models.cost import validate_theta
from scioc.models.delayed.lag import check_wheel, lag_coefficients, lagged_planning_plant
from scioc.models.design import WheelParameters
from scioc.models.lq import Policy, lq_tracking_policy
from scioc.models.maxent import Demonstration
from scioc.models.plant import DiscretePlant, discretize_lagged
from scioc.models.runtime import njit
from scioc.models.segment import Feedback, Segment


@njit(cache=True, fastmath=False, error_model="python")
def closed_loop(Aw, bw, a, al, Ab, bc, ba, gain, feedback, known, L, f, z0, eps, m, d, At, bt, physical):
    """Run the closed loop for every column of the noises.

    Parameters
    ----------
    Aw, bw : ndarray, shapes (2, 2), (2,)
        The wheel.
    a, al : float
        The lag's pole and mixing (:func:`scioc.models.delayed.lag.lag_coefficients`).
    Ab, bc, ba : ndarray, shapes (3, 3), (3,), (3,)
        The planning plant (:func:`scioc.models.delayed.lag.lagged_planning_plant`).
    gain : ndarray, shape (2,)
        The assistant's state feedback (used if ``feedback``).
    feedback : bool
        The assistant is ``u_A,k = -gain x_k + known_k`` on the true state; otherwise
        ``u_A,k = known_k``, a given sequence.
    known : ndarray, shape (>= K,)
        The human's known input: feedforward or recorded u_A, N·m.
    L, f : ndarray, shapes (>= K, 3), (>= K,)
        The policy over the plan (its first K steps are used).
    z0 : ndarray, shape (3,)
        Initial angle, velocity, arm torque.
    eps : ndarray, shape (K, N)
        Max-ent deviations ε_k, N·m.
    m : ndarray, shape (K + d, N)
        Motor noise m_{-d}..m_{K-1}, N·m.
    d : int
        Delay, samples.
    At, bt : ndarray, shapes (3, 3), (3,)
        The physically lagged wheel (:func:`scioc.models.plant.discretize_lagged`: A and b_c),
        used if ``physical``.
    physical : bool
        The true state moves on the physically lagged wheel (the arm torque acts
        continuously within the sample) and u_H is its ZOH-equivalent torque, read off
        the velocity row; otherwise it moves with u_H = α τ + (1 - α) c̃ held over the
        sample (the likelihood's convention).

    Returns
    -------
    z : ndarray, shape (K + 1, 3, N)
    u_H : ndarray, shape (K, N)
    u_A : ndarray, shape (K, N)
    """
    K, N = eps.shape
    z = np.empty((K + 1, 3, N))
    uH = np.empty((K, N))
    uA = np.empty((K, N))
    c = np.empty(K)
    zh = np.empty(3)
    tmp = np.empty(3)
    for col in range(N):
        z[0, :, col] = z0
        for k in range(K):
            if k >= d:
                j0 = k - d
                zh[:] = z[j0, :, col]
            else:
                j0 = 0
                # the human's view of z_0 from z_{k-d}: z_0 minus the unseen pre-window noises' effect
                for i in range(3):
                    tmp[i] = 0.0
                for q in range(d - k, 0, -1):  # Horner: sum_{q=1..d-k} Ā^{q-1} b_c m_{-q}
                    mq = m[d - q, col]
                    for i in range(3):
                        zh[i] = Ab[i, 0] * tmp[0] + Ab[i, 1] * tmp[1] + Ab[i, 2] * tmp[2] + bc[i] * mq
                    tmp[:] = zh
                for i in range(3):
                    zh[i] = z[0, i, col] - tmp[i]
            for j in range(j0, k):  # the internal model with its own commands
                for i in range(3):
                    tmp[i] = Ab[i, 0] * zh[0] + Ab[i, 1] * zh[1] + Ab[i, 2] * zh[2] + bc[i] * c[j] + ba[i] * known[j]
                zh[:] = tmp
            ck = f[k] + eps[k, col] - (L[k, 0] * zh[0] + L[k, 1] * zh[1] + L[k, 2] * zh[2])
            c[k] = ck
            cm = ck + m[k + d, col]
            x1 = z[k, 0, col]
            x2 = z[k, 1, col]
            tk = z[k, 2, col]
            ua = known[k] - (gain[0] * x1 + gain[1] * x2) if feedback else known[k]
            uA[k, col] = ua
            if physical:
                for i in range(3):
                    z[k + 1, i, col] = At[i, 0] * x1 + At[i, 1] * x2 + At[i, 2] * tk + bt[i] * cm
                z[k + 1, 0, col] += bw[0] * ua
                z[k + 1, 1, col] += bw[1] * ua
                uH[k, col] = (z[k + 1, 1, col] - Aw[1, 0] * x1 - Aw[1, 1] * x2) / bw[1] - ua
            else:
                u = al * tk + (1.0 - al) * cm
                uH[k, col] = u
                z[k + 1, 0, col] = Aw[0, 0] * x1 + Aw[0, 1] * x2 + bw[0] * (u + ua)
                z[k + 1, 1, col] = Aw[1, 0] * x1 + Aw[1, 1] * x2 + bw[1] * (u + ua)
                z[k + 1, 2, col] = a * tk + (1.0 - a) * cm
    return z, uH, uA


#: The physically lagged wheel by (τ_nm, dt, params), kept: a matrix exponential costs about as much as a
#: window's angle likelihood (:mod:`scioc.models.delayed.angles`), and a search moves τ_nm in one of five coordinates.
_lagged_wheel = lru_cache(maxsize=64)(discretize_lagged)


class DelayedSetup(NamedTuple):
    """Everything :func:`closed_loop` needs besides the noises (built by :func:`delayed_setup`)."""

    a: float
    alpha: float
    A: np.ndarray
    b_c: np.ndarray
    b_a: np.ndarray
    gain: np.ndarray
    feedback: bool
    known: np.ndarray
    policy: Policy
    true_A: np.ndarray
    true_b: np.ndarray
    physical: bool


def delayed_setup(theta, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                  tau_nm: float = 0.0, params: WheelParameters = WheelParameters(),
                  physical: bool = False) -> DelayedSetup:
    """The lag, the planning plant, the assistant and the policy (command cost θ) of one window.

    ``angle_ref`` has K + M + 1 entries; ``u_A`` (given sequence) or ``feedback`` (the law,
    its feedforward over K + M steps) describes the assistant; neither is manual control.
    ``physical``: the true state moves on the physically lagged wheel (:func:`closed_loop`),
    and the human plans and predicts with it; the same as the likelihood's convention when
    τ_nm = 0.
    """
    q11, q22, R = validate_theta(theta)
    check_wheel(plant, params)
    ref = np.ascontiguousarray(angle_ref, dtype=float)
    if ref.ndim != 1 or ref.shape[0] < 2:
        raise ValueError(f"angle_ref must be a vector of K + M + 1 >= 2 samples; got shape {ref.shape}")
    n_plan = ref.shape[0] - 1
    if u_A is not None and feedback is not None:
        raise ValueError("give the assistant either as a torque sequence u_A or as a feedback law, not both")
    if feedback is not None:
        gain = np.asarray(feedback.gain, dtype=float).reshape(2)
        known = np.ascontiguousarray(feedback.feedforward, dtype=float)
    else:
        gain = np.zeros(2)
        known = np.zeros(n_plan) if u_A is None else np.ascontiguousarray(u_A, dtype=float)
    if known.shape != (n_plan,):
        raise ValueError(f"the assistant's torque or feedforward needs {n_plan} samples (angle_ref has {n_plan + 1}); "
                         f"got shape {known.shape}")
    lag = lag_coefficients(float(tau_nm), plant.dt, params)
    pp = lagged_planning_plant(plant, lag.a, lag.alpha, gain)
    physical = bool(physical) and float(tau_nm) > 0.0
    if physical:
        # A physical arm: the wheel moves on the physically lagged plant, and the human plans and
        # predicts with that plant (as models.humans' humans do).
        lp = _lagged_wheel(float(tau_nm), float(plant.dt), params)
        true_A, true_b = lp.A.copy(), lp.b_c.copy()
        pp = pp._replace(A=true_A - np.outer(pp.b_a, np.append(gain, 0.0)), b_c=true_b)
    else:
        true_A, true_b = np.zeros((3, 3)), np.zeros(3)
    x_ref = np.zeros((n_plan + 1, 3))
    x_ref[:, 0] = ref
    pol = lq_tracking_policy(pp.A, pp.b_c, pp.b_a, np.diag([q11, q22, 0.0]), R, x_ref, known)
    return DelayedSetup(lag.a, lag.alpha, pp.A, pp.b_c, pp.b_a, gain, feedback is not None, known, pol, true_A,
                        true_b, physical)


class DelayedDraw(NamedTuple):
    """Draws of the ``delayed`` human; a trailing axis of length ``size`` if one was asked for.

    Attributes
    ----------
    x : ndarray, shape (K + 1, 2[, size])
        Angle (rad) and velocity (rad/s).
    u_H : ndarray, shape (K[, size])
        Observed (ZOH-equivalent) human torque, N·m.
    u_A : ndarray, shape (K[, size])
        Assistant torque, N·m.
    tau : ndarray, shape (K + 1[, size])
        Arm torque, N·m.
    segments : list of Segment
        Each draw as a window for :func:`scioc.models.segment.prepare_batch` (the plan's
        reference and known input included).
    """

    x: np.ndarray
    u_H: np.ndarray
    u_A: np.ndarray
    tau: np.ndarray
    segments: list


def sample_delayed(theta, x0, angle_ref, plant: DiscretePlant, rng: np.random.Generator, *, u_A=None,
                   feedback: Feedback | None = None, tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0,
                   tau0: float = 0.0, n_obs: int | None = None, size: int | None = None,
                   params: WheelParameters = WheelParameters(), physical: bool = True) -> DelayedDraw:
    """Draw (x, u_H, u_A) from the ``delayed`` human in closed loop, exactly.

    Parameters
    ----------
    theta : array_like, shape (3,)
        Command cost [q11, q22, R].
    x0 : array_like, shape (2,)
        Initial angle (rad) and velocity (rad/s).
    angle_ref : array_like, shape (K + M + 1,)
        Reference over the plan, rad.
    plant : DiscretePlant
    rng : numpy.random.Generator
        Draws ε (shape (K, size), scaled by 1/sqrt(2 S_k)) first, then the motor noise
        m_{-d}..m_{K-1} (shape (K + d, size), scaled by σ_m).
    u_A : array_like, shape (K + M,), optional
        A given assistant torque sequence (the human knows it).
    feedback : Feedback, optional
        The assistant's law, acting on the true state; the human plans with it.
    tau_nm, sigma_m, delay, tau0 : float, float, int, float
        Lag time constant (s), motor-noise SD (N·m per sample), delay (samples), arm
        torque at the start (N·m).
    n_obs : int, optional
        Steps to simulate, K (default: the whole plan, K + M).
    size : int, optional
        Number of independent draws (a trailing axis); None for one draw without it.
    params : WheelParameters
    physical : bool
        The wheel feels the arm torque continuously within each sample (the physically
        lagged wheel, :func:`scioc.models.plant.discretize_lagged`; default), as a real arm
        does, and the human plans and predicts on that wheel; the recorded u_H is its
        ZOH-equivalent torque. ``False``: the state moves
        with that torque held over the sample, the convention in which
        :mod:`scioc.models.delayed.likelihood` is exact; the two differ in the angle by about
        1e-5 rad per step (:mod:`scioc.models.humans`).

    Returns
    -------
    DelayedDraw
    """
    setup = delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                          physical=physical)
    n_plan = setup.known.shape[0]
    K = n_plan if n_obs is None else int(n_obs)
    d = int(delay)
    if not (1 <= K <= n_plan) or d != delay or d < 0 or not (np.isfinite(sigma_m) and sigma_m >= 0):
        raise ValueError(f"need 1 <= n_obs <= {n_plan}, a whole delay >= 0 and sigma_m >= 0; "
                         f"got {n_obs!r}, {delay!r}, {sigma_m!r}")
    N = 1 if size is None else int(size)
    eps = rng.standard_normal((K, N)) / np.sqrt(2.0 * setup.policy.S[:K, None])
    m = rng.standard_normal((K + d, N)) * float(sigma_m)
    z0 = np.array([*np.asarray(x0, dtype=float).reshape(2), float(tau0)])
    z, uH, uA = closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                            setup.feedback, setup.known, setup.policy.L, setup.policy.f, z0, eps, m, d, setup.true_A,
                            setup.true_b, setup.physical)
    ref = np.asarray(angle_ref, dtype=float)
    segs = [Segment(z0[:2].copy(), ref, uH[:, j].copy(), np.concatenate([uA[:, j], setup.known[K:]]), feedback)
            for j in range(N)]
    if size is None:
        z, uH, uA = z[..., 0], uH[:, 0], uA[:, 0]
    return DelayedDraw(z[:, :2], uH, uA, z[:, 2], segs)


def forward_delayed(theta, x0, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                    tau_nm: float = 0.0, tau0: float = 0.0, n_obs: int | None = None,
                    params: WheelParameters = WheelParameters(), physical: bool = True) -> Demonstration:
    """The ``delayed`` human's mean behaviour for θ: its closed loop with every noise at zero.

    The counterpart of :func:`scioc.models.maxent.forward_optimal_control` (the dashed trajectories
    of Fig. 6) for this model: the loop is affine in its noises, so the noise-free run is
    the mean of :func:`sample_delayed`'s draws. Without motor noise the human's prediction
    is exact, so the delay does not enter; the lag does (the arm torque starts at ``tau0``).
    Arguments as :func:`sample_delayed`'s; ``u_H`` is the observed (ZOH-equivalent) torque.
    """
    setup = delayed_setup(theta, angle_ref, plant, u_A=u_A, feedback=feedback, tau_nm=tau_nm, params=params,
                          physical=physical)
    n_plan = setup.known.shape[0]
    K = n_plan if n_obs is None else int(n_obs)
    if not 1 <= K <= n_plan:
        raise ValueError(f"need 1 <= n_obs <= {n_plan}; got {n_obs!r}")
    zeros = np.zeros((K, 1))
    z0 = np.array([*np.asarray(x0, dtype=float).reshape(2), float(tau0)])
    z, uH, _ = closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                           setup.feedback, setup.known, setup.policy.L, setup.policy.f, z0, zeros, zeros, 0,
                           setup.true_A, setup.true_b, setup.physical)
    return Demonstration(z[:, :2, 0], uH[:, 0])


__all__ = ["DelayedDraw", "DelayedSetup", "closed_loop", "delayed_setup", "forward_delayed", "sample_delayed"]
