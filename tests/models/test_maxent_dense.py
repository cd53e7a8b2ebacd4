"""The dense reference itself: a closed form at K = 1, the lifted system, its own gradient."""

import math

import numpy as np
import pytest

from scioc.models.maxent_dense import lifted_matrices, loglik_dense
from scioc.models.plant import propagate
from tests.conftest import random_segment, random_theta


@pytest.mark.parametrize("shared", [False, True])
def test_one_step_is_the_scalar_gaussian(plant, shared):
    """K = 1 by hand: J = eᵀQe + R u², e = A x0 + b (u + a) - (r_1, 0); g = dJ/du, H = 2 (bᵀQb + R)."""
    rng = np.random.default_rng([50, shared])
    for _ in range(5):
        seg = random_segment(rng, 1, shared)
        q11, q22, R = theta = random_theta(rng, False)
        Q = np.diag([q11, q22])
        e = plant.A @ seg.x0 + plant.b * (seg.u_H[0] + seg.u_A[0]) - np.array([seg.angle_ref[1], 0.0])
        g = 2.0 * plant.b @ Q @ e + 2.0 * R * seg.u_H[0]
        H = 2.0 * (plant.b @ Q @ plant.b + R)
        expected = -0.5 * g * g / H + 0.5 * math.log(H) - 0.5 * math.log(2.0 * math.pi)
        res = loglik_dense(theta, seg, plant)
        assert res.loglik == pytest.approx(expected, rel=1e-12)
        assert res.H[0, 0] == pytest.approx(H, rel=1e-14)
        assert res.u_opt[0] == pytest.approx(seg.u_H[0] - g / H, rel=1e-12, abs=1e-15)


def test_lifted_system_is_the_propagated_plant(plant):
    rng = np.random.default_rng(51)
    K = 40
    x0, u = rng.normal(size=2), rng.normal(size=K)
    Phi, Gamma = lifted_matrices(plant, K)
    x = propagate(plant, x0, u)
    np.testing.assert_allclose(Phi @ x0 + Gamma @ u, x[1:].ravel(), rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("shared", [False, True])
def test_dense_gradient_matches_central_differences(plant, shared):
    rng = np.random.default_rng([52, shared])
    seg = random_segment(rng, 60, shared)
    theta = random_theta(rng, False)
    theta[1] = max(theta[1], 0.05)  # a central difference needs room on both sides of q22
    grad = loglik_dense(theta, seg, plant).grad
    for j in range(3):
        h = 1e-5 * theta[j]
        tp, tm = theta.copy(), theta.copy()
        tp[j] += h
        tm[j] -= h
        fd = (loglik_dense(tp, seg, plant, with_grad=False).loglik
              - loglik_dense(tm, seg, plant, with_grad=False).loglik) / (2 * h)
        # O(h²) truncation and eps·|ll|/h rounding are both far below 1e-6 relative here.
        assert abs(fd - grad[j]) <= 1e-6 * abs(grad[j]), (j, fd, grad[j])
