"""The hierarchical ``delayed`` model: its log-likelihood is the kernel's, nutpie's compiled logp is PyMC's,
the cost blocks are the max-ent model's, and a short fit on delayed data recovers τ_nm and σ_m."""

import warnings

import numpy as np
import nutpie
import pymc as pm
import pytest

from scioc.models.bayes.blocks import Parameterization
from scioc.models.bayes.delayed_model import DelayedForm, build_delayed_model
from scioc.models.bayes.delayed_op import DelayedLoglikOp
from scioc.models.bayes.delayed_value import DelayedLoglikValueOp
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.bayes.hierarchical import build_model
from scioc.models.cost import from_normalized
from scioc.models.delayed import loglik_grad
from scioc.models.segment import prepare_batch
from scioc.models.units import index_study

#: The kernel sums with reassociation; the same arithmetic compiled inside the Op rounds
#: differently (test_delayed_op.RTOL says by how much).
RTOL = 1e-10


@pytest.fixture(scope="module")
def study():
    return delayed_windows(3, np.random.default_rng(7), K=200, preview=30)


def _point(model, seed):
    """A random point near the prior's centre, on the value variables' (transformed) scale."""
    rng = np.random.default_rng(seed)
    return {k: v + rng.normal(0, 0.3, np.shape(v)) for k, v in model.initial_point().items()}


@pytest.mark.validation
def test_pointwise_log_likelihood_is_the_kernels(plant, study):
    w = study
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, tau0=w.tau0)
    point = _point(model, 3)
    ll_fn = model.compile_fn(model.logp(vars=[model["u_H"]], sum=False)[0], inputs=model.value_vars,
                             on_unused_input="ignore")
    # Deterministics as functions of the value variables (compile_fn alone would draw the random variables).
    outs = model.replace_rvs_by_values([model[v] for v in ("log_theta1", "log_R", "theta2", "tau_nm", "sigma_m")])
    det = model.compile_fn(outs, inputs=model.value_vars, on_unused_input="ignore")
    lt1, lR, t2, tau, sig = det(point)
    idx = index_study(w.subjects, w.conditions)
    s, c = idx.subject_idx, idx.condition_idx
    theta = from_normalized(np.exp(lt1[s, c]), t2[s, c], np.exp(lR[s, c]))
    ref = loglik_grad(theta, prepare_batch(plant, w.segments), plant, tau_nm=tau[s], sigma_m=sig[s], delay=w.delay)
    np.testing.assert_allclose(ll_fn(point), ref.loglik, rtol=RTOL)
    # ... computed by the kernel's value alone: nothing in this graph reads the gradient (models/bayes/delayed_value.py)
    ops = {type(n.op) for n in ll_fn.f.maker.fgraph.apply_nodes}
    assert DelayedLoglikValueOp in ops and DelayedLoglikOp not in ops
    # Per-subject lag and noise: both levels of a subject share them.
    assert tau.shape == (3,) and sig.shape == (3,)


@pytest.mark.validation
def test_nutpie_compiled_logp_equals_pymcs(plant, study):
    """The numba function nutpie samples with (the Op's numba dispatch) gives PyMC's logp and gradient."""
    w = study
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, tau0=w.tau0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        compiled = nutpie.compile_pymc_model(model, backend="numba")
    assert not [m for m in caught if "object mode" in str(m.message)]
    point = _point(model, 4)
    # nutpie joins the value variables in the order of the free random variables
    x = np.concatenate([np.ravel(point[model.rvs_to_values[rv].name]) for rv in model.free_RVs])
    assert x.size == compiled.n_dim
    logp, grad = compiled.logp_func(x)
    ref_logp = model.compile_logp(mode="FAST_COMPILE")(point)  # the Op's perform, from Python
    ref_grad = model.compile_dlogp(mode="FAST_COMPILE")(point)
    assert logp == pytest.approx(ref_logp, rel=RTOL)
    np.testing.assert_allclose(grad, ref_grad, rtol=1e-8, atol=1e-8 * np.abs(ref_grad).max())
    ops = [n.op for n in compiled.logp_func.maker.fgraph.apply_nodes if isinstance(n.op, DelayedLoglikOp)]
    assert len(ops) == 1  # one kernel call for logp and gradient


