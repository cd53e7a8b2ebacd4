"""Exact likelihood of the ``delayed`` human: perceptual delay, neuromuscular lag and motor noise.

The model
---------
Sample time dt; wheel x_k = (angle, velocity), ``x_{k+1} = A x_k + b (u_k + u_A,k)``
(:func:`scioc.models.plant.discretize`); u_k is the observed human torque, acting from t_k to
t_{k+1}.

*Lag* (:mod:`scioc.models.delayed.lag`). The human issues commands c_k; the effective command
is ``c̃_k = c_k + m_k`` with motor noise m_k. The arm torque τ follows
``τ_{k+1} = a τ_k + (1 - a) c̃_k`` and the observed (ZOH-equivalent) torque is
``u_k = α τ_k + (1 - α) c̃_k``. Given the data, τ_k is a recursion of observed torques
from the arm torque at the segment's start, τ_0 (``tau0``; 0 at rest), and
``c̃_k = (u_k - α τ_k) / (1 - α)``. The map u -> c̃ is triangular with Jacobian
(1 - α)^{-K}, so ``log p(u) = log p(c̃) - K log(1 - α)``. τ_nm = 0 gives a = α = 0 and
u = c̃.

*Plan.* The human plans on z = (x, τ), ``z_{k+1} = A_z z_k + b_c c_k + b_a u_A,k`` with
A_z = [[A, α b], [0, a]], b_c = [(1 - α) b; 1 - a], b_a = [b; 0], and the paper's Eq. 8
cost with the command in place of the torque: ``J = sum_{k=1..K+M} e_kᵀ Q e_k +
sum_k R c_k²``, e = (angle - ref, velocity), Q = diag(q11, q22) on the wheel states
only, over the window and M preview steps. With the assistant's law (a segment with
:class:`scioc.models.segment.Feedback`) it plans on ``Ā = A_z - b_a [gainᵀ, 0]`` with the
feedforward as known input, otherwise on Ā = A_z with the recorded u_A as known input;
the recursion is :func:`scioc.models.lq.lq_tracking_policy`'s (:mod:`scioc.models.delayed.riccati`).
Max-ent over the commands (as :mod:`scioc.models.maxent` over torques): given the state the
human acts on, ``c_k = -L_k ẑ_k + f_k + ε_k``, ``ε_k ~ N(0, 1 / (2 S_k))``,
``S_k = R + b_cᵀ P_{k+1} b_c``.

*Delay.* The human sees z_{k-d} (d samples, d >= 0) and predicts the present with its
internal model and its own commands; it does not know m. Motor noise is white,
``m_k ~ N(0, σ_m²)``. Then ``z_k - ẑ_k = sum_{j=1..d} Ā^{j-1} b_c m_{k-j}`` (in SC the
assistant's law acts on the true state, so it is part of Ā on both sides; with an
exogenous u_A the recorded torque enters truth and prediction alike), and the residual
of the effective command against the optimal law at the *observed* state is::

    r_k = c̃_k + L_k z_k - f_k = ε_k + m_k + sum_{j=1..d} h_{k,j} m_{k-j},
    h_{k,j} = L_k Ā^{j-1} b_c.

What is conditioned on. The density is of u_0..u_{K-1} given the initial state z_0 =
(x_0, τ_0), the reference, the assistant (its recorded torques, or its law and
feedforward) and the parameters. The motor noises before the window, m_{-d}..m_{-1},
enter r_0..r_{d-1}; they are taken independent of z_0 with their prior N(0, σ_m²)
(the human's view of z_0 from before the window is the true z_0 minus their
propagated effect; see :func:`scioc.models.delayed.sample.closed_loop`). The observed states
z_k (x_k propagated from x_0 with the observed torques, as
:func:`scioc.models.segment.prepare_batch` does, and τ_k from the recursion) depend on θ only
through (a, α) in τ_k. A window that starts inside a run has τ_0 = the arm torque
after the torques before it (:func:`scioc.models.delayed.lag.arm_torque`, from rest at the
recording's start), which depends on (a, α) as well; ``dtau0`` passes those tangents in
and the recursion carries them on.

*Likelihood.* r = ε + C m with C banded (c_{k,0} = 1, c_{k,j} = h_{k,j}, m over
-d..K-1), all terms independent and Gaussian, so r ~ N(0, Σ) with Σ = diag(1 / (2 S_k))
+ σ_m² C Cᵀ, a band matrix of bandwidth d. The map u -> r is triangular (z_k depends on
u_{<k} only) with diagonal 1/(1 - α), hence::

    log p(u) = log N(r; 0, Σ) - K log(1 - α).

With d = 0, τ_nm = 0 and σ_m = 0 this is :func:`scioc.models.maxent.loglik_grad`'s
``sum_k [-S_k v_k² + ½ log(2 S_k) - ½ log 2π]`` (tested to rounding).

Computation
-----------
Per segment, in O(K d) plus O(d²) for each row after the plan's stationary part:

* the plan (:mod:`scioc.models.delayed.riccati`): the LQ recursion backward, recording its steps
  until P is stationary to :data:`scioc.models.maxent.FREEZE_RTOL` (a few hundred steps from the
  plan's end); from there on only the s-recursion runs;
* the data: τ_k and c̃_k by their recursions, with tangents in a and α;
* log N(r; 0, Σ) in innovations form, ``Σ = L D Lᵀ`` (:mod:`scioc.models.delayed.innovations`;
  the innovations of a Kalman filter over the last d + 1 motor noises, without its
  covariance state). Where the plan is stationary Σ is Toeplitz and the Schur algorithm
  gives its factor column by column in O(d); once the columns are stationary (the
  filter's steady state, a few hundred steps for d = 30) they are not computed again and
  the solves cost O(d) per row. The rows after the plan's stationary part (the last steps
  of a plan that ends with the window, fewer with preview) are factored row by row,
  O(d²) each;
* the gradient: reverse mode through the factorization (∂/∂Σ for those rows, ∂/∂γ for the
  Toeplitz ones, back through the Schur steps), then the chain rule through the MA
  coefficients, the data recursion and the plan (:mod:`scioc.models.delayed.kernel`; the plan's
  part in :mod:`scioc.models.delayed.riccati` and :mod:`scioc.models.delayed.reverse`): one reverse
  sweep for all parameters, where forward tangents would cost five passes through an O(d²)
  filter. R comes from homogeneity.

With the stationary parts held the result equals the computation without holding them to
rounding, and the gradient is the exact derivative of the held computation (equal to the
unheld one to about 1e-13 relative; tested). At τ_nm = 0 the τ_nm-derivative is the
one-sided derivative from above (a = exp(-dt/τ_nm) is flat there, α is not); at
σ_m = 0 the σ_m-derivative is 0 (the likelihood depends on σ_m²).
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
    """Log-likelihood per segment and its gradient.

    Attributes
    ----------
    loglik : ndarray, shape (n,)
        Nats.
    grad : ndarray, shape (5, n)
        d loglik / d[q11, q22, R, τ_nm, σ_m] (:data:`PARAMETERS`).
    """

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
    """Validate the parameters, call the batch kernel; (out (6, n), innovations (n, K or 0)); ``grad`` False leaves
    the gradient rows NaN (the kernel's value-only path)."""
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
        ``[q11, q22, R]`` of the command cost, one for all segments or one column each.
    batch : SegmentBatch
        From :func:`scioc.models.segment.prepare_batch` with the same plant.
    plant : DiscretePlant
        The wheel at the human's sample time.
    tau_nm : float or array_like (n,)
        Neuromuscular time constant, s, >= 0.
    sigma_m : float or array_like (n,)
        Motor-noise SD per sample, N·m, >= 0.
    delay : int or array_like (n,)
        Perceptual delay d in samples, >= 0.
    tau0 : float or array_like (n,)
        Arm torque at each segment's start, N·m (0 at rest).
    dtau0 : 0.0 or array_like (2,) or (n, 2)
        d tau0 / d[a, α] (:class:`scioc.models.delayed.lag.LagCoefficients`): τ_0's own dependence
        on the lag when it is the arm torque after the torques before the window
        (:func:`scioc.models.delayed.lag.arm_torque`); the τ_nm-derivative then includes it.
        Default 0: τ_0 fixed.
    freeze : bool
        Hold the plan and the innovations once stationary (default); ``False`` computes
        every step, to test the fast path.
    params : WheelParameters
        The wheel ``plant`` was discretized from (needed for the lag).

    Returns
    -------
    DelayedLoglikGrad
        ``loglik`` (n,) and ``grad`` (5, n) in :data:`PARAMETERS` order.

    Examples
    --------
    >>> from models.plant import discretize
    >>> from models.segment import Segment, prepare_batch
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
    """The log-likelihood of :func:`loglik_grad` alone, (n,): the same number, without the reverse sweeps that give
    the gradient (the kernel stops after the log-density). Arguments as :func:`loglik_grad`."""
    out, _ = _run(theta, batch, plant, tau_nm, sigma_m, delay, tau0, 0.0, freeze, params, False, grad=False)
    return out[0].copy()


def innovations(theta, batch: SegmentBatch, plant: DiscretePlant, *, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0,
                params: WheelParameters = WheelParameters()) -> np.ndarray:
    """Standardized innovations ``y_k / sqrt(D_k)`` of every segment: iid N(0, 1) if the model holds.

    The innovations of the residuals r (module docstring) against their own past,
    divided by their SD (the Kalman filter's innovations over the motor noises); the
    log-likelihood is ``sum_k -½ e_k² - ½ log(2π D_k)`` plus the lag's Jacobian.
    Arguments as :func:`loglik_grad`.

    Returns
    -------
    ndarray, shape (n, K)
    """
    _, inn = _run(theta, batch, plant, tau_nm, sigma_m, delay, tau0, 0.0, True, params, True, grad=False)
    return inn


__all__ = ["DelayedLoglikGrad", "PARAMETERS", "innovations", "loglik", "loglik_grad"]
