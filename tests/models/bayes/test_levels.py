"""The hierarchical model for any experiment: two levels exactly as before, three levels with a
``contrast`` dim (log density by hand, a brief fit), the rate-independent prior on log R, the
prior predictive check and leave-one-subject-out with three levels, trials and another rate."""

import math
import warnings

import numpy as np
import pymc as pm
import pytensor
import pytest
from scipy import special, stats

from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS, Parameterization, Priors, build_model
from scioc.models.bayes.prior_predictive import prior_predictive_summary
from scioc.models.bayes.subject_loo import subject_loglik
from scioc.models.bayes.unit_model import UnitPrior
from scioc.models.design import REFERENCE_DT, Design, WheelParameters
from scioc.models.maxent import loglik_grad, sample_maxent
from scioc.models.plant import discretize
from scioc.models.segment import Segment, prepare_batch
from scioc.models.units import index_study
from tests.models.bayes.test_hierarchical import FORMS, small_study
from tests.models.bayes.test_op import preview_segment

LEVELS = ("none", "weak", "strong")

#: The free variables of the two-level model (default parameterization) and their dims, as
#: every version before the experiment file defined them: the draws of a seed depend on them.
TWO_LEVEL_FREE = [
    ("mu_log_theta1", ()), ("beta", ()), ("sigma_log_theta1", ()), ("sigma_beta", ()), ("mu_log_R", ()),
    ("beta_log_R", ()), ("sigma_log_R", ()), ("sigma_beta_log_R", ()), ("tau_theta2", ()),
    ("z_log_theta1_SC", ("subject",)), ("log_theta1_mean", ("subject",)), ("log_R_MC", ("subject",)),
    ("log_R_SC", ("subject",)), ("z_theta2", ("subject", "condition")),
]
#: The same for the pooled two-level model.
TWO_LEVEL_POOLED_FREE = [(n, d) for n, d in TWO_LEVEL_FREE if n not in ("beta", "sigma_beta", "z_log_theta1_SC")]
UNIT_DETERMINISTICS = ("log_theta1", "log_R", "theta1", "R", "theta2")


def _free(model):
    return [(rv.name, tuple(model.named_vars_to_dims.get(rv.name, ()))) for rv in model.free_RVs]


def three_level_study(K=40, n_subjects=3, seed=40, M=0, trials=2):
    """Subjects S0.. in every level of LEVELS, ``trials`` segments each (assisted levels with random u_A)."""
    rng = np.random.default_rng(seed)
    subjects, conditions, segs = [], [], []
    for i in range(n_subjects):
        for c in LEVELS:
            for _ in range(trials):
                subjects.append(f"S{i}")
                conditions.append(c)
                segs.append(preview_segment(rng, K, M, c != "none"))
    return subjects, conditions, segs


@pytest.mark.parametrize("condition_effects, expected", [(True, TWO_LEVEL_FREE), (False, TWO_LEVEL_POOLED_FREE)],
                         ids=["condition", "pooled"])
def test_two_levels_keep_todays_names_and_dims(plant, condition_effects, expected):
    subjects, conditions, segs = small_study(plant)
    model = build_model(subjects, conditions, segs, plant, condition_effects=condition_effects)
    assert _free(model) == expected
    assert "contrast" not in model.coords and model.coords["condition"] == ("MC", "SC")
    for name in UNIT_DETERMINISTICS:
        assert model.named_vars_to_dims[name] == ("subject", "condition")
    # Other labels keep the names too ("MC" and "SC" in a name mean the baseline and the other level).
    relabelled = build_model(subjects, ["off" if c == "MC" else "on" for c in conditions], segs, plant,
                             condition_effects=condition_effects, levels=("off", "on"))
    assert _free(relabelled) == expected and relabelled.coords["condition"] == ("off", "on")