def test_cost_blocks_are_the_max_ent_models(plant, study):
    """The same free variables, dims and priors for θ (the max-ent model's condition model), plus the motor blocks."""
    w = study
    delayed = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                  parameterization=Parameterization())
    maxent = build_model(w.subjects, w.conditions, w.segments, plant)
    names = {v.name for v in maxent.free_RVs}
    assert names <= {v.name for v in delayed.free_RVs}
    assert {v.name for v in delayed.free_RVs} - names == {"tau_nm_scale", "sigma_m_scale_sq", "tau_nm", "sigma_m"}
    for n in names:
        assert delayed.named_vars_to_dims.get(n) == maxent.named_vars_to_dims.get(n)
    draws_d = pm.draw([delayed[n] for n in sorted(names)], draws=200, random_seed=5)
    draws_m = pm.draw([maxent[n] for n in sorted(names)], draws=200, random_seed=5)
    for a, b in zip(draws_d, draws_m):  # the same prior, drawn in the same order
        np.testing.assert_array_equal(a, b)
    noncentred = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                     delayed_form=DelayedForm("noncentred", "noncentred"))
    assert {"z_tau_nm", "z_sigma_m", "z_log_R_MC", "z_log_R_SC"} <= {v.name for v in noncentred.free_RVs}
    with pytest.raises(ValueError, match="centred"):
        DelayedForm("sometimes")


@pytest.mark.validation
def test_folded_motor_blocks(plant, study):
    """DelayedForm(sigma_m="folded"): σ_m = s_m |z|, z ~ N(0, 1) unconstrained (so σ_m -> 0 is the interior point
    z = 0, where the likelihood, a function of σ_m², is smooth), starting at z = 1; the law of σ_m is the centred
    form's half-normal, and the model's density is the centred one's at the same σ_m up to z's density."""
    from scipy import stats

    w = study
    folded = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                 delayed_form=DelayedForm("folded", "folded"))
    centred = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                  delayed_form=DelayedForm("centred", "centred"))
    names = {v.name for v in folded.free_RVs}
    assert names - {v.name for v in centred.free_RVs} == {"z_tau_nm", "z_sigma_m"}
    assert folded.rvs_to_transforms[folded["z_sigma_m"]] is None  # unconstrained: no log transform
    start = folded.initial_point()
    np.testing.assert_array_equal(start["z_sigma_m"], np.ones(3))
    np.testing.assert_array_equal(start["z_tau_nm"], np.ones(3))
    point = _point(folded, 4)
    point["z_sigma_m"] = np.array([-0.4, 0.0, 1.3])
    outs = folded.replace_rvs_by_values([folded[v] for v in ("sigma_m", "sigma_m_scale", "tau_nm", "tau_nm_scale")])
    sig, s_m, tau, s_t = folded.compile_fn(outs, inputs=folded.value_vars, on_unused_input="ignore")(point)
    np.testing.assert_allclose(sig, s_m * np.array([0.4, 0.0, 1.3]), rtol=1e-12)
    np.testing.assert_allclose(tau, s_t * np.abs(point["z_tau_nm"]), rtol=1e-12)
    # At the same σ_m and τ_nm (both > 0) the centred model's density differs only by the blocks' own priors.
    point["z_tau_nm"], point["z_sigma_m"] = np.array([0.5, -0.8, 1.2]), np.array([-0.4, 0.01, 1.3])
    tau, sig = s_t * np.abs(point["z_tau_nm"]), s_m * np.abs(point["z_sigma_m"])
    cpoint = {k: v for k, v in point.items() if k not in ("z_tau_nm", "z_sigma_m")}
    cpoint["tau_nm_log__"], cpoint["sigma_m_log__"] = np.log(tau), np.log(sig)
    lf, lc = folded.compile_logp()(point), centred.compile_logp()(cpoint)
    # folded: N(z; 0, 1) per subject; centred: HalfNormal(x; s) times the log transform's Jacobian x
    diff = (stats.norm.logpdf(point["z_tau_nm"]).sum() + stats.norm.logpdf(point["z_sigma_m"]).sum()
            - (stats.halfnorm(scale=s_t).logpdf(tau) + np.log(tau)).sum()
            - (stats.halfnorm(scale=s_m).logpdf(sig) + np.log(sig)).sum())
    assert lf - lc == pytest.approx(diff, rel=1e-9, abs=1e-8)
    with pytest.raises(ValueError, match="folded"):
        DelayedForm(sigma_m="partial")


