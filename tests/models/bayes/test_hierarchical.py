"""The hierarchical model: its log density by hand, its design checks, numba compilation, a fit."""

import warnings

import arviz as az
import numpy as np
import pymc as pm
import pytensor
import pytest
from scipy import stats

from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS, Parameterization, Priors, build_model
from scioc.models.bayes.op import MaxEntLoglikOp
from scioc.models.design import CONDITIONS
from scioc.models.maxent import loglik_grad
from scioc.models.segment import prepare_batch
from scioc.models.units import index_study
from tests.conftest import random_segment
from tests.models.bayes.test_op import preview_segment

FORMS = [
    Parameterization(),
    Parameterization("centred", "centred", "centred", "centred", "centred"),
    Parameterization("noncentred", "noncentred", "noncentred", "noncentred", "noncentred"),
    Parameterization("mean", "centred", "mean", "noncentred", "noncentred"),
    Parameterization(theta2="quantile"),
]


def small_study(plant, K=60, n_subjects=3, seed=30, M=0):
    """Subjects S0.. in MC and SC; subject S0 has a second MC segment (two segments, one unit).

    M > 0 gives every segment a plan M steps past its K observed torques.
    """
    rng = np.random.default_rng(seed)
    subjects, conditions, segs = [], [], []
    for i in range(n_subjects):
        for c in CONDITIONS:
            subjects.append(f"S{i}")
            conditions.append(c)
            segs.append(preview_segment(rng, K, M, c == "SC"))
    subjects.append("S0")
    conditions.append("MC")
    segs.append(preview_segment(rng, K, M, False))
    return subjects, conditions, segs


def _raw_point(rng, n_subj, form: Parameterization):
    """Values of every free variable (untransformed), keyed by name."""
    v = {
        "mu_log_theta1": np.log(40.0) + 0.3 * rng.standard_normal(),
        "beta": -0.5 + 0.1 * rng.standard_normal(),
        "sigma_log_theta1": rng.uniform(0.2, 0.6),
        "sigma_beta": rng.uniform(0.1, 0.4),
        "mu_log_R": 0.2 * rng.standard_normal(),
        "beta_log_R": 0.1 * rng.standard_normal(),
        "sigma_log_R": rng.uniform(0.1, 0.5),
        "sigma_beta_log_R": rng.uniform(0.05, 0.3),
        "tau_theta2": rng.uniform(0.05, 0.5),
    }
    for name, f_mc, f_sc, centre in (
        ("log_theta1", form.theta1_mc, form.theta1_sc, np.log(40.0)),
        ("log_R", form.R_mc, form.R_sc, 0.0),
    ):
        if f_sc == "noncentred":
            v[f"z_{name}_SC"] = rng.standard_normal(n_subj)
        elif f_mc == "mean":
            v[f"{name}_change"] = -0.3 + 0.2 * rng.standard_normal(n_subj)
        else:
            v[f"{name}_SC"] = centre - 0.3 + 0.4 * rng.standard_normal(n_subj)
        if f_mc == "noncentred":
            v[f"z_{name}_MC"] = rng.standard_normal(n_subj)
        else:
            v[f"{name}_MC" if f_mc == "centred" else f"{name}_mean"] = centre + 0.4 * rng.standard_normal(n_subj)
    if form.theta2 == "quantile":
        v["n_theta2"] = rng.standard_normal((n_subj, 2))
    else:
        v["theta2" if form.theta2 == "centred" else "z_theta2"] = np.abs(0.2 * rng.standard_normal((n_subj, 2)))
    return v


