"""The whitening measured on draws (models/bayes/whiten_draws.py): on draws of a known law each block's centre,
factor and curvature are that law's, and the draws mapped to w are uncorrelated with unit scale.

Tolerances are Monte Carlo: 20 000 draws per block, so a mean is within 5 SEs (false alarm about 5.7e-7 per
mean) and a variance within 5 % (its SE is about 1 %). The negative controls use the same draws with the
factor the check is about left out, or the reflection; each must fail.
"""

import numpy as np
import pytest

from scioc.models.bayes.whiten import to_unconstrained
from scioc.models.bayes.whiten_draws import covariance_factor, draws_factors, to_white

N_DRAWS = 20_000


def test_to_white_inverts_to_unconstrained_and_the_forward_map_alone_does_not():
    rng = np.random.default_rng(6)
    blocks = np.arange(6).reshape(3, 2)
    L = np.linalg.cholesky(np.array([[2.0, 0.5], [0.5, 1.0]]))[None].repeat(3, axis=0)
    a = np.column_stack([np.zeros(3), rng.normal(size=3)])
    groups = [(blocks, L, (0, a)), (np.array([[6], [7]]), np.array([[[2.0]], [[3.0]]]))]
    x_hat = rng.normal(size=8)
    w = rng.normal(size=(5, 4, 8))
    np.testing.assert_allclose(to_white(to_unconstrained(w, x_hat, groups), x_hat, groups), w, atol=1e-12)
    # negative control: without the curvature the inverse misses
    flat = [(blocks, L, (0, np.zeros_like(a))), groups[1]]
    assert np.max(np.abs(to_white(to_unconstrained(w, x_hat, groups), x_hat, flat) - w)) > 0.1


def test_an_affine_block_takes_its_draws_mean_and_covariance():
    rng = np.random.default_rng(1)
    covs = [np.array([[1.0, 0.9, 0.0], [0.9, 1.0, 0.3], [0.0, 0.3, 4.0]]), np.diag([0.01, 1.0, 100.0])]
    means = [np.array([1.0, -2.0, 3.0]), np.array([0.0, 5.0, -1.0])]
    x = np.concatenate([rng.multivariate_normal(m, c, N_DRAWS) for m, c in zip(means, covs)], axis=1)
    blocks = np.arange(6).reshape(2, 3)
    old = [(blocks, np.broadcast_to(np.eye(3), (2, 3, 3)).copy())]
    x_hat, groups, kept = draws_factors(x, np.zeros(6), old, [None])
    assert kept == 0
    [(b, L)] = groups
    np.testing.assert_array_equal(b, blocks)
    for i in range(2):
        se = np.sqrt(np.diag(covs[i]) / N_DRAWS)
        assert np.all(np.abs(x_hat[blocks[i]] - means[i]) < 5 * se)
        scale = np.sqrt(np.outer(np.diag(covs[i]), np.diag(covs[i])))
        assert np.max(np.abs(L[i] @ L[i].T - covs[i]) / scale) < 0.05  # each entry within 5 % of its scale
    w = to_white(x, x_hat, groups)
    cw = np.cov(w, rowvar=False)
    for i in range(2):  # within a block exactly the identity, by construction; between blocks the draws' noise
        np.testing.assert_allclose(cw[np.ix_(blocks[i], blocks[i])], np.eye(3), atol=1e-9)
    assert np.max(np.abs(cw[np.ix_(blocks[0], blocks[1])])) < 5 / np.sqrt(N_DRAWS)
    np.testing.assert_allclose(to_unconstrained(w, x_hat, groups), x, rtol=1e-10, atol=1e-10)
    # negative control: the same draws in the old coordinates are neither unit-scaled nor uncorrelated
    assert np.max(np.abs(np.cov(to_white(x, x_hat, old), rowvar=False) - np.eye(6))) > 0.5


def _parabola(rng, signed_mean=0.0, c=3.0, s=0.5, t=0.1):
    """Draws of v ~ N(signed_mean, s) and y = 1 + c v² + N(0, t), the pivot v first."""
    v = rng.normal(signed_mean, s, N_DRAWS)
    return np.column_stack([v, 1.0 + c * v**2 + rng.normal(0.0, t, N_DRAWS)])


def test_a_curved_block_straightens_its_parabola_and_an_affine_one_does_not():
    rng = np.random.default_rng(2)
    x = _parabola(rng)
    blocks = np.array([[0, 1]])
    curved = [(blocks, np.eye(2)[None].copy(), (0, np.zeros((1, 2))))]
    x_hat, groups, _ = draws_factors(x, np.zeros(2), curved, [np.array([True])])
    [(_, L, (pivot, a, b))] = groups
    assert pivot == 0 and x_hat[0] == 0.0 and a[0, 0] == 0.0  # a signed pivot is centred on its fold
    assert b[0] == np.inf  # a normal pivot keeps the affine map (models/bayes/pivot_tails.py)
    assert abs(a[0, 1] - 3.0) < 0.05 and abs(x_hat[1] - 1.0) < 0.01
    np.testing.assert_allclose(np.diag(L[0] @ L[0].T), [0.25, 0.01], rtol=0.05)

    def bend(w):  # what is left of the parabola in w: the slope of w_y on w_v²
        return np.polyfit(w[:, 0] ** 2, w[:, 1], 1)[0]

    assert abs(bend(to_white(x, x_hat, groups))) < 0.05
    np.testing.assert_allclose(to_unconstrained(to_white(x, x_hat, groups), x_hat, groups), x, rtol=1e-10, atol=1e-10)
    # negative control: measured as an affine block, the same draws keep their parabola
    x_aff, affine, _ = draws_factors(x, np.zeros(2), [(blocks, np.eye(2)[None].copy())], [None])
    assert abs(bend(to_white(x, x_aff, affine))) > 0.5


