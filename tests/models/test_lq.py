import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from models.lq import lq_policy
from models.plant import discretize


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