def _by_hand(v, priors: Priors, form: Parameterization, index, batch, plant):
    """Σ prior log densities (scipy.stats) + Σ segment log-likelihoods (models.maxent), no Jacobians."""
    N, HN = stats.norm.logpdf, stats.halfnorm.logpdf
    lp = N(v["mu_log_theta1"], *priors.mu_log_theta1) + N(v["beta"], 0, priors.beta_sd)
    lp += HN(v["sigma_log_theta1"], scale=priors.sigma_log_theta1) + HN(v["sigma_beta"], scale=priors.sigma_beta)
    lp += N(v["mu_log_R"], *priors.mu_log_R) + N(v["beta_log_R"], 0, priors.beta_log_R_sd)
    lp += HN(v["sigma_log_R"], scale=priors.sigma_log_R) + HN(v["sigma_beta_log_R"], scale=priors.sigma_beta_log_R)
    lp += HN(v["tau_theta2"], scale=priors.tau_theta2)
    units = {}
    for name, f_mc, f_sc, mu, beta, s, sb in (
        ("log_theta1", form.theta1_mc, form.theta1_sc, "mu_log_theta1", "beta", "sigma_log_theta1", "sigma_beta"),
        ("log_R", form.R_mc, form.R_sc, "mu_log_R", "beta_log_R", "sigma_log_R", "sigma_beta_log_R"),
    ):
        if f_mc == "mean":
            # The change first, then the subject mean given it (the model's order).
            if f_sc == "centred":
                d = v[f"{name}_change"]
                lp += N(d, v[beta], v[sb]).sum()
            else:
                z = v[f"z_{name}_SC"]
                lp += N(z).sum()
                d = v[beta] + v[sb] * z
            m = v[f"{name}_mean"]
            lp += N(m, v[mu] + d / 2, v[s]).sum()
            mc, sc = m - d / 2, m + d / 2
            units[name] = np.column_stack([mc, sc])
            continue
        if f_mc == "centred":
            mc = v[f"{name}_MC"]
            lp += N(mc, v[mu], v[s]).sum()
        else:
            z = v[f"z_{name}_MC"]
            lp += N(z).sum()
            mc = v[mu] + v[s] * z
        if f_sc == "centred":
            sc = v[f"{name}_SC"]
            lp += N(sc, mc + v[beta], v[sb]).sum()
        else:
            z = v[f"z_{name}_SC"]
            lp += N(z).sum()
            sc = mc + v[beta] + v[sb] * z
        units[name] = np.column_stack([mc, sc])
    if form.theta2 == "centred":
        theta2 = v["theta2"]
        lp += HN(theta2, scale=v["tau_theta2"]).sum()
    elif form.theta2 == "quantile":  # n ~ N(0, 1), θ2 = τ F⁻¹(Φ(n)), F the half-normal's
        lp += N(v["n_theta2"]).sum()
        theta2 = v["tau_theta2"] * stats.halfnorm.ppf(stats.norm.cdf(v["n_theta2"]))
    else:
        lp += HN(v["z_theta2"]).sum()
        theta2 = v["tau_theta2"] * v["z_theta2"]
    s, c = index.subject_idx, index.condition_idx
    R = np.exp(units["log_R"][s, c])
    theta = np.array([np.exp(units["log_theta1"][s, c]) * R, theta2[s, c] * R, R])
    return lp + loglik_grad(theta, batch, plant).loglik.sum()


@pytest.mark.parametrize(
    "form, M", [(f, 0) for f in FORMS] + [(FORMS[0], 90)],
    ids=["default", "centred", "noncentred", "mean", "quantile", "preview"]
)
def test_log_density_is_priors_plus_likelihood(plant, form, M):
    subjects, conditions, segs = small_study(plant, M=M)
    batch = prepare_batch(plant, segs)
    index = index_study(subjects, conditions)
    priors = Priors()
    model = build_model(subjects, conditions, batch, plant, priors=priors, parameterization=form)
    rng = np.random.default_rng(31)
    logp_nojac = model.compile_logp(jacobian=False)
    logp_jac = model.compile_logp(jacobian=True)
    for _ in range(3):
        v = _raw_point(rng, len(index.subjects), form)
        point, log_jac = {}, 0.0
        for rv in model.free_RVs:
            value_name = model.rvs_to_values[rv].name
            if model.rvs_to_transforms.get(rv) is not None:
                # Every positive variable here has the log transform.
                assert value_name == f"{rv.name}_log__"
                point[value_name] = np.log(v[rv.name])
                log_jac += np.sum(np.log(v[rv.name]))
            else:
                point[value_name] = np.asarray(v[rv.name], dtype=float)
        assert set(point) == set(model.initial_point())
        expected = _by_hand(v, priors, form, index, batch, plant)
        # PyTensor forms q11 = exp(log θ1 + log R) rather than θ1 R and sums the terms in its own
        # order (before 2026-12-04 also with fast-math, models.bayes): a few 1e-12 relative.
        assert logp_nojac(point) == pytest.approx(expected, rel=1e-10)
        assert logp_jac(point) == pytest.approx(expected + log_jac, rel=1e-10)


