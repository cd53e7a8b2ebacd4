"""The ``delayed`` human as a generative closed loop: exact draws, and the affine map the dense reference uses.

:func:`closed_loop` runs the model of :mod:`.likelihood` forward, literally, without its MA
coefficients: the human predicts z_k from z_{k-d} with Ā and its own commands. For k < d its
view of z_0 is ``z_0 - sum_{i=1..d-k} Ā^{i-1} b_c m_{-i}``, the pre-window noises drawn from
their prior, independent of z_0: the likelihood's conditioning.
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
    """Run the closed loop for every column N of the noises; return z (K + 1, 3, N), u_H and u_A (K, N).

    ``Aw``, ``bw``: the wheel; ``a``, ``al``: the lag; ``Ab``, ``bc``, ``ba``: the planning plant;
    ``u_A,k = -gain x_k + known_k`` on the true state if ``feedback``, else ``known_k``; ``known``
    (>= K,) is the human's known input, N·m; ``L``, ``f``: the policy; ``z0`` (3,); ``eps`` (K, N):
    ε_k; ``m`` (K + d, N): m_{-d}..m_{K-1}. With ``physical`` the truth moves on the physically
    lagged wheel ``At``, ``bt`` (:func:`scioc.models.plant.discretize_lagged`) and u_H is its
    ZOH-equivalent torque; otherwise u_H = α τ + (1 - α) c̃, held over the sample.
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


#: The physically lagged wheel, cached: a matrix exponential per call would cost as much as a
#: window's angle likelihood.
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


def known_inputs(angle_ref, u_A, feedback):
    """(reference (K + M + 1,), the human's known input (K + M,), the assistant's gain (2,)), checked: the
    assistant as a torque sequence ``u_A`` or as a :class:`~scioc.models.segment.Feedback` law, or neither."""
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
    return ref, known, gain


def delayed_setup(theta, angle_ref, plant: DiscretePlant, *, u_A=None, feedback: Feedback | None = None,
                  tau_nm: float = 0.0, params: WheelParameters = WheelParameters(),
                  physical: bool = False) -> DelayedSetup:
    """The lag, the planning plant, the assistant and the policy (command cost θ) of one window.

    ``angle_ref`` has K + M + 1 entries; the assistant is ``u_A`` (a given sequence) or
    ``feedback`` (its law and feedforward), neither for manual control. ``physical``
    (τ_nm > 0): the human plans and predicts on the physically lagged wheel it moves.
    """
    q11, q22, R = validate_theta(theta)
    check_wheel(plant, params)
    ref, known, gain = known_inputs(angle_ref, u_A, feedback)
    n_plan = ref.shape[0] - 1
    lag = lag_coefficients(float(tau_nm), plant.dt, params)
    pp = lagged_planning_plant(plant, lag.a, lag.alpha, gain)
    physical = bool(physical) and float(tau_nm) > 0.0
    if physical:
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
    """Draws: ``x`` (K + 1, 2) rad, rad/s; ``u_H``, ``u_A`` (K,) N·m; arm torque ``tau`` (K + 1,); ``segments``.

    A trailing axis of length ``size`` if one was asked for; ``segments`` are the draws as
    windows for :func:`scioc.models.segment.prepare_batch`.
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

    ``theta`` [q11, q22, R]; ``x0`` (2,) initial angle (rad) and velocity (rad/s); ``angle_ref``
    (K + M + 1,) rad. The assistant is ``u_A`` (K + M,), a torque sequence the human knows, or
    ``feedback``, its law on the true state. ``tau_nm`` (s), ``sigma_m`` (N·m per sample),
    ``delay`` (samples), ``tau0`` (N·m): lag, motor noise, delay, initial arm torque. ``n_obs``:
    steps simulated (default K + M); ``size``: draws along a trailing axis (None: one, no axis).
    ``rng`` draws ε (K, size), then m_{-d}..m_{K-1} (K + d, size). ``physical``: the wheel feels
    the arm torque within each sample, as with a real arm (default); ``False``: the torque held
    over the sample, the likelihood's convention. Returns a :class:`DelayedDraw`.
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

    The counterpart of :func:`scioc.models.maxent.forward_optimal_control` (Fig. 6's dashed trajectories);
    without motor noise the delay does not enter. Arguments as :func:`sample_delayed`'s."""
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


__all__ = ["DelayedDraw", "DelayedSetup", "closed_loop", "delayed_setup", "forward_delayed", "known_inputs", "sample_delayed"]
