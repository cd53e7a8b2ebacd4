"""The neuromuscular lag as the ``delayed`` human sees it: pole a, mixing α, and the planning plant.

The arm torque τ lags the held effective command c̃ with time constant τ_nm
(:func:`scioc.models.plant.discretize_lagged`); the recorded (ZOH-equivalent) torque follows
from that plant's velocity row: ``u_k = α τ_k + (1 - α) c̃_k``, ``τ_{k+1} = a τ_k + (1 - a) c̃_k``,
``a = exp(-dt / τ_nm)``. With μ = 1/τ_nm, (A_c, b_w) the continuous wheel and Φ = e^{A_c dt},
α = v[1] / b[1] for ``v = (A_c + μ I)⁻¹ (Φ - a I) b_w``, ``dv/dμ = (A_c + μ I)⁻¹ (dt a b_w - v)``;
near a real wheel pole at -μ the block exponential and its Fréchet derivative replace the solve.
As τ_nm -> 0, α ≈ τ_nm [Φ b_w]_1 / b[1], the one-sided derivative at 0.

Eliminating c̃, ``τ_{k+1} = p τ_k + q u_k``, p = (a - α) / (1 - α), q = (1 - a) / (1 - α), |p| < 1:
a window's τ_0 follows from the torques before it (:func:`arm_torque`), forgetting the start as |p|^k.
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
    """a = exp(-dt/τ_nm), α and their τ_nm-derivatives (1/s); at τ_nm = 0 a = α = da = 0, dalpha one-sided."""

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
    """The pole a and mixing α of the ZOH-sampled lag, and their τ_nm-derivatives, shaped as ``tau_nm``.

    ``tau_nm``: time constant(s), s, >= 0; ``dt``: sample time, s; ``params``: the wheel (Table I).

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
    """(a, α, da/dτ_nm, dα/dτ_nm) of one τ_nm, cached: a search asks for it once per segment."""
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
    """The planning plant: A = [[A_wheel - b gainᵀ, α b], [0, a]], b_c = [(1 - α) b; 1 - a], b_a = [b; 0]."""

    A: np.ndarray
    b_c: np.ndarray
    b_a: np.ndarray


def lagged_planning_plant(plant: DiscretePlant, a: float, alpha: float, gain=None) -> LaggedPlanningPlant:
    """The plant ``z_{k+1} = A z_k + b_c c_k + b_a u_A,k`` the human plans on, z = (angle, velocity, arm torque).

    From the wheel ``plant`` and the lag ``a``, ``alpha``, closed by the assistant's feedback
    ``gain`` (2,) if given; the angle row ignores the torque's shape within a sample.
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
    """The continuous wheel, its discretization and its poles, cached per (dt, params)."""
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
    """Fill τ over ``u`` (K,) from ``tau[0]``, its (a, α) tangents ``dtau`` from ``dtau[0]``, and c̃_k's in ``dct``.

    As ``τ_{k+1} = p τ_k + q u_k``, each step depends on the last through one product and one sum.
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
    """τ_0..τ_K (K + 1,) and dτ_k/d[a, α] (K + 1, 2), N·m (:func:`arm_torque`)."""

    tau: np.ndarray
    dtau: np.ndarray


def arm_torque(u, a: float, alpha: float, tau_start: float = 0.0) -> ArmTorque:
    """The arm torque over observed torques ``u`` (K,), N·m, and its tangents in (a, α), from ``tau_start``.

    ``tau[-1]`` is the arm torque after ``u``, e.g. at the start of the window that follows;
    ``tau_start`` (N·m, 0 at rest) is held fixed. A held torque passes the lag unchanged:

    >>> lag = lag_coefficients(0.06)
    >>> round(float(arm_torque(np.ones(400), lag.a, lag.alpha).tau[-1]), 12)
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
    """The torques ``u`` (J,) before a window, N·m, and the arm torque ``tau_start`` before them (0: at rest)."""

    u: np.ndarray
    tau_start: float = 0.0


def window_tau0(warmups, a: float, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """τ_0 (n,) and dτ_0/d[a, α] (n, 2) of each window from its :class:`Warmup` (None: at rest, τ_0 = 0)."""
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