def test_model_gradient_matches_central_differences(plant):
    subjects, conditions, segs = small_study(plant)
    model = build_model(subjects, conditions, segs, plant)
    logp = model.compile_logp()
    dlogp = model.compile_dlogp()
    point = model.initial_point()
    g = dlogp(point)
    names = [model.rvs_to_values[rv].name for rv in model.free_RVs]
    flat = np.concatenate([np.ravel(point[n]) for n in names])
    sizes = [np.size(point[n]) for n in names]

    def at(x):
        out, i = {}, 0
        for n, sz in zip(names, sizes):
            out[n] = x[i : i + sz].reshape(np.shape(point[n]))
            i += sz
        return out

    h = 1e-6
    fd = np.array([(logp(at(flat + h * e)) - logp(at(flat - h * e))) / (2 * h) for e in np.eye(flat.size)])
    # O(h²) truncation and eps·|logp|/h rounding (|logp| ~ 1e3) are both below 1e-5 here.
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-5)


def test_numba_logp_and_gradient_have_one_kernel_node_and_no_object_mode(plant):
    import nutpie

    subjects, conditions, segs = small_study(plant)
    model = build_model(subjects, conditions, segs, plant)
    logp = model.logp()
    grads = pytensor.grad(logp, model.value_vars)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = pytensor.function(model.value_vars, [logp, *grads], mode="NUMBA")
        f(**{k: v for k, v in model.initial_point().items()})
        nutpie.compile_pymc_model(model, backend="numba")
    msgs = [str(w.message) for w in caught]
    assert not [m for m in msgs if "object mode" in m], msgs
    assert sum(isinstance(n.op, MaxEntLoglikOp) for n in f.maker.fgraph.apply_nodes) == 1


def test_pointwise_log_likelihood_per_segment(plant):
    subjects, conditions, segs = small_study(plant)
    batch = prepare_batch(plant, segs)
    index = index_study(subjects, conditions)
    model = build_model(subjects, conditions, batch, plant)
    names = [rv.name for rv in model.free_RVs]
    # One call, so that the unit parameters belong to the free-variable draws.
    out = pm.draw([*model.free_RVs, model["log_theta1"], model["log_R"], model["theta2"]], draws=3, random_seed=32)
    draws, det = out[: len(names)], out[len(names) :]
    dims = {name: list(model.named_vars_to_dims.get(name, ())) for name in names}
    idata = az.from_dict(
        {"posterior": {n: d[None] for n, d in zip(names, draws)}},
        dims=dims,
        coords={k: list(v) for k, v in model.coords.items()},
    )
    pm.compute_log_likelihood(idata, model=model, progressbar=False)
    ll = idata["log_likelihood"]["u_H"]
    assert ll.dims == ("chain", "draw", "segment")
    s, c = index.subject_idx, index.condition_idx
    for d in range(3):
        lt1, lR, t2 = det[0][d], det[1][d], det[2][d]
        R = np.exp(lR[s, c])
        theta = np.array([np.exp(lt1[s, c]) * R, t2[s, c] * R, R])
        np.testing.assert_allclose(ll.values[0, d], loglik_grad(theta, batch, plant).loglik, rtol=1e-10)


def test_design_errors_are_named(plant):
    rng = np.random.default_rng(33)
    segs = [random_segment(rng, 20, False) for _ in range(4)]
    with pytest.raises(ValueError, match=r"subject 'b' has no SC segment"):
        build_model(["a", "a", "b", "b"], ["MC", "SC", "MC", "MC"], segs, plant)
    with pytest.raises(ValueError, match=r"no SC segments at all"):
        build_model(["a", "b", "c", "d"], ["MC"] * 4, segs, plant)
    with pytest.raises(ValueError, match=r"segment 2 must be one of 'MC', 'SC'"):
        build_model(["a", "a", "b", "b"], ["MC", "SC", "mc", "SC"], segs, plant)
    with pytest.raises(ValueError, match=r"got 4 segments but 2"):
        build_model(["a", "a"], ["MC", "SC"], segs, plant)
    with pytest.raises(ValueError, match="centred"):
        Parameterization(theta2="partial")
    with pytest.raises(ValueError, match="theta1_sc"):
        Parameterization(theta1_sc="mean")


