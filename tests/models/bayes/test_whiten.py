"""Per-subject whitening (models/bayes/whiten.py): the blocks are each subject's coordinates, the Hessian blocks are
exact on a Gaussian, L is a square root of the inverse (of |H| where H is not negative definite), and the whitened
model's density is the original's at x(w)."""

import numpy as np
import pymc as pm
import pytest
from pymc.blocking import DictToArrayBijection, RaveledVars
from pymc.pytensorf import join_nonshared_inputs

from scioc.models.bayes.whiten import (
    block_column,
    block_hessian,
    coordinate_scales,
    nearest_fold,
    ridge_curvature,
    subject_blocks,
    to_unconstrained,
    whitened_model,
    whitening_factors,
)


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


def _banana(n=3, beta=0.7, c=(4.0, -2.0, 9.0), s=(0.5, 0.3, 0.2), t=0.05):
    """Per subject v ~ N(0, s_i), y ~ N(beta v + c_i v², t): a ridge y = beta v + c_i v² through the mode 0."""
    with pm.Model(coords={"subject": [f"s{i}" for i in range(n)]}) as model:
        v = pm.Normal("v", 0.0, np.asarray(s), dims="subject")
        pm.Normal("y", beta * v + np.asarray(c) * v**2, t, dims="subject")
    return model


def test_ridge_curvature_is_exact_on_a_banana_and_its_curved_map_is_a_standard_normal():
    # the ridge is quadratic in the pivot, so the second difference is exact at any span, and x(w) = x̂ + L w +
    # a δ² makes the density exactly -½|w|² + const (the map's Jacobian is constant)
    beta, c, s, t = 0.7, np.array([4.0, -2.0, 9.0]), np.array([0.5, 0.3, 0.2]), 0.05
    model = _banana(beta=beta, c=c, s=s, t=t)
    point, raveled, dims = _flat(model)
    blocks = subject_blocks(raveled.point_map_info, dims, 3)
    pivot = block_column(raveled.point_map_info, dims, 3, "v")
    assert pivot == 0 and blocks.shape == (3, 2)
    [logp], flat = join_nonshared_inputs(point, [model.logp()], model.value_vars)
    import pytensor
    import pytensor.tensor as pt
    grad = pytensor.function([flat], pt.grad(logp, flat))
    x_hat = np.zeros(raveled.data.size)
    H = block_hessian(grad, x_hat, blocks, 1e-4)
    L, _ = whitening_factors(H)
    for span in (1.0, 2.5):
        a, record = ridge_curvature(grad, x_hat, blocks, L, pivot, span=span)
        np.testing.assert_allclose(a[:, 1], c, rtol=1e-6)
        np.testing.assert_array_equal(a[:, 0], 0.0)
        assert record["subjects_without_curvature"] == 0
    # the pivot's marginal scale is s_i (H by central differences of step 1e-4, whose error here is O(1e-5))
    np.testing.assert_allclose(record["pivot_scale_range"], [2.5 * s.min(), 2.5 * s.max()], rtol=1e-4)
    # the map itself, with the exact precision at the mode ((v, y) order): -½|w|² + const to rounding
    P = np.array([[[1 / si**2 + beta**2 / t**2, -beta / t**2], [-beta / t**2, 1 / t**2]] for si in s])
    L = np.linalg.cholesky(np.linalg.inv(P))
    a, _ = ridge_curvature(grad, x_hat, blocks, L, pivot)
    np.testing.assert_allclose(a[:, 1], c, rtol=1e-9)
    groups = [(blocks, L, (pivot, a))]
    white = whitened_model(logp, flat, x_hat, groups).compile_logp()
    rng = np.random.default_rng(5)
    values = [white({"w": w}) + 0.5 * w @ w for w in rng.normal(size=(6, x_hat.size)) * 2.0]
    np.testing.assert_allclose(values, values[0], rtol=1e-9)
    # to_unconstrained is the same map, on draws (chain, draw, D): y - beta v - c v² is linear in w
    w = rng.normal(size=(2, 4, x_hat.size))
    x = to_unconstrained(w, x_hat, groups)
    v, y = x[..., blocks[:, 0]], x[..., blocks[:, 1]]
    straight = to_unconstrained(w, x_hat, [(blocks, L)])
    np.testing.assert_allclose(y - c * v**2, straight[..., blocks[:, 1]], rtol=1e-12, atol=1e-14)
    np.testing.assert_array_equal(v, straight[..., blocks[:, 0]])
    # without the curvature, the same density is not a standard normal in w
    flat_white = whitened_model(logp, flat, x_hat, [(blocks, L)]).compile_logp()
    values = [flat_white({"w": w}) + 0.5 * w @ w for w in rng.normal(size=(6, x_hat.size)) * 2.0]
    assert np.ptp(values) > 1.0


