import numpy as np
import pytest

from models.cost import Theta, normalize, validate_theta


@pytest.mark.parametrize(
    "theta, message",
    [
        ([1.0, 0.0, 0.0], "R must be > 0"),
        ([-1.0, 0.0, 1.0], "q11 must be >= 0"),
        ([1.0, -0.1, 1.0], "q22 must be >= 0"),
        ([np.nan, 0.0, 1.0], "finite"),
        ([1.0, 0.0, np.inf], "finite"),
        ([1.0, 0.0], "shape"),
    ],
)
def test_bad_theta_is_rejected_with_a_clear_message(theta, message):
    with pytest.raises(ValueError, match=message):
        validate_theta(theta)


def test_column_theta_names_the_segment():
    with pytest.raises(ValueError, match="segment 1"):
        validate_theta(np.array([[1.0, 1.0], [0.0, 0.0], [1.0, -1.0]]))


def test_normalize_divides_by_R():
    np.testing.assert_allclose(normalize([10.0, 2.0, 4.0]), [2.5, 0.5, 1.0])
    assert Theta(10.0, 2.0, 4.0).normalized() == Theta(2.5, 0.5, 1.0)