@pytest.mark.validation
def test_folded_centred_motor_block(plant, study):
    """DelayedForm(sigma_m="folded_centred"): σ_m = |v|, v ~ N(0, s_m) unconstrained, starting off 0 at
    FOLDED_CENTRED_START; the model's density is the centred one's at the same σ_m less the log transform's
    Jacobian log σ_m and log 2 per subject (N(v; 0, s) = HalfNormal(|v|; s) / 2)."""
    from scioc.models.bayes.delayed_blocks import FOLDED_CENTRED_START

    w = study
    fc = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                             delayed_form=DelayedForm("centred", "folded_centred"))
    centred = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                  delayed_form=DelayedForm("centred", "centred"))
    assert {v.name for v in fc.free_RVs} - {v.name for v in centred.free_RVs} == {"sigma_m_signed"}
    assert fc.rvs_to_transforms[fc["sigma_m_signed"]] is None  # unconstrained
    np.testing.assert_array_equal(fc.initial_point()["sigma_m_signed"], np.full(3, FOLDED_CENTRED_START["sigma_m"]))
    point = _point(fc, 4)
    point["sigma_m_signed"] = np.array([-0.4, 0.01, 0.13])
    sig = fc.compile_fn(fc.replace_rvs_by_values([fc["sigma_m"]])[0], inputs=fc.value_vars,
                        on_unused_input="ignore")(point)
    np.testing.assert_allclose(sig, [0.4, 0.01, 0.13], rtol=1e-15)
    cpoint = {k: v for k, v in point.items() if k != "sigma_m_signed"}
    cpoint["sigma_m_log__"] = np.log(sig)
    lf, lc = fc.compile_logp()(point), centred.compile_logp()(cpoint)
    assert lf - lc == pytest.approx(-np.sum(np.log(2.0) + np.log(sig)), rel=1e-9, abs=1e-8)


def test_motor_coordinate_is_the_free_variable_each_form_samples(plant, study):
    """The coordinate a curved whitening bends along (models.bayes.delayed_blocks.motor_coordinate) is the free
    variable of σ_m's block, with one value per subject, in every form."""
    from scioc.models.bayes.delayed_blocks import MOTOR_FORMS, motor_coordinate

    w = study
    for form in MOTOR_FORMS:
        model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                    delayed_form=DelayedForm("centred", form))
        name = motor_coordinate("sigma_m", form)
        assert model[name] in model.free_RVs and model.named_vars_to_dims[name] == ("subject",)
        assert {v.name for v in model.free_RVs} & {"sigma_m", "z_sigma_m", "sigma_m_signed"} == {name}
    with pytest.raises(ValueError, match="unknown form 'wavy'"):
        motor_coordinate("sigma_m", "wavy")


