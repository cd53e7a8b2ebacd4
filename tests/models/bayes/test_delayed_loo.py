"""Leave-one-subject-out terms of the delayed model: its conditional prior is SciPy's, its segment likelihood the
kernel's (τ_0 following the warm-up at each proposed lag), and the integrated log-likelihood is finite."""

import numpy as np
import pytest
from scipy import special, stats

from scioc.models.bayes.delayed_loo import DelayedSubjectTerms
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.bayes.subject_loo import subject_loglik
from scioc.models.cost import from_normalized
from scioc.models.delayed import loglik_grad
from scioc.models.delayed.lag import Warmup, lag_coefficients, window_tau0
from scioc.models.segment import prepare_batch


def _posterior(w, S, rng):
    n_subj = len(set(w.subjects))
    lt = np.log(w.theta[0] / w.theta[2]).reshape(n_subj, 2)
    lR = np.log(w.theta[2]).reshape(n_subj, 2)
    post = {"log_theta1": lt[None] + rng.normal(0, 0.05, (S, n_subj, 2)),
            "log_R": lR[None] + rng.normal(0, 0.05, (S, n_subj, 2)),
            "theta2": np.abs(rng.normal(0, 0.01, (S, n_subj, 2))),
            "tau_nm": w.tau_nm[::2][None] * np.exp(rng.normal(0, 0.05, (S, n_subj))),
            "sigma_m": w.sigma_m[::2][None] * np.exp(rng.normal(0, 0.05, (S, n_subj)))}
    for k, m in (("mu_log_theta1", 3.0), ("mu_log_R", 3.0), ("beta", -0.7), ("beta_log_R", 0.0)):
        post[k] = m + rng.normal(0, 0.05, S)
    for k, m in (("sigma_log_theta1", 0.5), ("sigma_log_R", 0.3), ("sigma_beta", 0.2), ("sigma_beta_log_R", 0.1),
                 ("tau_theta2", 0.05), ("tau_nm_scale", 0.1), ("sigma_m_scale", 0.3)):
        post[k] = m * np.exp(rng.normal(0, 0.1, S))
    return post


@pytest.mark.validation
def test_terms_are_scipys_prior_and_the_kernels_likelihood(plant):
    w = delayed_windows(2, np.random.default_rng(4), K=200, preview=20)
    batch = prepare_batch(plant, w.segments)
    rng = np.random.default_rng(5)
    warm = [Warmup(rng.normal(0, 0.3, 50), 0.2), None, Warmup(rng.normal(0, 0.3, 20), 0.0), None]
    post = _posterior(w, 30, rng)
    terms = DelayedSubjectTerms(post, batch, plant, w.delay, warm, chunk=7)
    z = np.column_stack([np.log(rng.uniform(0.03, 0.12, 20)), np.log(rng.uniform(0.05, 0.4, 20))])
    lp = terms.log_prior(z)
    ref = (stats.halfnorm.logpdf(np.exp(z[:, 0])[None], scale=post["tau_nm_scale"][:, None])
           + stats.halfnorm.logpdf(np.exp(z[:, 1])[None], scale=post["sigma_m_scale"][:, None]) + z.sum(axis=1)[None])
    np.testing.assert_allclose(lp, ref, rtol=1e-12)
    lt1, lR, t2 = np.full(20, 3.0), np.full(20, 3.0), np.full(20, 0.01)
    got = terms.segment_loglik(0, lt1, lR, t2, z)  # segment 0 has a warm-up: τ_0 moves with τ_nm
    for m in range(20):
        tau = float(np.exp(z[m, 0]))
        lag = lag_coefficients(tau)
        t0 = window_tau0([warm[0]], lag.a, lag.alpha)[0][0]
        one = loglik_grad(from_normalized(np.exp(3.0), 0.01, np.exp(3.0)), batch.repeat(0, 1), plant, tau_nm=tau,
                          sigma_m=float(np.exp(z[m, 1])), delay=int(w.delay[0]), tau0=t0).loglik[0]
        assert got[m] == one


