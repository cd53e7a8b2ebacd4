"""The batched max-ent log-likelihood (paper Eq. 8) as a PyTensor Op, with a numba implementation.

One node runs :func:`scioc.models.maxent.batch_kernel` once for ``loglik`` (n,), nats, and ``grad`` (3, n) in each
segment's [q11, q22, R]; the pullback scales ``grad`` by the cotangent, so a logp-and-gradient function (each
leapfrog step) runs the kernel once. :class:`MaxEntLoglikDataOp` takes the data as inputs, so a model compiled once
refits new data (``compiled.with_data``, as SBC does); :class:`MaxEntLoglikOp` binds one batch and equals only
itself, so PyTensor never merges nodes of different data. nutpie calls the compiled function from several
threads: outputs and scratch are allocated per call.
"""

from __future__ import annotations

import numpy as np
import pytensor.tensor as pt
from pytensor.gradient import DisconnectedType, disconnected_type, grad_not_implemented
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify

from scioc.models.maxent import batch_kernel
from scioc.models.plant import DiscretePlant
from scioc.models.runtime import njit
from scioc.models.segment import SegmentBatch

#: The data inputs after θ, in order: the arrays of a :class:`scioc.models.segment.SegmentBatch`.
DATA_NAMES = ("x1", "x2", "r", "u", "a", "fb")


@njit(cache=True, fastmath=False, error_model="python")
def _evaluate(A, b, theta, x1, x2, r, u, a, fb):
    # Allocated per call: nutpie evaluates chains in parallel threads.
    n = u.shape[0]
    ll = np.empty(n)
    g = np.empty((3, n))
    wbuf = np.empty((a.shape[1], 2))
    vbuf = np.empty(a.shape[1])
    batch_kernel(A, b, fb, theta, x1, x2, r, u, a, True, ll, g, wbuf, vbuf)
    return ll, g


def _frozen(x) -> np.ndarray:
    arr = np.array(x, dtype=np.float64, order="C", copy=True)
    arr.flags.writeable = False
    return arr


class MaxEntLoglikDataOp(Op):
    """Per-segment max-ent log-likelihood ``loglik`` (n,) and θ-gradient ``grad`` (3, n), the data as inputs:
    ``theta`` (3, n), rows [q11, q22, R] (1/rad², 1/(rad/s)², 1/(N·m)²), then :data:`DATA_NAMES`. A non-finite θ
    gives a non-finite log-likelihood, which NUTS rejects."""

    __props__ = ("key",)
    #: The bound data (x1, x2, r, u, a, fb), or None when they are inputs.
    bound = None

    def __init__(self, plant: DiscretePlant):
        self.A = _frozen(plant.A)
        self.b = _frozen(plant.b)
        self.key = (tuple(self.A.ravel().tolist()), tuple(self.b.tolist()))

    def make_node(self, theta, x1, x2, r, u, a, fb):
        theta = pt.cast(pt.as_tensor_variable(theta), "float64")
        data = [pt.cast(pt.as_tensor_variable(v), "float64") for v in (x1, x2, r, u, a, fb)]
        if theta.type.ndim != 2 or any(d.type.ndim != 2 for d in data):
            raise TypeError("theta and every data input must be matrices")
        return Apply(self, [theta, *data], [pt.dvector(), pt.dmatrix()])

    def perform(self, node, inputs, output_storage):
        theta, *data = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs)
        ll, g = _evaluate(self.A, self.b, theta, *(data or self.bound))
        output_storage[0][0] = ll
        output_storage[1][0] = g

    def infer_shape(self, node, input_shapes):
        n = input_shapes[4][0]
        return [(n,), (3, n)]

    def pullback(self, inputs, outputs, cotangents):
        theta = inputs[0]
        _, grad = outputs
        g_ll, g_grad = cotangents
        rest = [disconnected_type() for _ in inputs[1:]]
        if not isinstance(g_grad.type, DisconnectedType):
            # d grad / d theta would be the Hessian, which the kernel does not provide.
            return [grad_not_implemented(self, 0, theta, "second derivatives of the max-ent likelihood"), *rest]
        if isinstance(g_ll.type, DisconnectedType):
            return [pt.zeros_like(theta), *rest]
        return [grad * g_ll[None, :], *rest]

    def connection_pattern(self, node):
        return [[True, True]] + [[False, False] for _ in node.inputs[1:]]


