"""The angle likelihood's Op: every window's value and gradient as :func:`scioc.models.delayed.window_loglik_grad`'s,
with windows of different lengths, assistants as torques and as feedback laws, warm-ups, and delays 0-30; its
gradient through PyTensor; the lagged wheel's exponential against scipy's."""

import numpy as np
import pytensor
import pytensor.tensor as pt
import pytest

from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.bayes.angle_op import ANGLE_DATA_NAMES, AngleLoglikDataOp, AngleLoglikOp, angle_data
from scioc.models.bayes.delayed_lag import lagged_wheel_nb
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.angles import AngleWindow, lagged_wheel, window_loglik_grad
from scioc.models.delayed.lag import Warmup
from scioc.models.design import WheelParameters
from scioc.models.plant import continuous_matrices
from scioc.models.reference import reference_trajectory

Q = 2 * np.pi / 4096  # an encoder step, rad
SIGMA_Y = Q / np.sqrt(12)


def windows(plant, rng, n):
    """n windows of different lengths drawn from the delayed human; odd ones assisted by a feedback law, every
    third by a known torque, warm-ups of different lengths on some."""
    out = []
    for i in range(n):
        K, M = 60 + 15 * i, 100
        ref = reference_trajectory((K + M) * plant.dt + 1.0, plant.dt).angle[i * 7: i * 7 + K + M + 1]
        kw = {}
        if i % 2:
            kw["feedback"] = human_feedback(design_assistant(), ref).window(0, K + M)
        elif i % 3 == 0:
            kw["u_A"] = rng.normal(0.0, 0.3, K + M)
        draw = sample_delayed([400.0, 0.5, 20.0], [0.01 * i, 0.0], ref, plant, rng, tau_nm=0.06, sigma_m=0.25,
                              delay=3 * i, n_obs=K, **kw)
        y = Q * np.round(draw.x[:, 0] / Q)
        warm = Warmup(rng.normal(0.0, 0.3, 30 + 20 * i), 0.1 * i) if i % 4 != 1 else None
        out.append(AngleWindow(y, ref, kw.get("u_A"), kw.get("feedback"), float(draw.x[0, 1]), warm))
    return out


@pytest.fixture(scope="module")
def study(plant):
    rng = np.random.default_rng(53)
    n = 6
    ws = windows(plant, rng, n)
    theta = np.stack([rng.uniform(200, 600, n), rng.uniform(0.0, 2.0, n), rng.uniform(10, 40, n)])
    tau = np.array([0.0, 0.03, 0.06, 0.1, 1e-12, 0.2])
    sig = np.array([0.2, 0.0, 0.3, 0.25, 0.1, 0.4])
    delay = np.array([0, 1, 5, 12, 30, 7])
    return ws, theta, tau, sig, delay


def test_every_windows_value_and_gradient_are_window_loglik_grads(plant, study):
    ws, theta, tau, sig, delay = study
    op = AngleLoglikOp(ws, plant, delay=delay, sigma_y=SIGMA_Y)
    ll, g = op.values([theta, tau, sig])
    ll0, g0 = op.values([theta, tau, sig], grad=False)
    np.testing.assert_array_equal(ll0, ll)  # the value alone is the value with the gradient
    for i, w in enumerate(ws):
        ref = window_loglik_grad(theta[:, i], tau[i], sig[i], int(delay[i]), w, plant, sigma_y=SIGMA_Y)
        tol = 1e-7 if 0 < tau[i] < 1e-5 else 1e-11  # scipy's exponential is the less exact one there
        assert ll[i] == pytest.approx(ref.loglik, rel=tol)
        np.testing.assert_allclose(g[:, i], ref.grad, rtol=1e3 * tol, atol=1e3 * tol * np.abs(ref.grad).max())


def test_the_ops_gradient_through_pytensor_is_the_sum_of_the_windows(plant, study):
    ws, theta, tau, sig, delay = study
    op = AngleLoglikOp(ws, plant, delay=delay, sigma_y=SIGMA_Y)
    th, t, s = pt.dmatrix("theta"), pt.dvector("tau"), pt.dvector("sigma")
    ll, _ = op(th, t, s)
    total = ll.sum()
    for mode in ("FAST_COMPILE", "NUMBA"):
        f = pytensor.function([th, t, s], [total, *pytensor.grad(total, [th, t, s])], mode=mode)
        value, g_th, g_t, g_s = f(theta, tau, sig)
        ll_ref, g_ref = op.values([theta, tau, sig])
        assert value == pytest.approx(ll_ref.sum(), rel=1e-14)
        np.testing.assert_allclose(g_th, g_ref[:3], rtol=1e-14)
        np.testing.assert_allclose(g_t, g_ref[3], rtol=1e-14)
        np.testing.assert_allclose(g_s, g_ref[4], rtol=1e-14)


