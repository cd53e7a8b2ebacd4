"""The PyTensor Op around the ``delayed`` kernel: values and gradient equal the kernel's, one kernel call,
no object mode, the lag's coefficients in numba equal SciPy's."""

import warnings

import numpy as np
import pytensor
import pytensor.tensor as pt
import pytest

from scioc.models.bayes.delayed_lag import lag_nb, wheel_constants
from scioc.models.bayes.delayed_op import (
    DELAYED_DATA_NAMES,
    DelayedLoglikDataOp,
    DelayedLoglikOp,
    delayed_loglik,
    pack_tau0,
    warm_samples,
)
from scioc.models.bayes.delayed_value import DelayedLoglikValueOp
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.delayed import loglik_grad
from scioc.models.delayed.lag import Warmup, lag_coefficients, window_tau0
from scioc.models.design import WheelParameters
from scioc.models.segment import prepare_batch

OBJECT_MODE = "object mode"
#: The kernel sums with reassociation (models.FASTMATH), so the same
#: arithmetic compiled inside another function (the Op's) rounds differently; the
#: log-likelihood of a 300-step segment is ~1e3 nats and moves by ~1e-9 between such
#: compilations (measured up to 3e-12 relative). Any modelling difference is far larger.
RTOL = 1e-10


@pytest.fixture(scope="module")
def setup(plant):
    w = delayed_windows(3, np.random.default_rng(2), K=300, preview=50)
    batch = prepare_batch(plant, w.segments)
    rng = np.random.default_rng(3)
    # Warm-ups of different lengths (one None: at rest), arm torques before them not 0.
    warm = [Warmup(rng.normal(0, 0.3, 40 + 10 * i), 0.1 * i) if i % 3 else None for i in range(batch.n)]
    tau = w.tau_nm * (1 + 0.1 * np.arange(batch.n))  # a different lag per segment
    return w, batch, warm, tau


def _reference(w, batch, plant, warm, tau, sig):
    """The kernel through its public function, τ_0 and its tangents from the warm-ups at each segment's lag."""
    t0, dt0 = np.zeros(batch.n), np.zeros((batch.n, 2))
    for i in range(batch.n):
        lag = lag_coefficients(tau[i])
        a, b = window_tau0([warm[i]], lag.a, lag.alpha)
        t0[i], dt0[i] = a[0], b[0]
    return loglik_grad(w.theta, batch, plant, tau_nm=tau, sigma_m=sig, delay=w.delay, tau0=t0, dtau0=dt0)


def _compile_quietly(inputs, outputs, mode):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = pytensor.function(inputs, outputs, mode=mode)
    return f, [str(m.message) for m in caught]


@pytest.mark.validation
@pytest.mark.parametrize("mode", ["NUMBA", "FAST_COMPILE"])
def test_outputs_are_the_kernels(plant, setup, mode):
    w, batch, warm, tau = setup
    op = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    f, msgs = _compile_quietly([th, tt, ss], list(op(th, tt, ss)), mode)
    ll, g = f(w.theta, tau, w.sigma_m)
    ref = _reference(w, batch, plant, warm, tau, w.sigma_m)
    np.testing.assert_allclose(ll, ref.loglik, rtol=RTOL)
    np.testing.assert_allclose(g, ref.grad, rtol=RTOL, atol=RTOL * np.abs(ref.grad).max())
    assert not [m for m in msgs if OBJECT_MODE in m], msgs
    # A fixed τ_0 per segment: its tangents are 0 (a different τ_nm-derivative from the warm-ups').
    t0 = np.linspace(-0.5, 0.5, batch.n)
    f0, _ = _compile_quietly([th, tt, ss], list(DelayedLoglikOp(batch, plant, delay=w.delay, tau0=t0)(th, tt, ss)),
                             mode)
    ll0, g0 = f0(w.theta, tau, w.sigma_m)
    ref0 = loglik_grad(w.theta, batch, plant, tau_nm=tau, sigma_m=w.sigma_m, delay=w.delay, tau0=t0)
    np.testing.assert_allclose(ll0, ref0.loglik, rtol=RTOL)
    np.testing.assert_allclose(g0, ref0.grad, rtol=RTOL, atol=RTOL * np.abs(ref0.grad).max())
    assert not np.allclose(g0[3], g[3], rtol=1e-3)


