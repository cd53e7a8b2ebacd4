import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from scioc.models.lq import lq_policy
from scioc.models.plant import discretize


@pytest.mark.parametrize("theta", [(60.0, 0.0, 1.0), (5.0, 0.0, 1.0), (200.0, 0.5, 0.3)])
def test_long_horizon_gain_is_the_dare_gain(plant, theta):
    # Closed-form reference: far from the end the finite-horizon Riccati solution is the DARE's.
    q11, q22, R = theta
    K = 3000
    pol = lq_policy(plant, theta, np.zeros(K + 1), np.zeros(K))
    A, B = plant.A, plant.b[:, None]
    P = solve_discrete_are(A, B, np.diag([q11, q22]), np.array([[R]]))
    L = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)[0]
    np.testing.assert_allclose(pol.L[0], L, rtol=1e-10)
    np.testing.assert_allclose(pol.S[0], R + (B.T @ P @ B)[0, 0], rtol=1e-10)
    # Invariant: the closed loop of the stationary gain is stable.
    assert np.max(np.abs(np.linalg.eigvals(A - B @ L[None, :]))) < 1.0


def test_scalar_closed_form_one_step(plant):
    # K = 1: u_0 minimizes q11 (x1 - r1)² + R u², x1 = (A x0 + b (u + a))_1 -> closed form.
    q11, R = 40.0, 0.5
    x0 = np.array([0.1, -0.3])
    r1, a0 = 0.25, 0.2
    pol = lq_policy(plant, (q11, 0.0, R), np.array([0.0, r1]), np.array([a0]))
    b1 = plant.b[0]
    c = (plant.A @ x0)[0] + b1 * a0 - r1
    u_star = -q11 * b1 * c / (R + q11 * b1**2)
    u_policy = -pol.L[0] @ x0 + pol.f[0]
    assert u_policy == pytest.approx(u_star, rel=1e-12)
    assert pol.S[0] == pytest.approx(R + q11 * b1**2, rel=1e-12)


def test_policy_rejects_mismatched_lengths(plant):
    with pytest.raises(ValueError, match="K \\+ 1"):
        lq_policy(plant, (1.0, 0.0, 1.0), np.zeros(5), np.zeros(5))


def test_assistant_plant_is_the_same_recursion():
    # Sanity of reuse: the 0.02-s plant gives a different but stable gain.
    p2 = discretize(0.02)
    pol = lq_policy(p2, (5.0, 0.0, 1.0), np.zeros(101), np.zeros(100))
    M = p2.A - np.outer(p2.b, pol.L[0])
    assert np.max(np.abs(np.linalg.eigvals(M))) < 1.0


# --------------------------------------------------------------------------- n-state recursion

from scioc.models.lq import lq_tracking_policy  # noqa: E402
from scioc.models.plant import discretize_lagged  # noqa: E402


@pytest.mark.parametrize("theta", [(400.0, 0.0, 20.0), (200.0, 0.5, 0.3)])
def test_general_recursion_is_lq_policy_on_the_wheel(plant, theta):
    # Invariant: with b_c = b_a = b and n = 2 the general recursion is lq_policy.
    rng = np.random.default_rng(0)
    K = 800
    r = 0.3 * np.sin(np.linspace(0.0, 12.0, K + 1))
    a = rng.normal(0.0, 0.3, K)
    q11, q22, R = theta
    ref = lq_policy(plant, theta, r, a)
    x_ref = np.column_stack([r, np.zeros(K + 1)])
    gen = lq_tracking_policy(plant.A, plant.b, plant.b, np.diag([q11, q22]), R, x_ref, a)
    np.testing.assert_allclose(gen.L, ref.L, rtol=1e-10)
    np.testing.assert_allclose(gen.f, ref.f, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(gen.S, ref.S, rtol=1e-10)


def test_general_recursion_on_the_lagged_wheel_reaches_the_dare():
    # Closed-form reference for n = 3: far from the end the gain is the DARE's, and its closed loop is stable.
    lp = discretize_lagged(0.06)
    Q = np.diag([400.0, 0.0, 0.0])
    R = 20.0
    K = 3000
    pol = lq_tracking_policy(lp.A, lp.b_c, lp.b_a, Q, R, np.zeros((K + 1, 3)), np.zeros(K))
    B = lp.b_c[:, None]
    P = solve_discrete_are(lp.A, B, Q, np.array([[R]]))
    L = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ lp.A)[0]
    np.testing.assert_allclose(pol.L[0], L, rtol=1e-8)
    assert np.max(np.abs(np.linalg.eigvals(lp.A - B @ L[None, :]))) < 1.0


def test_general_recursion_minimizes_the_cost_with_known_input():
    # The policy's rollout beats any perturbation of its commands (cost is quadratic, so a strict minimum).
    lp = discretize_lagged(0.1)
    rng = np.random.default_rng(1)
    K = 60
    Q, R = np.diag([50.0, 0.2, 0.0]), 2.0
    x_ref = np.zeros((K + 1, 3))
    x_ref[:, 0] = 0.2 * np.sin(np.linspace(0.0, 3.0, K + 1))
    a = rng.normal(0.0, 0.5, K)
    pol = lq_tracking_policy(lp.A, lp.b_c, lp.b_a, Q, R, x_ref, a)

    def cost(c):
        z, J = np.array([0.05, 0.0, 0.1]), 0.0
        for k in range(K):
            J += R * c[k] ** 2
            z = lp.A @ z + lp.b_c * c[k] + lp.b_a * a[k]
            J += (z - x_ref[k + 1]) @ Q @ (z - x_ref[k + 1])
        return J

    z, c_opt = np.array([0.05, 0.0, 0.1]), np.empty(K)
    for k in range(K):
        c_opt[k] = -pol.L[k] @ z + pol.f[k]
        z = lp.A @ z + lp.b_c * c_opt[k] + lp.b_a * a[k]
    J0 = cost(c_opt)
    for _ in range(5):
        assert cost(c_opt + 1e-3 * rng.standard_normal(K)) > J0


def test_general_recursion_rejects_bad_shapes(plant):
    with pytest.raises(ValueError, match="K \\+ 1"):
        lq_tracking_policy(plant.A, plant.b, plant.b, np.eye(2), 1.0, np.zeros((5, 2)), np.zeros(5))
    with pytest.raises(ValueError, match="b_c"):
        lq_tracking_policy(plant.A, np.zeros(3), plant.b, np.eye(2), 1.0, np.zeros((6, 2)), np.zeros(5))
    with pytest.raises(ValueError, match="positive semi-definite"):
        lq_tracking_policy(plant.A, plant.b, plant.b, -np.eye(2), 1.0, np.zeros((6, 2)), np.zeros(5))
    with pytest.raises(ValueError, match="R must be > 0"):
        lq_tracking_policy(plant.A, plant.b, plant.b, np.eye(2), 0.0, np.zeros((6, 2)), np.zeros(5))