def test_observed_draws_have_the_data_shape(plant):
    subjects, conditions, segs = small_study(plant, K=40, M=25)
    model = build_model(subjects, conditions, segs, plant)
    with warnings.catch_warnings():
        # Drawing u_H runs sample_maxent in Python (object mode under numba); only the
        # log density has to be compiled.
        warnings.simplefilter("ignore")
        u = pm.draw(model["u_H"], random_seed=34)
    assert u.shape == (len(segs), 40)
    assert np.isfinite(u).all()


#: Units whose true log R must lie in their own 94 % HDI: with calibrated intervals, 16
#: units and independent errors, fewer than 13 happens with probability 0.009.
MIN_UNITS_COVERED = 13


@pytest.mark.validation
def test_small_fit_recovers_known_parameters(plant):
    """8 simulated subjects × {MC, SC} × K = 1500 (two chains of 600 draws): β, μ_R and the unit R.

    With 8 subjects β mixes slowly (coupled to σ_β): 2 × 300 draws gave β an ESS of
    about 100 and R-hat 1.055 on this data set; 2 × 600 give about 350 and 1.002.

    The data come from the study simulator (SC: the human plans with the assistant's law,
    in closed loop), true torques, 2-s preview. Negative control: β = 0 (no SC change)
    must lie outside the 94 % HDI, i.e. the interval is narrow enough to tell the
    simulated change from none.
    """
    import nutpie

    from scioc.models.simulate import Population, simulate_windows

    truth = Population()
    study = simulate_windows(8, np.random.default_rng(3), truth)
    log_R = np.log(study.theta[2]).reshape(8, 2)  # rows subject, columns MC, SC
    model = build_model(study.subjects, study.conditions, study.segments, plant)
    compiled = nutpie.compile_pymc_model(model)
    idata = nutpie.sample(compiled, draws=600, tune=600, chains=2, seed=4, progress_bar=False)
    # Select before calling ArviZ: its var_names filter on a Dataset leaves the Dataset's
    # cached accessor holding only those variables for later calls (arviz-stats 1.x).
    post = idata["posterior"].to_dataset()[["beta", "mu_log_R", "log_R"]]
    assert int(idata["sample_stats"]["diverging"].sum()) == 0
    assert float(az.rhat(post)["beta"]) < 1.05
    hdi = az.hdi(post, prob=0.94)
    lo, hi = hdi["beta"].values
    assert lo <= truth.beta <= hi
    assert not (lo <= 0.0 <= hi)
    lo, hi = hdi["mu_log_R"].values
    assert lo <= truth.log_R <= hi
    lr = hdi["log_R"].transpose("subject", "condition", ...).values  # (subject, condition, 2)
    covered = (lr[..., 0] <= log_R) & (log_R <= lr[..., 1])
    assert covered.sum() >= MIN_UNITS_COVERED, covered