@pytest.mark.validation
def test_verify_grad(plant, setup):
    w, batch, warm, tau = setup
    op = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)
    # In the model's coordinates: log θ1, log R, log τ_nm, σ_m; θ2 > 0 inside its domain.

    def f(lt1, t2, lR, ltau, sig):
        R = pt.exp(lR)
        return op(pt.stack([pt.exp(lt1 + lR), t2 * R, R]), pt.exp(ltau), sig)[0]

    args = [np.log(w.theta[0] / w.theta[2]), np.full(batch.n, 0.05), np.log(w.theta[2]), np.log(tau), w.sigma_m]
    # verify_grad's one-sided differences (step 1e-7) of a random projection resolve this strongly
    # curved log-likelihood to about 1e-4 (measured 1.0e-4 here), hence its tolerance 1e-3: enough to
    # catch a wrong row or sign in the pullback (errors of order 1). The tight check follows.
    pytensor.gradient.verify_grad(f, args, rng=np.random.default_rng(21), n_tests=2, abs_tol=1e-3, rel_tol=1e-3)
    xs = [pt.dvector() for _ in args]
    total = f(*xs).sum()
    fn = pytensor.function(xs, [total, *pytensor.grad(total, xs)], mode="NUMBA")
    _, *grads = fn(*args)
    for j in range(len(args)):
        for i in range(batch.n):
            h = 1e-5
            up, dn = [a.copy() for a in args], [a.copy() for a in args]
            up[j][i] += h
            dn[j][i] -= h
            fd = (fn(*up)[0] - fn(*dn)[0]) / (2 * h)
            # central differences: truncation ~ h² f''' / 6 and rounding ~ 1e-13 |f| / h, both below 1e-6 here
            assert grads[j][i] == pytest.approx(fd, rel=1e-6, abs=1e-6 * np.abs(grads[j]).max()), (j, i)


def test_logp_and_gradient_use_one_kernel_call(plant, setup):
    w, batch, warm, tau = setup
    op = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    weights = np.arange(1.0, batch.n + 1.0)
    logp = (op(th, tt, ss)[0] * weights).sum()
    f, _ = _compile_quietly([th, tt, ss], [logp, *pytensor.grad(logp, [th, tt, ss])], "NUMBA")
    assert len([n for n in f.maker.fgraph.apply_nodes if isinstance(n.op, DelayedLoglikOp)]) == 1
    val, gth, gt, gs = f(w.theta, tau, w.sigma_m)
    ref = _reference(w, batch, plant, warm, tau, w.sigma_m)
    np.testing.assert_allclose(val, ref.loglik @ weights, rtol=RTOL)
    np.testing.assert_allclose(np.vstack([gth, gt, gs]), ref.grad * weights, rtol=RTOL,
                               atol=RTOL * np.abs(ref.grad * weights).max())


@pytest.mark.validation
def test_data_op_equals_the_bound_op_bit_for_bit(plant, setup):
    w, batch, warm, tau = setup
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    data = [pt.tensor(name, dtype="int64" if name in ("delay", "warm_start") else "float64",
                      shape=(None,) * (1 if name in ("delay", "warm_start", "tau_start") else 2))
            for name in DELAYED_DATA_NAMES]
    ll_d, g_d = DelayedLoglikDataOp(plant)(th, tt, ss, *data)
    ll_b, g_b = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)(th, tt, ss)
    f, msgs = _compile_quietly([th, tt, ss, *data], [ll_d, g_d, ll_b, g_b], "NUMBA")
    values = [getattr(batch, name) for name in DELAYED_DATA_NAMES[:6]] + [w.delay, *pack_tau0(warm, batch.n)]
    vd, gd, vb, gb = f(w.theta, tau, w.sigma_m, *values)
    np.testing.assert_allclose(vd, vb, rtol=RTOL)
    np.testing.assert_allclose(gd, gb, rtol=RTOL, atol=RTOL * np.abs(gb).max())
    assert not [m for m in msgs if OBJECT_MODE in m], msgs
    with pytest.raises(pytensor.gradient.DisconnectedInputError):
        pytensor.grad(ll_d.sum(), data[0])


