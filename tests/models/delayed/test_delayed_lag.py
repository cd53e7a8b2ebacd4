"""The lag map τ_nm -> (a, α) against the exact lagged plant, finite differences and its limits."""

import numpy as np
import pytest

from scioc.models.delayed.lag import lag_coefficients, lagged_planning_plant
from scioc.models.design import WheelParameters
from scioc.models.plant import discretize, discretize_lagged


@pytest.mark.parametrize("tau", [0.001, 0.01, 0.06, 0.1, 1.0])
def test_pole_and_mixing_are_the_lagged_plants_velocity_row(plant, tau):
    lag = lag_coefficients(tau)
    lp = discretize_lagged(tau)
    b1 = plant.b[1]
    np.testing.assert_allclose(lp.A[:2, :2], plant.A, rtol=0, atol=1e-15)  # the same wheel
    assert lag.a == pytest.approx(lp.A[2, 2], rel=1e-14)
    assert lag.alpha == pytest.approx(lp.A[1, 2] / b1, rel=1e-12)
    assert 1.0 - lag.alpha == pytest.approx(lp.b_c[1] / b1, rel=1e-12)
    # a held torque passes the lag unchanged: the two weights sum to one
    assert lp.A[1, 2] / b1 + lp.b_c[1] / b1 == pytest.approx(1.0, abs=1e-14)


@pytest.mark.parametrize("tau", [0.005, 0.06, 0.1, 1.0])
def test_derivatives_match_central_differences(tau):
    lag = lag_coefficients(tau)
    h = 1e-4 * tau  # O(h²) truncation ~1e-8 relative, rounding ~1e-12
    up, down = lag_coefficients(tau + h), lag_coefficients(tau - h)
    assert lag.da == pytest.approx((up.a - down.a) / (2 * h), rel=1e-6)
    assert lag.dalpha == pytest.approx((up.alpha - down.alpha) / (2 * h), rel=1e-6)


def test_no_lag_and_the_one_sided_derivative_at_zero():
    lag = lag_coefficients(0.0)
    assert (lag.a, lag.alpha, lag.da) == (0.0, 0.0, 0.0)
    # second-order one-sided difference; a = exp(-dt/h) is below 1e-40 here
    h = 1e-4
    fd = (-3 * 0.0 + 4 * lag_coefficients(h).alpha - lag_coefficients(2 * h).alpha) / (2 * h)
    assert lag.dalpha == pytest.approx(fd, rel=1e-6)
    assert lag_coefficients(h).da < 1e-30


def test_a_wheel_with_real_poles_is_exact_near_the_removable_singularity():
    # spring 0.1 N·m/rad: real poles, A_c + I/τ_nm is singular at τ_nm = -1/λ
    params = WheelParameters(0.04, 0.1, 0.286)
    b1 = discretize(0.01, params).b[1]
    lam = np.linalg.eigvals(np.array([[0.0, 1.0], [-0.1 / 0.04, -0.286 / 0.04]])).real
    tau_star = -1.0 / lam.min()
    for tau in (tau_star, tau_star * (1 + 1e-7), tau_star * 1.03, tau_star * 1.06):
        lag = lag_coefficients(tau, 0.01, params)
        assert lag.alpha == pytest.approx(discretize_lagged(tau, 0.01, params).A[1, 2] / b1, rel=1e-13)
        h = 1e-5 * tau
        fd = (lag_coefficients(tau + h, 0.01, params).alpha - lag_coefficients(tau - h, 0.01, params).alpha) / (2 * h)
        assert lag.dalpha == pytest.approx(fd, rel=1e-6)


def test_arrays_keep_their_shape():
    lag = lag_coefficients(np.array([[0.0, 0.06], [0.1, 0.06]]))
    assert lag.alpha.shape == (2, 2)
    assert lag.alpha[0, 1] == lag.alpha[1, 1] == lag_coefficients(0.06).alpha


@pytest.mark.parametrize("bad", [-0.01, np.nan, np.inf, [0.1, -1.0]])
def test_invalid_time_constants_are_refused(bad):
    with pytest.raises(ValueError, match="tau_nm"):
        lag_coefficients(bad)


def test_planning_plant(plant):
    lag = lag_coefficients(0.06)
    gain = np.array([2.0, 0.3])
    pp = lagged_planning_plant(plant, lag.a, lag.alpha, gain)
    np.testing.assert_allclose(pp.A[:2, :2], plant.A - np.outer(plant.b, gain), rtol=0, atol=1e-15)
    np.testing.assert_allclose(pp.A[:2, 2], lag.alpha * plant.b)
    np.testing.assert_array_equal(pp.A[2], [0.0, 0.0, lag.a])
    np.testing.assert_allclose(pp.b_c, [*(1 - lag.alpha) * plant.b, 1 - lag.a])
    np.testing.assert_array_equal(pp.b_a, [*plant.b, 0.0])
    # no lag: the arm torque is not a state the wheel feels, the command is the torque
    pp0 = lagged_planning_plant(plant, 0.0, 0.0)
    np.testing.assert_array_equal(pp0.A[:, 2], 0.0)
    np.testing.assert_array_equal(pp0.b_c, [*plant.b, 1.0])