def test_pooled_model_is_priors_plus_likelihood_without_condition_effects(plant):
    """condition_effects=False: no β, σ_β; log θ1 = m_i in both conditions; log R and θ2 as before."""
    subjects, conditions, segs = small_study(plant)
    batch = prepare_batch(plant, segs)
    index = index_study(subjects, conditions)
    priors = Priors()
    model = build_model(subjects, conditions, batch, plant, priors=priors, condition_effects=False)
    names = {rv.name for rv in model.free_RVs}
    assert not names & {"beta", "sigma_beta", "z_log_theta1_SC"}
    assert {"log_theta1_mean", "beta_log_R", "sigma_beta_log_R", "log_R_SC", "z_theta2"} <= names
    n = len(index.subjects)
    rng = np.random.default_rng(36)
    v = _raw_point(rng, n, Parameterization())
    v["log_theta1_mean"] = np.log(40.0) + 0.4 * rng.standard_normal(n)
    point = {}
    for rv in model.free_RVs:
        value_name = model.rvs_to_values[rv].name
        point[value_name] = np.log(v[rv.name]) if value_name.endswith("_log__") else np.asarray(v[rv.name], float)
    N, HN = stats.norm.logpdf, stats.halfnorm.logpdf
    lp = N(v["mu_log_theta1"], *priors.mu_log_theta1) + HN(v["sigma_log_theta1"], scale=priors.sigma_log_theta1)
    lp += N(v["mu_log_R"], *priors.mu_log_R) + N(v["beta_log_R"], 0, priors.beta_log_R_sd)
    lp += HN(v["sigma_log_R"], scale=priors.sigma_log_R) + HN(v["sigma_beta_log_R"], scale=priors.sigma_beta_log_R)
    lp += HN(v["tau_theta2"], scale=priors.tau_theta2)
    m = v["log_theta1_mean"]
    lp += N(m, v["mu_log_theta1"], v["sigma_log_theta1"]).sum()
    lp += N(v["log_R_MC"], v["mu_log_R"], v["sigma_log_R"]).sum()
    lp += N(v["log_R_SC"], v["log_R_MC"] + v["beta_log_R"], v["sigma_beta_log_R"]).sum()
    lp += HN(v["z_theta2"]).sum()
    s, c = index.subject_idx, index.condition_idx
    log_R = np.column_stack([v["log_R_MC"], v["log_R_SC"]])[s, c]
    R = np.exp(log_R)
    theta = np.array([np.exp(m[s]) * R, (v["tau_theta2"] * v["z_theta2"])[s, c] * R, R])
    lp += loglik_grad(theta, batch, plant).loglik.sum()
    # PyTensor's own order of operations: a few 1e-12 relative (as above).
    assert model.compile_logp(jacobian=False)(point) == pytest.approx(lp, rel=1e-10)
    lt1 = pm.draw(model["log_theta1"], random_seed=37)
    np.testing.assert_array_equal(lt1[:, 0], lt1[:, 1])


@pytest.mark.parametrize("condition_effects", [True, False])
def test_population_parameters_are_the_models_scalar_free_variables(plant, condition_effects):
    """The one list of population-parameter names is what the model defines (pooled: without β, σ_β)."""
    subjects, conditions, segs = small_study(plant)
    model = build_model(subjects, conditions, segs, plant, condition_effects=condition_effects)
    scalars = [rv.name for rv in model.free_RVs if rv.ndim == 0]
    expected = [n for n in POPULATION_PARAMETERS if condition_effects or n not in ("beta", "sigma_beta")]
    assert scalars == expected



def test_half_normal_quantile_is_the_half_normals_quantile_of_the_normal_probability_with_finite_gradients():
    import pytensor
    import pytensor.tensor as pt

    from scioc.models.bayes.blocks import half_normal_quantile

    n = pt.dvector("n")
    h = half_normal_quantile(n)
    f = pytensor.function([n], [h, pt.grad(pt.sum(pt.log(h)), n)])
    moderate = np.linspace(-5.0, 5.0, 201)
    np.testing.assert_allclose(f(moderate)[0], stats.halfnorm.ppf(stats.norm.cdf(moderate)), rtol=1e-7)
    # far out (where scipy's composition under- or overflows) the value and the gradient of log h stay finite,
    # increasing, and agree with central differences
    wide = np.linspace(-30.0, 30.0, 241)
    value, slope = f(wide)
    assert np.all(np.isfinite(value)) and np.all(value > 0) and np.all(np.diff(value) > 0)
    step = 1e-6
    numeric = (np.log(f(wide + step)[0]) - np.log(f(wide - step)[0])) / (2 * step)
    np.testing.assert_allclose(slope, numeric, rtol=1e-5)
    # the form's prior on θ2 is HalfNormal(τ): the quartiles of n map to the half-normal's
    np.testing.assert_allclose(f(stats.norm.ppf([0.25, 0.5, 0.75]))[0], stats.halfnorm.ppf([0.25, 0.5, 0.75]),
                               rtol=1e-12)
    with pytest.raises(ValueError, match="theta2"):
        Parameterization(theta2="mean")
