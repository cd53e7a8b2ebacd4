"""The ``delayed`` log-likelihood without its gradient, wherever a graph does not read the gradient.

A :class:`scioc.models.bayes.delayed_op.DelayedLoglikDataOp` node computes value and gradient whatever its graph
reads; the pointwise log-likelihood (``pm.compute_log_likelihood``, every kept draw) reads only the value. The
rewrite :func:`local_delayed_loglik_value_only`, registered in PyTensor's ``specialize`` phase on import (the model
builders import this module), replaces such a node by a :class:`DelayedLoglikValueOp`, which runs the kernel's
value-only path: the same number, without the reverse sweeps. ``scioc bench --parts delayed`` measures both.
"""

from __future__ import annotations

import pytensor.tensor as pt
from pytensor.gradient import grad_not_implemented
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op
from pytensor.graph.rewriting.basic import node_rewriter
from pytensor.link.numba.dispatch import basic as numba_basic
from pytensor.link.numba.dispatch.basic import numba_funcify
from pytensor.tensor.rewriting.basic import register_specialize

from scioc.models.bayes.delayed_op import DelayedLoglikDataOp, numba_funcify_delayed_loglik


class DelayedLoglikValueOp(Op):
    """The first output of ``base`` (a :class:`scioc.models.bayes.delayed_op.DelayedLoglikDataOp`) alone; not
    differentiable, as it replaces only nodes whose gradient nothing reads."""

    __props__ = ("base",)

    def __init__(self, base: DelayedLoglikDataOp):
        if not isinstance(base, DelayedLoglikDataOp):
            raise TypeError(f"DelayedLoglikValueOp wraps a DelayedLoglikDataOp; got {type(base).__name__}")
        self.base = base

    def make_node(self, *inputs):
        n = getattr(self.base, "n", None)
        return Apply(self, list(inputs), [pt.dvector(shape=(n,))])

    def perform(self, node, inputs, output_storage):
        output_storage[0][0] = self.base.values(inputs, grad=False)[0]

    def infer_shape(self, node, input_shapes):
        return [self.base.infer_shape(node, input_shapes)[0]]

    def pullback(self, inputs, outputs, cotangents):
        return [grad_not_implemented(self, j, v, "the value-only delayed likelihood") for j, v in enumerate(inputs)]


@register_specialize
@node_rewriter([DelayedLoglikDataOp])
def local_delayed_loglik_value_only(fgraph, node):
    """A delayed-likelihood node whose gradient output has no client -> :class:`DelayedLoglikValueOp`."""
    if fgraph.clients.get(node.outputs[1]):
        return None
    value = DelayedLoglikValueOp(node.op)(*node.inputs)
    return {node.outputs[0]: value}


@numba_funcify.register(DelayedLoglikValueOp)
def numba_funcify_delayed_value(op: DelayedLoglikValueOp, node=None, **kwargs):
    """Numba implementation: the base Op's, on the kernel's value-only path, first output."""
    both = numba_funcify_delayed_loglik(op.base, node=node, grad=False)

    @numba_basic.numba_njit
    def delayed_loglik_value(*args):
        return both(*args)[0]

    return delayed_loglik_value


__all__ = ["DelayedLoglikValueOp", "local_delayed_loglik_value_only", "numba_funcify_delayed_value"]
