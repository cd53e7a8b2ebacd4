"""Sampling in whitened coordinates (pipelines/fit/whiten.py) gives the model's posterior, in the model's variables.

The check: a linear Gaussian hierarchical model whose posterior is known exactly, with each subject's two values
correlated at -0.991 (the geometry the whitening is for). Its 12 means and 6 within-subject correlations must match
the exact ones within 5 Monte Carlo SEs (the means, ESS estimated) and 0.02 (the correlations). False alarms: a
5-SE error of one of 12 means, about 12 × 5.7e-7 (two-sided normal tail); 0.02 is about 16 SEs of a correlation
near -0.991 at an ESS of 200 (SE ≈ (1 - ρ²) / sqrt(ESS) = 0.0012), so negligible. The negative control maps the
same draws back without the subjects' factors L; the check must fail on it.
"""

import numpy as np
import pymc as pm
import pytest

from scioc.models.bayes.whiten import WHITE, to_unconstrained
from scioc.pipelines.fit.whiten import nutpie_setting, posterior_of, sample_whitened, whitening

N = 6
Y = np.linspace(-1.0, 2.0, N)
NOISE = 0.1


def _model():
    """mu ~ N(0, 1); a_i ~ N(mu, 1); b_i ~ N(0, 1); y_i ~ N(a_i + b_i, NOISE): a and b are tied by y."""
    with pm.Model(coords={"subject": [f"s{i}" for i in range(N)]}) as model:
        mu = pm.Normal("mu", 0.0, 1.0)
        a = pm.Normal("a", mu, 1.0, dims="subject")
        b = pm.Normal("b", 0.0, 1.0, dims="subject")
        pm.Deterministic("total", a + b, dims="subject")
        pm.Normal("y", a + b, NOISE, observed=Y, dims="subject")
    return model


def _exact():
    """Posterior mean and covariance of (mu, a_1..a_N, b_1..b_N): a Gaussian, from its precision."""
    d = 1 + 2 * N
    P = np.zeros((d, d))
    h = np.zeros(d)
    P[0, 0] = 1.0
    for i in range(N):
        a, b = 1 + i, 1 + N + i
        P[0, 0] += 1.0
        P[a, a] += 1.0
        P[0, a] -= 1.0
        P[a, 0] -= 1.0
        P[b, b] += 1.0
        for u in (a, b):
            for v in (a, b):
                P[u, v] += 1.0 / NOISE**2
            h[u] += Y[i] / NOISE**2
    cov = np.linalg.inv(P)
    return cov @ h, cov


def _check(post) -> list:
    """The failures of the module docstring's check (empty: passes)."""
    import arviz as az

    mean, cov = _exact()
    failures = []
    for name, offset in (("a", 1), ("b", 1 + N)):
        draws = post[name].values.reshape(-1, N)
        ess = az.ess(post[name].values)
        for i in range(N):
            se = np.sqrt(cov[offset + i, offset + i] / float(np.asarray(ess)[i]))
            if abs(draws[:, i].mean() - mean[offset + i]) > 5 * se:
                failures.append(f"mean of {name}[{i}]")
    a, b = post["a"].values.reshape(-1, N), post["b"].values.reshape(-1, N)
    for i in range(N):
        exact = cov[1 + i, 1 + N + i] / np.sqrt(cov[1 + i, 1 + i] * cov[1 + N + i, 1 + N + i])
        if abs(np.corrcoef(a[:, i], b[:, i])[0, 1] - exact) > 0.02:
            failures.append(f"correlation of a[{i}], b[{i}]")
    return failures


@pytest.fixture(scope="module")
def whitened_run():
    model = _model()
    idata, sec, record = sample_whitened(model, None, seed=3, chains=2, draws=1000, tune=500, cores=1,
                                         nuts={"adaptation": "diag"})
    return model, idata, sec, record