def test_integrated_log_likelihood_is_finite_with_the_delayed_terms(plant):
    w = delayed_windows(2, np.random.default_rng(4), K=200, preview=20)
    batch = prepare_batch(plant, w.segments)
    post = _posterior(w, 40, np.random.default_rng(6))
    s_idx, c_idx = np.repeat([0, 1], 2), np.tile([0, 1], 2)
    res = subject_loglik(post, batch, s_idx, c_idx, plant, np.random.default_rng(7), M=200,
                         extra=DelayedSubjectTerms(post, batch, plant, w.delay))
    assert res.loglik.shape == (40, 2) and np.all(np.isfinite(res.loglik))
    assert np.all(res.is_ess > 1.0)


def test_the_lag_population_half_of_the_proposal_is_a_density_and_keeps_the_integral(plant):
    """prior_grid_logpdf is the density prior_grid_draw samples; with it the integral is still the integral.

    Terms whose segment likelihood is the max-ent one (ignoring τ_nm, σ_m): their block then
    integrates to exactly 1 under each population draw, so the leave-one-out density must equal the
    max-ent model's (extra=None) within 4 combined Monte Carlo SEs (1/sqrt(is_ess_loo) each; false
    alarm about 6e-5 per comparison if Gaussian), whatever the proposal, and a wrong density of the
    population half (off by a factor e) must be caught. The setup is the max-ent test's (short
    windows, prior draws as "posterior" draws), with s_τ over more than an order of magnitude.
    """
    from scioc.models.maxent import loglik_grad as maxent_loglik
    from tests.models.bayes.test_subject_loo import _prior_study

    rng = np.random.default_rng(12)
    S = 400
    batch, post = _prior_study(plant, rng, S)
    post["tau_nm_scale"], post["sigma_m_scale"] = np.geomspace(0.01, 0.3, S), np.full(S, 0.3)
    post["tau_nm"] = np.abs(post["tau_nm_scale"][:, None] * rng.standard_normal((S, 2)))
    post["sigma_m"] = np.abs(0.3 * rng.standard_normal((S, 2)))

    class MaxentLikelihood(DelayedSubjectTerms):
        def segment_loglik(self, j, lt1, lR, t2, z):
            theta = from_normalized(np.exp(lt1), t2, np.exp(lR))
            return maxent_loglik(theta, self.batch.repeat(j, lt1.shape[0]), self.plant).loglik

    class WrongDensity(MaxentLikelihood):
        def prior_grid_logpdf(self, z):
            return super().prior_grid_logpdf(z) + 1.0

    terms = MaxentLikelihood(post, batch, plant, np.zeros(batch.n, dtype=np.int64))
    u = np.linspace(-40.0, 3.0, 200_001)
    dens = np.exp(terms.prior_grid_logpdf(u[:, None]))
    assert np.trapezoid(dens, u) == pytest.approx(1.0, abs=1e-6)
    draws = terms.prior_grid_draw(np.random.default_rng(8), 200_000)[:, 0]
    mean = np.trapezoid(u * dens, u)
    sd = np.sqrt(np.trapezoid(u * u * dens, u) - mean**2)
    assert abs(draws.mean() - mean) < 4 * sd / np.sqrt(draws.size)

    def loo(extra, seed):
        r = subject_loglik(post, batch, np.repeat([0, 1], 2), np.tile([0, 1], 2), plant, np.random.default_rng(seed),
                           M=4000, extra=extra)
        return -special.logsumexp(-r.loglik, axis=0) + np.log(S), 1.0 / np.sqrt(r.is_ess_loo)

    (plain, se_p), (mixed, se_m) = loo(None, 9), loo(terms, 10)
    wrong, se_w = loo(WrongDensity(post, batch, plant, np.zeros(batch.n, dtype=np.int64)), 10)
    assert np.all(np.abs(mixed - plain) < 4 * np.hypot(se_m, se_p)), (mixed, plain, se_m, se_p)
    assert np.all(np.abs(wrong - plain) > 4 * np.hypot(se_w, se_p)), (wrong, plain, se_w, se_p)
