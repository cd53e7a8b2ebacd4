"""The angle likelihood of the ``delayed`` human (Kalman filter) against the dense joint Gaussian of its
generative loop, and against draws of that loop."""

import numpy as np
import pytest

from scioc.models.delayed import sample_delayed
from scioc.models.delayed.angles import angle_loglik
from scioc.models.delayed.dense import angle_loglik_dense
from tests.conftest import random_window_inputs

MODES = ("MC", "SC feedback", "SC exogenous")
Q = 2 * np.pi / 40000  # the study's encoder step


def window(rng, plant, K, M, mode, *, theta, tau_nm, sigma_m, delay, tau0, quantize=True):
    """Angles y_0..y_K drawn from the delayed human, quantized, with the window's reference and assistant."""
    ref, x0, _, _, kw = random_window_inputs(rng, plant, K, M, mode)
    draw = sample_delayed(theta, x0, ref, plant, rng, tau_nm=tau_nm, sigma_m=sigma_m, delay=delay, tau0=tau0,
                          n_obs=K, physical=True, **kw)
    y = Q * np.round(draw.x[:, 0] / Q) if quantize else draw.x[:, 0]
    return y, ref, kw, np.array([*x0, tau0])


def _case(i):
    rng = np.random.default_rng([31, i])
    return dict(K=int(rng.integers(30, 161)), M=int(rng.choice([0, 25, 120])), mode=MODES[i % 3],
                delay=int(rng.integers(0, 31)), tau_nm=float(rng.choice([0.0, 0.05, 0.1])),
                sigma_m=float(rng.choice([0.0, 0.1, 0.3])), tau0=float(rng.normal(0, 0.2)))


CASES = [_case(i) for i in range(18)] + [
    dict(K=25, M=10, mode="MC", delay=30, tau_nm=0.05, sigma_m=0.3, tau0=0.0),  # delay longer than the window
    dict(K=60, M=0, mode="SC feedback", delay=30, tau_nm=0.1, sigma_m=0.3, tau0=0.1),
]


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c['mode']}-K{c['K']}-M{c['M']}-d{c['delay']}-"
                                                      f"tau{c['tau_nm']}-sig{c['sigma_m']}")
def test_kalman_filter_equals_dense_joint_gaussian(plant, case):
    rng = np.random.default_rng([32, case["K"], case["delay"]])
    theta = np.array([rng.uniform(100.0, 600.0), rng.uniform(0.0, 0.5), rng.uniform(5.0, 30.0)])
    y, ref, kw, z0 = window(rng, plant, case["K"], case["M"], case["mode"], theta=theta, tau_nm=case["tau_nm"],
                            sigma_m=case["sigma_m"], delay=case["delay"], tau0=case["tau0"])
    # evaluated at parameters other than the truth's, with an uncertain start
    par = dict(tau_nm=case["tau_nm"] * 1.2, sigma_m=case["sigma_m"] + 0.05, delay=case["delay"], sigma_y=Q / np.sqrt(12),
               z0_mean=z0 + np.array([1e-4, 0.02, 0.05]), z0_cov=np.array([[1e-8, 0, 0], [0, 0.01, 0.002],
                                                                            [0, 0.002, 0.04]]))
    th = theta * np.array([0.8, 1.0, 1.3])
    fast = angle_loglik(th, y, ref, plant, **kw, **par)
    dense = angle_loglik_dense(th, y, ref, plant, **kw, **par)
    assert fast.loglik == pytest.approx(dense.loglik, rel=1e-9, abs=1e-9)
    assert fast.innovations.shape == (case["K"],)


def test_a_known_start_without_encoder_noise_needs_no_update_at_y0(plant):
    # exact angles and a start whose angle is known: y_0 carries nothing and the filter skips its update
    rng = np.random.default_rng(33)
    theta = np.array([300.0, 0.1, 20.0])
    y, ref, kw, z0 = window(rng, plant, 50, 20, "MC", theta=theta, tau_nm=0.06, sigma_m=0.2, delay=5, tau0=0.0,
                            quantize=False)
    par = dict(tau_nm=0.06, sigma_m=0.2, delay=5, z0_mean=z0, z0_cov=np.diag([0.0, 1e-4, 1e-3]))
    exact = angle_loglik(theta, y, ref, plant, sigma_y=0.0, **par)
    assert np.isfinite(exact.loglik)
    # the limit of a vanishing encoder noise
    near = angle_loglik(theta, y, ref, plant, sigma_y=1e-10, **par)
    assert exact.loglik == pytest.approx(near.loglik, rel=1e-6)