@pytest.mark.validation
def test_the_whitened_draws_are_the_models_posterior(whitened_run):
    model, idata, sec, record = whitened_run
    post = idata["posterior"]
    assert set(post.data_vars) == {"mu", "a", "b", "total"} and post["a"].dims == ("chain", "draw", "subject")
    assert list(post["a"].coords["subject"].values) == [f"s{i}" for i in range(N)]
    np.testing.assert_allclose(post["total"].values, post["a"].values + post["b"].values, rtol=1e-12)
    assert _check(post) == []
    assert idata["log_likelihood"]["y"].shape == (2, 1000, N)
    assert record["coordinates_per_subject"] == 2 and record["subjects_not_at_a_maximum"] == 0
    assert record["mode_used"] and sec["whitening"] > 0
    # mu, the one coordinate outside the blocks, on its own scale: its prior and the N subjects' give curvature 1 + N
    assert record["other_coordinates"] == 1
    np.testing.assert_allclose(record["other_scale_range"], [(1 + N) ** -0.5] * 2, rtol=1e-6)
    # the exact posterior's within-subject correlation is what the whitening removes
    mean, cov = _exact()
    assert cov[1, 1 + N] / np.sqrt(cov[1, 1] * cov[1 + N, 1 + N]) < -0.95


def test_the_check_fails_when_the_draws_are_mapped_back_without_the_subjects_factors(whitened_run):
    # negative control: the same w draws, with L replaced by the identity (what sampling in w without mapping
    # the whitening back would report)
    model, idata, _, _ = whitened_run
    _, _, x_hat, groups, info, _, _ = whitening(model, None)
    (blocks, L), (others, S) = groups
    w = _w_draws(idata, x_hat, blocks, L, others, S)
    np.testing.assert_allclose(posterior_of(model, to_unconstrained(w, x_hat, groups), info)["a"].values,
                               idata["posterior"]["a"].values, rtol=1e-10, atol=1e-12)  # the recovery is right
    wrong = to_unconstrained(w, x_hat, [(blocks, np.broadcast_to(np.eye(2), L.shape)), (others, S)])
    assert _check(posterior_of(model, wrong, info)) != []


def _w_draws(idata, x_hat, blocks, L, others, S):
    """The sampler's w draws, recovered from the posterior's unconstrained values (x = x̂ + L w per subject,
    x̂ + s w for the others)."""
    post = idata["posterior"]
    x = np.concatenate([post["mu"].values[..., None], post["a"].values, post["b"].values], axis=-1)
    w = x - x_hat  # the model's value order: mu, a, b
    w[..., blocks] = np.einsum("ijk,...ik->...ij", np.linalg.inv(L), w[..., blocks])
    w[..., others[:, 0]] /= S[:, 0, 0]
    return w


def test_same_seed_same_draws(whitened_run):
    model, idata, _, _ = whitened_run
    again, _, _ = sample_whitened(_model(), None, seed=3, chains=2, draws=1000, tune=500, cores=1,
                                  nuts={"adaptation": "diag"})
    for v in ("mu", "a", "b"):
        np.testing.assert_array_equal(again["posterior"][v].values, idata["posterior"][v].values)
    assert WHITE not in idata["posterior"]


BETA, CURVE, SCALE, NOISE_Y = 0.7, np.array([4.0, -6.0]), np.array([0.5, 0.3]), 0.05


def _banana():
    """Per subject v ~ N(0, SCALE_i), y ~ N(BETA v + CURVE_i v², NOISE_Y): a curved ridge through the mode."""
    with pm.Model(coords={"subject": ["s0", "s1"]}) as model:
        v = pm.Normal("v", 0.0, SCALE, dims="subject")
        pm.Normal("y", BETA * v + CURVE * v**2, NOISE_Y, dims="subject")
    return model


