"""The PyTensor Op around the max-ent kernel: values, gradient, one kernel call, no object mode."""

import warnings

import numpy as np
import pytensor
import pytensor.tensor as pt
import pytest
from pytensor.graph.basic import Apply
from pytensor.graph.op import Op

from scioc.models.bayes.op import DATA_NAMES, MaxEntLoglikDataOp, MaxEntLoglikOp, maxent_loglik
from scioc.models.maxent import loglik_grad
from scioc.models.segment import Segment, prepare_batch
from tests.conftest import random_segment, random_theta

OBJECT_MODE = "object mode"


def preview_segment(rng, K, M, shared):
    """A segment with K observed torques whose plan looks M steps further (u_A, reference)."""
    seg = random_segment(rng, K + M, shared)
    return Segment(seg.x0, seg.angle_ref, seg.u_H[:K], seg.u_A)


def _setup(plant, M):
    rng = np.random.default_rng([20, M])
    segs = [preview_segment(rng, 120, M, i % 2 == 1) for i in range(4)]
    batch = prepare_batch(plant, segs)
    theta = np.column_stack([random_theta(rng, i % 2 == 0) for i in range(4)])
    theta[1] = np.maximum(theta[1], 0.05)  # finite differences need room on both sides of q22
    return batch, theta


@pytest.fixture(scope="module")
def setup(plant):
    return _setup(plant, 0)


@pytest.fixture(scope="module", params=[0, 150], ids=["M=0", "M=150"])
def setup_m(plant, request):
    """Without and with a preview longer than the observed window (scratch must cover K + M)."""
    return _setup(plant, request.param)


