"""The hierarchical model of recorded angles: its likelihood is the windows' angle likelihood at the model's θ, τ_nm
and σ_m (the max-ent human's with motor=False), its gradient compiles without object mode, and it draws angles."""

import numpy as np
import pymc as pm
import pytest

from scioc.models.bayes.angle_model import OBSERVED, build_angle_model
from scioc.models.delayed.angles import window_loglik
from scioc.models.units import index_study
from tests.models.bayes.test_angle_op import SIGMA_Y, windows

SUBJECTS = ["a", "a", "b", "b", "c", "c"]
CONDITIONS = ["MC", "SC"] * 3
DELAY = np.array([0, 1, 5, 12, 30, 7])


@pytest.fixture(scope="module")
def recorded(plant):
    return windows(plant, np.random.default_rng(53), 6)


def point_values(model, point, names):
    outs = model.replace_rvs_by_values([model[n] for n in names])
    fn = model.compile_fn(outs, inputs=model.value_vars, on_unused_input="ignore")
    return [np.array(v, copy=True) for v in fn(point)]


@pytest.mark.parametrize("motor", [True, False])
def test_the_models_likelihood_is_the_windows_angle_likelihood(plant, recorded, motor):
    model = build_angle_model(SUBJECTS, CONDITIONS, recorded, plant, delay=DELAY, sigma_y=SIGMA_Y, motor=motor)
    rng = np.random.default_rng(1)
    point = {k: v + rng.normal(0.0, 0.3, np.shape(v)) for k, v in model.initial_point().items()}
    ll = model.compile_logp(vars=[model[OBSERVED]], sum=False)(point)[0]
    names = ["theta1", "R", "theta2"] + (["tau_nm", "sigma_m"] if motor else [])
    vals = point_values(model, point, names)
    index = index_study(SUBJECTS, CONDITIONS, ("MC", "SC"))
    for i, w in enumerate(recorded):
        s, c = index.subject_idx[i], index.condition_idx[i]
        th1, R, th2 = vals[0][s, c], vals[1][s, c], vals[2][s, c]
        tau, sig, d = (vals[3][s], vals[4][s], int(DELAY[i])) if motor else (0.0, 0.0, 0)
        ref = window_loglik([th1 * R, th2 * R, R], tau, sig, d, w, plant, sigma_y=SIGMA_Y).loglik
        assert ll[i] == pytest.approx(ref, rel=1e-10)
    if not motor:
        assert "tau_nm" not in model.named_vars and "sigma_m" not in model.named_vars


def test_the_gradient_compiles_to_numba_and_matches_differences(plant, recorded):
    model = build_angle_model(SUBJECTS, CONDITIONS, recorded, plant, delay=DELAY, sigma_y=SIGMA_Y)
    point = model.initial_point()
    logp = model.compile_logp(mode="NUMBA")
    dlogp = model.compile_dlogp(mode="NUMBA")
    g = dlogp(point)
    assert np.all(np.isfinite(g))
    # one coordinate by central differences: the first subject's log R (non-centred z), a cost parameter
    name = next(k for k in point if k.startswith("z_log_R"))
    offset = sum(np.size(point[k]) for k in list(point)[: list(point).index(name)])
    h = 1e-5
    up, down = dict(point), dict(point)
    up[name] = point[name].copy()
    down[name] = point[name].copy()
    up[name].flat[0] += h
    down[name].flat[0] -= h
    assert g[offset] == pytest.approx((logp(up) - logp(down)) / (2 * h), rel=1e-5)


def test_it_draws_angles_of_each_windows_length(plant, recorded):
    model = build_angle_model(SUBJECTS, CONDITIONS, recorded, plant, delay=DELAY, sigma_y=SIGMA_Y)
    with model:
        draws = pm.draw(model[OBSERVED], draws=2, random_seed=3)
    assert draws.shape == (2, 6, max(len(w.angles) for w in recorded))
    for i, w in enumerate(recorded):
        K = len(w.angles)
        assert np.all(np.isfinite(draws[:, i, :K])) and np.all(draws[:, i, K:] == 0.0)
        # each draw starts at its window's recorded angle, read by the encoder
        assert np.all(np.abs(draws[:, i, 0] - w.angles[0]) < 6 * SIGMA_Y)


def test_the_leave_one_subject_out_terms_score_each_window_by_its_angles(plant, recorded):
    """The delayed and max-ent terms of the integrated importance sampling: each window's angle likelihood at every
    point, the max-ent's with no delay, lag or motor noise."""
    from scioc.models.bayes.angle_op import AngleLoglikOp
    from scioc.models.bayes.delayed_loo import AngleSubjectTerms, MaxentAngleTerms

    rng = np.random.default_rng(4)
    M = 5
    lt1, lR, t2 = rng.normal(3.0, 0.5, M), rng.normal(2.5, 0.5, M), rng.uniform(0.0, 1.0, M)
    z = np.column_stack([np.log(rng.uniform(0.01, 0.2, M)), np.log(rng.uniform(0.05, 0.4, M))])
    post = {"tau_nm": np.full((3, 3), 0.05), "sigma_m": np.full((3, 3), 0.2), "tau_nm_scale": np.full(3, 0.1),
            "sigma_m_scale": np.full(3, 0.3)}
    delayed = AngleSubjectTerms(post, AngleLoglikOp(recorded, plant, delay=DELAY, sigma_y=SIGMA_Y))
    maxent = MaxentAngleTerms(AngleLoglikOp(recorded, plant, delay=0, sigma_y=SIGMA_Y))
    assert maxent.columns(0) == [] and maxent.log_prior(z) == 0.0
    for j in (0, 3, 5):
        got_d = delayed.segment_loglik(j, lt1, lR, t2, z)
        got_m = maxent.segment_loglik(j, lt1, lR, t2, z[:, :0])
        for m in range(M):
            R = np.exp(lR[m])
            theta = [np.exp(lt1[m]) * R, t2[m] * R, R]
            ref_d = window_loglik(theta, np.exp(z[m, 0]), np.exp(z[m, 1]), int(DELAY[j]), recorded[j], plant,
                                  sigma_y=SIGMA_Y).loglik
            ref_m = window_loglik(theta, 0.0, 0.0, 0, recorded[j], plant, sigma_y=SIGMA_Y).loglik
            assert got_d[m] == pytest.approx(ref_d, rel=1e-10)
            assert got_m[m] == pytest.approx(ref_m, rel=1e-10)
