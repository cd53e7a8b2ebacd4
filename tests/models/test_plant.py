import numpy as np
import pytest
from scipy.signal import cont2discrete

from models.plant import WheelParameters, continuous_matrices, discretize, propagate


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
