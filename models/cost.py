"""The human's quadratic tracking cost (paper Eq. 6) and its parameters θ = [q11, q22, R].

``J = sum_{k=1..K} e_kᵀ Q e_k + sum_{k=0..K-1} R u_H,k²`` with ``Q = diag(q11, q22)``
and ``e_k = x_k - (angle_ref_k, 0)`` (the data convention shifts the paper's control
index by one so that u_H,k acts from t_k to t_{k+1}).

Units: q11 in 1/rad², q22 in 1/(rad/s)², R in 1/(N·m)²; J is dimensionless, as the
maximum-entropy density ``p(u) ∝ exp(-J)`` requires.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

THETA_NAMES = ("q11", "q22", "R")


class Theta(NamedTuple):
    """Cost parameters θ = [q11, q22, R] (paper Section IV-C).

    Attributes
    ----------
    q11 : float
        Weight of the squared angle error, 1/rad². Must be >= 0.
    q22 : float
        Weight of the squared angular velocity, 1/(rad/s)². Must be >= 0.
    R : float
        Weight of the squared human torque, 1/(N·m)². Must be > 0.
    """

    q11: float
    q22: float
    R: float

    def normalized(self) -> "Theta":
        """θ / θ3, the paper's normalization (Section V-A): the same optimal policy, R = 1."""
        return Theta(self.q11 / self.R, self.q22 / self.R, 1.0)


def validate_theta(theta, *, name: str = "theta") -> np.ndarray:
    """Check cost parameters and return them as a float array.

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
        ``[q11, q22, R]``, optionally one column per segment.
    name : str
        How to call the argument in the error message.

    Returns
    -------
    ndarray, shape (3,) or (3, n), float64

    Raises
    ------
    ValueError
        If the shape is not (3,) or (3, n), or any entry is not finite, or
        q11 < 0, q22 < 0 or R <= 0; the message names the first offending entry.

    Examples
    --------
    >>> validate_theta([10.0, 0.0, 1.0])
    array([10.,  0.,  1.])
    """
    arr = np.asarray(theta, dtype=float)
    if arr.ndim not in (1, 2) or arr.shape[0] != 3:
        raise ValueError(f"{name} must have shape (3,) or (3, n) as [q11, q22, R]; got shape {arr.shape}")
    # The likelihoods call this tens of thousands of times in a fit: one vectorized check,
    # and the loop below only to name the first bad entry.
    if np.all(np.isfinite(arr)) and np.all(arr[:2] >= 0) and np.all(arr[2] > 0):
        return arr
    cols = arr.reshape(3, -1)
    for j in range(cols.shape[1]):
        where = "" if arr.ndim == 1 else f" (segment {j})"
        q11, q22, R = cols[:, j]
        if not np.isfinite(cols[:, j]).all():
            raise ValueError(f"{name}{where} must be finite; got q11={q11!r}, q22={q22!r}, R={R!r}")
        if q11 < 0:
            raise ValueError(f"{name}{where}: q11 must be >= 0; got {q11!r}")
        if q22 < 0:
            raise ValueError(f"{name}{where}: q22 must be >= 0; got {q22!r}")
        if R <= 0:
            raise ValueError(f"{name}{where}: R must be > 0; got {R!r}")
    return arr


def normalize(theta) -> np.ndarray:
    """Divide θ by R (paper Section V-A): ``[q11/R, q22/R, 1]``; scaling J by c > 0 keeps the optimum.

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)

    Returns
    -------
    ndarray, same shape
    """
    arr = validate_theta(theta)
    return arr / arr[2]


def from_normalized(theta1, theta2, R) -> np.ndarray:
    """``[θ1 R, θ2 R, R]``: θ = [q11, q22, R] from the paper's normalized θ1 = q11/R, θ2 = q22/R and R.

    Parameters
    ----------
    theta1, theta2, R : float or array_like, broadcastable
        1/rad², 1/(rad/s)², 1/(N·m)².

    Returns
    -------
    ndarray, shape (3,) or (3, n)
    """
    t1, t2, r = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta1, theta2, R)))
    return np.stack([t1 * r, t2 * r, r])


def from_log_normalized(log_theta1, theta2, log_R) -> np.ndarray:
    """``[exp(log θ1 + log R), θ2 exp(log R), exp(log R)]``: θ from log θ1, θ2 and log R.

    The same θ as :func:`from_normalized` of ``exp(log θ1), θ2, exp(log R)``, but q11 is one
    exp of a sum, as the PyTensor models of :mod:`scioc.models.bayes` write it in their graphs
    and the simulator draws it; the two differ in the last bit.

    Parameters
    ----------
    log_theta1, theta2, log_R : float or array_like, broadcastable
        log(1/rad²), 1/(rad/s)², log(1/(N·m)²).

    Returns
    -------
    ndarray, shape (3,) or (3, n)
    """
    lt1, t2, lr = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (log_theta1, theta2, log_R)))
    r = np.exp(lr)
    return np.stack([np.exp(lt1 + lr), t2 * r, r])