def _banana_failures(post) -> list:
    """Means of v and y against the exact ones (0 and CURVE SCALE²) within 5 Monte Carlo SEs (ESS estimated; a
    false alarm of one of 4 means about 4 × 5.7e-7), and y's SD against the exact sqrt(BETA² s² + 2 c² s⁴ + t²)
    within 10 %."""
    import arviz as az

    failures = []
    sd = {"v": SCALE, "y": np.sqrt(BETA**2 * SCALE**2 + 2 * CURVE**2 * SCALE**4 + NOISE_Y**2)}
    mean = {"v": np.zeros(2), "y": CURVE * SCALE**2}
    for name in ("v", "y"):
        ess = np.asarray(az.ess(post[name].values))
        draws = post[name].values.reshape(-1, 2)
        for i in range(2):
            if abs(draws[:, i].mean() - mean[name][i]) > 5 * sd[name][i] / np.sqrt(ess[i]):
                failures.append(f"mean of {name}[{i}]")
        if name == "y" and np.any(np.abs(draws.std(axis=0) / sd["y"] - 1) > 0.1):
            failures.append("sd of y")
    return failures


def test_the_curved_map_samples_a_banana_exactly_and_its_negative_control_fails():
    # pivot v: each subject's ridge y = BETA v + CURVE v² is straightened (models/bayes/test_whiten.py: exactly), so
    # the draws mapped back are the banana's; mapped back without the curvature they are not
    model = _banana()
    idata, _, record = sample_whitened(model, None, seed=4, chains=2, draws=1000, tune=500, cores=1,
                                       nuts={"adaptation": "diag"}, pivots=[("v", np.ones(2, bool))])
    assert record["curved_along"] == {"v": 2} and record["subjects_without_curvature"] == 0
    assert _banana_failures(idata["posterior"]) == []
    _, _, x_hat, groups, info, _, _ = whitening(_banana(), None, [("v", np.ones(2, bool))])
    [(blocks, L, (pivot, a))] = groups
    np.testing.assert_allclose(a[:, 1], CURVE, rtol=1e-4)
    post = idata["posterior"]
    x = np.concatenate([post["v"].values, post["y"].values], axis=-1)  # value order v (2), y (2)
    np.testing.assert_array_equal(blocks, [[0, 2], [1, 3]])
    dx = x[..., blocks] - x_hat[blocks]
    w = np.einsum("ijk,...ik->...ij", np.linalg.inv(L), dx - a * dx[..., pivot:pivot + 1] ** 2)
    flat_w = np.zeros_like(x)
    flat_w[..., blocks] = w
    np.testing.assert_allclose(to_unconstrained(flat_w, x_hat, groups), x, rtol=1e-9, atol=1e-12)
    assert _banana_failures(posterior_of(model, to_unconstrained(flat_w, x_hat, [(blocks, L)]), info)) != []


#: Both coordinates signed in both subjects.
PIVOTS = [("u", np.ones(2, bool)), ("v", np.ones(2, bool))]


def _crossed_bananas():
    """Two signed coordinates u, v per subject; subject 0's ridge y = BETA v + CURVE_0 v² is curved along v (u ~
    N(2.5, SCALE_0) apart, its mode far from u's fold), subject 1's y = BETA u + CURVE_1 u² along u (v apart)."""
    with pm.Model(coords={"subject": ["s0", "s1"]}) as model:
        u = pm.Normal("u", np.array([2.5, 0.0]), SCALE, dims="subject")
        v = pm.Normal("v", np.array([0.0, 2.5]), SCALE, dims="subject")
        t = pm.math.stack([v[0], u[1]])
        pm.Normal("y", BETA * t + CURVE * t**2, NOISE_Y, dims="subject")
    return model


