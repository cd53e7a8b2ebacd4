"""Integrated leave-one-subject-out: the importance-sampling integral against brute force."""

import numpy as np
import pytest
from scipy import special

from scioc.models.bayes.subject_loo import subject_loglik
from scioc.models.maxent import loglik_grad
from scioc.models.segment import prepare_batch
from scioc.models.simulate import Population, simulate_windows

PSI = {"mu_log_theta1": 3.0, "sigma_log_theta1": 0.4, "beta": -0.7, "sigma_beta": 0.2, "mu_log_R": 3.0,
       "beta_log_R": 0.0, "sigma_log_R": 0.3, "sigma_beta_log_R": 0.1, "tau_theta2": 0.05}


def _prior_draws(rng, n, n_subj, condition_effects):
    """Unit parameters from the model's prior given PSI (as a stand-in for posterior draws)."""
    p = PSI
    lt_mc = p["mu_log_theta1"] + p["sigma_log_theta1"] * rng.standard_normal((n, n_subj))
    lt_sc = lt_mc + (p["beta"] + p["sigma_beta"] * rng.standard_normal((n, n_subj)) if condition_effects else 0.0)
    lr_mc = p["mu_log_R"] + p["sigma_log_R"] * rng.standard_normal((n, n_subj))
    lr_sc = lr_mc + p["beta_log_R"] + p["sigma_beta_log_R"] * rng.standard_normal((n, n_subj))
    t2 = p["tau_theta2"] * np.abs(rng.standard_normal((n, n_subj, 2)))
    return np.stack([lt_mc, lt_sc], -1), np.stack([lr_mc, lr_sc], -1), t2


def _prior_study(plant, rng, S, condition_effects=True, K=30, preview=20):
    """Two subjects' max-ent windows and S prior draws given PSI as stand-in posterior draws: (batch, post)."""
    study = simulate_windows(2, rng, Population(), K=K, preview=preview)
    batch = prepare_batch(plant, study.segments)
    lt, lr, t2 = _prior_draws(rng, S, 2, condition_effects)
    return batch, dict(log_theta1=lt, log_R=lr, theta2=t2, **{k: np.full(S, v) for k, v in PSI.items()})


@pytest.mark.parametrize("condition_effects", [True, False])
def test_integral_matches_plain_monte_carlo_over_the_prior(plant, condition_effects):
    # Short windows (K = 30) keep the likelihood broad, so plain Monte Carlo over the
    # conditional prior (200 000 points) is accurate; the importance sampler with 2000
    # points around "posterior" draws must agree within 4 combined standard errors
    # (false-failure rate about 6e-5 per comparison if both errors are Gaussian).
    s_idx = np.repeat([0, 1], 2)
    c_idx = np.tile([0, 1], 2)
    # The proposal is built from the unit draws it is given: hand it 400 prior draws, all
    # with the same population values ψ.
    batch, post = _prior_study(plant, np.random.default_rng(5), 400, condition_effects)
    res = subject_loglik(post, batch, s_idx, c_idx, plant, np.random.default_rng(6),
                         condition_effects=condition_effects, M=2000)
    assert res.loglik.shape == (400, 2)
    assert np.all(res.loglik == res.loglik[0])  # same ψ in every draw -> same value
    N = 200_000
    lt_b, lr_b, t2_b = _prior_draws(np.random.default_rng(7), N, 2, condition_effects)
    for i in range(2):
        ll = np.zeros(N)
        for j in np.flatnonzero(s_idx == i):
            c = c_idx[j]
            R = np.exp(lr_b[:, i, c])
            theta = np.vstack([np.exp(lt_b[:, i, c]) * R, t2_b[:, i, c] * R, R])
            rep = batch.repeat(j, N)
            ll += loglik_grad(theta, rep, plant).loglik
        brute = special.logsumexp(ll) - np.log(N)
        w = np.exp(ll - ll.max())
        se_brute = np.sqrt(np.var(w) / N) / np.mean(w)  # delta method on the log
        se_is = 1.0 / np.sqrt(res.is_ess[i])
        assert se_brute < 0.05 and res.is_ess[i] > 100
        assert abs(res.loglik[0, i] - brute) <= 4 * np.hypot(se_brute, se_is), (res.loglik[0, i], brute)