def test_second_derivatives_are_refused_and_shapes_checked(plant, setup):
    w, batch, warm, tau = setup
    op = DelayedLoglikOp(batch, plant, delay=w.delay)
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    g = pytensor.grad(op(th, tt, ss)[0].sum(), tt)
    with pytest.raises(pytensor.gradient.NullTypeGradError):
        pytensor.grad(g.sum(), tt)
    with pytest.raises(ValueError, match=rf"\(3, {batch.n}\)"):
        op(pt.dmatrix(shape=(3, batch.n + 1)), tt, ss)
    with pytest.raises(ValueError, match="whole numbers"):
        DelayedLoglikOp(batch, plant, delay=1.5)
    with pytest.raises(ValueError, match="one Warmup or None per segment"):
        delayed_loglik(th, tt, ss, batch, plant, delay=3, tau0=[None])


@pytest.mark.parametrize("params", [WheelParameters(), WheelParameters(0.04, 0.0, 0.286),
                                    WheelParameters(0.04, 0.2, 0.5), WheelParameters(0.04, 0.0, 20.0)],
                         ids=["paper", "no spring", "real poles", "stiff damper"])
def test_lag_coefficients_in_numba_equal_scipys(params):
    """Both branches: the closed form and, near a real pole, the series (SciPy: the Fréchet derivative)."""
    c = wheel_constants(0.01, params)
    near = [f / -lam.real for lam in c[-1] if lam.real < 0 and lam.imag == 0 for f in (0.97, 1.0, 1.03)]
    for tau in [0.0, 1e-5, 1e-3, 0.01, 0.06, 0.1, 0.3, 1.0, *near]:
        ref = lag_coefficients(tau, 0.01, params)
        got = lag_nb(tau, *c)
        # The closed form's solve loses up to ~1e-13 near 5 % of a pole (models.delayed.lag); 1e-12 leaves room.
        np.testing.assert_allclose(got, tuple(ref), rtol=1e-12, atol=1e-300, err_msg=f"tau_nm = {tau}")
    if params == WheelParameters(0.04, 0.0, 0.286):
        assert near  # the series branch was exercised


def test_a_vanishing_lag_is_finite_and_continuous():
    """A sampler may propose τ_nm = 1e-200: the coefficients stay finite and meet the τ_nm = 0 limit."""
    c = wheel_constants(0.01)
    zero = np.array(lag_nb(0.0, *c))
    for tau in (1e-200, 1e-12, 1e-9 * 0.999):
        got = np.array(lag_nb(tau, *c))
        assert np.all(np.isfinite(got))
        np.testing.assert_allclose(got, zero + [0.0, tau * zero[3], 0.0, 0.0], rtol=1e-12, atol=1e-300)
    # just above the switch the closed form agrees with the expansion to first order
    above = np.array(lag_nb(1.001e-9, *c))
    np.testing.assert_allclose(above[[1, 3]], [1.001e-9 * zero[3], zero[3]], rtol=1e-6)


def test_long_warm_ups_run_only_their_last_samples_to_rounding(plant, setup):
    """A measured torque's warm-up is the whole run (thousands of samples); the Op runs only the part that
    matters above 1e-20 and equals the kernel with τ_0 from the whole warm-up."""
    w, batch, _, tau = setup
    rng = np.random.default_rng(8)
    warm = [Warmup(np.cumsum(rng.normal(0, 0.05, 6000)) * 0.1, 0.0) for _ in range(batch.n)]
    assert all(warm_samples(*lag_coefficients(t)[:2]) < 6000 for t in tau)  # the truncation is exercised
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    f, _ = _compile_quietly([th, tt, ss], list(DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)(th, tt, ss)),
                            "NUMBA")
    ll, g = f(w.theta, tau, w.sigma_m)
    ref = _reference(w, batch, plant, warm, tau, w.sigma_m)
    np.testing.assert_allclose(ll, ref.loglik, rtol=RTOL)
    np.testing.assert_allclose(g, ref.grad, rtol=RTOL, atol=RTOL * np.abs(ref.grad).max())


