"""The batched ``delayed`` log-likelihood as a PyTensor Op, with a numba implementation.

One call of :data:`scioc.models.delayed.kernel.batch_kernel_serial` gives ``loglik`` (n,), nats, and ``grad`` (5, n)
in each segment's q11, q22, R, τ_nm, σ_m; as for the max-ent Op (:mod:`scioc.models.bayes.op`) the pullback scales
``grad``, so logp and gradient cost one kernel call. The delay (samples) is data, and so is the arm torque τ_0 at
each window's start: a number, or the torques before the window (a Warmup), from which τ_0 and its tangents follow
by the arm's recursion at the current τ_nm. That recursion forgets its start as |p|^k, p = a - (1 - a) α / (1 - α),
so only its last :func:`warm_samples` samples are run. The numba implementation runs in the calling thread (nutpie
runs a chain per thread) and allocates per call.
"""

from __future__ import annotations

import math

import numpy as np
import pytensor.tensor as pt
from pytensor.gradient import DisconnectedType, disconnected_type, grad_not_implemented
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify

from scioc.models.bayes.delayed_lag import lag_nb, wheel_constants
from scioc.models.bayes.op import DATA_NAMES
from scioc.models.delayed.kernel import batch_kernel_serial
from scioc.models.delayed.lag import Warmup, arm_torque_recursion, check_wheel
from scioc.models.design import WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit
from scioc.models.segment import SegmentBatch

#: The data inputs after θ, τ_nm and σ_m: the batch's arrays, the delay and the packed τ_0 (:func:`pack_tau0`).
DELAYED_DATA_NAMES = (*DATA_NAMES, "delay", "warm", "warm_start", "tau_start")
#: Number of differentiable inputs (θ, τ_nm, σ_m).
N_PARAMETER_INPUTS = 3


#: The weight of the warm-up's start in τ_0 and its tangents below which older samples are not run.
WARM_EPS = 1e-20


@njit(cache=True, fastmath=False, error_model="python")
def warm_samples(a, alpha):
    """Samples of warm-up after which its start weighs < :data:`WARM_EPS` in the arm torque (lag a, α)."""
    if alpha >= 1.0:
        return 2**62
    p = abs(a - (1.0 - a) * alpha / (1.0 - alpha))
    if p >= 1.0:
        return 2**62
    if p < 1e-300:
        return 1
    return int(math.ceil(math.log(WARM_EPS) / math.log(p)))


@njit(cache=True, fastmath=False, error_model="python")
def window_start_torque(la, al, warm, j0, start, tau, dtau, dct):
    """The arm torque at a window's start and its (a, α) tangents, from its warm-up ``warm`` (J,) from index ``j0``
    on (before it: ``start``), run only over its last :func:`warm_samples` samples; ``tau`` (J + 1,), ``dtau``
    (J + 1, 2), ``dct`` (max(J, 1), 2) are work space."""
    J = warm.shape[0]
    m = warm_samples(la, al)
    if j0 < J - m:  # the warm-up's older part weighs less than WARM_EPS (module docstring)
        j0 = J - m
        start = warm[j0 - 1]
    tau[j0] = start
    dtau[j0, 0] = 0.0
    dtau[j0, 1] = 0.0
    arm_torque_recursion(warm[j0:], la, al, tau[j0:], dtau[j0:], dct)
    return tau[J], dtau[J, 0], dtau[J, 1]


@njit(cache=True, fastmath=False, error_model="python")
def _evaluate(A, b, dt, A_c, b_w, Pb, b1, poles, theta, tau_nm, sigma_m, x1, x2, r, u, a, fb, delay, warm, wstart,
              tstart, grad=True):
    n = u.shape[0]
    J = warm.shape[1]
    lag = np.empty((4, n))
    t0 = np.empty(n)
    dt0 = np.empty((n, 2))
    tau = np.empty(J + 1)
    dtau = np.empty((J + 1, 2))
    dct = np.empty((max(J, 1), 2))
    for i in range(n):
        la, al, da, dal = lag_nb(tau_nm[i], dt, A_c, b_w, Pb, b1, poles)
        lag[0, i] = la
        lag[1, i] = al
        lag[2, i] = da
        lag[3, i] = dal
        t0[i], dt0[i, 0], dt0[i, 1] = window_start_torque(la, al, warm[i], wstart[i], tstart[i], tau, dtau, dct)
    out = np.empty((6, n))
    batch_kernel_serial(A, b, fb, theta, lag, sigma_m, delay, t0, dt0, x1, x2, r, u, a, True, grad, 1, out,
                        np.empty((n, 0)))
    return out[0].copy(), out[1:].copy()