@pytest.mark.validation
def test_with_two_pivots_each_subject_bends_along_the_one_whose_fold_its_mode_is_nearest():
    # pivots ("u", "v"): subject 0's mode is at v = 0, 2.5 scales of u from u's fold, so it bends along v; subject 1
    # along u; one group per pivot, each with its own ridge's curvature, and the draws are the exact posterior's
    # (y's mean CURVE SCALE² and SD as in _banana_failures, with the pivot in place of v)
    model = _crossed_bananas()
    idata, _, record = sample_whitened(model, None, seed=4, chains=2, draws=1000, tune=500, cores=1,
                                       nuts={"adaptation": "diag"}, pivots=PIVOTS)
    assert record["curved_along"] == {"u": 1, "v": 1} and record["pivot_by_subject"] == ["v", "u"]
    assert set(record["ridge"]) == {"u", "v"} and record["subjects_without_curvature"] == 0
    _, _, x_hat, groups, _, _, folds = whitening(_crossed_bananas(), None, PIVOTS)
    assert [f.tolist() for f in folds] == [[True], [True]]  # each group's one subject: its pivot is signed
    [(rows_u, _, (col_u, a_u)), (rows_v, _, (col_v, a_v))] = groups  # value order u (2), v (2), y (2)
    np.testing.assert_array_equal(rows_u, [[1, 3, 5]])
    np.testing.assert_array_equal(rows_v, [[0, 2, 4]])
    assert (col_u, col_v) == (0, 1)
    np.testing.assert_allclose([a_u[0, 2], a_v[0, 2]], [CURVE[1], CURVE[0]], rtol=1e-4)
    np.testing.assert_allclose([a_u[0, 1], a_v[0, 0]], 0.0, atol=1e-6)  # the other signed coordinate is apart
    post = idata["posterior"]

    def as_banana(u, v, y):
        return {"v": post["v"].copy(data=np.stack([v[..., 0], u[..., 1]], -1)), "y": post["y"].copy(data=y)}

    assert _banana_failures(as_banana(post["u"].values, post["v"].values, post["y"].values)) == []
    # negative control: the same w draws mapped back with each group bent by the other group's curvature
    x = np.concatenate([post["u"].values, post["v"].values, post["y"].values], axis=-1)
    w = np.zeros_like(x)
    for rows, L, (col, a) in groups:
        dx = x[..., rows] - x_hat[rows]
        w[..., rows] = np.einsum("ijk,...ik->...ij", np.linalg.inv(L), dx - a * dx[..., col:col + 1] ** 2)
    (_, L_u, _), (_, L_v, _) = groups
    swapped = to_unconstrained(w, x_hat, [(rows_u, L_u, (col_u, a_v)), (rows_v, L_v, (col_v, a_u))])
    assert _banana_failures(as_banana(swapped[..., :2], swapped[..., 2:4], swapped[..., 4:])) != []


def _symmetric_banana():
    """Per subject v ~ N(0, SCALE_i), y ~ N(CURVE_i v², NOISE_Y): the banana with its law symmetric in v, so that v
    may be a signed pivot (models/bayes/whiten_draws.py reflects its draws about 0)."""
    with pm.Model(coords={"subject": ["s0", "s1"]}) as model:
        v = pm.Normal("v", 0.0, SCALE, dims="subject")
        pm.Normal("y", CURVE * v**2, NOISE_Y, dims="subject")
    return model


def _symmetric_failures(v, y, ess_v, ess_y) -> list:
    """v's and y's means (exact 0 and CURVE SCALE²) and v's SD (SCALE) within 5 Monte Carlo SEs (the SD's SE
    SCALE / sqrt(2 ESS), v being normal); a false alarm of one of the 6 about 6 × 5.7e-7."""
    failures = []
    sd_y = np.sqrt(2 * CURVE**2 * SCALE**4 + NOISE_Y**2)
    for i in range(2):
        if abs(v[:, i].mean()) > 5 * SCALE[i] / np.sqrt(ess_v[i]):
            failures.append(f"mean of v[{i}]")
        if abs(y[:, i].mean() - CURVE[i] * SCALE[i] ** 2) > 5 * sd_y[i] / np.sqrt(ess_y[i]):
            failures.append(f"mean of y[{i}]")
        if abs(v[:, i].std() - SCALE[i]) > 5 * SCALE[i] / np.sqrt(2 * ess_v[i]):
            failures.append(f"sd of v[{i}]")
    return failures


