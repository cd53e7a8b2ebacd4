import numpy as np
import pytest

from scioc.models.cost import Theta, from_log_normalized, from_normalized, normalize, validate_theta


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


def test_from_normalized_is_the_products_bit_for_bit():
    """[θ1 R, θ2 R, R]: the same floating-point operations as the hand-written form it replaced."""
    rng = np.random.default_rng(60)
    t1, t2, r = np.exp(rng.normal(3.0, 1.0, 50)), np.abs(rng.normal(0.0, 0.1, 50)), np.exp(rng.normal(3.0, 1.0, 50))
    np.testing.assert_array_equal(from_normalized(t1, t2, r), np.vstack([t1 * r, t2 * r, r]))
    np.testing.assert_array_equal(from_normalized(t1[0], t2[0], r[0]), np.array([t1[0] * r[0], t2[0] * r[0], r[0]]))
    assert from_normalized(t1, 0.0, r[0]).shape == (3, 50)
    np.testing.assert_allclose(normalize(from_normalized(t1, t2, r)), np.vstack([t1, t2, np.ones(50)]), rtol=1e-15)


def test_from_log_normalized_is_one_exp_of_the_sum():
    rng = np.random.default_rng(61)
    lt1, t2, lr = rng.normal(3.0, 1.0, 50), np.abs(rng.normal(0.0, 0.1, 50)), rng.normal(3.0, 1.0, 50)
    np.testing.assert_array_equal(from_log_normalized(lt1, t2, lr),
                                  np.vstack([np.exp(lt1 + lr), t2 * np.exp(lr), np.exp(lr)]))
    # The same θ as the product form up to rounding (a few ulps of exp).
    np.testing.assert_allclose(from_log_normalized(lt1, t2, lr), from_normalized(np.exp(lt1), t2, np.exp(lr)),
                               rtol=1e-14)