@pytest.mark.parametrize("form", FORMS, ids=["default", "centred", "noncentred", "mean", "quantile"])
def test_three_levels_have_a_contrast_dim(plant, form):
    subjects, conditions, segs = three_level_study()
    model = build_model(subjects, conditions, segs, plant, levels=LEVELS, parameterization=form)
    assert model.coords["condition"] == LEVELS and model.coords["contrast"] == LEVELS[1:]
    dims = model.named_vars_to_dims
    for name in ("beta", "sigma_beta", "beta_log_R", "sigma_beta_log_R"):
        assert dims[name] == ("contrast",)
    for name in UNIT_DETERMINISTICS:
        assert dims[name] == ("subject", "condition")
    scalars = [rv.name for rv in model.free_RVs if rv.ndim == 0]
    assert scalars == [n for n in POPULATION_PARAMETERS if n not in ("beta", "sigma_beta", "beta_log_R",
                                                                      "sigma_beta_log_R")]
    lt1 = pm.draw(model["log_theta1"], random_seed=41)
    assert lt1.shape == (3, 3)


def _raw_point(rng, n, form: Parameterization, L: int):
    """Values of every free variable of the L-level model (untransformed), keyed by name."""
    C = L - 1
    v = {"mu_log_theta1": 3.0 + 0.3 * rng.standard_normal(), "beta": -0.5 + 0.1 * rng.standard_normal(C),
         "sigma_log_theta1": rng.uniform(0.2, 0.6), "sigma_beta": rng.uniform(0.1, 0.4, C),
         "mu_log_R": 0.2 * rng.standard_normal(), "beta_log_R": 0.1 * rng.standard_normal(C),
         "sigma_log_R": rng.uniform(0.1, 0.5), "sigma_beta_log_R": rng.uniform(0.05, 0.3, C),
         "tau_theta2": rng.uniform(0.05, 0.5)}
    for name, f_mc, f_sc, centre in (("log_theta1", form.theta1_mc, form.theta1_sc, 3.0),
                                     ("log_R", form.R_mc, form.R_sc, 0.0)):
        if f_sc == "noncentred":
            v[f"z_{name}_contrast"] = rng.standard_normal((n, C))
        elif f_mc == "mean":
            v[f"{name}_change"] = -0.3 + 0.2 * rng.standard_normal((n, C))
        else:
            v[f"{name}_contrast"] = centre - 0.3 + 0.4 * rng.standard_normal((n, C))
        key = {"noncentred": f"z_{name}_baseline", "centred": f"{name}_baseline", "mean": f"{name}_mean"}[f_mc]
        v[key] = (0.0 if f_mc == "noncentred" else centre) + 0.4 * rng.standard_normal(n)
    if form.theta2 == "quantile":
        v["n_theta2"] = rng.standard_normal((n, L))
    else:
        v["theta2" if form.theta2 == "centred" else "z_theta2"] = np.abs(0.2 * rng.standard_normal((n, L)))
    return v


def _by_hand(v, priors: Priors, form: Parameterization, index, batch, plant, L):
    """Σ prior log densities (scipy.stats) + Σ segment log-likelihoods, no Jacobians: the model as documented."""
    N, HN = stats.norm.logpdf, stats.halfnorm.logpdf
    lp = N(v["mu_log_theta1"], *priors.mu_log_theta1) + N(v["beta"], 0, priors.beta_sd).sum()
    lp += HN(v["sigma_log_theta1"], scale=priors.sigma_log_theta1) + HN(v["sigma_beta"], scale=priors.sigma_beta).sum()
    lp += N(v["mu_log_R"], *priors.mu_log_R) + N(v["beta_log_R"], 0, priors.beta_log_R_sd).sum()
    lp += HN(v["sigma_log_R"], scale=priors.sigma_log_R)
    lp += HN(v["sigma_beta_log_R"], scale=priors.sigma_beta_log_R).sum() + HN(v["tau_theta2"], scale=priors.tau_theta2)
    units = {}
    for name, f_mc, f_sc, mu, beta, s, sb in (
        ("log_theta1", form.theta1_mc, form.theta1_sc, "mu_log_theta1", "beta", "sigma_log_theta1", "sigma_beta"),
        ("log_R", form.R_mc, form.R_sc, "mu_log_R", "beta_log_R", "sigma_log_R", "sigma_beta_log_R"),
    ):
        b, sd = v[beta][None, :], v[sb][None, :]
        if f_mc == "mean":
            if f_sc == "centred":
                d = v[f"{name}_change"]
                lp += N(d, b, sd).sum()
            else:
                z = v[f"z_{name}_contrast"]
                lp += N(z).sum()
                d = b + sd * z
            m = v[f"{name}_mean"]
            # The subject mean over all L levels, the baseline's change being 0.
            lp += N(m, v[mu] + d.sum(axis=1) / L, v[s]).sum()
            base = m - d.sum(axis=1) / L
            others = base[:, None] + d
        else:
            if f_mc == "centred":
                base = v[f"{name}_baseline"]
                lp += N(base, v[mu], v[s]).sum()
            else:
                z = v[f"z_{name}_baseline"]
                lp += N(z).sum()
                base = v[mu] + v[s] * z
            if f_sc == "centred":
                others = v[f"{name}_contrast"]
                lp += N(others, base[:, None] + b, sd).sum()
            else:
                z = v[f"z_{name}_contrast"]
                lp += N(z).sum()
                others = base[:, None] + b + sd * z
        units[name] = np.column_stack([base, others])
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
    return lp + loglik_grad(theta, batch, plant).loglik.sum(), units