def warmups_of(tau0, n: int) -> list | None:
    """``tau0`` as a list of n Warmup or None when it gives warm-ups (:func:`pack_tau0`), else None (fixed values)."""
    if isinstance(tau0, (list, tuple)) and any(w is None or isinstance(w, Warmup) for w in tau0):
        if len(tau0) != n or not all(w is None or isinstance(w, Warmup) for w in tau0):
            raise ValueError(f"tau0 as warm-ups needs one Warmup or None per segment ({n})")
        return list(tau0)
    return None


def pack_tau0(tau0, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(warm (n, J), warm_start (n,), tau_start (n,))`` for the Op from ``tau0``: a fixed arm torque at each
    window's start, N·m (J = 0), or per segment the torques before the window (a Warmup; None: at rest)."""
    warmups = warmups_of(tau0, n)
    if warmups is not None:
        lens = [0 if w is None else np.asarray(w.u).shape[0] for w in warmups]
        J = max(lens)
        warm = np.zeros((n, J))
        start = np.empty(n, dtype=np.int64)
        tstart = np.zeros(n)
        for i, (w, m) in enumerate(zip(warmups, lens)):
            start[i] = J - m
            if w is not None:
                warm[i, J - m:] = np.asarray(w.u, dtype=float)
                tstart[i] = float(w.tau_start)
        if not (np.isfinite(warm).all() and np.isfinite(tstart).all()):
            raise ValueError("the warm-up torques and their tau_start must be finite")
        return warm, start, tstart
    fixed = np.broadcast_to(np.asarray(tau0, dtype=float), (n,))
    if not np.isfinite(fixed).all():
        raise ValueError(f"tau0 must be finite; got {tau0!r}")
    return np.zeros((n, 0)), np.zeros(n, dtype=np.int64), np.array(fixed)


def _frozen(x, dtype=np.float64) -> np.ndarray:
    arr = np.array(x, dtype=dtype, order="C", copy=True)
    arr.flags.writeable = False
    return arr


class ParameterGradient:
    """``perform`` and the pullback of an Op whose ``values(inputs)`` gives its outputs ``loglik`` (n,) and ``grad``
    (5, n) in its first :data:`N_PARAMETER_INPUTS` inputs, θ (3, n), τ_nm (n,) and σ_m (n,): logp and gradient cost
    one call."""

    def perform(self, node, inputs, output_storage):
        ll, g = self.values(inputs)
        output_storage[0][0] = ll
        output_storage[1][0] = g

    def pullback(self, inputs, outputs, cotangents):
        _, grad = outputs
        g_ll, g_grad = cotangents
        params = inputs[:N_PARAMETER_INPUTS]
        rest = [disconnected_type() for _ in inputs[N_PARAMETER_INPUTS:]]
        if not isinstance(g_grad.type, DisconnectedType):
            return [grad_not_implemented(self, j, v, "second derivatives of the delayed likelihood")
                    for j, v in enumerate(params)] + rest
        if isinstance(g_ll.type, DisconnectedType):
            return [pt.zeros_like(v) for v in params] + rest
        return [grad[:3] * g_ll[None, :], grad[3] * g_ll, grad[4] * g_ll, *rest]

    def connection_pattern(self, node):
        return [[True, True]] * N_PARAMETER_INPUTS + [[False, False] for _ in node.inputs[N_PARAMETER_INPUTS:]]


class DelayedLoglikDataOp(ParameterGradient, Op):
    """Per-segment ``delayed`` log-likelihood and its gradient in (θ, τ_nm, σ_m), the data as inputs.

    Inputs: ``theta`` (3, n) rows q11, q22, R; ``tau_nm`` (n,), s; ``sigma_m`` (n,), N·m; :data:`DELAYED_DATA_NAMES`.
    Outputs ``loglik`` (n,) and ``grad`` (5, n), as :func:`scioc.models.delayed.loglik_grad`'s. ``plant`` is the wheel
    at the recording's sample time, ``params`` the wheel it was discretized from.
    """

    __props__ = ("key",)
    bound = None

    def __init__(self, plant: DiscretePlant, params: WheelParameters = WheelParameters()):
        check_wheel(plant, params)
        self.A = _frozen(plant.A)
        self.b = _frozen(plant.b)
        self.wheel = wheel_constants(plant.dt, params)
        self.key = (tuple(self.A.ravel().tolist()), tuple(self.b.tolist()), float(plant.dt), tuple(params))

    def make_node(self, theta, tau_nm, sigma_m, x1, x2, r, u, a, fb, delay, warm, warm_start, tau_start):
        theta, tau_nm, sigma_m = (pt.cast(pt.as_tensor_variable(v), "float64") for v in (theta, tau_nm, sigma_m))
        if theta.type.ndim != 2 or tau_nm.type.ndim != 1 or sigma_m.type.ndim != 1:
            raise TypeError("theta must be a matrix (3, n), tau_nm and sigma_m vectors (n,)")
        mats = [pt.cast(pt.as_tensor_variable(v), "float64") for v in (x1, x2, r, u, a, fb, warm)]
        ints = [pt.cast(pt.as_tensor_variable(v), "int64") for v in (delay, warm_start)]
        tstart = pt.cast(pt.as_tensor_variable(tau_start), "float64")
        data = [*mats[:6], ints[0], mats[6], ints[1], tstart]
        return Apply(self, [theta, tau_nm, sigma_m, *data], [pt.dvector(), pt.dmatrix()])

    def values(self, inputs, grad: bool = True):
        """(log-likelihood (n,), gradient (5, n)) at a node's input values; ``grad`` False: the value alone."""
        theta, tau_nm, sigma_m = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs[:3])
        data = inputs[3:] or self.bound
        data = [np.ascontiguousarray(v, dtype=np.int64 if j in (6, 8) else np.float64) for j, v in enumerate(data)]
        return _evaluate(self.A, self.b, *self.wheel, theta, tau_nm, sigma_m, *data, grad)

    def infer_shape(self, node, input_shapes):
        n = input_shapes[1][0]
        return [(n,), (5, n)]

