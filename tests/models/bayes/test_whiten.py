"""Per-subject whitening (models/bayes/whiten.py): the blocks are each subject's coordinates, the Hessian blocks are
exact on a Gaussian, L is a square root of the inverse (of |H| where H is not negative definite), and the whitened
model's density is the original's at x(w)."""

import numpy as np
import pymc as pm
import pytest
from pymc.blocking import DictToArrayBijection, RaveledVars
from pymc.pytensorf import join_nonshared_inputs

from models.bayes.whiten import (block_hessian, coordinate_scales, subject_blocks, to_unconstrained, whitened_model,
                                 whitening_factors)


def _model(n=4):
    """A small hierarchical model: a population location and scale, per-subject values with and without transforms."""
    with pm.Model(coords={"subject": [f"s{i}" for i in range(n)], "condition": ["MC", "SC"]}) as model:
        mu = pm.Normal("mu", 0.0, 1.0)
        scale = pm.HalfNormal("scale", 1.0)
        a = pm.Normal("a", mu, scale, dims=("subject", "condition"))
        b = pm.HalfNormal("b", 1.0, dims="subject")
        pm.Normal("y", a.sum(axis=1) + b, 0.1, observed=np.linspace(0.5, 1.5, n), dims="subject")
    return model


def _flat(model):
    point = model.initial_point()
    raveled = DictToArrayBijection.map({v.name: point[v.name] for v in model.value_vars})
    dims = [model.named_vars_to_dims.get(model.values_to_rvs[v].name) for v in model.value_vars]
    return point, raveled, dims


def test_blocks_are_each_subjects_coordinates_in_the_same_order():
    model = _model(4)
    point, raveled, dims = _flat(model)
    blocks = subject_blocks(raveled.point_map_info, dims, 4)
    assert blocks.shape == (4, 3)  # a (2 conditions) and b's log
    # value order mu, scale_log__, a, b_log__: a occupies 2..9 (subject-major), b_log__ 10..13
    np.testing.assert_array_equal(blocks[:, :2], np.arange(2, 10).reshape(4, 2))
    np.testing.assert_array_equal(blocks[:, 2], np.arange(10, 14))
    with pytest.raises(ValueError, match="'subject' must be its first dim"):
        subject_blocks([("x", (2, 4), 8, "float64")], [("condition", "subject")], 4)
    with pytest.raises(ValueError, match="nothing to whiten"):
        subject_blocks([("x", (2,), 2, "float64")], [None], 4)


def test_hessian_blocks_are_exact_on_a_gaussian_with_a_population_coupling():
    rng = np.random.default_rng(0)
    n, k = 5, 3
    blocks = 1 + np.arange(n * k).reshape(n, k)  # coordinate 0 is a population coordinate
    P = np.zeros((1 + n * k, 1 + n * k))
    P[0, 0] = 4.0
    truth = []
    for i in range(n):
        A = rng.normal(size=(k, k))
        Pi = A @ A.T + k * np.eye(k)
        truth.append(-Pi)
        P[np.ix_(blocks[i], blocks[i])] = Pi
        P[0, blocks[i]] = P[blocks[i], 0] = 0.3  # couples every subject to the population coordinate
    x0 = rng.normal(size=1 + n * k)
    H = block_hessian(lambda x: -P @ (x - x0), rng.normal(size=x0.size), blocks, 1e-4)
    np.testing.assert_allclose(H, np.array(truth), rtol=1e-9, atol=1e-9)


def test_L_is_a_square_root_of_the_inverse_of_minus_H_and_of_its_absolute_value_where_H_is_indefinite():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(3, 3))
    neg_def = -(A @ A.T + np.eye(3))
    V = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    indefinite = V @ np.diag([-5.0, 2.0, -0.5]) @ V.T  # -H has eigenvalues 5, -2, 0.5
    L, n_neg = whitening_factors(np.stack([neg_def, indefinite]))
    np.testing.assert_allclose(L[0] @ L[0].T, np.linalg.inv(-neg_def), rtol=1e-10)
    np.testing.assert_allclose(L[1] @ L[1].T, V @ np.diag([1 / 5.0, 1 / 2.0, 1 / 0.5]) @ V.T, rtol=1e-10, atol=1e-12)
    np.testing.assert_array_equal(n_neg, [0, 1])
    assert np.allclose(np.triu(L[0], 1), 0.0)
    with pytest.raises(ValueError, match="subject block 0: the Hessian is not finite"):
        whitening_factors(np.full((1, 2, 2), np.nan))