@pytest.mark.parametrize("form", FORMS, ids=["default", "centred", "noncentred", "mean", "quantile"])
def test_three_level_log_density_is_priors_plus_likelihood(plant, form):
    subjects, conditions, segs = three_level_study(M=20)
    batch = prepare_batch(plant, segs)
    index = index_study(subjects, conditions, LEVELS)
    priors = Priors()
    model = build_model(subjects, conditions, batch, plant, priors=priors, parameterization=form, levels=LEVELS)
    logp = model.compile_logp(jacobian=False)
    outs = model.replace_rvs_by_values([model["log_theta1"], model["log_R"]])
    units_fn = pytensor.function(model.value_vars, outs, on_unused_input="ignore")
    rng = np.random.default_rng(42)
    for _ in range(2):
        v = _raw_point(rng, len(index.subjects), form, 3)
        point = {}
        for rv in model.free_RVs:
            value_name = model.rvs_to_values[rv].name
            transformed = model.rvs_to_transforms.get(rv) is not None
            point[value_name] = np.log(v[rv.name]) if transformed else np.asarray(v[rv.name], dtype=float)
        assert set(point) == set(model.initial_point())
        expected, units = _by_hand(v, priors, form, index, batch, plant, 3)
        # fastmath in the numba backend: a few 1e-12 relative (test_hierarchical.py).
        assert logp(point) == pytest.approx(expected, rel=1e-10)
        lt1, lR = units_fn(**point)
        np.testing.assert_allclose(lt1, units["log_theta1"], rtol=1e-12)
        np.testing.assert_allclose(lR, units["log_R"], rtol=1e-12)


def test_three_level_pooled_model_shares_log_theta1_across_levels(plant):
    subjects, conditions, segs = three_level_study()
    model = build_model(subjects, conditions, segs, plant, levels=LEVELS, condition_effects=False)
    names = {rv.name for rv in model.free_RVs}
    assert not names & {"beta", "sigma_beta", "z_log_theta1_contrast"}
    assert model.named_vars_to_dims["beta_log_R"] == ("contrast",)
    lt1 = pm.draw(model["log_theta1"], random_seed=43)
    assert lt1.shape == (3, 3) and (lt1 == lt1[:, :1]).all()


@pytest.mark.validation
def test_three_level_model_samples_briefly(plant):
    """nutpie on tiny data: the posterior has the coordinates and dims the fit stage reads."""
    import nutpie

    subjects, conditions, segs = three_level_study(K=30, n_subjects=3, trials=2)
    model = build_model(subjects, conditions, segs, plant, levels=LEVELS,
                        segment_ids=[f"{s}/{c}/{j % 2 + 1}" for j, (s, c) in enumerate(zip(subjects, conditions))])
    idata = nutpie.sample(nutpie.compile_pymc_model(model), draws=30, tune=30, chains=1, seed=44, progress_bar=False)
    post = idata["posterior"]
    assert post["beta"].dims == ("chain", "draw", "contrast")
    assert list(post["beta"]["contrast"].values) == list(LEVELS[1:])
    assert post["log_theta1"].dims == ("chain", "draw", "subject", "condition")
    assert list(post["theta2"]["condition"].values) == list(LEVELS)
    assert np.isfinite(post["log_R"].values).all() and post["log_R"].shape == (1, 30, 3, 3)