class DelayedLoglikOp(DelayedLoglikDataOp):
    """Per-segment ``delayed`` log-likelihood for fixed data: inputs θ (3, n), τ_nm (n,), σ_m (n,), and
    optionally a sampled ``delay`` (n,) in place of the bound one (samples); ``tau0`` as :func:`pack_tau0`."""

    __eq__ = object.__eq__
    __hash__ = object.__hash__

    def __init__(self, batch: SegmentBatch, plant: DiscretePlant, *, delay, tau0=0.0,
                 params: WheelParameters = WheelParameters()):
        super().__init__(plant, params)
        n = int(batch.n)
        d = np.broadcast_to(np.asarray(delay), (n,))
        if not (np.all(np.isfinite(d.astype(float))) and np.all(d == np.round(d)) and np.all(d >= 0)):
            raise ValueError(f"delay must be whole numbers of samples >= 0, one per segment; got {delay!r}")
        arrays = [getattr(batch, name) for name in DATA_NAMES]
        warm, start, tstart = pack_tau0(tau0, n)
        self.bound = tuple(_frozen(v) for v in arrays) + (_frozen(d, np.int64), _frozen(warm),
                                                          _frozen(start, np.int64), _frozen(tstart))
        self.n, self.K, self.delay = n, int(batch.K), self.bound[6]

    def __str__(self):
        return f"DelayedLoglik{{n={self.n}, K={self.K}, d={int(self.delay.min())}..{int(self.delay.max())}}}"

    def make_node(self, theta, tau_nm, sigma_m, delay=None):
        theta, tau_nm, sigma_m = (pt.cast(pt.as_tensor_variable(v), "float64") for v in (theta, tau_nm, sigma_m))
        if theta.type.ndim != 2 or tau_nm.type.ndim != 1 or sigma_m.type.ndim != 1:
            raise TypeError(f"theta must be a matrix (3, {self.n}), tau_nm and sigma_m vectors ({self.n},)")
        if theta.type.shape[0] not in (None, 3) or any(s not in (None, self.n) for s in
                                                        (theta.type.shape[1], tau_nm.type.shape[0],
                                                         sigma_m.type.shape[0])):
            raise ValueError(f"theta must have shape (3, {self.n}), tau_nm and sigma_m ({self.n},)")
        theta = pt.specify_shape(theta, (3, self.n))
        tau_nm = pt.specify_shape(tau_nm, (self.n,))
        sigma_m = pt.specify_shape(sigma_m, (self.n,))
        inputs = [theta, tau_nm, sigma_m]
        if delay is not None:  # the delays as an input (sampled), in place of the bound ones
            inputs.append(pt.specify_shape(pt.cast(pt.as_tensor_variable(delay), "int64"), (self.n,)))
        return Apply(self, inputs, [pt.dvector(shape=(self.n,)), pt.dmatrix(shape=(5, self.n))])

    def values(self, inputs, grad: bool = True):
        data = list(self.bound)
        if len(inputs) > N_PARAMETER_INPUTS:
            data[6] = np.ascontiguousarray(inputs[N_PARAMETER_INPUTS], dtype=np.int64)
        theta, tau_nm, sigma_m = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs[:N_PARAMETER_INPUTS])
        return _evaluate(self.A, self.b, *self.wheel, theta, tau_nm, sigma_m, *data, grad)

    def infer_shape(self, node, input_shapes):
        return [(self.n,), (5, self.n)]


