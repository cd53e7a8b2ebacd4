"""The MPC haptic assistant (paper Section IV-D) and the 100-Hz closed-loop simulator.

The assistant solves Eq. 19 over ``N_P = 50`` steps of the ``T_C = 0.02``-s
discretization with θ_A = [5, 0, 1], predicting the wheel with u_H = 0 and previewing
the reference ``r(t + j T_C)``, j = 1..N_P, and applies the first torque. The paper
gives the prediction grid, not how often the real-time loop re-solves; we re-solve at
every 10-ms sample of the 100-Hz loop (``period=0.01``, receding horizon). The
assistant then acts on the wheel as a time-invariant state feedback plus a feedforward
from the reference, which a human who knows it feels as a changed wheel (an added
spring and damper) and which the human model of :mod:`scioc.models.maxent` can plan with
exactly. ``period=0.02`` (compute every 20 ms, hold for two samples) is available for
the simulator.

Eq. 19 is an unconstrained LQ tracking problem whose horizon and weights never
change, so its first optimal torque is a fixed linear function of the current state
and of the previewed reference::

    u_A(t) = -gain @ x(t) + preview_weights @ [r(t + T_C), ..., r(t + N_P T_C)]

:func:`design_assistant` computes ``gain`` and ``preview_weights`` once with the
Riccati recursion of :mod:`scioc.models.lq`; solving the quadratic program at every sample
gives the same torque (tested against the dense solution).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.cost import validate_theta
from scioc.models.design import (
    ASSISTANT_HORIZON,
    DT_ASSISTANT,
    DT_HUMAN,
    THETA_ASSISTANT,
    AssistantSpec,
    Design,
    WheelParameters,
)
from scioc.models.lq import lq_policy
from scioc.models.plant import DiscretePlant, discretize
from scioc.models.runtime import njit
from scioc.models.segment import Feedback


class MPCAssistant(NamedTuple):
    """The assistant as a fixed affine law of state and reference preview.

    Attributes
    ----------
    gain : ndarray, shape (2,)
        Feedback on (angle, velocity), N·m per (rad, rad/s).
    preview_weights : ndarray, shape (N_P,)
        Weights on the previewed reference angles r(t + j T_C), j = 1..N_P, N·m/rad.
    hold : int
        Samples between two solutions, for which the torque is held (1: every sample).
    stride : int
        Samples per prediction step (T_C / dt = 2): r(t + j T_C) is sample k + stride·j.
    theta : ndarray, shape (3,)
        θ_A.
    plant : DiscretePlant
        The T_C discretization the assistant predicts with.
    """

    gain: np.ndarray
    preview_weights: np.ndarray
    hold: int
    stride: int
    theta: np.ndarray
    plant: DiscretePlant


def design_assistant(
    theta_A=THETA_ASSISTANT,
    horizon: int = ASSISTANT_HORIZON,
    dt_assistant: float = DT_ASSISTANT,
    dt: float = DT_HUMAN,
    params: WheelParameters = WheelParameters(),
    period: float = DT_HUMAN,
) -> MPCAssistant:
    """Precompute the MPC law of Eq. 19.

    Parameters
    ----------
    theta_A : array_like, shape (3,)
        Assistant cost [q11, q22, R]; default [5, 0, 1].
    horizon : int
        N_P, default 50.
    dt_assistant : float
        T_C in s, default 0.02.
    dt : float
        Sample time of the loop it runs in, s (default 0.01); ``dt_assistant`` must be
        a whole multiple of it.
    params : WheelParameters
        Table I by default (the assistant's internal model).
    period : float
        How often the assistant re-solves, s (default 0.01: every sample); a whole
        multiple of ``dt``. The torque is held in between.

    Returns
    -------
    MPCAssistant
    """
    theta = validate_theta(theta_A, name="theta_A")
    if int(horizon) != horizon or horizon < 1:
        raise ValueError(f"horizon must be a positive integer; got {horizon!r}")
    stride = round(dt_assistant / dt)
    if stride < 1 or abs(stride * dt - dt_assistant) > 1e-12:
        raise ValueError(f"dt_assistant={dt_assistant} must be a whole multiple of dt={dt}")
    hold = round(period / dt)
    if hold < 1 or abs(hold * dt - period) > 1e-12:
        raise ValueError(f"period={period} must be a whole multiple of dt={dt}")
    plant = discretize(dt_assistant, params)
    N = int(horizon)
    zeros_a = np.zeros(N)
    base = lq_policy(plant, theta, np.zeros(N + 1), zeros_a)
    gain = base.L[0].copy()
    # f_0 is linear in r_1..r_N: read off the weights with unit impulses.
    weights = np.empty(N)
    for j in range(1, N + 1):
        r = np.zeros(N + 1)
        r[j] = 1.0
        weights[j - 1] = lq_policy(plant, theta, r, zeros_a).f[0]
    return MPCAssistant(gain=gain, preview_weights=weights, hold=int(hold), stride=int(stride), theta=theta, plant=plant)


def linear_assistant(gain, reference_gain: float, dt: float = DT_HUMAN,
                     params: WheelParameters = WheelParameters()) -> MPCAssistant:
    """A fixed linear assistant, ``u_A,k = -gain @ x_k + reference_gain · r_k``, in the same form as the MPC.

    It is an :class:`MPCAssistant` with one preview weight on the current reference
    sample (``stride = 0``) that acts every sample, so the closed-loop simulator,
    :func:`feedforward` and :func:`human_feedback` treat both kinds alike. ``theta`` is
    NaN (it has no cost) and ``plant`` is the loop's own discretization.

    Examples
    --------
    >>> a = linear_assistant([6.0, 0.3], 6.0)
    >>> float(assistant_torque(a, [0.1, 0.0], [0.2]))
    0.6
    """
    g = np.asarray(gain, dtype=float).reshape(2)
    rg = float(reference_gain)
    if not (np.all(np.isfinite(g)) and np.isfinite(rg)):
        raise ValueError(f"a linear assistant needs finite gains; got gain={gain!r}, reference_gain={reference_gain!r}")
    return MPCAssistant(gain=g, preview_weights=np.array([rg]), hold=1, stride=0,
                        theta=np.full(3, np.nan), plant=discretize(dt, params))


def build_assistant(spec: AssistantSpec, design: Design) -> MPCAssistant:
    """The assistant law ``spec`` declares, on ``design``'s wheel and sample time."""
    if spec.kind == "linear":
        return linear_assistant(spec.gain, spec.reference_gain, design.dt, design.wheel)
    return design_assistant(spec.theta, spec.horizon, spec.step_s, design.dt, design.wheel, spec.period_s)


def assistant_torque(assistant: MPCAssistant, x, r_preview) -> float:
    """The assistant's torque for state ``x`` and previewed reference, N·m.

    Parameters
    ----------
    assistant : MPCAssistant
    x : array_like, shape (2,)
        Angle (rad) and velocity (rad/s) now.
    r_preview : array_like, shape (N_P,)
        Reference angles at t + j T_C, j = 1..N_P, rad.
    """
    return float(-assistant.gain @ np.asarray(x, float) + assistant.preview_weights @ np.asarray(r_preview, float))


def feedforward(assistant: MPCAssistant, angle_ref) -> np.ndarray:
    """The reference part of the assistant's torque at every sample, N·m.

    ``u_A,k = -gain @ x_k + feedforward[k]`` for an assistant that re-solves every sample
    (``hold == 1``); the preview beyond the end of ``angle_ref`` repeats its last value,
    as in :func:`simulate_closed_loop`.

    Parameters
    ----------
    assistant : MPCAssistant
    angle_ref : array_like, shape (K + 1,)
        Reference angle on the 100-Hz grid, rad.

    Returns
    -------
    ndarray, shape (K,)
    """
    r = np.asarray(angle_ref, dtype=float)
    if r.ndim != 1 or r.shape[0] < 2:
        raise ValueError(f"angle_ref must be a vector of at least two samples; got shape {r.shape}")
    K = r.shape[0] - 1
    last = K
    out = np.zeros(K)
    k = np.arange(K)
    for j, w in enumerate(assistant.preview_weights, start=1):
        out += w * r[np.minimum(k + assistant.stride * j, last)]
    return out


def human_feedback(assistant: MPCAssistant, angle_ref) -> Feedback:
    """The assistant as the human who knows it plans with it (:class:`scioc.models.segment.Feedback`).

    Parameters
    ----------
    assistant : MPCAssistant
        Must re-solve every sample (``hold == 1``): a held torque is not a state
        feedback of the current sample.
    angle_ref : array_like, shape (K + 1,)
        Reference angle, rad, over the whole run (the preview looks 1 s ahead).

    Returns
    -------
    Feedback
        ``gain`` and ``feedforward`` of shape (K,).
    """
    if assistant.hold != 1:
        raise ValueError(
            f"the human can plan with the assistant's feedback only if it re-solves every sample; this one holds "
            f"its torque for {assistant.hold} samples (design_assistant(period=...))"
        )
    return Feedback(np.array(assistant.gain, dtype=float), feedforward(assistant, angle_ref))


class ClosedLoop(NamedTuple):
    """A 100-Hz closed-loop run.

    Attributes
    ----------
    x : ndarray, shape (K + 1, 2)
        Angle (rad) and velocity (rad/s).
    u_H : ndarray, shape (K,)
        Human torque, N·m.
    u_A : ndarray, shape (K,)
        Assistant torque, N·m (zeros without assistance).
    """

    x: np.ndarray
    u_H: np.ndarray
    u_A: np.ndarray


@njit(cache=True, fastmath=False, error_model="python")
def _closed_loop(A, b, gain, weights, hold, stride, assist, x0, r, L, f, noise):
    K = noise.shape[0]
    N = weights.shape[0]
    last = r.shape[0] - 1
    x = np.empty((K + 1, 2))
    uH = np.empty(K)
    uA = np.zeros(K)
    x[0, 0] = x0[0]
    x[0, 1] = x0[1]
    ua = 0.0
    for k in range(K):
        if assist and k % hold == 0:
            ua = -(gain[0] * x[k, 0] + gain[1] * x[k, 1])
            for j in range(1, N + 1):
                idx = k + stride * j
                ua += weights[j - 1] * r[idx if idx < last else last]
        if assist:
            uA[k] = ua
        uH[k] = -(L[k, 0] * x[k, 0] + L[k, 1] * x[k, 1]) + f[k] + noise[k]
        tot = uH[k] + uA[k]
        x[k + 1, 0] = A[0, 0] * x[k, 0] + A[0, 1] * x[k, 1] + b[0] * tot
        x[k + 1, 1] = A[1, 0] * x[k, 0] + A[1, 1] * x[k, 1] + b[1] * tot
    return x, uH, uA


def simulate_closed_loop(
    plant: DiscretePlant,
    assistant: MPCAssistant | None,
    x0,
    angle_ref,
    human_L=None,
    human_f=None,
    human_noise=None,
) -> ClosedLoop:
    """Step wheel, assistant and a human policy together at the plant's rate.

    The human acts by ``u_H,k = -human_L[k] @ x_k + human_f[k] + human_noise[k]``
    (omit all three for a passive human, u_H = 0). The assistant, if given, recomputes
    its torque from the actual state every ``hold`` samples and holds it; its
    reference preview beyond the end of ``angle_ref`` repeats the last value.

    Parameters
    ----------
    plant : DiscretePlant
        The 0.01-s wheel.
    assistant : MPCAssistant or None
        None for manual control (u_A = 0).
    x0 : array_like, shape (2,)
        rad, rad/s.
    angle_ref : array_like, shape (K + 1,)
        Reference angle on the plant's time grid, rad.
    human_L : array_like, shape (K, 2), optional
    human_f : array_like, shape (K,), optional
    human_noise : array_like, shape (K,), optional
        N·m.

    Returns
    -------
    ClosedLoop
    """
    r = np.ascontiguousarray(angle_ref, dtype=float)
    K = r.shape[0] - 1
    L = np.zeros((K, 2)) if human_L is None else np.ascontiguousarray(human_L, dtype=float)
    f = np.zeros(K) if human_f is None else np.ascontiguousarray(human_f, dtype=float)
    noise = np.zeros(K) if human_noise is None else np.ascontiguousarray(human_noise, dtype=float)
    if L.shape != (K, 2) or f.shape != (K,) or noise.shape != (K,):
        raise ValueError(f"human policy arrays must have shapes ({K}, 2), ({K},), ({K},) for {K + 1} reference samples")
    if assistant is None:
        gain, weights, hold, stride, assist = np.zeros(2), np.zeros(1), 1, 1, False
    else:
        gain, weights, hold, stride, assist = (assistant.gain, assistant.preview_weights, assistant.hold,
                                               assistant.stride, True)
    x, uH, uA = _closed_loop(plant.A, plant.b, gain, weights, hold, stride, assist, np.asarray(x0, float), r, L, f,
                             noise)
    return ClosedLoop(x, uH, uA)