def test_priors_for_design_shift_only_mu_log_R_by_the_log_sample_time_ratio():
    assert Priors.for_design(Design()) == Priors()
    assert Priors.for_design(Design()).mu_log_R[0] == 3.0  # 3.0 + log(1.0), exactly
    fast = Priors.for_design(Design(dt=0.001))
    assert fast.mu_log_R[0] == pytest.approx(3.0 + math.log(0.1), rel=1e-14)
    assert fast.mu_log_R[1] == Priors().mu_log_R[1]
    assert Priors.for_design(Design(dt=0.005)).mu_log_R[0] == pytest.approx(3.0 + math.log(0.005 / REFERENCE_DT))
    unchanged = {k: v for k, v in vars(fast).items() if k != "mu_log_R"}
    assert unchanged == {k: v for k, v in vars(Priors()).items() if k != "mu_log_R"}
    # Overrides are stated at 100 Hz too.
    shifted = Priors.for_design(Design(dt=0.001), mu_log_R=(2.0, 0.5)).mu_log_R
    assert shifted == pytest.approx((2.0 + math.log(0.1), 0.5))
    # The unit-level prior of calibration likewise.
    assert UnitPrior.for_design(Design()) == UnitPrior()
    assert UnitPrior.for_design(Design(dt=0.001)).log_R[0] == pytest.approx(math.log(20.0) + math.log(0.1))


def test_prior_predictive_runs_with_three_levels_at_another_rate():
    """1 kHz, another wheel, three levels: the check works per level and is seeded."""
    design = Design(dt=0.001, wheel=WheelParameters(0.06, 2.0, 0.4), levels=LEVELS, baseline="none", assistants=())
    plant = discretize(design.dt, design.wheel)
    subjects, conditions, segs = three_level_study(K=60, M=20, trials=1)
    priors = Priors.for_design(design)
    a = prior_predictive_summary(subjects, conditions, segs, plant, np.random.default_rng(45), draws=8,
                                 priors=priors, levels=design.ordered_levels)
    b = prior_predictive_summary(subjects, conditions, segs, plant, np.random.default_rng(45), draws=8,
                                 priors=priors, levels=design.ordered_levels)
    assert set(a.torque_rms) == set(LEVELS) == set(a.observed_error_rms)
    for c in LEVELS:
        np.testing.assert_array_equal(a.torque_rms[c], b.torque_rms[c])
        assert np.all(np.diff(a.error_rms[c]) >= 0) and np.all(a.torque_rms[c] > 0)


PSI = {"mu_log_theta1": 3.0, "sigma_log_theta1": 0.4, "mu_log_R": 3.0, "sigma_log_R": 0.3, "tau_theta2": 0.05}
PSI_LEVELS = {"beta": [-0.7, -0.3], "sigma_beta": [0.2, 0.3], "beta_log_R": [0.0, 0.1], "sigma_beta_log_R": [0.1, 0.2]}


def _prior_draws(rng, n, n_subj, condition_effects):
    """Unit parameters of three levels from the model's prior given PSI, (n, n_subj, 3) each."""
    p, q = PSI, {k: np.array(v) for k, v in PSI_LEVELS.items()}
    lt0 = p["mu_log_theta1"] + p["sigma_log_theta1"] * rng.standard_normal((n, n_subj, 1))
    change = q["beta"] + q["sigma_beta"] * rng.standard_normal((n, n_subj, 2)) if condition_effects else 0.0
    lt = np.concatenate([lt0, lt0 + change], axis=-1) if condition_effects else np.repeat(lt0, 3, axis=-1)
    lr0 = p["mu_log_R"] + p["sigma_log_R"] * rng.standard_normal((n, n_subj, 1))
    lr = np.concatenate([lr0, lr0 + q["beta_log_R"] + q["sigma_beta_log_R"] * rng.standard_normal((n, n_subj, 2))],
                        axis=-1)
    return lt, lr, p["tau_theta2"] * np.abs(rng.standard_normal((n, n_subj, 3)))