def test_the_whitened_density_is_the_models_at_x_of_w():
    model = _model(4)
    point, raveled, dims = _flat(model)
    blocks = subject_blocks(raveled.point_map_info, dims, 4)
    rng = np.random.default_rng(2)
    x_hat = raveled.data + rng.normal(size=raveled.data.size)
    L = np.array([np.linalg.cholesky(M @ M.T + np.eye(3)) for M in rng.normal(size=(4, 3, 3))])
    [logp], flat = join_nonshared_inputs(point, [model.logp()], model.value_vars)
    white = whitened_model(logp, flat, x_hat, [(blocks, L)])
    white_logp = white.compile_logp()
    model_logp = model.compile_logp()
    for _ in range(5):
        w = rng.normal(size=x_hat.size)
        x = to_unconstrained(w, x_hat, [(blocks, L)])
        p = DictToArrayBijection.rmap(RaveledVars(x, raveled.point_map_info))
        np.testing.assert_allclose(white_logp({"w": w}), model_logp(p), rtol=1e-12)
    # x(w): subject blocks move by L w, the rest by w; w = 0 is x̂
    np.testing.assert_array_equal(to_unconstrained(np.zeros(x_hat.size), x_hat, [(blocks, L)]), x_hat)
    w = rng.normal(size=(2, 3, x_hat.size))  # draws (chain, draw, D)
    x = to_unconstrained(w, x_hat, [(blocks, L)])
    np.testing.assert_allclose(x[1, 2, blocks[3]], x_hat[blocks[3]] + L[3] @ w[1, 2, blocks[3]], rtol=1e-14)
    np.testing.assert_allclose(x[0, 1, :2], x_hat[:2] + w[0, 1, :2], rtol=1e-14)



def test_coordinate_scales_are_each_coordinates_curvature_capped_at_one():
    # log p = -½ (x - x0)ᵀ P (x - x0) with off-diagonal terms: each scale is P_cc^(-1/2) (the conditional scale,
    # not the marginal one), and a coordinate with P_cc < 1 keeps the unit scale
    rng = np.random.default_rng(4)
    A = rng.normal(size=(4, 4))
    P = A @ A.T + np.diag([400.0, 25.0, 0.0, 0.0])
    P[3, :] = P[:, 3] = 0.0
    P[3, 3] = 0.25
    x0 = rng.normal(size=4)
    S = coordinate_scales(lambda x: -P @ (x - x0), rng.normal(size=4), np.array([0, 1, 3]), 1e-4)
    assert S.shape == (3, 1, 1)
    np.testing.assert_allclose(S[:2, 0, 0], np.diag(P)[:2] ** -0.5, rtol=1e-9)
    assert S[2, 0, 0] == 1.0
    # a negative curvature (not a maximum there) is scaled by its absolute value
    np.testing.assert_allclose(coordinate_scales(lambda x: 9.0 * x, np.zeros(1), np.array([0]), 1e-4)[0, 0, 0],
                               1 / 3, rtol=1e-9)
    with pytest.raises(ValueError, match="coordinate 0: the second derivative is not finite"):
        coordinate_scales(lambda x: np.full_like(x, np.nan), np.zeros(1), np.array([0]), 1e-4)


def test_one_coordinate_groups_scale_their_coordinates():
    x_hat = np.array([1.0, 2.0, 3.0])
    groups = [(np.array([[0], [2]]), np.array([[[0.5]], [[0.1]]]))]
    np.testing.assert_allclose(to_unconstrained(np.array([2.0, 2.0, 2.0]), x_hat, groups), [2.0, 4.0, 3.2])
