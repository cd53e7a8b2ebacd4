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