@pytest.mark.validation
@pytest.mark.parametrize("mode", ["NUMBA", "FAST_COMPILE"])
def test_a_delay_input_replaces_the_bound_delays(plant, setup, mode):
    # The sampled-delay form: the same Op with the delays as a fourth (integer, non-differentiable) input.
    w, batch, warm, tau = setup
    other = (np.asarray(w.delay) + np.arange(1, batch.n + 1)) % 31
    op = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)
    th, tt, ss, dd = pt.dmatrix(), pt.dvector(), pt.dvector(), pt.lvector()
    ll, g = op(th, tt, ss, dd)
    f, msgs = _compile_quietly([th, tt, ss, dd], [ll, g, pytensor.grad(ll.sum(), th)], mode)
    got, grad, dth = f(w.theta, tau, w.sigma_m, other)
    ref = DelayedLoglikOp(batch, plant, delay=other, tau0=warm)
    f_ref, _ = _compile_quietly([th, tt, ss], list(ref(th, tt, ss)), mode)
    want, want_g = f_ref(w.theta, tau, w.sigma_m)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(grad, want_g)
    np.testing.assert_array_equal(dth, want_g[:3])
    assert not np.allclose(got, f(w.theta, tau, w.sigma_m, np.asarray(w.delay))[0])  # the delays matter
    assert not [m for m in msgs if OBJECT_MODE in m], msgs


def test_the_kernels_value_alone_is_its_value_with_the_gradient_bit_for_bit(plant, setup):
    w, batch, warm, tau = setup
    op = DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm)
    inputs = [w.theta, tau, w.sigma_m]
    ll, g = op.values(inputs)
    ll_alone, g_alone = op.values(inputs, grad=False)
    assert np.array_equal(ll_alone, ll) and np.all(np.isfinite(g))
    assert np.all(np.isnan(g_alone))  # not computed: NaN, so that no one reads it as a gradient


# the rewrite runs in the optimizer's specialize phase: PyTensor's default (numba) and a Python linker (perform)
@pytest.mark.validation
@pytest.mark.parametrize("mode", ["NUMBA", pytensor.compile.mode.Mode(linker="py", optimizer="fast_run")])
def test_a_graph_that_does_not_read_the_gradient_runs_the_value_alone(plant, setup, mode):
    w, batch, warm, tau = setup
    th, tt, ss = pt.dmatrix(), pt.dvector(), pt.dvector()
    for op, args in [(DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm), ()),
                     (DelayedLoglikOp(batch, plant, delay=w.delay, tau0=warm), (pt.lvector(),)),  # a sampled delay
                     (DelayedLoglikDataOp(plant), tuple(
                         pt.tensor(name, dtype="int64" if name in ("delay", "warm_start") else "float64",
                                   shape=(None,) * (1 if name in ("delay", "warm_start", "tau_start") else 2))
                         for name in DELAYED_DATA_NAMES))]:
        ll, _ = op(th, tt, ss, *args)
        logp = ll.sum()
        f_value, msgs = _compile_quietly([th, tt, ss, *args], ll, mode)
        f_both, _ = _compile_quietly([th, tt, ss, *args], [ll, pytensor.grad(logp, th)], mode)
        ops_value = [type(n.op) for n in f_value.maker.fgraph.apply_nodes]
        ops_both = [type(n.op) for n in f_both.maker.fgraph.apply_nodes]
        assert DelayedLoglikValueOp in ops_value and type(op) not in ops_value
        assert type(op) in ops_both and DelayedLoglikValueOp not in ops_both
        assert not [m for m in msgs if OBJECT_MODE in m], msgs
        values = {0: (), 1: (w.delay,),
                  2: tuple([getattr(batch, name) for name in DELAYED_DATA_NAMES[:6]]
                           + [w.delay, *pack_tau0(warm, batch.n)])}[len(args) if len(args) < 2 else 2]
        value = f_value(w.theta, tau, w.sigma_m, *values)
        with_grad, _ = f_both(w.theta, tau, w.sigma_m, *values)
        np.testing.assert_allclose(value, with_grad, rtol=RTOL)
        assert np.all(np.isfinite(value))
