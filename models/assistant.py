"""The MPC haptic assistant (paper Section IV-D, Eq. 19) and the closed-loop simulator.

Eq. 19 is unconstrained LQ tracking with fixed horizon and weights, so its first torque is a fixed affine
law ``u_A(t) = -gain @ x(t) + preview_weights @ [r(t + T_C), ..., r(t + N_P T_C)]``, computed once by
:func:`design_assistant`. Re-solved every sample it is a state feedback the human can plan with
(docs/decisions/assistant-as-state-feedback.md).
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
    """The assistant's law: ``gain`` (2,), N·m per (rad, rad/s); ``preview_weights`` (N_P,), N·m/rad, on r at
    sample k + ``stride``·j; the torque held ``hold`` samples; ``theta`` = θ_A; ``plant`` its T_C model."""

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
    """The MPC law of Eq. 19 for θ_A, N_P = ``horizon`` steps of T_C = ``dt_assistant``, re-solved every
    ``period`` in a loop of sample time ``dt`` (times in s, multiples of ``dt``), on the wheel ``params``."""
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
    """A fixed law ``u_A,k = -gain @ x_k + reference_gain · r_k`` as an :class:`MPCAssistant`.

    One preview weight on the current sample (``stride = 0``), so every consumer treats both kinds alike;
    ``theta`` is NaN and ``plant`` the loop's own discretization.
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
    """Torque, N·m, for the state ``x`` (rad, rad/s) and the reference at t + j T_C, j = 1..N_P, rad."""
    return float(-assistant.gain @ np.asarray(x, float) + assistant.preview_weights @ np.asarray(r_preview, float))


def feedforward(assistant: MPCAssistant, angle_ref) -> np.ndarray:
    """The reference part of the torque, (K,) N·m, for ``angle_ref`` (K + 1,) rad on the loop's grid.

    ``u_A,k = -gain @ x_k + feedforward[k]`` when ``hold == 1``; the preview past the end repeats the last
    reference value, as in :func:`simulate_closed_loop`.
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
    """The assistant as the human who knows it plans with it: a :class:`scioc.models.segment.Feedback`.

    ``assistant`` must re-solve every sample (a held torque is no state feedback); ``angle_ref`` (K + 1,),
    rad, covers the whole run, since the preview looks 1 s ahead.
    """
    if assistant.hold != 1:
        raise ValueError(
            f"the human can plan with the assistant's feedback only if it re-solves every sample; this one holds "
            f"its torque for {assistant.hold} samples (design_assistant(period=...))"
        )
    return Feedback(np.array(assistant.gain, dtype=float), feedforward(assistant, angle_ref))


class ClosedLoop(NamedTuple):
    """A closed-loop run: ``x`` (K + 1, 2) in rad, rad/s; ``u_H``, ``u_A`` (K,) in N·m (u_A = 0 unassisted)."""

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
    """Step wheel, assistant (None: manual control) and a human policy together at the plant's rate.

    The human acts by ``u_H,k = -human_L[k] @ x_k + human_f[k] + human_noise[k]`` (shapes (K, 2), (K,),
    (K,); omitted: u_H = 0). The assistant recomputes its torque from the actual state every ``hold``
    samples. ``x0`` in rad, rad/s; ``angle_ref`` (K + 1,) in rad on the plant's grid.
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