def _compile_quietly(inputs, outputs, mode):
    """Compile and run nothing else; return the function and the warnings raised while compiling."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = pytensor.function(inputs, outputs, mode=mode)
    return f, [str(w.message) for w in caught]


@pytest.mark.parametrize("mode", ["NUMBA", "FAST_COMPILE"])
def test_outputs_are_the_kernels(plant, setup_m, mode):
    batch, theta = setup_m
    op = MaxEntLoglikOp(batch, plant)
    th = pt.dmatrix("theta")
    f, _ = _compile_quietly([th], list(op(th)), mode)
    ll, g = f(theta)
    ref = loglik_grad(theta, batch, plant)
    # The same njit kernel on the same numbers; only numba's specialization for read-only
    # data arrays differs, so allow a few ulps.
    np.testing.assert_allclose(ll, ref.loglik, rtol=1e-13)
    np.testing.assert_allclose(g, ref.grad, rtol=1e-12, atol=1e-13 * np.abs(ref.grad).max())
    # A non-contiguous θ (a transposed view) gives the same numbers.
    ll_t, _ = f(np.asfortranarray(theta))
    np.testing.assert_array_equal(ll_t, ll)


def test_verify_grad(plant, setup_m):
    batch, theta = setup_m
    op = MaxEntLoglikOp(batch, plant)
    pytensor.gradient.verify_grad(lambda th: op(th)[0], [theta], rng=np.random.default_rng(21), n_tests=3)


def test_verify_grad_in_log_parameters(plant, setup):
    """Through the (θ1, θ2, R) -> (q11, q22, R) map the model uses, θ2 = 0 included."""
    batch, theta = setup
    op = MaxEntLoglikOp(batch, plant)

    def f(log_t1, t2, log_R):
        R = pt.exp(log_R)
        return op(pt.stack([pt.exp(log_t1 + log_R), t2 * R, R]))[0]

    pt_ = [np.log(theta[0] / theta[2]), np.zeros(4), np.log(theta[2])]
    # θ2 = 0 is the boundary; the one-sided sensitivity there is what the sampler sees,
    # and a forward difference of size eps is inside the domain for half the projections,
    # so evaluate at a tiny positive θ2 instead.
    pt_[1] = np.full(4, 1e-3)
    pytensor.gradient.verify_grad(f, pt_, rng=np.random.default_rng(22), n_tests=3)


def test_logp_and_gradient_use_one_kernel_call(plant, setup):
    batch, theta = setup
    op = MaxEntLoglikOp(batch, plant)
    th = pt.dmatrix("theta")
    logp = (op(th)[0] * np.arange(1.0, 5.0)).sum()
    f, _ = _compile_quietly([th], [logp, pytensor.grad(logp, th)], "NUMBA")
    nodes = [n for n in f.maker.fgraph.apply_nodes if isinstance(n.op, MaxEntLoglikOp)]
    assert len(nodes) == 1
    val, grad = f(theta)
    ref = loglik_grad(theta, batch, plant)
    np.testing.assert_allclose(val, ref.loglik @ np.arange(1.0, 5.0), rtol=1e-13)
    np.testing.assert_allclose(grad, ref.grad * np.arange(1.0, 5.0), rtol=1e-12, atol=1e-12 * np.abs(ref.grad).max())


class _NoNumbaOp(Op):
    """An Op without a numba implementation: PyTensor must fall back to object mode."""

    __props__ = ()

    def make_node(self, x):
        x = pt.as_tensor_variable(x)
        return Apply(self, [x], [x.type()])

    def perform(self, node, inputs, output_storage):
        output_storage[0][0] = 2.0 * inputs[0]


def test_numba_mode_never_falls_back_to_object_mode(plant, setup):
    batch, theta = setup
    th = pt.dmatrix("theta")
    logp = maxent_loglik(th, batch, plant).sum()
    f, msgs = _compile_quietly([th], [logp, pytensor.grad(logp, th)], "NUMBA")
    f(theta)  # numba compiles lazily on some paths; make sure nothing warns on the first call either
    assert not [m for m in msgs if OBJECT_MODE in m], msgs
    # Negative control: the same check catches an Op that has no numba implementation.
    x = pt.dvector("x")
    _, msgs = _compile_quietly([x], [_NoNumbaOp()(x)], "NUMBA")
    assert any(OBJECT_MODE in m for m in msgs)


def test_second_derivatives_are_refused(plant, setup):
    batch, _ = setup
    op = MaxEntLoglikOp(batch, plant)
    th = pt.dmatrix("theta")
    g = pytensor.grad(op(th)[0].sum(), th)
    with pytest.raises(pytensor.gradient.NullTypeGradError):
        pytensor.grad(g.sum(), th)


def test_wrong_theta_shape_is_refused(plant, setup):
    batch, _ = setup
    op = MaxEntLoglikOp(batch, plant)
    with pytest.raises(ValueError, match=r"shape \(3, 4\)"):
        op(pt.dmatrix("t", shape=(3, 5)))
    with pytest.raises(TypeError, match="matrix"):
        op(pt.dvector("t"))


def test_ops_with_different_data_are_not_merged(plant):
    rng = np.random.default_rng(23)
    b1 = prepare_batch(plant, [random_segment(rng, 30, False)])
    b2 = prepare_batch(plant, [random_segment(rng, 30, True)])
    th = pt.dmatrix("theta")
    f, _ = _compile_quietly([th], [maxent_loglik(th, b1, plant), maxent_loglik(th, b2, plant)], "NUMBA")
    theta = np.array([[50.0], [0.0], [1.0]])
    l1, l2 = f(theta)
    assert l1[0] == pytest.approx(loglik_grad(theta, b1, plant).loglik[0], rel=1e-13)
    assert l2[0] == pytest.approx(loglik_grad(theta, b2, plant).loglik[0], rel=1e-13)


@pytest.mark.parametrize("mode", ["NUMBA", "FAST_COMPILE"])
def test_data_input_op_equals_the_bound_op_bit_for_bit(plant, setup_m, mode):
    """One implementation: data as inputs or bound into the Op, the same numbers and gradient."""
    batch, theta = setup_m
    th = pt.dmatrix("theta")
    data = [pt.dmatrix(name) for name in DATA_NAMES]
    ll_d, _ = MaxEntLoglikDataOp(plant)(th, *data)
    ll_b, _ = MaxEntLoglikOp(batch, plant)(th)
    w = np.arange(1.0, batch.n + 1.0)
    logp_d, logp_b = (ll_d * w).sum(), (ll_b * w).sum()
    outs = [logp_d, pytensor.grad(logp_d, th), logp_b, pytensor.grad(logp_b, th)]
    f, msgs = _compile_quietly([th, *data], outs, mode)
    vd, gd, vb, gb = f(theta, *(getattr(batch, name) for name in DATA_NAMES))
    assert vd == vb
    np.testing.assert_array_equal(gd, gb)
    assert not [m for m in msgs if OBJECT_MODE in m], msgs


def test_data_inputs_are_not_differentiable(plant, setup):
    batch, _ = setup
    th = pt.dmatrix("theta")
    data = [pt.dmatrix(name) for name in DATA_NAMES]
    ll, _ = MaxEntLoglikDataOp(plant)(th, *data)
    with pytest.raises(pytensor.gradient.DisconnectedInputError):
        pytensor.grad(ll.sum(), data[0])


def test_data_ops_of_one_plant_are_equal_and_bound_ops_are_not(plant, setup):
    batch, _ = setup
    assert MaxEntLoglikDataOp(plant) == MaxEntLoglikDataOp(plant)
    assert hash(MaxEntLoglikDataOp(plant)) == hash(MaxEntLoglikDataOp(plant))
    a, b = MaxEntLoglikOp(batch, plant), MaxEntLoglikOp(batch, plant)
    assert a == a and a != b
    assert MaxEntLoglikDataOp(plant) != a