class MaxEntLoglikOp(MaxEntLoglikDataOp):
    """Per-segment max-ent log-likelihood and its θ-gradient for fixed data: input θ (3, n) in the batch's order.

    Examples
    --------
    >>> import numpy as np, pytensor.tensor as pt
    >>> from scioc.models.segment import Segment, prepare_batch
    >>> from scioc.models.plant import discretize
    >>> plant, seg = discretize(0.01), Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> theta = pt.dmatrix("theta")
    >>> ll, g = MaxEntLoglikOp(prepare_batch(plant, [seg]), plant)(theta)
    >>> ll.eval({theta: np.array([[10.0], [0.0], [1.0]])}).shape
    (1,)
    """

    # Equality is identity, because the data are part of the Op.
    __eq__ = object.__eq__
    __hash__ = object.__hash__

    def __init__(self, batch: SegmentBatch, plant: DiscretePlant):
        super().__init__(plant)
        self.x1, self.x2, self.r, self.u, self.a, self.fb = self.bound = tuple(
            _frozen(getattr(batch, name)) for name in DATA_NAMES)
        self.n = int(self.u.shape[0])
        self.K = int(self.u.shape[1])
        # The plan may look M >= 0 steps past the observed torques; the kernel's scratch covers it.
        self.K_plan = int(self.a.shape[1])

    def __str__(self):
        return f"MaxEntLoglik{{n={self.n}, K={self.K}, M={self.K_plan - self.K}}}"

    def make_node(self, theta):
        theta = pt.as_tensor_variable(theta)
        if theta.type.ndim != 2:
            raise TypeError(f"theta must be a matrix of shape (3, n); got a {theta.type.ndim}-d tensor")
        theta = pt.cast(theta, "float64")
        shape = theta.type.shape
        if shape[0] not in (None, 3) or shape[1] not in (None, self.n):
            raise ValueError(f"theta must have static shape (3, {self.n}); got {shape}")
        theta = pt.specify_shape(theta, (3, self.n))
        return Apply(self, [theta], [pt.dvector(shape=(self.n,)), pt.dmatrix(shape=(3, self.n))])

    def infer_shape(self, node, input_shapes):
        return [(self.n,), (3, self.n)]


@numba_funcify.register(MaxEntLoglikDataOp)
def numba_funcify_maxent_loglik(op: MaxEntLoglikDataOp, node=None, **kwargs):
    """Numba implementation of both Ops, no object mode; bound data are globals of the compiled function."""
    A, b = op.A, op.b
    evaluate = _evaluate
    if op.bound is None:

        @numba_basic.numba_njit
        def maxent_loglik_data(theta, x1, x2, r, u, a, fb):
            return evaluate(A, b, np.ascontiguousarray(theta), np.ascontiguousarray(x1), np.ascontiguousarray(x2),
                            np.ascontiguousarray(r), np.ascontiguousarray(u), np.ascontiguousarray(a),
                            np.ascontiguousarray(fb))

        return maxent_loglik_data
    x1, x2, r, u, a, fb = op.bound

    @numba_basic.numba_njit
    def maxent_loglik(theta):
        return evaluate(A, b, np.ascontiguousarray(theta), x1, x2, r, u, a, fb)

    return maxent_loglik


def maxent_loglik(theta, batch: SegmentBatch, plant: DiscretePlant):
    """Symbolic per-segment max-ent log-likelihood, nats, shape (n,), of θ (3, n): a new :class:`MaxEntLoglikOp`."""
    ll, _ = MaxEntLoglikOp(batch, plant)(theta)
    return ll


__all__ = ["DATA_NAMES", "MaxEntLoglikDataOp", "MaxEntLoglikOp", "maxent_loglik", "numba_funcify_maxent_loglik"]