def test_the_op_with_the_windows_as_inputs_is_the_bound_op(plant, study):
    """Same bits as :class:`AngleLoglikOp` in python and NUMBA modes, the delay a graph of an integer (as sampled)."""
    ws, theta, tau, sig, delay = study
    bound = AngleLoglikOp(ws, plant, delay=delay, sigma_y=SIGMA_Y)
    op = AngleLoglikDataOp(plant, sigma_y=SIGMA_Y)
    data = angle_data(ws, delay)
    ll_ref, g_ref = bound.values([theta, tau, sig])
    ll, g = op.values([theta, tau, sig, *(data[k] for k in ANGLE_DATA_NAMES)])
    np.testing.assert_array_equal(ll, ll_ref)
    np.testing.assert_array_equal(g, g_ref)
    th, t, s, shift = pt.dmatrix("theta"), pt.dvector("tau"), pt.dvector("sigma"), pt.lscalar("shift")
    inputs = {k: pt.as_tensor(v) for k, v in data.items() if k != "delay"}
    d = pt.as_tensor(delay) + shift
    ll_g, _ = op(th, t, s, d, *(inputs[k] for k in ANGLE_DATA_NAMES[1:]))
    total = ll_g.sum()
    for mode in ("FAST_COMPILE", "NUMBA"):
        f = pytensor.function([th, t, s, shift], [ll_g, *pytensor.grad(total, [th, t, s])], mode=mode)
        for k in (0, 2):
            value, g_th, g_t, g_s = f(theta, tau, sig, k)
            ll_k, g_k = AngleLoglikOp(ws, plant, delay=delay + k, sigma_y=SIGMA_Y).values([theta, tau, sig])
            np.testing.assert_array_equal(value, ll_k)
            np.testing.assert_allclose(g_th, g_k[:3], rtol=1e-14)
            np.testing.assert_allclose(g_t, g_k[3], rtol=1e-14)
            np.testing.assert_allclose(g_s, g_k[4], rtol=1e-14)
    with pytest.raises(ValueError, match="delay"):
        angle_data(ws, -1)


@pytest.mark.parametrize("tau_nm", [0.0, 1e-12, 1e-9, 1e-5, 0.005, 0.06, 0.3, 2.0])
def test_the_lagged_wheel_and_its_derivative_are_the_exponentials(plant, tau_nm):
    """Against the matrix exponential and its Fréchet derivative (scipy); below 1e-8 s, where scipy's exponential
    loses digits, against the lag's first order at 0 (v = τ_nm Φ b_w, exact to O(τ_nm²))."""
    params = WheelParameters()
    A_c, b_w = continuous_matrices(params)
    poles = np.linalg.eigvals(A_c).astype(np.complex128)
    A, b_c, dA, db_c = lagged_wheel_nb(tau_nm, plant.dt, A_c, b_w, plant.A, plant.b, poles)
    ref = lagged_wheel.__wrapped__(tau_nm if tau_nm >= 1e-8 else 0.0, plant.dt, params)
    ref_A, ref_b = ref.A.copy(), ref.b_c.copy()
    if tau_nm < 1e-8:
        ref_A[:2, 2] = tau_nm * ref.dA[:2, 2]
        ref_b[:2] -= tau_nm * ref.dA[:2, 2]
    np.testing.assert_allclose(A, ref_A, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(b_c, ref_b, rtol=1e-12, atol=1e-15)
    rtol = 1e-10 + 1e3 * tau_nm * (tau_nm < 1e-8)  # the first order's derivative is exact to O(τ_nm)
    # scipy's Fréchet derivative rounds to ~1e-10 where e^{-dt/τ_nm} underflows (1e-5 s), the closed form to 0
    np.testing.assert_allclose(dA, ref.dA, rtol=rtol, atol=1e-9)
    np.testing.assert_allclose(db_c, ref.db_c, rtol=rtol, atol=1e-9)


def test_bad_windows_and_delays_are_refused(plant, study):
    ws = study[0]
    with pytest.raises(ValueError, match="delay"):
        AngleLoglikOp(ws, plant, delay=-1, sigma_y=SIGMA_Y)
    with pytest.raises(ValueError, match="sigma_y"):
        AngleLoglikOp(ws, plant, delay=0, sigma_y=0.0)
    bad = ws[0]._replace(angles=np.full(3, np.nan))
    with pytest.raises(ValueError, match="finite"):
        AngleLoglikOp([bad], plant, delay=0, sigma_y=SIGMA_Y)