def test_the_ridge_pivots_are_rhos_coordinate_where_rho_has_one_then_sigma_ms_with_where_each_is_signed(plant, study):
    """models.bayes.delayed_blocks.ridge_pivots: with R_population="policy_scale" a curved whitening may bend along ρ's
    free variable (signed where its form is folded or folded centred), and along σ_m's, last (signed where its form
    is); each subject's is the signed one whose fold its mode is nearest, else σ_m's (models.bayes.whiten.nearest_fold).
    Without ρ, σ_m's alone. Each is a free variable of the model with one value per subject."""
    from scioc.models.bayes.delayed_blocks import MOTOR_FORMS, SIGNED_FORMS, ridge_pivots
    from scioc.models.bayes.delayed_model import DelayedPriors

    w = study
    n = len(dict.fromkeys(w.subjects))
    rho_name = {"centred": "rho", "noncentred": "z_rho", "folded": "z_rho", "folded_centred": "rho_signed"}
    sigma_m = {"centred": "sigma_m", "noncentred": "z_sigma_m", "folded": "z_sigma_m",
               "folded_centred": "sigma_m_signed"}
    assert set(SIGNED_FORMS) == {"folded", "folded_centred"} and set(rho_name) == set(MOTOR_FORMS)
    seen = set()
    for population in ("lognormal", "policy_scale", "unpooled"):
        for rho in MOTOR_FORMS:
            for sm in ("centred", "folded_centred"):
                dp = DelayedPriors(R_population=population)
                form = DelayedForm("noncentred", sm, rho=rho)
                pivots = ridge_pivots(dp, form, n)
                want_sm = (sigma_m[sm], [sm in SIGNED_FORMS] * n)
                if population == "policy_scale":
                    want = [(rho_name[rho], [rho in SIGNED_FORMS] * n), want_sm]
                else:
                    want = [want_sm]
                assert [(name, list(signed)) for name, signed in pivots] == want, (population, rho, sm)
                seen.update(name for name, _ in pivots)
                if population == "policy_scale":
                    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay,
                                                delayed_priors=dp, delayed_form=form)
                    for name, _ in pivots:
                        assert model[name] in model.free_RVs and model.named_vars_to_dims[name] == ("subject",)
    assert seen == set(rho_name.values()) | {"sigma_m", "sigma_m_signed"}
    for gone in ("mixed", "polar", "squared"):  # no forms of ρ
        with pytest.raises(ValueError, match="DelayedForm.rho must be one of"):
            DelayedForm(rho=gone)


def test_the_motor_noise_variance_has_an_inverse_gamma_prior(plant, study):
    """s_m² ~ IG(1, 0.03) (sampled as sigma_m_scale_sq, s_m its square root), its shape and scale checked."""
    from scipy import stats

    from scioc.models.bayes.delayed_model import DelayedPriors

    w = study
    assert DelayedPriors().sigma_m_variance_inverse_gamma == (1.0, 0.03)
    ig = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay)
    assert "sigma_m_scale_sq" in {v.name for v in ig.free_RVs} and ig["sigma_m_scale"] in ig.deterministics
    s_of = ig.compile_fn(ig.replace_rvs_by_values([ig["sigma_m_scale"]])[0], inputs=ig.value_vars,
                         on_unused_input="ignore")
    point = _point(ig, 4)
    for x in (0.01, 0.2, 0.9):
        assert float(pm.logp(ig["sigma_m_scale_sq"], x ** 2).eval()) == pytest.approx(
            stats.invgamma(1.0, scale=0.03).logpdf(x ** 2), rel=1e-6)
        point["sigma_m_scale_sq_log__"] = np.log(x ** 2)
        assert float(s_of(point)) == pytest.approx(x, rel=1e-12)
    # the quantiles the docstrings quote: median 0.21 N·m, 90 % on 0.10-0.77, below 0.05 at odds of 1 in 160 000
    s_q = np.sqrt(stats.invgamma(1.0, scale=0.03).ppf([0.05, 0.5, 0.95]))
    np.testing.assert_allclose(s_q, [0.100, 0.208, 0.765], atol=1e-3)
    assert 1 / stats.invgamma(1.0, scale=0.03).cdf(0.05 ** 2) == pytest.approx(162_755, rel=1e-3)
    for bad in (None, (2.0,), (2.0, -1.0), (0.0, 0.03), (1.0, np.nan)):
        with pytest.raises(ValueError, match="sigma_m_variance_inverse_gamma"):
            DelayedPriors(sigma_m_variance_inverse_gamma=bad)