def test_a_signed_pivot_counts_its_draws_reflected_and_an_unsigned_one_does_not():
    # the draws of one side of a fold (a chain that stayed at v > 0): reflected, they are the symmetric law's, whose
    # SD is s = 0.5; not reflected, the half-normal's sqrt(1 - 2/π) s about its mean s sqrt(2/π)
    rng = np.random.default_rng(3)
    x = _parabola(rng)
    x[:, 0] = np.abs(x[:, 0])
    blocks = np.array([[0, 1]])
    curved = [(blocks, np.eye(2)[None].copy(), (0, np.zeros((1, 2))))]
    x_hat, (grp,), _ = draws_factors(x, np.zeros(2), curved, [np.array([True])])
    assert x_hat[0] == 0.0 and abs(np.sqrt((grp[1][0] @ grp[1][0].T)[0, 0]) - 0.5) < 0.01
    assert abs(grp[2][1][0, 1] - 3.0) < 0.05
    x_hat, (grp,), _ = draws_factors(x, np.zeros(2), curved, [np.array([False])])
    assert abs(x_hat[0] - 0.5 * np.sqrt(2 / np.pi)) < 0.01
    assert abs(np.sqrt((grp[1][0] @ grp[1][0].T)[0, 0]) - 0.5 * np.sqrt(1 - 2 / np.pi)) < 0.01


def test_a_block_whose_draws_did_not_move_keeps_its_factor_and_centre():
    rng = np.random.default_rng(4)
    x = np.column_stack([rng.normal(size=50), np.full(50, 7.0)])
    old_L = np.array([[[2.0]], [[3.0]]])
    x_hat, [(_, L)], kept = draws_factors(x, np.array([1.0, 2.0]), [(np.array([[0], [1]]), old_L)], [None])
    assert kept == 1
    assert L[1, 0, 0] == 3.0 and x_hat[1] == 2.0 and L[0, 0, 0] != 2.0


def test_covariance_factor_floors_a_singular_covariance_and_refuses_none():
    v = np.array([1.0, 2.0])
    L = covariance_factor(np.outer(v, v))
    lam = np.linalg.eigvalsh(L @ L.T)
    np.testing.assert_allclose(lam, [5e-6, 5.0], rtol=1e-6)
    assert covariance_factor(np.zeros((2, 2))) is None
    assert covariance_factor(np.array([[np.nan]])) is None


def test_draws_factors_errors():
    groups = [(np.array([[0]]), np.ones((1, 1, 1)))]
    with pytest.raises(ValueError, match="at least 2 finite draws"):
        draws_factors(np.zeros((1, 1)), np.zeros(1), groups, [None])
    with pytest.raises(ValueError, match="at least 2 finite draws"):
        draws_factors(np.array([[0.0], [np.nan]]), np.zeros(1), groups, [None])
    with pytest.raises(ValueError, match="one entry per group"):
        draws_factors(np.zeros((3, 1)), np.zeros(1), groups, [])


def test_a_pivot_with_walls_gets_a_tail_map_that_makes_it_normal_and_without_one_it_stays_walled():
    # v = f_b(m), m ~ N(0, 1), b = 0.7: |v| grows like √|m|, a law with quartic walls; y = 1 + 3 v² + N(0, 0.1). The
    # pivot's whitened draws are then normal (excess kurtosis within 0.15 of 0: its SE on 40 000 counted draws is
    # about 0.025, so 6 SEs), and with tails=False (the affine pivot) they are not (below -0.5)
    from scipy.stats import kurtosis

    from scioc.models.bayes.pivot_tails import tail_map

    rng = np.random.default_rng(12)
    v = tail_map(rng.normal(size=N_DRAWS), 0.7)
    x = np.column_stack([v, 1.0 + 3.0 * v**2 + rng.normal(0.0, 0.1, N_DRAWS)])
    blocks = np.array([[0, 1]])
    curved = [(blocks, np.eye(2)[None].copy(), (0, np.zeros((1, 2))))]
    x_hat, groups, _ = draws_factors(x, np.zeros(2), curved, [np.array([True])])
    [(_, L, (_, a, b))] = groups
    assert np.isfinite(b[0]) and abs(a[0, 1] - 3.0) < 0.05
    w = to_white(x, x_hat, groups)
    assert abs(kurtosis(np.concatenate([w[:, 0], -w[:, 0]]))) < 0.15
    np.testing.assert_allclose(to_unconstrained(w, x_hat, groups), x, rtol=1e-10, atol=1e-10)
    x_aff, affine, _ = draws_factors(x, np.zeros(2), curved, [np.array([True])], tails=False)
    assert affine[0][2][2][0] == np.inf
    assert kurtosis(np.concatenate([to_white(x, x_aff, affine)[:, 0], -to_white(x, x_aff, affine)[:, 0]])) < -0.5
