"""Steering-wheel dynamics (paper Eq. 18, Table I) and their exact zero-order-hold discretization.

The wheel is a damped rotational spring driven by the sum of the human torque
``u_H`` and the assistant torque ``u_A`` (both in N·m, entering through the same
input vector, so ``B_H = B_A``)::

    d/dt [phi, phi_dot] = [[0, 1], [-c/J, -d/J]] [phi, phi_dot] + [0, 1/J] (u_H + u_A)

State ``x = (phi, phi_dot)`` in (rad, rad/s). The parameters and sample times are the
study design's (:mod:`scioc.models.design`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import expm

from scioc.models.design import DT_HUMAN, WheelParameters
from scioc.models.runtime import njit


class DiscretePlant(NamedTuple):
    """Discrete-time plant ``x[k+1] = A x[k] + b (u_H[k] + u_A[k])`` (paper Eq. 1).

    Attributes
    ----------
    A : ndarray, shape (2, 2)
        State transition over one sample.
    b : ndarray, shape (2,)
        Input vector for a torque held constant over the sample (ZOH), (rad, rad/s) per N·m.
    dt : float
        Sample time, s.
    """

    A: np.ndarray
    b: np.ndarray
    dt: float


def continuous_matrices(params: WheelParameters = WheelParameters()) -> tuple[np.ndarray, np.ndarray]:
    """Continuous-time matrices of paper Eq. 18.

    Parameters
    ----------
    params : WheelParameters
        Inertia (kg·m²), spring (N·m/rad) and damper (N·m·s/rad); Table I by default.

    Returns
    -------
    A_c : ndarray, shape (2, 2)
    b_c : ndarray, shape (2,)

    Examples
    --------
    >>> A_c, b_c = continuous_matrices()
    >>> float(b_c[1])
    25.0
    """
    J, c, d = (float(v) for v in params)
    if not (J > 0 and c >= 0 and d >= 0 and np.isfinite([J, c, d]).all()):
        raise ValueError(f"wheel parameters must be finite with inertia > 0, spring >= 0, damper >= 0; got {params}")
    A_c = np.array([[0.0, 1.0], [-c / J, -d / J]])
    b_c = np.array([0.0, 1.0 / J])
    return A_c, b_c


def discretize(dt: float = DT_HUMAN, params: WheelParameters = WheelParameters()) -> DiscretePlant:
    """Exact zero-order-hold discretization of Eq. 18 for sample time ``dt``.

    Uses the block matrix exponential ``expm([[A_c, b_c], [0, 0]] dt)``, which is
    exact for an input held constant over each sample.

    Parameters
    ----------
    dt : float
        Sample time in s (0.01 for the human, 0.02 for the assistant).
    params : WheelParameters
        Table I by default.

    Returns
    -------
    DiscretePlant

    Examples
    --------
    >>> plant = discretize(0.01)
    >>> plant.A.shape, plant.b.shape
    ((2, 2), (2,))
    """
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
    """States driven from ``x0`` by the total torque sequence ``u`` (paper Eq. 11).

    Parameters
    ----------
    plant : DiscretePlant
    x0 : ndarray, shape (2,)
        Initial angle (rad) and velocity (rad/s).
    u : ndarray, shape (K,)
        Total torque ``u_H + u_A`` in N·m acting from t_k to t_{k+1}.

    Returns
    -------
    ndarray, shape (K + 1, 2)
        States x_0 .. x_K.
    """
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
    """The wheel driven through a first-order neuromuscular lag, sampled with ZOH.

    State ``z = (phi, phi_dot, tau)`` in (rad, rad/s, N·m), where ``tau`` is the torque
    the arm applies to the wheel::

        z[k+1] = A z[k] + b_c c[k] + b_a u_A[k]

    Attributes
    ----------
    A : ndarray, shape (3, 3)
    b_c : ndarray, shape (3,)
        Input vector of the command ``c`` into the lag (N·m, held over the sample).
    b_a : ndarray, shape (3,)
        Input vector of a torque acting on the wheel directly (the assistant's u_A);
        equal to ``(b, 0)`` of the plain wheel.
    dt : float
        Sample time, s.
    tau_nm : float
        Time constant of the lag, s.
    """

    A: np.ndarray
    b_c: np.ndarray
    b_a: np.ndarray
    dt: float
    tau_nm: float


def discretize_lagged(tau_nm: float, dt: float = DT_HUMAN, params: WheelParameters = WheelParameters()) -> LaggedPlant:
    """Exact ZOH discretization of the wheel with a neuromuscular lag on the human torque.

    Continuous dynamics (J, c, d of Table I)::

        J phi'' = -c phi - d phi' + tau + u_A,      tau_nm tau' = c_cmd - tau

    Both inputs (the command ``c_cmd`` and ``u_A``) are held over each sample; the
    block matrix exponential of the 3-state system gives A, b_c and b_a at once.

    Parameters
    ----------
    tau_nm : float
        Neuromuscular time constant, s (> 0).
    dt : float
        Sample time, s (default 0.01).
    params : WheelParameters
        Table I by default.

    Returns
    -------
    LaggedPlant

    Examples
    --------
    >>> lp = discretize_lagged(0.1)
    >>> lp.A.shape, lp.b_c.shape, float(lp.b_a[2])
    ((3, 3), (3,), 0.0)
    """
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