@pytest.mark.validation
def test_policy_scale_population_of_R(plant, study):
    """DelayedPriors(R_population="policy_scale"): the baseline log R is -2 log ρ, ρ ~ HalfNormal(s_ρ) per
    subject; the level changes are the lognormal model's; the LOSO density of log R is that law's."""
    from scipy import integrate, stats

    from scioc.models.bayes.delayed_loo import DelayedSubjectTerms
    from scioc.models.bayes.delayed_model import DelayedPriors
    from scioc.models.bayes.hierarchical import Priors

    w = study
    dp = DelayedPriors(R_population="policy_scale")
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, delayed_priors=dp,
                                delayed_form=DelayedForm(rho="centred"))
    lognormal = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay)
    names = {v.name for v in model.free_RVs}
    assert names - {v.name for v in lognormal.free_RVs} == {"rho_scale", "rho"}
    assert {v.name for v in lognormal.free_RVs} - names == {"mu_log_R", "sigma_log_R", "z_log_R_MC"}
    assert model.named_vars_to_dims["rho"] == ("subject",)
    assert dp.rho_prior_scale(Priors()) == pytest.approx(2.0 * np.exp(-1.5))
    # The deterministic log R: baseline -2 log ρ, the other level baseline + β_R + σ_βR z.
    point = _point(model, 9)
    outs = model.replace_rvs_by_values([model[v] for v in ("log_R", "rho", "beta_log_R", "sigma_beta_log_R")])
    lR, rho, bR, sbR = model.compile_fn(outs, inputs=model.value_vars, on_unused_input="ignore")(point)
    np.testing.assert_allclose(lR[:, 0], -2.0 * np.log(rho), rtol=1e-12)
    np.testing.assert_allclose(lR[:, 1], lR[:, 0] + bR + sbR * point["z_log_R_SC"], rtol=1e-12)
    assert float(pm.logp(model["rho"], np.array([0.1, 0.2, 0.3])).sum().eval({model["rho_scale"]: 0.4})) == \
        pytest.approx(stats.halfnorm(scale=0.4).logpdf([0.1, 0.2, 0.3]).sum(), rel=1e-10)
    # The LOSO density of the baseline log R: the law of -2 log ρ (integrates to 1, matches draws).
    post = {"tau_nm": np.full((2, 3), 0.05), "sigma_m": np.full((2, 3), 0.2), "tau_nm_scale": np.full(2, 0.1),
            "sigma_m_scale": np.full(2, 0.3), "rho_scale": np.array([0.2, 0.5])}
    terms = DelayedSubjectTerms(post, prepare_batch(plant, w.segments), plant, w.delay)
    for s, scale in enumerate(post["rho_scale"]):
        mass = integrate.quad(lambda x: np.exp(terms.baseline_log_R_logpdf(np.array([x]))[s, 0]), -20, 60,
                              points=[-2 * np.log(scale)], limit=200)[0]
        assert mass == pytest.approx(1.0, rel=1e-7)
        x = -2.0 * np.log(stats.halfnorm(scale=scale).rvs(200_000, random_state=np.random.default_rng(s)))
        lo, hi = np.quantile(x, [0.25, 0.75])
        cdf = integrate.quad(lambda v: np.exp(terms.baseline_log_R_logpdf(np.array([v]))[s, 0]), lo, hi)[0]
        assert cdf == pytest.approx(0.5, abs=0.005)
    # The lognormal model's terms have no such density: subject_loglik uses N(μ_R, σ_R).
    assert not hasattr(DelayedSubjectTerms({k: v for k, v in post.items() if k != "rho_scale"},
                                           prepare_batch(plant, w.segments), plant, w.delay),
                       "baseline_log_R_logpdf")
    # The folded form: ρ = s_ρ |z| with z ~ N(0, 1), starting at z = 1 (z = 0 would be R = ∞).
    folded = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, delayed_priors=dp)
    assert DelayedForm().rho == "folded" and {v.name for v in folded.free_RVs} - names == {"z_rho"}
    start = folded.initial_point()
    np.testing.assert_array_equal(start["z_rho"], np.ones(3))
    assert np.isfinite(folded.compile_logp()(start))
    start["z_rho"] = np.array([-0.5, 0.7, 2.0])
    outs = folded.replace_rvs_by_values([folded["rho"], folded["rho_scale"]])
    rho, scale = folded.compile_fn(outs, inputs=folded.value_vars, on_unused_input="ignore")(start)
    np.testing.assert_allclose(rho, scale * np.array([0.5, 0.7, 2.0]), rtol=1e-12)
    # Folded and centred: ρ = |ρ̃|, ρ̃ ~ N(0, s_ρ), starting at ρ = exp(-μ/2) (R at the prior's centre).
    fc = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, delayed_priors=dp,
                             delayed_form=DelayedForm(rho="folded_centred"))
    assert {v.name for v in fc.free_RVs} - names == {"rho_signed"}
    start = fc.initial_point()
    np.testing.assert_allclose(start["rho_signed"], np.full(3, np.exp(-0.5 * Priors().mu_log_R[0])), rtol=1e-12)
    assert np.isfinite(fc.compile_logp()(start))
    start["rho_signed"] = np.array([-0.05, 0.07, 0.2])
    outs = fc.replace_rvs_by_values([fc["rho"], fc["log_R"]])
    rho, lR = fc.compile_fn(outs, inputs=fc.value_vars, on_unused_input="ignore")(start)
    np.testing.assert_allclose(rho, [0.05, 0.07, 0.2], rtol=1e-12)
    np.testing.assert_allclose(lR[:, 0], -2.0 * np.log(rho), rtol=1e-12)
    assert float(pm.logp(fc["rho_signed"], np.array([-0.1, 0.3])).sum().eval({fc["rho_scale"]: 0.4})) == \
        pytest.approx(stats.norm(scale=0.4).logpdf([-0.1, 0.3]).sum(), rel=1e-10)
    with pytest.raises(ValueError, match="folded"):
        DelayedForm(rho="partial")
    with pytest.raises(ValueError, match="R_population"):
        DelayedPriors(R_population="flat")


