import numpy as np
import pytest

from scioc.models.assistant import assistant_torque, design_assistant, feedforward, human_feedback, simulate_closed_loop
from scioc.models.lq import lq_policy
from scioc.models.maxent_dense import lifted_matrices
from scioc.models.plant import discretize


@pytest.fixture(scope="module")
def assistant():
    return design_assistant()


def _dense_mpc_first_torque(assistant, x, r_preview):
    """Eq. 19 as a dense QP on the 0.02-s plant with u_H = 0; returns u_A,0."""
    q11, q22, R = assistant.theta
    N = r_preview.shape[0]
    Phi, Gamma = lifted_matrices(assistant.plant, N)
    q = np.tile([q11, q22], N)
    x_ref = np.zeros(2 * N)
    x_ref[0::2] = r_preview
    H = Gamma.T @ (q[:, None] * Gamma) + R * np.eye(N)
    g = Gamma.T @ (q * (Phi @ x - x_ref))
    return np.linalg.solve(H, -g)[0]


def test_mpc_law_equals_solving_the_qp_every_sample(assistant):
    rng = np.random.default_rng(0)
    for _ in range(5):
        x = rng.normal(0.0, [0.3, 1.0])
        r_preview = rng.normal(0.0, 0.3, 50)
        assert assistant_torque(assistant, x, r_preview) == pytest.approx(
            _dense_mpc_first_torque(assistant, x, r_preview), rel=1e-10, abs=1e-12
        )


def test_assistant_defaults_follow_the_paper(assistant):
    np.testing.assert_array_equal(assistant.theta, [5.0, 0.0, 1.0])
    assert assistant.preview_weights.shape == (50,)
    assert assistant.hold == 1  # re-solved every 10-ms sample ...
    assert assistant.stride == 2  # ... on the 0.02-s prediction grid
    assert assistant.plant.dt == 0.02


def _reference(K):
    t = np.arange(K + 1) * 0.01
    return 0.25 * np.sin(2 * np.pi * 0.1 * t) + 0.15 * np.sin(2 * np.pi * 0.23 * t + 1.0)


def test_assistant_alone_tracks_but_not_perfectly(assistant):
    plant = discretize(0.01)
    ref = _reference(3000)
    alone = simulate_closed_loop(plant, assistant, [ref[0], 0.0], ref)
    passive = simulate_closed_loop(plant, None, [ref[0], 0.0], ref)
    rms = lambda v: float(np.sqrt(np.mean(v**2)))  # noqa: E731
    err_alone = rms(alone.x[:, 0] - ref)
    err_passive = rms(passive.x[:, 0] - ref)
    # It tracks: far better than a wheel nobody touches ...
    assert err_alone < 0.5 * err_passive
    # ... but "slight assistance": it cannot follow the reference on its own.
    assert err_alone > 0.1 * rms(ref)
    assert np.all(passive.u_A == 0.0)
    assert rms(alone.u_A) > 0.0


def test_torque_is_held_for_two_samples_when_solved_every_20_ms():
    plant = discretize(0.01)
    ref = _reference(200)
    slow = design_assistant(period=0.02)
    run = simulate_closed_loop(plant, slow, [0.1, 0.0], ref)
    np.testing.assert_array_equal(run.u_A[0::2], run.u_A[1::2])
    assert not np.array_equal(simulate_closed_loop(plant, design_assistant(), [0.1, 0.0], ref).u_A, run.u_A)
    with pytest.raises(ValueError, match="every sample"):
        human_feedback(slow, ref)


def test_assistant_is_state_feedback_plus_reference_feedforward(assistant):
    # What the human who knows the assistant plans with: u_A,k = -gain @ x_k + feedforward_k,
    # with the preview clamped at the end of the reference exactly as in the closed loop.
    plant = discretize(0.01)
    ref = _reference(400)
    pol = lq_policy(plant, (60.0, 0.0, 1.0), ref, np.zeros(400))
    noise = np.random.default_rng(2).normal(0.0, 0.1, 400)
    run = simulate_closed_loop(plant, assistant, [0.05, 0.0], ref, pol.L, pol.f, noise)
    fb = human_feedback(assistant, ref)
    np.testing.assert_allclose(run.u_A, -run.x[:-1] @ fb.gain + fb.feedforward, rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(fb.feedforward, feedforward(assistant, ref))
    # The feedforward is the torque the assistant applies to a wheel at rest at zero.
    r_preview = ref[np.minimum(7 + 2 * np.arange(1, 51), 400)]
    assert fb.feedforward[7] == pytest.approx(assistant_torque(assistant, [0.0, 0.0], r_preview), rel=1e-12)


def test_closed_loop_with_a_human_policy_matches_open_loop_replay(assistant):
    # The closed loop's u_A, replayed as a known input, gives the same states (u_A enters affinely).
    plant = discretize(0.01)
    ref = _reference(300)
    pol = lq_policy(plant, (60.0, 0.0, 1.0), ref, np.zeros(300))
    noise = np.random.default_rng(1).normal(0.0, 0.1, 300)
    run = simulate_closed_loop(plant, assistant, [0.0, 0.0], ref, pol.L, pol.f, noise)
    from scioc.models.plant import propagate

    np.testing.assert_allclose(propagate(plant, [0.0, 0.0], run.u_H + run.u_A), run.x, rtol=1e-12, atol=1e-14)


def test_bad_assistant_settings_are_rejected():
    with pytest.raises(ValueError, match="multiple"):
        design_assistant(dt_assistant=0.015)
    with pytest.raises(ValueError, match="period"):
        design_assistant(period=0.015)
    with pytest.raises(ValueError, match="R must be > 0"):
        design_assistant(theta_A=(5.0, 0.0, 0.0))