@numba_funcify.register(DelayedLoglikDataOp)
def numba_funcify_delayed_loglik(op: DelayedLoglikDataOp, node=None, grad: bool = True, **kwargs):
    """Numba implementation of both Ops, no object mode; ``grad`` False for the value alone."""
    A, b = op.A, op.b
    dt, A_c, b_w, Pb, b1, poles = op.wheel
    evaluate = _evaluate
    if op.bound is None:

        @numba_basic.numba_njit
        def delayed_loglik_data(theta, tau_nm, sigma_m, x1, x2, r, u, a, fb, delay, warm, wstart, tstart):
            c = np.ascontiguousarray
            return evaluate(A, b, dt, A_c, b_w, Pb, b1, poles, c(theta), c(tau_nm), c(sigma_m), c(x1), c(x2), c(r),
                            c(u), c(a), c(fb), c(delay), c(warm), c(wstart), c(tstart), grad)

        return delayed_loglik_data
    x1, x2, r, u, a, fb, delay, warm, wstart, tstart = op.bound
    if node is not None and len(node.inputs) > N_PARAMETER_INPUTS:

        @numba_basic.numba_njit
        def delayed_loglik_sampled(theta, tau_nm, sigma_m, d):
            c = np.ascontiguousarray
            return evaluate(A, b, dt, A_c, b_w, Pb, b1, poles, c(theta), c(tau_nm), c(sigma_m), x1, x2, r, u, a, fb,
                            c(d), warm, wstart, tstart, grad)

        return delayed_loglik_sampled

    @numba_basic.numba_njit
    def delayed_loglik(theta, tau_nm, sigma_m):
        c = np.ascontiguousarray
        return evaluate(A, b, dt, A_c, b_w, Pb, b1, poles, c(theta), c(tau_nm), c(sigma_m), x1, x2, r, u, a, fb,
                        delay, warm, wstart, tstart, grad)

    return delayed_loglik


def delayed_loglik(theta, tau_nm, sigma_m, batch: SegmentBatch, plant: DiscretePlant, *, delay, tau0=0.0,
                   params: WheelParameters = WheelParameters()):
    """Symbolic per-segment ``delayed`` log-likelihood (a new :class:`DelayedLoglikOp`), nats, shape (n,)."""
    ll, _ = DelayedLoglikOp(batch, plant, delay=delay, tau0=tau0, params=params)(theta, tau_nm, sigma_m)
    return ll


__all__ = ["ParameterGradient", "WARM_EPS", "warm_samples", "window_start_torque", "DELAYED_DATA_NAMES", "DelayedLoglikDataOp", "DelayedLoglikOp", "delayed_loglik",
           "numba_funcify_delayed_loglik", "pack_tau0", "warmups_of"]