def test_unpooled_baseline_R(plant, study):
    """DelayedPriors(R_population="unpooled"): each subject's baseline log R ~ N(m, s) on its own (no μ_R, σ_R);
    the level changes are the lognormal model's; the LOSO density of log R is that N(m, s) under every draw."""
    from scipy import stats

    from scioc.models.bayes.delayed_loo import DelayedSubjectTerms
    from scioc.models.bayes.delayed_model import DelayedPriors
    from scioc.models.bayes.hierarchical import Priors

    w = study
    dp = DelayedPriors(R_population="unpooled")
    m, s = dp.unpooled_log_R_prior(Priors(mu_log_R=(2.0, 0.6), sigma_log_R=0.8))
    assert (m, s) == (2.0, pytest.approx(1.0, rel=1e-12))
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, delayed_priors=dp)
    lognormal = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay)
    names = {v.name for v in model.free_RVs}
    assert names - {v.name for v in lognormal.free_RVs} == {"log_R_base"}
    assert {v.name for v in lognormal.free_RVs} - names == {"mu_log_R", "sigma_log_R", "z_log_R_MC"}
    m, s = dp.unpooled_log_R_prior(Priors())
    x = np.array([1.0, 3.0, 6.0])
    assert float(pm.logp(model["log_R_base"], x).sum().eval()) == \
        pytest.approx(stats.norm(m, s).logpdf(x).sum(), rel=1e-12)
    point = _point(model, 5)
    outs = model.replace_rvs_by_values([model[v] for v in ("log_R", "beta_log_R", "sigma_beta_log_R")])
    lR, bR, sbR = model.compile_fn(outs, inputs=model.value_vars, on_unused_input="ignore")(point)
    np.testing.assert_allclose(lR[:, 0], point["log_R_base"], rtol=1e-12)
    np.testing.assert_allclose(lR[:, 1], lR[:, 0] + bR + sbR * point["z_log_R_SC"], rtol=1e-12)
    post = {"tau_nm": np.full((2, 3), 0.05), "sigma_m": np.full((2, 3), 0.2), "tau_nm_scale": np.full(2, 0.1),
            "sigma_m_scale": np.full(2, 0.3)}
    batch = prepare_batch(plant, w.segments)
    terms = DelayedSubjectTerms(post, batch, plant, w.delay, baseline_log_R_prior=(m, s))
    got = terms.baseline_log_R_logpdf(x)
    assert got.shape == (2, 3)
    np.testing.assert_allclose(got, np.tile(stats.norm(m, s).logpdf(x), (2, 1)), rtol=1e-12)
    with pytest.raises(ValueError, match="policy_scale"):
        DelayedSubjectTerms({**post, "rho_scale": np.ones(2)}, batch, plant, w.delay, baseline_log_R_prior=(m, s))


