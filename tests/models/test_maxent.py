"""The linear-time max-ent likelihood against the dense Eq. 8-16, finite differences and itself."""

import numpy as np
import pytest
from scipy import stats

from scioc.models.maxent import forward_optimal_control, loglik_grad, loglik_segments, sample_maxent
from scioc.models.maxent_dense import loglik_dense
from scioc.models.segment import Feedback, Segment, planning_plant, prepare_batch
from tests.conftest import random_segment, random_theta

CASES = [(K, shared, q22_zero) for K in (1, 7, 60, 250, 500) for shared in (False, True) for q22_zero in (True, False)]


@pytest.mark.parametrize("K, shared, q22_zero", CASES)
def test_linear_time_equals_dense(plant, K, shared, q22_zero):
    rng = np.random.default_rng([K, shared, q22_zero])
    for _ in range(3):
        seg = random_segment(rng, K, shared)
        theta = random_theta(rng, q22_zero)
        dense = loglik_dense(theta, seg, plant)
        fast = loglik_grad(theta, prepare_batch(plant, [seg]), plant)
        assert abs(fast.loglik[0] - dense.loglik) <= 1e-9 * abs(dense.loglik)
        # Gradient against the dense analytic gradient, relative to the gradient's size.
        assert np.max(np.abs(fast.grad[:, 0] - dense.grad)) <= 1e-9 * np.max(np.abs(dense.grad))


def _assert_gradient_matches_central_differences(theta, batch, plant):
    """Each component of the one-segment gradient against a central difference with h = 1e-5 θ_j."""
    grad = loglik_grad(theta, batch, plant).grad[:, 0]
    for j in range(3):
        h = 1e-5 * theta[j]
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        fd = (loglik_grad(tp, batch, plant).loglik[0] - loglik_grad(tm, batch, plant).loglik[0]) / (2 * h)
        # Each component on its own: O(h²) truncation and eps·|ll|/h rounding are both < 1e-8 here.
        assert abs(fd - grad[j]) <= 1e-6 * abs(grad[j]), (j, fd, grad[j])


@pytest.mark.parametrize("shared", [False, True])
@pytest.mark.parametrize("q22_zero", [True, False])
def test_gradient_matches_central_differences(plant, shared, q22_zero):
    rng = np.random.default_rng([11, shared, q22_zero])
    seg = random_segment(rng, 400, shared)
    batch = prepare_batch(plant, [seg])
    theta = random_theta(rng, q22_zero)
    theta[1] = max(theta[1], 0.05)  # a central difference needs room on both sides of q22
    _assert_gradient_matches_central_differences(theta, batch, plant)


def test_freeze_shortcut_agrees_with_tangents_through_every_step(plant):
    rng = np.random.default_rng(3)
    segs = [random_segment(rng, 1500, i % 2 == 1) for i in range(6)]
    thetas = np.column_stack([random_theta(rng, i % 3 == 0) for i in range(6)])
    batch = prepare_batch(plant, segs)
    fast = loglik_grad(thetas, batch, plant)
    slow = loglik_grad(thetas, batch, plant, freeze=False)
    # The frozen step quantities differ from the still-moving ones by <= FREEZE_RTOL relative,
    # and over 1500 steps that adds up to a few 1e-14 of the gradient's size.
    np.testing.assert_allclose(fast.loglik, slow.loglik, rtol=1e-12)
    np.testing.assert_allclose(fast.grad, slow.grad, rtol=1e-10, atol=1e-12 * np.abs(slow.grad).max())


def test_segment_result_does_not_depend_on_its_batch(plant):
    rng = np.random.default_rng(4)
    segs = [random_segment(rng, 300, i % 2 == 1) for i in range(5)]
    thetas = np.column_stack([random_theta(rng, False) for _ in range(5)])
    together = loglik_grad(thetas, prepare_batch(plant, segs), plant)
    for i, s in enumerate(segs):
        alone = loglik_grad(thetas[:, i], prepare_batch(plant, [s]), plant)
        assert alone.loglik[0] == together.loglik[i]
        assert np.array_equal(alone.grad[:, 0], together.grad[:, i])


def test_mixed_lengths_are_batched_by_length(plant):
    rng = np.random.default_rng(5)
    segs = [random_segment(rng, K, True) for K in (30, 80, 30)]
    theta = random_theta(rng, True)
    res = loglik_segments(theta, segs, plant)
    for i, s in enumerate(segs):
        assert res.loglik[i] == pytest.approx(loglik_dense(theta, s, plant).loglik, rel=1e-10)


