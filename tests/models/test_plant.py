import numpy as np
import pytest
from scipy.signal import cont2discrete

from scioc.models.plant import WheelParameters, continuous_matrices, discretize, propagate


def test_table_one_defaults():
    A_c, b_c = continuous_matrices()
    np.testing.assert_allclose(A_c, [[0.0, 1.0], [-1.146 / 0.04, -0.286 / 0.04]])
    np.testing.assert_allclose(b_c, [0.0, 25.0])


@pytest.mark.parametrize("dt", [0.01, 0.02, 0.05, 1e-3])
def test_zoh_matches_scipy_cont2discrete(dt):
    A_c, b_c = continuous_matrices()
    Ad, Bd, *_ = cont2discrete((A_c, b_c[:, None], np.eye(2), np.zeros((2, 1))), dt, method="zoh")
    plant = discretize(dt)
    np.testing.assert_allclose(plant.A, Ad, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(plant.b, Bd[:, 0], rtol=1e-13, atol=1e-15)


def test_sampling_zero_of_the_100hz_plant():
    # The zero of angle/torque transfer of the ZOH plant sits at about -0.976 (issue 3): (b1 z + (a12 b2 - a22 b1)) = 0.
    p = discretize(0.01)
    zero = -(p.A[0, 1] * p.b[1] - p.A[1, 1] * p.b[0]) / p.b[0]
    assert zero == pytest.approx(-0.976, abs=1e-3)


def test_propagate_matches_two_half_steps():
    # Exactness of ZOH: one 0.02-s step equals two 0.01-s steps with the same held torque.
    p1, p2 = discretize(0.01), discretize(0.02)
    x0 = np.array([0.3, -1.2])
    x_two = propagate(p1, x0, np.array([0.7, 0.7]))[-1]
    x_one = propagate(p2, x0, np.array([0.7]))[-1]
    np.testing.assert_allclose(x_two, x_one, rtol=1e-13)


def test_bad_parameters_are_rejected():
    with pytest.raises(ValueError, match="inertia"):
        continuous_matrices(WheelParameters(inertia=0.0))
    with pytest.raises(ValueError, match="sample time"):
        discretize(-0.01)


# --------------------------------------------------------------------------- neuromuscular lag

from scioc.models.plant import discretize_lagged  # noqa: E402


@pytest.mark.parametrize("tau_nm", [0.06, 0.1, 0.3])
def test_lagged_wheel_is_the_zoh_of_the_three_state_system(tau_nm):
    # Reference: scipy's ZOH of z = (phi, phi_dot, tau) with inputs (command, u_A).
    J, c, d = WheelParameters()
    A_c = np.array([[0.0, 1.0, 0.0], [-c / J, -d / J, 1.0 / J], [0.0, 0.0, -1.0 / tau_nm]])
    B_c = np.array([[0.0, 0.0], [0.0, 1.0 / J], [1.0 / tau_nm, 0.0]])
    Ad, Bd, *_ = cont2discrete((A_c, B_c, np.eye(3), np.zeros((3, 2))), 0.01, method="zoh")
    lp = discretize_lagged(tau_nm)
    np.testing.assert_allclose(lp.A, Ad, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(lp.b_c, Bd[:, 0], rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(lp.b_a, Bd[:, 1], rtol=1e-12, atol=1e-15)
    # The wheel block and u_A's path are the plain wheel's, whatever the lag.
    plant = discretize(0.01)
    np.testing.assert_allclose(lp.A[:2, :2], plant.A, rtol=1e-13, atol=1e-15)
    np.testing.assert_allclose(lp.b_a, [*plant.b, 0.0], rtol=1e-13, atol=1e-15)


def test_lagged_wheel_tends_to_the_plain_wheel():
    # As tau_nm -> 0 the command acts on the wheel directly: b_c -> (b, 0·), the lag state's effect -> 0.
    plant = discretize(0.01)
    errors = []
    for tau_nm in (1e-3, 1e-4, 1e-5):
        lp = discretize_lagged(tau_nm)
        errors.append(max(np.max(np.abs(lp.b_c[:2] - plant.b) / np.abs(plant.b)),
                          np.max(np.abs(lp.A[:2, 2]) / np.abs(plant.b))))
    assert errors[-1] < 2e-3
    assert errors[0] > errors[1] > errors[2]  # first order in tau_nm / dt


def test_lagged_wheel_rejects_bad_lags():
    with pytest.raises(ValueError, match="tau_nm"):
        discretize_lagged(0.0)
    with pytest.raises(ValueError, match="sample time"):
        discretize_lagged(0.1, dt=0.0)
