"""The steering wheel ``J phi'' = -c phi - d phi' + u_H + u_A`` (paper Eq. 18, Table I), exactly discretized.

State ``x = (phi, phi_dot)`` in (rad, rad/s); both torques (N·m) enter alike, ``B_H = B_A``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import expm

from scioc.models.design import DT_HUMAN, WheelParameters
from scioc.models.runtime import njit


class DiscretePlant(NamedTuple):
    """Discrete-time plant ``x[k+1] = A x[k] + b (u_H[k] + u_A[k])`` (paper Eq. 1).

    ``A`` (2, 2); ``b`` (2,), (rad, rad/s) per N·m of a torque held over the sample; ``dt`` in s.
    """

    A: np.ndarray
    b: np.ndarray
    dt: float


def continuous_matrices(params: WheelParameters = WheelParameters()) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time ``A_c`` (2, 2) and ``b_c`` (2,) of paper Eq. 18 for ``params`` (Table I by default)."""
    J, c, d = (float(v) for v in params)
    if not (J > 0 and c >= 0 and d >= 0 and np.isfinite([J, c, d]).all()):
        raise ValueError(f"wheel parameters must be finite with inertia > 0, spring >= 0, damper >= 0; got {params}")
    A_c = np.array([[0.0, 1.0], [-c / J, -d / J]])
    b_c = np.array([0.0, 1.0 / J])
    return A_c, b_c


def discretize(dt: float = DT_HUMAN, params: WheelParameters = WheelParameters()) -> DiscretePlant:
    """Exact ZOH discretization of Eq. 18, ``expm([[A_c, b_c], [0, 0]] dt)``, for sample time ``dt``, s."""
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample time dt must be a positive number of seconds; got {dt!r}")
    A_c, b_c = continuous_matrices(params)
    M = np.zeros((3, 3))
    M[:2, :2] = A_c
    M[:2, 2] = b_c
    E = expm(M * dt)
    A = np.ascontiguousarray(E[:2, :2])
    b = np.ascontiguousarray(E[:2, 2])
    return DiscretePlant(A=A, b=b, dt=float(dt))


def propagate(plant: DiscretePlant, x0: np.ndarray, u: np.ndarray) -> np.ndarray:
    """States x_0..x_K (K + 1, 2) driven from ``x0`` (rad, rad/s) by the total torque ``u`` (K,), N·m (Eq. 11)."""
    u = np.ascontiguousarray(u, dtype=float)
    x0 = np.asarray(x0, dtype=float)
    return _propagate(plant.A, plant.b, x0[0], x0[1], u)


@njit(cache=True, fastmath=False, error_model="python")
def _propagate(A, b, phi0, omega0, u):
    x = np.empty((u.shape[0] + 1, 2))
    x[0, 0] = phi0
    x[0, 1] = omega0
    for k in range(u.shape[0]):
        x[k + 1, 0] = A[0, 0] * x[k, 0] + A[0, 1] * x[k, 1] + b[0] * u[k]
        x[k + 1, 1] = A[1, 0] * x[k, 0] + A[1, 1] * x[k, 1] + b[1] * u[k]
    return x


class LaggedPlant(NamedTuple):
    """The wheel behind a neuromuscular lag, ``z[k+1] = A z[k] + b_c c[k] + b_a u_A[k]``, z = (phi, phi_dot,
    tau) in (rad, rad/s, N·m): the command ``c`` drives the lag, ``b_a = (b, 0)``; ``dt``, ``tau_nm`` in s."""

    A: np.ndarray
    b_c: np.ndarray
    b_a: np.ndarray
    dt: float
    tau_nm: float


def discretize_lagged(tau_nm: float, dt: float = DT_HUMAN, params: WheelParameters = WheelParameters()) -> LaggedPlant:
    """Exact ZOH discretization of ``J phi'' = -c phi - d phi' + tau + u_A``, ``tau_nm tau' = c_cmd - tau`` (s)."""
    if not (np.isfinite(tau_nm) and tau_nm > 0):
        raise ValueError(f"neuromuscular time constant tau_nm must be a positive number of seconds; got {tau_nm!r}")
    if not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"sample time dt must be a positive number of seconds; got {dt!r}")
    A_c, b_w = continuous_matrices(params)
    M = np.zeros((5, 5))
    M[:2, :2] = A_c
    M[:2, 2] = b_w  # the arm's torque drives the wheel like u_A does
    M[2, 2] = -1.0 / tau_nm
    M[2, 3] = 1.0 / tau_nm  # command into the lag
    M[:2, 4] = b_w  # u_A
    E = expm(M * dt)
    return LaggedPlant(A=np.ascontiguousarray(E[:3, :3]), b_c=np.ascontiguousarray(E[:3, 3]),
                       b_a=np.ascontiguousarray(E[:3, 4]), dt=float(dt), tau_nm=float(tau_nm))
