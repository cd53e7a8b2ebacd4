"""The neuromuscular lag as the ``delayed`` human model sees it: pole a, mixing α, and the planning plant.

The simulated human (:func:`scioc.models.humans.simulate_human`) drives the wheel through a
first-order lag with time constant τ_nm, discretized exactly with a zero-order hold
(:func:`scioc.models.plant.discretize_lagged`): the arm torque τ follows the held command
c̃ (command plus motor noise). Recorded torques are ZOH-equivalent: u_k is the torque
that, held over the sample, gives the velocity x_{k+1}[1] on the 2-state wheel. From the
velocity row of the lagged plant::

    u_k = α τ_k + (1 - α) c̃_k,        τ_{k+1} = a τ_k + (1 - a) c̃_k,

with ``a = exp(-dt / τ_nm)``, ``α = A_lag[1, 2] / b[1]`` and ``1 - α = b_c,lag[1] / b[1]``
(a held constant torque passes the lag unchanged, hence the two weights sum to one;
tested against :func:`scioc.models.plant.discretize_lagged`). τ_nm = 0 is no lag: a = α = 0.

Closed form of α. The arm torque decays as ``exp(-μ s)``, μ = 1/τ_nm, over the sample,
so the velocity it adds at the sample's end is the second entry of::

    ∫_0^dt e^{A_c (dt - s)} b_w e^{-μ s} ds = (A_c + μ I)⁻¹ (Φ - a I) b_w,   Φ = e^{A_c dt},

with (A_c, b_w) the continuous wheel (:func:`scioc.models.plant.continuous_matrices`) and
Φ = the discrete wheel's A. Its τ_nm-derivative follows by differentiating in μ:
``dv/dμ = (A_c + μ I)⁻¹ (dt a b_w - v)``. When A_c + μ I is (nearly) singular, possible
only for a wheel with real poles at τ_nm = -1/λ (within 5 %), the block matrix exponential and its
Fréchet derivative are used instead (:func:`scipy.linalg.expm_frechet`). As τ_nm -> 0,
``α ≈ τ_nm [Φ b_w]_1 / b[1]``: the one-sided derivative at 0 is ``[Φ b_w]_1 / b[1]``, and
``da/dτ_nm -> 0``.

The human plans on z = (angle, velocity, arm torque) with the command c as input (see
:mod:`scioc.models.delayed.likelihood`)::

    z_{k+1} = A_z z_k + b_c c_k + b_a u_A,k,
    A_z = [[A, α b], [0, a]],  b_c = [(1 - α) b; 1 - a],  b_a = [b; 0].

This is the ZOH-equivalent description of the lagged wheel: its velocity row is exact,
its angle row differs from the lagged plant's by the within-sample shape of the torque
(about 1e-5 rad per step, see :mod:`scioc.models.humans`).

The arm torque from the observed torques (:func:`arm_torque`). Eliminating c̃ gives
``τ_{k+1} = p τ_k + (1 - a) / (1 - α) u_k`` with ``p = a - (1 - a) α / (1 - α)``: a
stable recursion (p = -0.92 for τ_nm = 0.06 s at 100 Hz, -0.97 at 1 s; |p| < 1 for
every τ_nm, approaching -1 as the lag slows), so the arm torque at a window's start
follows from the torques before it, run from the arm at rest at the recording's start.
It depends on τ_nm through (a, α); its tangents in (a, α) carry that into the
likelihood's gradient (:func:`scioc.models.delayed.likelihood.loglik_grad`'s ``dtau0``).
The start's influence decays as |p|^k: started from a guess instead of rest, after
1 s it is 3e-4 of the guess's error at τ_nm = 0.06 s, 3e-3 at 0.1 s.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from scipy.linalg import expm_frechet

from scioc.models.design import DT_HUMAN, WheelParameters
from scioc.models.plant import DiscretePlant, continuous_matrices, discretize
from scioc.models.runtime import FASTMATH, njit


class LagCoefficients(NamedTuple):
    """The lag of one τ_nm in the data convention, with derivatives.

    Attributes
    ----------
    a : float or ndarray
        Pole ``exp(-dt / τ_nm)`` (0 for τ_nm = 0).
    alpha : float or ndarray
        Weight of the arm torque in the ZOH-equivalent torque (0 for τ_nm = 0).
    da : float or ndarray
        da/dτ_nm, 1/s (0 at τ_nm = 0).
    dalpha : float or ndarray
        dα/dτ_nm, 1/s; at τ_nm = 0 the one-sided derivative from above.
    """

    a: float | np.ndarray
    alpha: float | np.ndarray
    da: float | np.ndarray
    dalpha: float | np.ndarray


def _check_tau(tau_nm) -> np.ndarray:
    tau = np.asarray(tau_nm, dtype=float)
    if not np.all(np.isfinite(tau)) or np.any(tau < 0):
        raise ValueError(f"neuromuscular time constant tau_nm must be finite and >= 0 s; got {tau_nm!r}")
    return tau


def lag_coefficients(tau_nm, dt: float = DT_HUMAN, params: WheelParameters = WheelParameters()) -> LagCoefficients:
    """The pole a and mixing α of the ZOH-sampled neuromuscular lag, and their τ_nm-derivatives.

    Parameters
    ----------
    tau_nm : float or array_like
        Neuromuscular time constant(s), s, >= 0.
    dt : float
        Sample time, s.
    params : WheelParameters
        The wheel (Table I by default).

    Returns
    -------
    LagCoefficients
        Same shape as ``tau_nm``.

    Examples
    --------
    >>> lag = lag_coefficients(0.06)
    >>> round(float(lag.a), 4), round(float(lag.alpha), 4)
    (0.8465, 0.9202)
    """
    tau = _check_tau(tau_nm)
    dt, params = float(dt), WheelParameters(*params)
    flat = tau.reshape(-1)
    out = np.zeros((4, flat.shape[0]))
    for i, t in enumerate(flat):
        out[:, i] = _lag_one(float(t), dt, params)
    if tau.ndim == 0:
        return LagCoefficients(*(float(v[0]) for v in out))
    return LagCoefficients(*(v.reshape(tau.shape) for v in out))


@lru_cache(maxsize=256)
def _lag_one(t: float, dt: float, params: WheelParameters) -> tuple:
    """(a, α, da/dτ_nm, dα/dτ_nm) of one τ_nm (kept: a search asks for the same τ_nm in the likelihood and in the
    warm-up of every segment)."""
    A_c, b_w, wheel, lam = _wheel(dt, params)
    b1 = wheel.b[1]
    Pb = wheel.A @ b_w
    if t == 0.0:
        return 0.0, 0.0, 0.0, float(Pb[1] / b1)
    mu = 1.0 / t
    a = np.exp(-dt * mu)
    Mu = A_c + mu * np.eye(2)
    # The solve loses about 1e-15 / (relative distance of μ from a pole) in α.
    if np.min(np.abs(mu + lam) / (mu + np.abs(lam))) > 0.05:
        v = np.linalg.solve(Mu, Pb - a * b_w)
        dv_dmu = np.linalg.solve(Mu, dt * a * b_w - v)
        alpha, dalpha = v[1] / b1, -mu * mu * dv_dmu[1] / b1
    else:  # A_c + μ I (nearly) singular: the block exponential, by value and Fréchet derivative
        M = np.zeros((4, 4))
        M[:2, :2] = A_c
        M[:2, 2] = b_w
        M[2, 2], M[2, 3] = -mu, mu
        dM = np.zeros((4, 4))
        dM[2, 2], dM[2, 3] = mu * mu, -mu * mu  # d/dτ_nm of -1/τ_nm and 1/τ_nm
        E, dE = expm_frechet(M * dt, dM * dt)
        alpha, dalpha = E[1, 2] / b1, dE[1, 2] / b1
    return float(a), float(alpha), float(a * dt * mu * mu), float(dalpha)


class LaggedPlanningPlant(NamedTuple):
    """The plant the ``delayed`` human plans on: z = (angle, velocity, arm torque).

    ``z_{k+1} = A z_k + b_c c_k + b_a u_k`` with the command c and the known input u (the
    assistant's recorded torque, or its feedforward when the human plans with its law).

    Attributes
    ----------
    A : ndarray, shape (3, 3)
        ``[[A_wheel - b gainᵀ, α b], [0, a]]``.
    b_c : ndarray, shape (3,)
        ``[(1 - α) b; 1 - a]``.
    b_a : ndarray, shape (3,)
        ``[b; 0]``.
    """

    A: np.ndarray
    b_c: np.ndarray
    b_a: np.ndarray


def lagged_planning_plant(plant: DiscretePlant, a: float, alpha: float, gain=None) -> LaggedPlanningPlant:
    """The augmented plant of the module docstring, closed by the assistant's state feedback ``gain``.

    Parameters
    ----------
    plant : DiscretePlant
        The 2-state wheel.
    a, alpha : float
        From :func:`lag_coefficients`.
    gain : array_like, shape (2,), optional
        The assistant's feedback the human plans with (None: the open wheel).

    Returns
    -------
    LaggedPlanningPlant
    """
    g = np.zeros(2) if gain is None else np.asarray(gain, dtype=float).reshape(2)
    A = np.zeros((3, 3))
    A[:2, :2] = plant.A - np.outer(plant.b, g)
    A[:2, 2] = alpha * plant.b
    A[2, 2] = a
    b_c = np.concatenate([(1.0 - alpha) * plant.b, [1.0 - a]])
    b_a = np.concatenate([plant.b, [0.0]])
    return LaggedPlanningPlant(A, b_c, b_a)


@lru_cache(maxsize=16)
def _wheel(dt: float, params: WheelParameters):
    """The continuous wheel, its discretization and its poles (computed once per wheel and dt: the
    likelihood asks for them at every evaluation)."""
    A_c, b_w = continuous_matrices(params)
    return A_c, b_w, discretize(dt, params), np.linalg.eigvals(A_c)


def check_wheel(plant: DiscretePlant, params: WheelParameters) -> None:
    """ValueError unless ``plant`` is the discretization of ``params`` at its own sample time."""
    wheel = _wheel(float(plant.dt), WheelParameters(*params))[2]
    if np.array_equal(wheel.A, plant.A) and np.array_equal(wheel.b, plant.b):
        return  # the usual case, checked exactly (a search calls this thousands of times)
    if not (np.allclose(wheel.A, plant.A, rtol=1e-12, atol=1e-15) and np.allclose(wheel.b, plant.b, rtol=1e-12,
                                                                                 atol=1e-15)):
        raise ValueError("plant is not the discretization of params; pass the WheelParameters it came from")


@njit(cache=True, error_model="numpy", fastmath=FASTMATH)
def arm_torque_recursion(u, a, al, tau, dtau, dct):
    """The arm torque over ``u`` (K,) from ``tau[0]`` and its tangents ``dtau[0]`` in (a, α).

    Fills ``tau`` (K + 1,), ``dtau`` (K + 1, 2) and ``dct`` (>= K, 2), the tangents of the
    effective command ``c̃_k = (u_k - α τ_k) / (1 - α)`` in (a, α). The likelihood's kernel
    (:mod:`scioc.models.delayed.kernel`) and :func:`arm_torque` share it.

    Written as ``τ_{k+1} = p τ_k + q u_k`` with p = a - (1 - a) α / (1 - α), q = (1 - a) / (1 - α),
    and its tangents ``∂τ_{k+1}/∂a = τ_k - c̃_k + p ∂τ_k/∂a``, ``∂τ_{k+1}/∂α = q (c̃_k - τ_k) + p ∂τ_k/∂α``
    (the same quantities as ``a τ_k + (1 - a) c̃_k`` and its chain rule): each recursion then waits on
    one product and one sum per step, not on c̃_k's four, and the loop runs about 4× faster
    (0.24 against 0.98 ms for the default study's 84 windows of 1500 steps, one core).
    """
    iom1 = 1.0 / (1.0 - al)
    p = a - (1.0 - a) * al * iom1
    q = (1.0 - a) * iom1
    tk = tau[0]
    tak = dtau[0, 0]
    tlk = dtau[0, 1]
    for k in range(u.shape[0]):
        uk = u[k]
        c = (uk - al * tk) * iom1  # off the recursions' path, as are the command's tangents
        dct[k, 0] = -al * tak * iom1
        dct[k, 1] = (c - tk - al * tlk) * iom1
        t_next = p * tk + q * uk
        ta_next = (tk - c) + p * tak
        tl_next = q * (c - tk) + p * tlk
        tau[k + 1] = t_next
        dtau[k + 1, 0] = ta_next
        dtau[k + 1, 1] = tl_next
        tk = t_next
        tak = ta_next
        tlk = tl_next


class ArmTorque(NamedTuple):
    """The arm torque over a torque sequence (:func:`arm_torque`).

    Attributes
    ----------
    tau : ndarray, shape (K + 1,)
        τ_0..τ_K, N·m.
    dtau : ndarray, shape (K + 1, 2)
        dτ_k/da and dτ_k/dα, N·m.
    """

    tau: np.ndarray
    dtau: np.ndarray


def arm_torque(u, a: float, alpha: float, tau_start: float = 0.0) -> ArmTorque:
    """The arm torque over observed torques and its tangents in (a, α).

    ``τ_{k+1} = a τ_k + (1 - a) c̃_k`` with ``c̃_k = (u_k - α τ_k) / (1 - α)``.

    The recursion of the module docstring run over observed (ZOH-equivalent) torques;
    ``tau[-1]`` is the arm torque after them, e.g. at the start of an analysis window
    when ``u`` holds the torques before it. ``tau_start`` is held fixed (its tangents are
    0): 0 for an arm at rest.

    Parameters
    ----------
    u : array_like, shape (K,)
        Observed torques, N·m.
    a, alpha : float
        From :func:`lag_coefficients` (α < 1).
    tau_start : float
        τ_0, N·m.

    Returns
    -------
    ArmTorque

    Examples
    --------
    >>> lag = lag_coefficients(0.06)
    >>> res = arm_torque(np.ones(400), lag.a, lag.alpha)
    >>> round(float(res.tau[-1]), 12)  # a held torque passes the lag unchanged
    1.0
    """
    u = np.ascontiguousarray(u, dtype=np.float64)
    if u.ndim != 1:
        raise ValueError(f"u must be a vector of torques; got shape {u.shape}")
    if not (np.isfinite(a) and np.isfinite(alpha) and np.isfinite(tau_start) and alpha < 1.0):
        raise ValueError(f"need finite a, alpha < 1 and tau_start; got {a!r}, {alpha!r}, {tau_start!r}")
    K = u.shape[0]
    tau = np.empty(K + 1)
    dtau = np.empty((K + 1, 2))
    tau[0] = float(tau_start)
    dtau[0] = 0.0
    arm_torque_recursion(u, float(a), float(alpha), tau, dtau, np.empty((K, 2)))
    return ArmTorque(tau, dtau)


class Warmup(NamedTuple):
    """The observed torques before a window, from which its arm torque τ_0 follows (:func:`window_tau0`).

    Attributes
    ----------
    u : ndarray, shape (J,)
        Torques before the window's first sample, N·m (J = 0: the window starts the
        recording, τ_0 = ``tau_start``).
    tau_start : float
        Arm torque before ``u[0]``, N·m, independent of the lag: 0 for an arm at rest at
        the recording's start.
    """

    u: np.ndarray
    tau_start: float = 0.0


def window_tau0(warmups, a: float, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """τ_0 of each window and its tangents in (a, α), for :func:`scioc.models.delayed.likelihood.loglik_grad`.

    Parameters
    ----------
    warmups : sequence of Warmup or None
        One per segment; None is an arm at rest at the window's start (τ_0 = 0).
    a, alpha : float
        The lag (:func:`lag_coefficients`).

    Returns
    -------
    tau0 : ndarray, shape (n,)
        N·m.
    dtau0 : ndarray, shape (n, 2)
        dτ_0/da and dτ_0/dα, N·m.
    """
    n = len(warmups)
    tau0 = np.zeros(n)
    dtau0 = np.zeros((n, 2))
    for i, w in enumerate(warmups):
        if w is None:
            continue
        res = arm_torque(w.u, a, alpha, w.tau_start)
        tau0[i] = res.tau[-1]
        dtau0[i] = res.dtau[-1]
    return tau0, dtau0


__all__ = ["ArmTorque", "LagCoefficients", "LaggedPlanningPlant", "arm_torque", "arm_torque_recursion", "check_wheel",
           "lag_coefficients", "lagged_planning_plant", "Warmup", "window_tau0"]