def test_innovations_of_draws_are_standard_normal(plant):
    # Draws of the loop itself (encoder noise as Gaussian, the model's own): the standardized
    # innovations are iid N(0, 1). 40 windows × 400 samples; the mean and variance tests have
    # false-alarm rates of 1e-4 each (|z| > 3.9).
    rng = np.random.default_rng(34)
    theta = np.array([300.0, 0.1, 20.0])
    sy = Q / np.sqrt(12)
    inn = []
    for i in range(40):
        y, ref, kw, z0 = window(rng, plant, 400, 100, MODES[i % 3], theta=theta, tau_nm=0.06, sigma_m=0.25,
                                delay=12, tau0=0.1, quantize=False)
        # the model's Gaussian encoder noise in place of the quantizer
        y = y + rng.normal(0.0, sy, y.shape)
        inn.append(angle_loglik(theta, y, ref, plant, **kw, tau_nm=0.06, sigma_m=0.25, delay=12, sigma_y=sy,
                                z0_mean=z0, z0_cov=np.zeros((3, 3))).innovations)
    e = np.concatenate(inn)
    n = e.size
    assert abs(e.mean()) * np.sqrt(n) < 3.9
    assert abs(e.var() - 1.0) / np.sqrt(2.0 / n) < 3.9
    # negative control: the same angles judged with the wrong delay and no motor noise are not N(0, 1)
    y, ref, kw, z0 = window(rng, plant, 400, 100, "MC", theta=theta, tau_nm=0.06, sigma_m=0.25, delay=12, tau0=0.1)
    wrong = angle_loglik(theta, y, ref, plant, tau_nm=0.06, sigma_m=0.0, delay=0, sigma_y=sy, z0_mean=z0,
                         z0_cov=np.zeros((3, 3))).innovations
    assert abs(wrong.var() - 1.0) / np.sqrt(2.0 / wrong.size) > 3.9


def test_invalid_arguments_are_refused(plant):
    rng = np.random.default_rng(35)
    theta = np.array([300.0, 0.1, 20.0])
    y, ref, kw, z0 = window(rng, plant, 30, 0, "MC", theta=theta, tau_nm=0.06, sigma_m=0.2, delay=3, tau0=0.0)
    ok = dict(sigma_y=1e-5, z0_mean=z0, z0_cov=np.zeros((3, 3)))
    for kw_bad, msg in [(dict(delay=-1), "delay"), (dict(delay=1.5), "delay"), (dict(sigma_m=-0.1), "sigma_m"),
                        (dict(sigma_y=np.nan), "sigma_y"), (dict(z0_cov=-np.eye(3)), "z0_cov")]:
        with pytest.raises(ValueError, match=msg):
            angle_loglik(theta, y, ref, plant, **{**ok, **kw_bad})
    with pytest.raises(ValueError, match="angles"):
        angle_loglik(theta, np.append(y, [0.0, 0.0]), ref, plant, **ok)


@pytest.mark.parametrize("mode", MODES)
def test_holding_the_stationary_filter_changes_nothing_but_rounding(plant, mode):
    rng = np.random.default_rng(36)
    theta = np.array([300.0, 0.1, 20.0])
    for d in (0, 12, 30):
        y, ref, kw, z0 = window(rng, plant, 1500, 200, mode, theta=theta, tau_nm=0.06, sigma_m=0.25, delay=d,
                                tau0=0.1)
        par = dict(tau_nm=0.06, sigma_m=0.25, delay=d, sigma_y=Q / np.sqrt(12), z0_mean=z0,
                   z0_cov=np.diag([1e-9, 1e-3, 1e-2]))
        held = angle_loglik(theta, y, ref, plant, **kw, **par)
        full = angle_loglik(theta, y, ref, plant, **kw, **par, freeze=False)
        assert held.loglik == pytest.approx(full.loglik, rel=1e-11)
        np.testing.assert_allclose(held.innovations, full.innovations, rtol=0, atol=1e-8)
