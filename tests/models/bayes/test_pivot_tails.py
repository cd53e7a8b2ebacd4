"""The pivot's tail map (models/bayes/pivot_tails.py): its inverse, its slope, its limits, and the choice of b.

The map's checks are exact (to rounding). The choice of b is checked on 20 000 seeded draws of laws whose answer is
clear (a normal: the identity; a law made by the map itself: a finite b within one grid step of the truth), with the
normal as the negative control of the second.
"""

import numpy as np
import pytensor
import pytensor.tensor as pt

from scioc.models.bayes.pivot_tails import TAIL_GRID, tail_inverse, tail_log_slope, tail_map, tail_scale


def test_the_inverse_inverts_the_map_from_tiny_to_huge_values_and_b_infinite_is_the_identity():
    m = np.concatenate([-np.logspace(-12, 6, 40), [0.0], np.logspace(-12, 6, 40)])
    for b in (1e-3, 0.3, 1.0, 50.0):
        delta = tail_map(m, b)
        np.testing.assert_allclose(tail_inverse(delta, b), m, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(tail_map(m, np.inf), m)
    np.testing.assert_array_equal(tail_inverse(m, np.inf), m)
    np.testing.assert_array_equal(tail_log_slope(m, np.inf), 0.0)
    # per-element b broadcasts, as a group's (n,) tail scales over draws (..., n)
    b = np.array([0.5, np.inf, 2.0])
    d = np.array([[0.1, -3.0, 7.0], [-2.0, 0.4, 0.0]])
    np.testing.assert_allclose(tail_map(tail_inverse(d, b), b), d, rtol=1e-13)


def test_the_map_is_odd_increasing_linear_at_zero_and_a_square_root_far_out():
    b = 0.4
    m = np.linspace(-30, 30, 2001)
    d = tail_map(m, b)
    np.testing.assert_array_equal(d, -tail_map(-m, b))
    assert np.all(np.diff(d) > 0)
    np.testing.assert_allclose(tail_map(1e-6, b), 1e-6, rtol=1e-11)
    np.testing.assert_allclose(tail_map(1e6, b), np.sqrt(b * 1e6), rtol=1e-6)


def test_the_log_slope_is_the_log_derivative_in_numpy_and_pytensor():
    m = np.linspace(-20, 20, 81)
    for b in (0.2, 3.0):
        h = 1e-6
        numeric = (tail_map(m + h, b) - tail_map(m - h, b)) / (2 * h)
        np.testing.assert_allclose(tail_log_slope(m, b), np.log(numeric), rtol=0, atol=1e-8)
        x = pt.dvector("m")
        f = pytensor.function([x], [tail_map(x, b), tail_log_slope(x, b, pt)])
        got_map, got_slope = f(m)
        np.testing.assert_allclose(got_map, tail_map(m, b), rtol=1e-14)
        np.testing.assert_allclose(got_slope, tail_log_slope(m, b), rtol=1e-12, atol=1e-15)


def test_tail_scale_keeps_a_normal_pivot_affine_and_finds_the_b_of_a_mapped_one():
    rng = np.random.default_rng(11)
    u = rng.normal(size=20_000)
    b, scores = tail_scale(0.3 * u)
    assert b == np.inf and set(scores) == {float(g) for g in TAIL_GRID}
    for truth in (0.5, 2.0):  # b in units of δ's SD, chosen to sit on the grid after the SD is measured
        delta = tail_map(u, truth)
        sd = np.sqrt(np.mean(delta**2))
        b, _ = tail_scale(delta)
        g = b / sd
        assert np.isfinite(b)
        grid = np.array([x for x in TAIL_GRID if np.isfinite(x)])
        nearest = grid[np.argmin(np.abs(np.log(grid) - np.log(truth / sd)))]
        assert g in (nearest, *grid[np.abs(np.log(grid / nearest)) <= np.log(2.0) + 1e-12])  # within one grid step
    # draws without spread keep the identity
    assert tail_scale(np.zeros(10))[0] == np.inf