def test_wrong_population_predicts_worse(plant):
    # Negative control: the integrated likelihood of the subjects must drop when ψ puts the
    # population's log θ1 far from where the data are.
    batch, post = _prior_study(plant, np.random.default_rng(8), 400, K=200, preview=50)
    post["mu_log_theta1"] = np.where(np.arange(400) < 200, 3.0, 6.0)
    res = subject_loglik(post, batch, np.repeat([0, 1], 2), np.tile([0, 1], 2), plant, np.random.default_rng(9))
    assert np.all(res.loglik[:200].mean(axis=0) > res.loglik[200:].mean(axis=0) + 5.0)


def test_points_that_overflow_get_weight_zero_instead_of_stopping(plant):
    # A chain that wandered (the max-ent study's delayed fit: log θ1 from -145 to 68) widens
    # the proposal until its tails reach log θ1 > 709, where q11 = θ1 R overflows; the
    # kernel's θ check then stopped `scioc human-models`. Such points must weigh 0 and be counted.
    from scioc.models.bayes.subject_loo import representable

    lt = np.array([[3.0, 3.0], [710.0, 3.0], [400.0, 3.0], [300.0, 3.0], [3.0, 3.0]])
    lR = np.array([[3.0, 3.0], [3.0, 3.0], [400.0, 3.0], [-300.0, 3.0], [3.0, -800.0]])
    t2 = np.zeros((5, 2))
    assert representable(lt, lR, t2).tolist() == [True, False, False, True, False]
    rng = np.random.default_rng(10)
    batch, post = _prior_study(plant, rng, 400)
    post["log_theta1"][:40, 0, :] = rng.normal(0.0, 300.0, (40, 2))  # a tenth of the draws far out
    res = subject_loglik(post, batch, np.repeat([0, 1], 2), np.tile([0, 1], 2), plant,
                         np.random.default_rng(11), M=2000)
    assert res.n_outside[0] > 0 and res.n_outside[1] == 0
    assert np.all(np.isfinite(res.loglik))


def test_leave_one_out_ess_predicts_the_scatter_of_the_left_out_density(plant):
    """is_ess_loo: the points behind 1 / mean_s(1 / p(y_i | ψ_s)); its 1/sqrt(ESS) is that value's Monte Carlo SE.

    ψ varies over the draws (σ_β and σ_βR down to near 0, where a conditional prior is much
    narrower than the proposal): the inner ESS at the worst draw is far below the ESS behind
    the left-out density, which is at least the ψ-weighted harmonic mean of the inner ESS's and so
    at least their minimum. Repeating the importance sampling with 20 seeds (2000 points), the
    scatter of log p(y_i | y_-i) must be within a factor 2 of the median 1 / sqrt(is_ess_loo)
    either way (the SD of 20 values is within ±45 % of its truth with probability > 0.99; the
    delta method and Kong's ESS are approximations). With 300 points the ESS falls to a few, where
    Kong's ESS overstates and the SE it implies is too small (measured: 1.3 nats against 0.36): that
    regime must stay below pipelines.fit.loo.LOSO_ESS_MIN, which then calls the comparison unreliable.
    """
    from scioc.pipelines.fit.loo import LOSO_ESS_MIN

    S = 200
    batch, post = _prior_study(plant, np.random.default_rng(12), S)
    post["sigma_beta"] = np.geomspace(0.002, 0.4, S)
    post["sigma_beta_log_R"] = np.geomspace(0.002, 0.2, S)[::-1]

    def repeat(M, n):
        loo, ess, worst = [], [], []
        for seed in range(n):
            res = subject_loglik(post, batch, np.repeat([0, 1], 2), np.tile([0, 1], 2), plant,
                                 np.random.default_rng(100 + seed), M=M)
            loo.append(-special.logsumexp(-res.loglik, axis=0) + np.log(S))
            ess.append(res.is_ess_loo)
            worst.append(res.is_ess)
        return np.array(loo), np.array(ess), np.array(worst)

    loo, ess, worst = repeat(2000, 20)
    assert np.all(ess >= worst - 1e-9) and np.all(ess <= 2000)
    predicted = 1.0 / np.sqrt(np.median(ess, axis=0))
    observed = loo.std(axis=0, ddof=1)
    assert np.all((observed > predicted / 2) & (observed < predicted * 2)), (observed, predicted)
    assert np.all(np.median(worst, axis=0) < np.median(ess, axis=0) / 2)
    _, few, _ = repeat(300, 5)
    assert np.all(few < LOSO_ESS_MIN)