def _tailed_banana(b, c=(4.0, -2.0, 9.0), s=(0.5, 0.3, 0.2), t=0.05):
    """Per subject v = f_b(m) with m ~ N(0, s_i) (models/bayes/pivot_tails.py; v's density written out, f_b⁻¹ in
    closed form) and y ~ N(c_i v², t): a pivot with quartic walls, on a parabola."""
    import pytensor.tensor as pt

    from scioc.models.bayes.pivot_tails import tail_log_slope

    with pm.Model(coords={"subject": [f"s{i}" for i in range(len(c))]}) as model:
        v = pm.Flat("v", dims="subject")
        r = v**2 / (2.0 * b**2)
        m = pt.sign(v) * pt.abs(v) * pt.sqrt(r + pt.sqrt(1.0 + r**2))
        pm.Potential("v_law", pt.sum(pm.logp(pm.Normal.dist(0.0, np.asarray(s)), m) - tail_log_slope(m, b, pt)))
        pm.Normal("y", np.asarray(c) * v**2, t, dims="subject")
    return model


def test_a_pivots_tail_map_and_its_jacobian_make_a_walled_banana_a_standard_normal():
    # x = x̂ + (f_b(m), L w) + a δ², m the pivot's row of L w: with L = diag(s_i, t), a = c and the law's own b, the
    # density of w is exactly -½|w|² + const, which needs both the map and its log Jacobian Σ log f_b'(m)
    b, c, s, t = 0.15, np.array([4.0, -2.0, 9.0]), np.array([0.5, 0.3, 0.2]), 0.05
    model = _tailed_banana(b, c, s, t)
    point, raveled, dims = _flat(model)
    blocks = subject_blocks(raveled.point_map_info, dims, 3)
    [logp], flat = join_nonshared_inputs(point, [model.logp()], model.value_vars)
    x_hat = np.zeros(raveled.data.size)
    L = np.array([np.diag([si, t]) for si in s])
    a = np.column_stack([np.zeros(3), c])
    groups = [(blocks, L, (0, a, np.full(3, b)))]
    white = whitened_model(logp, flat, x_hat, groups).compile_logp()
    rng = np.random.default_rng(9)
    ws = rng.normal(size=(6, x_hat.size)) * 2.0
    values = [white({"w": w}) + 0.5 * w @ w for w in ws]
    np.testing.assert_allclose(values, values[0], rtol=1e-9)
    # to_unconstrained is the same map: the pivot is f_b of its affine coordinate
    x = to_unconstrained(ws, x_hat, groups)
    from scioc.models.bayes.pivot_tails import tail_map
    np.testing.assert_allclose(x[:, blocks[:, 0]], tail_map(ws[:, blocks[:, 0]] * s, b), rtol=1e-13)
    # negative controls: the affine pivot (no tail map), and the map without its Jacobian, are not standard normals
    affine = whitened_model(logp, flat, x_hat, [(blocks, L, (0, a))]).compile_logp()
    assert np.ptp([affine({"w": w}) + 0.5 * w @ w for w in ws]) > 1.0
    no_jacobian = [white({"w": w}) + 0.5 * w @ w
                   - float(np.sum(np.log1p(0.5 * (w[blocks[:, 0]] * s / b) ** 2)
                                  - 1.25 * np.log1p((w[blocks[:, 0]] * s / b) ** 2))) for w in ws]
    assert np.ptp(no_jacobian) > 1.0


