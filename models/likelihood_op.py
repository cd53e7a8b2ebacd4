"""The batched max-ent log-likelihood (paper Eq. 8) as a PyTensor Op, with a numba implementation.

:class:`MaxEntLoglikOp` wraps the linear-time kernel of :mod:`models.maxent` for use in a
PyMC model. One node computes, in one kernel call, both

* ``loglik`` (n,): the log-likelihood of each segment, nats, and
* ``grad`` (3, n): its derivative with respect to that segment's ``[q11, q22, R]``.

Its pullback multiplies the second output by the cotangent of the first, so a compiled
logp-and-gradient function (what nutpie evaluates at every leapfrog step) contains the
node once and runs the kernel once per evaluation: there is no second pass for the
gradient. Second derivatives are not implemented (NUTS needs none).

The data (the θ-independent arrays of a :class:`models.maxent.SegmentBatch` and the plant
matrices) are baked into the Op instance; its only input is θ. Two instances compare
equal only if they are the same object, so PyTensor never merges nodes of different data.

PyMC 6 compiles with numba and nutpie calls the compiled function from several threads
at once. The numba implementation registered here (:func:`numba_funcify_MaxEntLoglikOp`)
calls the njit kernel :func:`models.maxent._batch_kernel` directly with ``freeze=True``
and allocates its outputs and scratch buffers per call, so nothing runs in object mode
and concurrent calls share no memory they write.
"""

from __future__ import annotations

import numpy as np
import pytensor.tensor as pt
from pytensor.gradient import DisconnectedType, grad_not_implemented
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify

from models.maxent import SegmentBatch, _batch_kernel
from models.plant import DiscretePlant


class MaxEntLoglikOp(Op):
    """Per-segment max-ent log-likelihood and its θ-gradient for fixed data.

    Parameters
    ----------
    batch : SegmentBatch
        From :func:`models.maxent.prepare_batch`; n segments of K observed steps, whose
        plan may look M >= 0 steps further (u_A and the reference of length K + M).
    plant : DiscretePlant
        The 0.01-s wheel discretization the batch was prepared with.

    Notes
    -----
    Input: ``theta``, a float64 tensor of shape (3, n): rows ``[q11, q22, R]``
    (1/rad², 1/(rad/s)², 1/(N·m)²), one column per segment, in the order of the batch.

    Outputs: ``loglik`` of shape (n,) and ``grad`` of shape (3, n), exactly as
    :func:`models.maxent.loglik_grad` returns them. θ is not validated inside the
    graph (a sampler proposes only what its transforms allow); an R <= 0 or a
    non-finite θ gives a non-finite log-likelihood, which the sampler rejects.

    Examples
    --------
    >>> import numpy as np, pytensor.tensor as pt
    >>> from models.maxent import Segment, prepare_batch
    >>> from models.plant import discretize
    >>> plant = discretize(0.01)
    >>> seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> op = MaxEntLoglikOp(prepare_batch(plant, [seg]), plant)
    >>> theta = pt.dmatrix("theta")
    >>> ll, g = op(theta)
    >>> ll.eval({theta: np.array([[10.0], [0.0], [1.0]])}).shape
    (1,)
    """

    # No __props__: equality is identity, because the data are part of the Op.

    def __init__(self, batch: SegmentBatch, plant: DiscretePlant):
        def c(x):
            arr = np.array(x, dtype=np.float64, order="C", copy=True)
            arr.flags.writeable = False
            return arr

        self.A = c(plant.A)
        self.b = c(plant.b)
        self.x1 = c(batch.x1)
        self.x2 = c(batch.x2)
        self.r = c(batch.r)
        self.u = c(batch.u)
        self.a = c(batch.a)
        self.fb = c(batch.fb)
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

    def perform(self, node, inputs, output_storage):
        (theta,) = inputs
        th = np.array(theta, dtype=np.float64, order="C")
        ll = np.empty(self.n)
        g = np.empty((3, self.n))
        wbuf = np.empty((self.K_plan, 2))
        vbuf = np.empty(self.K_plan)
        _batch_kernel(self.A, self.b, self.fb, th, self.x1, self.x2, self.r, self.u, self.a, True, ll, g, wbuf, vbuf)
        output_storage[0][0] = ll
        output_storage[1][0] = g

    def infer_shape(self, node, input_shapes):
        return [(self.n,), (3, self.n)]

    def pullback(self, inputs, outputs, cotangents):
        (theta,) = inputs
        _, grad = outputs
        g_ll, g_grad = cotangents
        if not isinstance(g_grad.type, DisconnectedType):
            # d grad / d theta would be the Hessian, which the kernel does not provide.
            return [grad_not_implemented(self, 0, theta, "second derivatives of the max-ent likelihood")]
        if isinstance(g_ll.type, DisconnectedType):
            return [pt.zeros_like(theta)]
        return [grad * g_ll[None, :]]

    def connection_pattern(self, node):
        return [[True, True]]


@numba_funcify.register(MaxEntLoglikOp)
def numba_funcify_MaxEntLoglikOp(op: MaxEntLoglikOp, node=None, **kwargs):
    """Numba implementation: calls :func:`models.maxent._batch_kernel` (no object mode).

    The data arrays become globals of the compiled function (numba embeds small ones as
    constants and references large ones by address; the Op keeps them alive). The
    compiled graph is not cached across sessions because the Op has no cache key.
    """
    A, b, fb, x1, x2, r, u, a = op.A, op.b, op.fb, op.x1, op.x2, op.r, op.u, op.a
    n, K_plan = op.n, op.K_plan
    kernel = _batch_kernel

    @numba_basic.numba_njit
    def maxent_loglik(theta):
        th = np.ascontiguousarray(theta)
        ll = np.empty(n)
        g = np.empty((3, n))
        # Scratch per call: nutpie evaluates chains in parallel threads.
        wbuf = np.empty((K_plan, 2))
        vbuf = np.empty(K_plan)
        kernel(A, b, fb, th, x1, x2, r, u, a, True, ll, g, wbuf, vbuf)
        return ll, g

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


__all__ = ["MaxEntLoglikOp", "maxent_loglik", "numba_funcify_MaxEntLoglikOp"]