def test_forward_optimal_control_is_the_dense_qp_solution(plant):
    rng = np.random.default_rng(6)
    for shared in (False, True):
        seg = random_segment(rng, 200, shared)
        theta = random_theta(rng, False)
        demo = forward_optimal_control(theta, seg.x0, seg.angle_ref, seg.u_A, plant)
        # The dense minimizer from any u: u - H⁻¹ g(u).
        dense = loglik_dense(theta, seg._replace(u_H=demo.u_H), plant, with_grad=False)
        np.testing.assert_allclose(dense.g, 0.0, atol=1e-9 * np.abs(dense.H).max())
        dense2 = loglik_dense(theta, seg, plant, with_grad=False)
        np.testing.assert_allclose(demo.u_H, dense2.u_opt, rtol=1e-8, atol=1e-10)


def test_optimal_torques_are_the_likelihood_mode(plant):
    rng = np.random.default_rng(7)
    seg = random_segment(rng, 100, True)
    theta = random_theta(rng, True)
    demo = forward_optimal_control(theta, seg.x0, seg.angle_ref, seg.u_A, plant)
    best = loglik_grad(theta, prepare_batch(plant, [seg._replace(u_H=demo.u_H)]), plant).loglik[0]
    perturbed = seg._replace(u_H=demo.u_H + 1e-3 * rng.standard_normal(100))
    assert loglik_grad(theta, prepare_batch(plant, [perturbed]), plant).loglik[0] < best


# Seeded statistical test of the exact sampler. False-failure budget per KS test:
ALPHA = 1e-3


def _whitened(plant, theta, seg, rng, n, noise_scale=1.0):
    """(u - u*)ᵀ H (u - u*) per draw; u ~ N(u*, H⁻¹) makes it χ² with K degrees of freedom."""
    dense = loglik_dense(theta, seg, plant, with_grad=False)
    out = np.empty(n)
    for i in range(n):
        demo = sample_maxent(theta, seg.x0, seg.angle_ref, seg.u_A, plant, rng)
        d = noise_scale * (demo.u_H - dense.u_opt)
        out[i] = d @ dense.H @ d
    return out


@pytest.mark.parametrize("shared", [False, True])
def test_sampler_draws_from_the_maxent_gaussian(plant, shared):
    rng = np.random.default_rng([8, shared])
    seg = random_segment(rng, 40, shared)
    theta = random_theta(rng, False)
    q = _whitened(plant, theta, seg, rng, 2000)
    assert stats.kstest(q, stats.chi2(df=40).cdf).pvalue > ALPHA


def test_sampler_test_catches_a_wrong_variance(plant):
    # Negative control: noise 10 % too large must be flagged by the same test at the same size.
    rng = np.random.default_rng(9)
    seg = random_segment(rng, 40, True)
    theta = random_theta(rng, False)
    q = _whitened(plant, theta, seg, rng, 2000, noise_scale=1.1)
    assert stats.kstest(q, stats.chi2(df=40).cdf).pvalue < ALPHA


@pytest.mark.parametrize("preview", [1, 30, 250])
@pytest.mark.parametrize("shared", [False, True])
def test_preview_equals_dense_marginal(plant, preview, shared):
    # Planning past the observed window: the marginal of the longer-horizon max-ent Gaussian.
    rng = np.random.default_rng([12, preview, shared])
    long = random_segment(rng, 150 + preview, shared)
    seg = Segment(long.x0, long.angle_ref, long.u_H[:150], long.u_A)
    theta = random_theta(rng, False)
    dense = loglik_dense(theta, seg, plant)
    fast = loglik_grad(theta, prepare_batch(plant, [seg]), plant)
    assert abs(fast.loglik[0] - dense.loglik) <= 1e-9 * abs(dense.loglik)
    slow = loglik_grad(theta, prepare_batch(plant, [seg]), plant, freeze=False)
    np.testing.assert_allclose(fast.grad, slow.grad, rtol=1e-10)


def test_preview_gradient_matches_central_differences(plant):
    rng = np.random.default_rng(13)
    long = random_segment(rng, 600, True)
    seg = Segment(long.x0, long.angle_ref, long.u_H[:400], long.u_A)
    batch = prepare_batch(plant, [seg])
    theta = random_theta(rng, False)
    _assert_gradient_matches_central_differences(theta, batch, plant)