@pytest.mark.validation
def test_short_fit_recovers_lag_and_motor_noise(plant):
    """4 subjects of the delayed human (each its own lag; motor noise 0.25 N·m), 2 chains × 300 draws: every
    subject's τ_nm and σ_m inside its 94 % interval, and the negative control (a max-ent human) finds σ_m far below.

    False-failure budget: with calibrated 94 % intervals, 8 intervals all cover with probability
    0.94^8 = 0.61 if independent; they are not miscalibrated in the other direction either, so the
    test asks for at least 6 of 8 (P(fewer) < 2 % at 0.94 each).
    """
    w = delayed_windows(4, np.random.default_rng(11), K=1500, preview=200)
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, tau0=w.tau0)
    idata = pm.sample(draws=300, tune=300, chains=2, cores=2, random_seed=12, nuts_sampler="nutpie", model=model,
                      progressbar=False)
    post = idata["posterior"]
    covered = 0
    for name, truth in (("tau_nm", w.tau_nm[::2]), ("sigma_m", w.sigma_m[::2])):
        x = post[name].values.reshape(-1, 4)
        lo, hi = np.quantile(x, 0.03, axis=0), np.quantile(x, 0.97, axis=0)
        covered += int(((lo <= truth) & (truth <= hi)).sum())
    assert covered >= 6, covered
    # Negative control: the same model on data without motor noise gives a σ_m far below 0.25.
    quiet = delayed_windows(4, np.random.default_rng(11), K=1500, preview=200, sigma_m=(0.0, 0.0))
    m0 = build_delayed_model(quiet.subjects, quiet.conditions, quiet.segments, plant, delay=quiet.delay,
                             delayed_form=DelayedForm("centred", "noncentred"))  # σ_m near 0: non-centred
    i0 = pm.sample(draws=300, tune=300, chains=2, cores=2, random_seed=12, nuts_sampler="nutpie", model=m0,
                   progressbar=False)
    assert float(np.quantile(i0["posterior"]["sigma_m"].values, 0.97)) < 0.1


@pytest.mark.validation
def test_sampled_delays_give_the_fixed_delay_model_at_each_index(plant, study):
    # delay=None: a delay index per subject, uniform over the grid. At any index the log density is the fixed-delay
    # model's at those delays plus the uniform prior, and the step's per-subject log-likelihoods sum to u_H's.
    from scioc.models.bayes.delayed_model import DELAY_INDEX, delay_step

    w = study
    grid = np.arange(0, 16, 3)
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=None, delay_grid=grid, tau0=w.tau0)
    point = _point(model, 5)
    idx = index_study(w.subjects, w.conditions)
    logp = model.compile_logp(mode="FAST_COMPILE")
    for chosen in ([0, 5, 2], [4, 4, 1]):
        pt_ = {**point, DELAY_INDEX: np.array(chosen)}
        fixed = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=grid[chosen][idx.subject_idx],
                                    tau0=w.tau0)
        ref = fixed.compile_logp(mode="FAST_COMPILE")({k: v for k, v in pt_.items() if k != DELAY_INDEX})
        assert logp(pt_) == pytest.approx(ref - 3 * np.log(grid.shape[0]), rel=RTOL)
        step = delay_step(model)
        per_subject = step.loglik(pt_)
        u_h = model.compile_fn(model.logp(vars=[model["u_H"]], sum=True), inputs=model.value_vars,
                               on_unused_input="ignore")(pt_)
        assert per_subject.shape == (3,) and float(per_subject.sum()) == pytest.approx(float(u_h), rel=RTOL)
    assert logp({**point, DELAY_INDEX: np.array([0, 5, 2])}) != pytest.approx(logp({**point, DELAY_INDEX:
                                                                                    np.array([1, 5, 2])}), rel=1e-6)
    with pytest.raises(ValueError, match="delay_grid"):
        build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=None)
    with pytest.raises(ValueError, match="fixed"):
        delay_step(build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay))