def test_ridge_curvature_refuses_a_pivot_outside_the_block_and_block_column_a_shared_variable():
    model = _model(4)
    point, raveled, dims = _flat(model)
    blocks = subject_blocks(raveled.point_map_info, dims, 4)
    assert block_column(raveled.point_map_info, dims, 4, "b_log__") == 2
    with pytest.raises(ValueError, match="exactly one coordinate per subject"):
        block_column(raveled.point_map_info, dims, 4, "a")
    with pytest.raises(ValueError, match="exactly one coordinate per subject"):
        block_column(raveled.point_map_info, dims, 4, "mu")
    with pytest.raises(ValueError, match="not a value variable"):
        block_column(raveled.point_map_info, dims, 4, "b")
    with pytest.raises(ValueError, match="pivot 3 is not one of a block's 3 coordinates"):
        ridge_curvature(lambda x: -x, np.zeros(14), blocks, np.broadcast_to(np.eye(3), (4, 3, 3)), 3)
    # a subject whose differences are not finite gets no curvature (the affine map), and is counted
    def grad(x):
        g = -x.copy()
        if abs(x[blocks[1, 2]]) > 0:
            g[blocks[1]] = np.nan
        return g
    a, record = ridge_curvature(grad, np.zeros(14), blocks, np.broadcast_to(np.eye(3), (4, 3, 3)), 2)
    np.testing.assert_array_equal(a[1], 0.0)
    assert record["subjects_without_curvature"] == 1


def test_ridge_curvature_halves_the_span_where_the_ridge_has_no_maximum():
    # log p = -v²/2 - ½ (1 - v²/0.64) (y - 0.5 v - 3 v²)² / 0.01: the ridge y = 0.5 v + 3 v² has a maximum over y only
    # where |v| < 0.8. The pivot's scale at the mode is 1, so ±1 finds none, ±0.5 the exact curvature 3.
    def grad(x):
        v, y = x
        r, prec = y - 0.5 * v - 3.0 * v**2, (1.0 - v**2 / 0.64) / 0.01
        dv = -v + (v / 0.64) * r**2 / 0.01 + prec * r * (0.5 + 6.0 * v)
        return np.array([dv, -prec * r])

    blocks = np.array([[0, 1]])
    H = block_hessian(grad, np.zeros(2), blocks, 1e-5)
    L, _ = whitening_factors(H)
    a, record = ridge_curvature(grad, np.zeros(2), blocks, L, 0)
    np.testing.assert_allclose(a[0], [0.0, 3.0], rtol=1e-6)
    assert record["subjects_without_curvature"] == 0
    np.testing.assert_allclose(record["pivot_scale_range"], [0.5, 0.5], rtol=1e-4)
    # with no halving allowed, the ridge's maximum at ±1 is not found, and the subject keeps the affine map
    a, record = ridge_curvature(grad, np.zeros(2), blocks, L, 0, halvings=0)
    np.testing.assert_array_equal(a, 0.0)
    assert record["subjects_without_curvature"] == 1


def test_nearest_fold_picks_the_signed_coordinate_nearest_its_zero_in_its_own_scale():
    # 3 subjects, block (p, q, r), pivots p and q, scales from L (diagonal 0.5, 2, 1). Subject 0: |p|/0.5 = 0.2 against
    # |q|/2 = 1, p; subject 1: 3 against 0.1, q; subject 2: 1 against 1, a tie, the first pivot given.
    blocks = np.arange(9).reshape(3, 3)
    L = np.broadcast_to(np.diag([0.5, 2.0, 1.0]), (3, 3, 3))
    x = np.array([0.1, 2.0, 9.0, 1.5, 0.2, 9.0, 0.5, 2.0, 0.0])
    both = np.ones((3, 2), dtype=bool)
    np.testing.assert_array_equal(nearest_fold(x, blocks, L, [0, 1], both), [0, 1, 0])
    np.testing.assert_array_equal(nearest_fold(x, blocks, L, [1, 0], both), [1, 0, 0])  # indices into the pivots
    np.testing.assert_array_equal(nearest_fold(-x, blocks, L, [0, 1], both), [0, 1, 0])  # a fold: the sign is no matter
    # the scales decide: with p's scale 0.1, subject 2's p is 5 scales from its fold and q 1, so q
    L2 = np.broadcast_to(np.diag([0.1, 2.0, 1.0]), (3, 3, 3))
    np.testing.assert_array_equal(nearest_fold(x, blocks, L2, [0, 1], both), [0, 1, 1])
    # only signed coordinates compete: p not signed in subject 0 gives it q; where neither is signed, the last pivot
    signed = np.array([[False, True], [True, False], [False, False]])
    np.testing.assert_array_equal(nearest_fold(x, blocks, L, [0, 1], signed), [1, 0, 1])
    np.testing.assert_array_equal(nearest_fold(x, blocks, L, [0, 1], [False, False]), [1, 1, 1])
    with pytest.raises(ValueError, match="must be columns of a block's 3 coordinates"):
        nearest_fold(x, blocks, L, [0, 3], both)