@pytest.mark.parametrize("condition_effects", [True, False], ids=["condition", "pooled"])
def test_subject_loo_integral_with_three_levels_and_trials_matches_plain_monte_carlo(plant, condition_effects):
    """As tests/models/bayes/test_subject_loo.py, with three levels and two trials per unit.

    The data are exact max-ent draws at θ from the prior (short windows: broad likelihoods,
    so plain Monte Carlo over the conditional prior with 200 000 points is accurate). The
    unit draws the proposal is built from are the posterior given ψ, by resampling those
    points with their likelihood weights (prior draws would make a proposal far too wide in
    nine dimensions). The importance sampler must agree within 4 combined standard errors
    (false-failure rate about 6e-5 per comparison if both errors are Gaussian).
    """
    rng = np.random.default_rng(46)
    K = 25
    lt, lr, t2 = _prior_draws(rng, 1, 2, True)
    segs, s_idx, c_idx = [], [], []
    for i in range(2):
        for c in range(3):
            R = np.exp(lr[0, i, c])
            theta = [np.exp(lt[0, i, c]) * R, t2[0, i, c] * R, R]
            for _ in range(2):  # two trials of the unit
                t = np.arange(K + 1) * 0.01
                ref = 0.2 * np.sin(2 * np.pi * rng.uniform(0.2, 0.5) * t)
                x0 = rng.normal(0.0, 0.05, 2)
                demo = sample_maxent(theta, x0, ref, np.zeros(K), plant, rng)
                segs.append(Segment(x0, ref, demo.u_H[:K], np.zeros(K)))
                s_idx.append(i)
                c_idx.append(c)
    batch = prepare_batch(plant, segs)
    s_idx, c_idx = np.array(s_idx), np.array(c_idx)
    N, S = 200_000, 400
    lt_b, lr_b, t2_b = _prior_draws(np.random.default_rng(48), N, 2, condition_effects)
    brute, se_brute = np.empty(2), np.empty(2)
    post = {"log_theta1": np.empty((S, 2, 3)), "log_R": np.empty((S, 2, 3)), "theta2": np.empty((S, 2, 3)),
            **{k: np.full(S, v) for k, v in PSI.items()}, **{k: np.tile(v, (S, 1)) for k, v in PSI_LEVELS.items()}}
    pick = np.random.default_rng(49)
    for i in range(2):
        ll = np.zeros(N)
        for j in np.flatnonzero(s_idx == i):
            c = c_idx[j]
            R = np.exp(lr_b[:, i, c])
            ll += loglik_grad(np.vstack([np.exp(lt_b[:, i, c]) * R, t2_b[:, i, c] * R, R]), batch.repeat(j, N),
                              plant).loglik
        brute[i] = special.logsumexp(ll) - np.log(N)
        w = np.exp(ll - ll.max())
        se_brute[i] = np.sqrt(np.var(w) / N) / np.mean(w)  # delta method on the log
        rows = pick.choice(N, S, p=w / w.sum())
        for name, draws in (("log_theta1", lt_b), ("log_R", lr_b), ("theta2", t2_b)):
            post[name][:, i] = draws[rows, i]
    res = subject_loglik(post, batch, s_idx, c_idx, plant, np.random.default_rng(47),
                         condition_effects=condition_effects, M=2000)
    assert res.loglik.shape == (S, 2) and np.all(res.loglik == res.loglik[0])  # same ψ in every draw
    for i in range(2):
        se_is = 1.0 / np.sqrt(res.is_ess[i])
        assert se_brute[i] < 0.05 and res.is_ess[i] > 100, (se_brute[i], res.is_ess[i])
        assert abs(res.loglik[0, i] - brute[i]) <= 4 * np.hypot(se_brute[i], se_is), (res.loglik[0, i], brute[i])
    if condition_effects:
        # Negative control: the two levels' effects swapped (a level-indexing error) must miss.
        swapped = dict(post, beta=post["beta"][:, ::-1], sigma_beta=post["sigma_beta"][:, ::-1])
        bad = subject_loglik(swapped, batch, s_idx, c_idx, plant, np.random.default_rng(47), M=2000)
        assert np.any(np.abs(bad.loglik[0] - brute) > 4 * np.hypot(se_brute, 1.0 / np.sqrt(bad.is_ess)))


def test_three_level_observed_draws_have_the_data_shape(plant):
    subjects, conditions, segs = three_level_study(K=20, M=10, trials=1)
    model = build_model(subjects, conditions, segs, plant, levels=LEVELS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sample_maxent in Python (object mode under numba)
        u = pm.draw(model["u_H"], random_seed=49)
    assert u.shape == (len(segs), 20) and np.isfinite(u).all()
