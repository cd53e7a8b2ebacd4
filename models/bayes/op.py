"""The batched max-ent log-likelihood (paper Eq. 8) as a PyTensor Op, with a numba implementation.

One Op wraps the linear-time kernel :func:`scioc.models.maxent.batch_kernel` for use in a PyMC
model. One node computes, in one kernel call, both

* ``loglik`` (n,): the log-likelihood of each segment, nats, and
* ``grad`` (3, n): its derivative with respect to that segment's ``[q11, q22, R]``.

Its pullback multiplies the second output by the cotangent of the first, so a compiled
logp-and-gradient function (what nutpie evaluates at every leapfrog step) contains the
node once and runs the kernel once per evaluation: there is no second pass for the
gradient. Second derivatives are not implemented (NUTS needs none).

The data are the θ-independent arrays of a :class:`scioc.models.segment.SegmentBatch`
(:data:`DATA_NAMES`) and the plant matrices. They enter in one of two ways:

* :class:`MaxEntLoglikDataOp` takes them as graph inputs after θ. With the data in
  ``pm.Data`` containers a model compiled once (nutpie's numba backend) can be refitted
  to new data of the same shape with ``compiled.with_data(...)``: what simulation-based
  calibration does a thousand times. Only θ is differentiable; the data inputs are
  disconnected from the gradient. Two instances for the same plant compare equal.
* :class:`MaxEntLoglikOp`, a thin subclass, binds one batch into the instance; its only
  input is θ. Two instances compare equal only if they are the same object, so PyTensor
  never merges nodes of different data.

Both share ``perform``, the pullback and the numba implementation
(:func:`numba_funcify_maxent_loglik`). PyMC 6 compiles with numba and nutpie calls the
compiled function from several threads at once: the numba implementation calls the
njit kernel directly with ``freeze=True`` and allocates its outputs and scratch buffers
per call, so nothing runs in object mode and concurrent calls share no memory they write.
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
    # Outputs and the kernel's scratch are allocated per call: nutpie evaluates chains in
    # parallel threads.
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
    """Per-segment max-ent log-likelihood and θ-gradient, the data as inputs.

    Parameters
    ----------
    plant : DiscretePlant
        The 0.01-s wheel (its matrices are part of the Op).

    Notes
    -----
    Inputs: ``theta`` (3, n), rows ``[q11, q22, R]`` (1/rad², 1/(rad/s)², 1/(N·m)²), one
    column per segment; then ``x1``, ``x2`` (n, K + 1), ``r`` (n, K + M + 1), ``u`` (n, K),
    ``a`` (n, K + M), ``fb`` (n, 2) as in :class:`scioc.models.segment.SegmentBatch`.
    Outputs: ``loglik`` (n,) and ``grad`` (3, n), exactly as
    :func:`scioc.models.maxent.loglik_grad` returns them. θ is not validated inside the graph
    (a sampler proposes only what its transforms allow); an R <= 0 or a non-finite θ
    gives a non-finite log-likelihood, which the sampler rejects.
    """

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
    """Per-segment max-ent log-likelihood and its θ-gradient for fixed data.

    Parameters
    ----------
    batch : SegmentBatch
        From :func:`scioc.models.segment.prepare_batch`; n segments of K observed steps, whose
        plan may look M >= 0 steps further (u_A and the reference of length K + M).
    plant : DiscretePlant
        The 0.01-s wheel discretization the batch was prepared with.

    Notes
    -----
    Input: ``theta``, a float64 tensor of shape (3, n), as for :class:`MaxEntLoglikDataOp`,
    in the order of the batch. Outputs as there.

    Examples
    --------
    >>> import numpy as np, pytensor.tensor as pt
    >>> from models.segment import Segment, prepare_batch
    >>> from models.plant import discretize
    >>> plant = discretize(0.01)
    >>> seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> op = MaxEntLoglikOp(prepare_batch(plant, [seg]), plant)
    >>> theta = pt.dmatrix("theta")
    >>> ll, g = op(theta)
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
        # The plan may look M >= 0 steps past the observed torques (u_A and the reference
        # run on); the kernel's scratch covers the whole plan.
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
    """Numba implementation of both Ops: :func:`scioc.models.maxent.batch_kernel`, no object mode.

    Bound data become globals of the compiled function (numba embeds small ones as
    constants and references large ones by address; the Op keeps them alive). The
    compiled graph is not cached across sessions: the bound Op has no cache key.
    """
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
    """Symbolic per-segment max-ent log-likelihood (a new :class:`MaxEntLoglikOp` applied to θ).

    Parameters
    ----------
    theta : TensorVariable, shape (3, n)
        ``[q11, q22, R]`` per segment.
    batch : SegmentBatch
    plant : DiscretePlant

    Returns
    -------
    TensorVariable, shape (n,)
        Log-likelihood of each segment, nats; differentiable in θ.
    """
    ll, _ = MaxEntLoglikOp(batch, plant)(theta)
    return ll


__all__ = ["DATA_NAMES", "MaxEntLoglikDataOp", "MaxEntLoglikOp", "maxent_loglik", "numba_funcify_maxent_loglik"]