def test_the_symmetric_banana_check_passes_exact_draws_and_fails_wrong_ones():
    rng = np.random.default_rng(5)
    v = rng.normal(0.0, SCALE, (4000, 2))
    y = CURVE * v**2 + rng.normal(0.0, NOISE_Y, (4000, 2))
    ess = np.full(2, 4000.0)
    assert _symmetric_failures(v, y, ess, ess) == []
    assert _symmetric_failures(v, 1.2 * CURVE * v**2, ess, ess) != []  # the curvature 20 % off
    assert _symmetric_failures(1.1 * v, y, ess, ess) != []  # v's scale 10 % off


@pytest.mark.validation
def test_pilot_runs_change_the_coordinates_not_the_posterior():
    # sampled again after two pilot runs, each measuring the whitening on its draws (models/bayes/whiten_draws.py,
    # with v signed: reflected about 0), the symmetric banana's draws are still its exact posterior's; and the
    # banana with a linear ridge too, whose v is not signed (its draws not reflected)
    import arviz as az

    idata, sec, record = sample_whitened(_symmetric_banana(), None, seed=4, chains=2, draws=1000, tune=500, cores=1,
                                         nuts={"adaptation": "diag"}, pivots=[("v", np.ones(2, bool))],
                                         pilot=[(50, 50), (50, 100)])
    post = idata["posterior"]
    v, y = post["v"].values, post["y"].values
    assert _symmetric_failures(v.reshape(-1, 2), y.reshape(-1, 2), np.asarray(az.ess(v)), np.asarray(az.ess(y))) == []
    runs = record["pilot"]
    assert [(r["tune"], r["draws"], r["blocks_kept_from_before"]) for r in runs] == [(50, 50, 0), (50, 100, 0)]
    assert all(r["leapfrog_steps"] > 0 for r in runs) and 0 < sum(r["sample_s"] for r in runs) <= sec["sample"]
    assert "2 pilot run(s)" in record["method"]
    idata, _, _ = sample_whitened(_banana(), None, seed=4, chains=2, draws=1000, tune=500, cores=1,
                                  nuts={"adaptation": "diag"}, pivots=[("v", np.zeros(2, bool))],
                                  pilot=[(50, 50), (50, 100)])
    assert _banana_failures(idata["posterior"]) == []
    with pytest.raises(ValueError, match="pilot needs"):
        sample_whitened(_banana(), None, seed=4, chains=2, draws=10, tune=10, cores=1, pilot=[(10, 1)])
    for bad in [(10, 10, 0), (10, 10, 1, 1.0), (10, 10, 1, 0.8, 0), (10, 10, 1, 0.8, 2.5), (10, 10, 1, 0.8, 3, 1),
                (10,)]:
        with pytest.raises(ValueError, match="pilot needs"):
            sample_whitened(_banana(), None, seed=4, chains=2, draws=10, tune=10, cores=1, pilot=[bad])


@pytest.mark.validation
def test_a_pilot_runs_on_its_own_chains_target_acceptance_and_tree_depth():
    # (tune, draws, chains, target_accept, max_tree_depth): what nutpie itself recorded for the pilot, not what was
    # asked; the kept run keeps the fit's own
    idata, _, record = sample_whitened(_banana(), None, seed=4, chains=2, draws=20, tune=20, cores=1,
                                       nuts={"adaptation": "diag", "target_accept": 0.9},
                                       pivots=[("v", np.zeros(2, bool))], pilot=[(20, 20, 1, 0.7, 3), (20, 20)])
    first, second = record["pilot"]
    assert (first["chains"], first["target_accept"], first["max_tree_depth"]) == (1, 0.7, 3)
    assert (second["chains"], second["target_accept"]) == (2, 0.9)  # None: the fit's own
    assert second["max_tree_depth"] == nutpie_setting(idata["sample_stats"].attrs, "maxdepth") > 3
