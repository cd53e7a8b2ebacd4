"""The human's tracking cost (paper Eq. 6), ``J = sum_{k=1..K} e_kᵀ Q e_k + sum_{k=0..K-1} R u_H,k²``.

``Q = diag(q11, q22)``, ``e_k = x_k - (r_k, 0)``, u_H,k acting from t_k to t_{k+1}. θ = [q11, q22, R] in
1/rad², 1/(rad/s)², 1/(N·m)² makes J dimensionless, as ``p(u) ∝ exp(-J)`` requires.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

THETA_NAMES = ("q11", "q22", "R")


class Theta(NamedTuple):
    """Cost parameters θ = [q11, q22, R] (Section IV-C): q11 >= 0, q22 >= 0, R > 0, units as above."""

    q11: float
    q22: float
    R: float

    def normalized(self) -> "Theta":
        """θ / θ3, the paper's normalization (Section V-A): the same optimal policy, R = 1."""
        return Theta(self.q11 / self.R, self.q22 / self.R, 1.0)


def validate_theta(theta, *, name: str = "theta") -> np.ndarray:
    """``theta`` (shape (3,) or (3, n): a column per segment) as floats, or ValueError naming ``name`` and
    the first entry that is not finite or breaks q11 >= 0, q22 >= 0, R > 0."""
    arr = np.asarray(theta, dtype=float)
    if arr.ndim not in (1, 2) or arr.shape[0] != 3:
        raise ValueError(f"{name} must have shape (3,) or (3, n) as [q11, q22, R]; got shape {arr.shape}")
    # Called for every likelihood evaluation: one vectorized check; the loop only names the bad entry.
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
    """``[q11/R, q22/R, 1]`` of θ, shape (3,) or (3, n) (Section V-A): scaling J by c > 0 keeps the optimum."""
    arr = validate_theta(theta)
    return arr / arr[2]


def from_normalized(theta1, theta2, R) -> np.ndarray:
    """θ = ``[θ1 R, θ2 R, R]`` from the normalized θ1 = q11/R, θ2 = q22/R and R (broadcastable), shape (3, ...)."""
    t1, t2, r = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta1, theta2, R)))
    return np.stack([t1 * r, t2 * r, r])


def from_log_normalized(log_theta1, theta2, log_R) -> np.ndarray:
    """θ = ``[exp(log θ1 + log R), θ2 exp(log R), exp(log R)]`` (broadcastable inputs), shape (3, ...).

    q11 is one exp of a sum, bit for bit as the PyTensor graphs of :mod:`scioc.models.bayes` write it
    (:func:`from_normalized` of the exps differs in the last bit).
    """
    lt1, t2, lr = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (log_theta1, theta2, log_R)))
    r = np.exp(lr)
    return np.stack([np.exp(lt1 + lr), t2 * r, r])