def _closed_loop_segment(plant, rng, K, preview):
    """A human planning with the MPC assistant's law, in closed loop with it (the simulator's SC)."""
    from scioc.models.assistant import design_assistant, human_feedback
    from scioc.models.reference import reference_trajectory

    ref = reference_trajectory(0.01 * (K + preview) + 2.0).angle
    fb = human_feedback(design_assistant(), ref)
    ref, ff = ref[: K + preview + 1], fb.feedforward[: K + preview]
    theta = random_theta(rng, False)
    x0 = np.array([ref[0] + 0.02, -0.1])
    demo = sample_maxent(theta, x0, ref, ff, planning_plant(plant, fb.gain), rng)
    u_A = ff - demo.x[:-1] @ fb.gain  # what the assistant applied along the trajectory
    seg = Segment(x0, ref, demo.u_H[:K], u_A, Feedback(fb.gain, ff))
    return theta, seg


@pytest.mark.parametrize("K, preview", [(1, 0), (60, 0), (500, 0), (150, 30)])
def test_feedback_model_equals_dense_in_closed_loop(plant, K, preview):
    # The fast kernel takes the states from the recorded u_A and plans on the closed wheel;
    # the dense reference plans and propagates on the closed wheel. In closed loop they agree.
    rng = np.random.default_rng([21, K, preview])
    theta, seg = _closed_loop_segment(plant, rng, K, preview)
    dense = loglik_dense(theta, seg, plant)
    fast = loglik_grad(theta, prepare_batch(plant, [seg]), plant)
    assert abs(fast.loglik[0] - dense.loglik) <= 1e-9 * abs(dense.loglik)
    if preview == 0:
        assert np.max(np.abs(fast.grad[:, 0] - dense.grad)) <= 1e-9 * np.max(np.abs(dense.grad))
    slow = loglik_grad(theta, prepare_batch(plant, [seg]), plant, freeze=False)
    np.testing.assert_allclose(fast.grad, slow.grad, rtol=1e-10)
    # The paper's model on the same data is a different likelihood (for K = 1 the one step's
    # assistant torque is already fixed by x_0, and the two coincide).
    paper = loglik_grad(theta, prepare_batch(plant, [seg._replace(feedback=None)]), plant)
    assert (abs(paper.loglik[0] - fast.loglik[0]) > 1e-6 * abs(fast.loglik[0])) == (K + preview > 1)


def test_feedback_gradient_matches_central_differences(plant):
    theta, seg = _closed_loop_segment(plant, np.random.default_rng(22), 400, 100)
    batch = prepare_batch(plant, [seg])
    _assert_gradient_matches_central_differences(theta, batch, plant)


def test_zero_feedback_is_the_paper_model_bit_for_bit(plant):
    # A Feedback with zero gain and the recorded u_A as feedforward is the exogenous model;
    # mixed in one batch, each segment keeps its own plan.
    rng = np.random.default_rng(23)
    seg = random_segment(rng, 300, True)
    theta = random_theta(rng, False)
    plain = loglik_grad(theta, prepare_batch(plant, [seg]), plant)
    zero = seg._replace(feedback=Feedback(np.zeros(2), seg.u_A.copy()))
    _, fb_seg = _closed_loop_segment(plant, rng, 300, 0)
    both = loglik_grad(theta, prepare_batch(plant, [zero, fb_seg]), plant)
    assert both.loglik[0] == plain.loglik[0]
    np.testing.assert_array_equal(both.grad[:, 0], plain.grad[:, 0])
    alone = loglik_grad(theta, prepare_batch(plant, [fb_seg]), plant)
    assert both.loglik[1] == alone.loglik[0]


@pytest.mark.parametrize("c", [1e10, 1e19, 1e40])
def test_an_extreme_theta_gives_the_scaled_density_not_infinity(plant, c):
    # Scaling θ by c scales every S_k by c and leaves the residuals v_k alone, so
    # log p(cθ) = log p(θ) + (c - 1) quad(θ) + K/2 log c, with quad(θ) = θ·∇log p(θ) - K/2 (Euler).
    # At c = 1e40 sixteen factors S_k overflowed the kernel's running product and gave +inf
    # (leave-one-subject-out's proposal reaches such θ); 1e10 and 1e19 were finite before too.
    rng = np.random.default_rng(41)
    seg = random_segment(rng, 60, True)
    theta = random_theta(rng, False)
    batch = prepare_batch(plant, [seg])
    base = loglik_grad(theta, batch, plant)
    quad = float(theta @ base.grad[:, 0]) - 0.5 * 60
    expected = base.loglik[0] + (c - 1.0) * quad + 0.5 * 60 * np.log(c)
    got = loglik_grad(c * np.asarray(theta), batch, plant).loglik[0]
    assert np.isfinite(got) and abs(got - expected) <= 1e-9 * abs(expected)
