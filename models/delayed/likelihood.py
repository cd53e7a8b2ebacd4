"""Exact likelihood of the ``delayed`` human: perceptual delay, neuromuscular lag and motor noise.

*Lag* (:mod:`.lag`). The human commands c_k; with motor noise m_k ~ N(0, σ_m²) the effective
command ``c̃_k = c_k + m_k`` drives the arm torque τ_k, and the observed torque is
``u_k = α τ_k + (1 - α) c̃_k``. Given τ_0, u -> c̃ is triangular with Jacobian (1 - α)^{-K}.

*Plan.* The human plans on z = (angle, velocity, τ) (:func:`.lag.lagged_planning_plant`; Ā
holds the assistant's law with :class:`scioc.models.segment.Feedback`, else the recorded u_A is
a known input) with the paper's Eq. 8 cost on the command over the window and M preview steps;
max-ent over the commands gives ``c_k = -L_k ẑ_k + f_k + ε_k``, ``ε_k ~ N(0, 1 / (2 S_k))``.

*Delay.* The human sees z_{k-d} and predicts the present with Ā and its own commands, not
knowing m, so ``z_k - ẑ_k = sum_{j=1..d} Ā^{j-1} b_c m_{k-j}`` and at the observed state::

    r_k = c̃_k + L_k z_k - f_k = ε_k + m_k + sum_{j=1..d} h_{k,j} m_{k-j},   h_{k,j} = L_k Ā^{j-1} b_c,
    log p(u) = log N(r; 0, Σ) - K log(1 - α),   Σ = diag(1 / (2 S_k)) + σ_m² C Cᵀ,

C the band of the h. This conditions on z_0 = (x_0, τ_0), the reference, the assistant and
the parameters, with the pre-window noises m_{-d}..m_{-1} at their prior, independent of z_0.
The observed z_k depend on θ only through (a, α), as does τ_0 inside a run (``dtau0``). With
d = τ_nm = σ_m = 0 this is :func:`scioc.models.maxent.loglik_grad`. O(K d) per segment
(:mod:`.kernel`); at τ_nm = 0 the τ_nm-derivative is one-sided, at σ_m = 0 the σ_m-one is 0.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import get_num_threads

from scioc.models.cost import validate_theta
from scioc.models.delayed.kernel import batch_kernel, batch_kernel_serial
from scioc.models.delayed.lag import check_wheel, lag_coefficients
from scioc.models.design import WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Parameter order of the gradient.
PARAMETERS = ("q11", "q22", "R", "tau_nm", "sigma_m")


class DelayedLoglikGrad(NamedTuple):
    """Log-likelihood per segment, nats (n,), and its gradient in :data:`PARAMETERS` order (5, n)."""

    loglik: np.ndarray
    grad: np.ndarray


def _per_segment(value, n: int, name: str, *, integer: bool = False, minimum: float | None = 0.0) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] != n):
        raise ValueError(f"{name} must be a scalar or have shape ({n},); got shape {arr.shape}")
    arr = np.broadcast_to(arr, (n,))
    if integer:
        if not np.all(np.isfinite(arr.astype(float))) or np.any(arr.astype(float) != np.round(arr.astype(float))):
            raise ValueError(f"{name} must be a whole number of samples; got {value!r}")
        out = np.ascontiguousarray(arr, dtype=np.int64)
    else:
        out = np.ascontiguousarray(arr, dtype=np.float64)
        if not np.all(np.isfinite(out)):
            raise ValueError(f"{name} must be finite; got {value!r}")
    if minimum is not None and np.any(out < minimum):
        raise ValueError(f"{name} must be >= {minimum:g}; got {value!r}")
    return out


def _per_segment_tangents(value, n: int) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0 and arr == 0.0:
        return np.zeros((n, 2))
    if arr.shape not in ((2,), (n, 2)):
        raise ValueError(f"dtau0 must have shape (2,) or ({n}, 2) (d tau0 / d[a, alpha]); got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"dtau0 must be finite; got {value!r}")
    return np.array(np.broadcast_to(arr, (n, 2)), dtype=np.float64, order="C")


def _run(theta, batch: SegmentBatch, plant: DiscretePlant, tau_nm, sigma_m, delay, tau0, dtau0, freeze: bool,
         params: WheelParameters, with_innovations: bool, grad: bool = True):
    """Validate, call the batch kernel; return (out (6, n), innovations (n, K or 0)), gradient NaN unless ``grad``."""
    if not isinstance(batch, SegmentBatch):
        raise TypeError(f"batch must be a models.segment.SegmentBatch (prepare_batch); got {type(batch).__name__}")
    n = batch.n
    th = validate_theta(theta)
    if th.ndim == 2 and th.shape[1] != n:
        raise ValueError(f"theta must have shape (3,) or (3, {n}); got {th.shape}")
    # always a fresh C array: one compiled specialization, and a segment's bits never depend on the caller's layout
    th = np.array(np.broadcast_to(th.reshape(3, -1), (3, n)), dtype=np.float64, order="C")
    tau = _per_segment(tau_nm, n, "tau_nm")
    sig = _per_segment(sigma_m, n, "sigma_m")
    d = _per_segment(delay, n, "delay", integer=True)
    t0 = _per_segment(tau0, n, "tau0", minimum=None)
    dt0 = _per_segment_tangents(dtau0, n)
    check_wheel(plant, params)
    if np.all(tau == tau[0]):  # one lag for the batch (the common case)
        values, inverse = tau[:1], np.zeros(n, dtype=np.intp)
    else:
        values, inverse = np.unique(tau, return_inverse=True)
    lag = np.empty((4, n))
    for row, v in enumerate(lag_coefficients(values, plant.dt, params)):
        lag[row] = np.asarray(v)[inverse]
    out = np.empty((6, n))
    inn = np.empty((n, batch.K if with_innovations else 0))
    nchunks = max(1, min(n, get_num_threads()))
    kernel = batch_kernel if nchunks > 1 else batch_kernel_serial
    kernel(plant.A, plant.b, np.ascontiguousarray(batch.fb, dtype=np.float64), th, lag, sig, d, t0, dt0, batch.x1,
           batch.x2, batch.r, batch.u, batch.a, bool(freeze), bool(grad), nchunks, out, inn)
    return out, inn


def loglik_grad(theta, batch: SegmentBatch, plant: DiscretePlant, *, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0,
                dtau0=0.0, freeze: bool = True, params: WheelParameters = WheelParameters()) -> DelayedLoglikGrad:
    """Exact log-likelihood of the ``delayed`` human and its gradient, per segment of a batch.

    Parameters
    ----------
    theta : array_like, shape (3,) or (3, n)
        ``[q11, q22, R]`` of the command cost, shared or one column per segment.
    batch, plant : SegmentBatch, DiscretePlant
        From :func:`scioc.models.segment.prepare_batch`, and the wheel at the human's sample time.
    tau_nm, sigma_m, delay, tau0 : float or array_like (n,)
        Lag (s), motor-noise SD per sample (N·m), delay (samples), all >= 0; the arm torque at
        each segment's start (N·m, 0 at rest).
    dtau0 : 0.0 or array_like (2,) or (n, 2)
        d tau0 / d[a, α] when τ_0 follows the torques before the window (:func:`.lag.window_tau0`).
    freeze : bool
        Hold the plan and the factorization once stationary; ``False`` computes every step.
    params : WheelParameters
        The wheel ``plant`` was discretized from.

    Returns
    -------
    DelayedLoglikGrad

    Examples
    --------
    >>> from scioc.models.plant import discretize
    >>> from scioc.models.segment import Segment, prepare_batch
    >>> plant = discretize(0.01)
    >>> seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> res = loglik_grad([10.0, 0.0, 1.0], prepare_batch(plant, [seg]), plant, tau_nm=0.06, sigma_m=0.2, delay=3)
    >>> res.loglik.shape, res.grad.shape
    ((1,), (5, 1))
    """
    out, _ = _run(theta, batch, plant, tau_nm, sigma_m, delay, tau0, dtau0, freeze, params, False)
    return DelayedLoglikGrad(out[0].copy(), out[1:].copy())


def loglik(theta, batch: SegmentBatch, plant: DiscretePlant, *, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0,
           freeze: bool = True, params: WheelParameters = WheelParameters()) -> np.ndarray:
    """The log-likelihood of :func:`loglik_grad` alone, (n,), without the reverse sweeps; same arguments."""
    out, _ = _run(theta, batch, plant, tau_nm, sigma_m, delay, tau0, 0.0, freeze, params, False, grad=False)
    return out[0].copy()


def innovations(theta, batch: SegmentBatch, plant: DiscretePlant, *, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0,
                params: WheelParameters = WheelParameters()) -> np.ndarray:
    """Standardized innovations of the residuals, (n, K), iid N(0, 1) under the model; as :func:`loglik_grad`."""
    _, inn = _run(theta, batch, plant, tau_nm, sigma_m, delay, tau0, 0.0, True, params, True, grad=False)
    return inn


__all__ = ["DelayedLoglikGrad", "PARAMETERS", "innovations", "loglik", "loglik_grad"]
