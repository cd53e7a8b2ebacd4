"""The batched max-ent likelihood as a PyTensor Op whose data are inputs, not constants.

:class:`MaxEntLoglikDataOp` computes the same outputs as
:class:`models.likelihood_op.MaxEntLoglikOp` (per-segment log-likelihood and its
θ-gradient, one kernel call), but takes the θ-independent arrays of a
:class:`models.maxent.SegmentBatch` as graph inputs. With the data in ``pm.Data``
containers a model compiled once (nutpie's numba backend) can be refitted to new data
of the same shape with ``compiled.with_data(...)``: what simulation-based calibration
does a thousand times. Only θ is differentiable; the data inputs are disconnected from
the gradient.
"""

from __future__ import annotations

import numpy as np
import pytensor.tensor as pt
from pytensor.gradient import DisconnectedType, disconnected_type, grad_not_implemented
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify

from models.maxent import _batch_kernel
from models.plant import DiscretePlant

DATA_NAMES = ("x1", "x2", "r", "u", "a", "fb")


class MaxEntLoglikDataOp(Op):
    """Per-segment max-ent log-likelihood and θ-gradient with data as inputs.

    Parameters
    ----------
    plant : DiscretePlant
        The 0.01-s wheel (its matrices are part of the Op).

    Notes
    -----
    Inputs: ``theta`` (3, n), then ``x1``, ``x2`` (n, K + 1), ``r`` (n, K + M + 1),
    ``u`` (n, K), ``a`` (n, K + M), ``fb`` (n, 2) as in :class:`models.maxent.SegmentBatch`.
    Outputs: ``loglik`` (n,) and ``grad`` (3, n).
    """

    __props__ = ("key",)

    def __init__(self, plant: DiscretePlant):
        self.A = np.array(plant.A, dtype=np.float64, order="C")
        self.b = np.array(plant.b, dtype=np.float64, order="C")
        self.key = (tuple(self.A.ravel().tolist()), tuple(self.b.tolist()))

    def make_node(self, theta, x1, x2, r, u, a, fb):
        theta = pt.cast(pt.as_tensor_variable(theta), "float64")
        data = [pt.cast(pt.as_tensor_variable(v), "float64") for v in (x1, x2, r, u, a, fb)]
        if theta.type.ndim != 2 or any(d.type.ndim != 2 for d in data):
            raise TypeError("theta and every data input must be matrices")
        return Apply(self, [theta, *data], [pt.dvector(), pt.dmatrix()])

    def perform(self, node, inputs, output_storage):
        theta, x1, x2, r, u, a, fb = (np.ascontiguousarray(v, dtype=np.float64) for v in inputs)
        n = u.shape[0]
        ll = np.empty(n)
        g = np.empty((3, n))
        wbuf = np.empty((a.shape[1], 2))
        vbuf = np.empty(a.shape[1])
        _batch_kernel(self.A, self.b, fb, theta, x1, x2, r, u, a, True, ll, g, wbuf, vbuf)
        output_storage[0][0] = ll
        output_storage[1][0] = g

    def infer_shape(self, node, input_shapes):
        n = input_shapes[4][0]
        return [(n,), (3, n)]

    def pullback(self, inputs, outputs, cotangents):
        theta = inputs[0]
        _, grad = outputs
        g_ll, g_grad = cotangents
        rest = [disconnected_type() for _ in DATA_NAMES]
        if not isinstance(g_grad.type, DisconnectedType):
            return [grad_not_implemented(self, 0, theta, "second derivatives of the max-ent likelihood"), *rest]
        if isinstance(g_ll.type, DisconnectedType):
            return [pt.zeros_like(theta), *rest]
        return [grad * g_ll[None, :], *rest]

    def connection_pattern(self, node):
        return [[True, True]] + [[False, False] for _ in DATA_NAMES]


@numba_funcify.register(MaxEntLoglikDataOp)
def numba_funcify_MaxEntLoglikDataOp(op: MaxEntLoglikDataOp, node=None, **kwargs):
    """Numba implementation calling :func:`models.maxent._batch_kernel` (no object mode)."""
    A, b = op.A, op.b
    kernel = _batch_kernel

    @numba_basic.numba_njit
    def maxent_loglik_data(theta, x1, x2, r, u, a, fb):
        n = u.shape[0]
        ll = np.empty(n)
        g = np.empty((3, n))
        # Scratch per call: nutpie evaluates chains in parallel threads.
        wbuf = np.empty((a.shape[1], 2))
        vbuf = np.empty(a.shape[1])
        kernel(A, b, np.ascontiguousarray(fb), np.ascontiguousarray(theta), np.ascontiguousarray(x1), np.ascontiguousarray(x2),
               np.ascontiguousarray(r), np.ascontiguousarray(u), np.ascontiguousarray(a), True, ll, g, wbuf, vbuf)
        return ll, g

    return maxent_loglik_data
