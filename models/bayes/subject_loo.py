"""Leave-one-subject-out predictive densities of the hierarchical model, by integrated importance sampling.

PSIS-LOO over segments fails here (a segment holds all the data on its unit's θ), and the comparison's question
is about new subjects. With unit parameters φ_i and population parameters ψ::

    p(y_i | y_-i) = E_{ψ ~ p(ψ | y_-i)} [ p(y_i | ψ) ],   p(y_i | ψ) = ∫ p(y_i | φ) p(φ | ψ) dφ.

Leaving one subject out barely moves ψ, so PSIS over the draws of ψ with ``log p(y_i | ψ_s)`` as the pointwise
term is reliable (Vehtari et al. 2016, Section 3.4; Merkle, Furr and Rabe-Hesketh 2019). The inner integral is
importance sampling, the same M points for every ψ_s: a Student-t fitted to the subject's draws of
(log θ1, log R), and for θ2 >= 0 a defensive mixture of fitted half-t's and the population's half-normals on a
grid of τ (τ's posterior spreads over orders of magnitude where the data leave θ2 at the prior's scale).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import special, stats

from scioc.models.cost import from_normalized
from scioc.models.maxent import loglik_grad
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Student-t degrees of freedom of the proposals.
NU = 4.0
#: Proposal scale relative to the posterior spread.
INFLATE = 1.5
#: Points of the geometric τ grid in the θ2 proposal.
TAU_GRID = 64
_LOG_SQRT_2PI = 0.5 * np.log(2.0 * np.pi)


class SubjectLoglik(NamedTuple):
    """Integrated log-likelihood ``loglik`` (S, n_subjects), nats, of each subject's data under each population draw,
    with the inner integral's importance-sampling ESS (``is_ess``, smallest over ψ_s; ``is_ess_loo``, of the weights
    averaged with the leave-one-out weights ∝ 1 / p(y_i | ψ_s)) and the points not representable (``n_outside``)."""

    loglik: np.ndarray
    is_ess: np.ndarray
    n_outside: np.ndarray
    is_ess_loo: np.ndarray


def _norm(x, m, s):
    return -0.5 * ((x - m) / s) ** 2 - np.log(s) - _LOG_SQRT_2PI


def _halfnorm(x, s):
    return np.log(2.0) + _norm(x, 0.0, s)


def _mvt_draw(rng, mean, cov, M):
    d = mean.shape[0]
    chol = np.linalg.cholesky(cov)
    z = rng.standard_normal((M, d))
    w = rng.chisquare(NU, M) / NU
    return mean + (z @ chol.T) / np.sqrt(w)[:, None], chol


def _mvt_logpdf(x, mean, chol):
    d = mean.shape[0]
    y = np.linalg.solve(chol, (x - mean).T).T
    maha = np.sum(y * y, axis=1)
    return (special.gammaln((NU + d) / 2) - special.gammaln(NU / 2) - 0.5 * d * np.log(NU * np.pi)
            - np.sum(np.log(np.diag(chol))) - 0.5 * (NU + d) * np.log1p(maha / NU))


def _segment_loglik(batch: SegmentBatch, j: int, plant: DiscretePlant, lt1, lR, t2, chunk: int = 256):
    """Exact log-likelihood of segment j at M points (θ1 = exp(lt1), R = exp(lR), θ2)."""
    M = lt1.shape[0]
    out = np.empty(M)
    for a in range(0, M, chunk):
        b = min(M, a + chunk)
        n = b - a
        rep = batch.repeat(j, n)
        theta = from_normalized(np.exp(lt1[a:b]), t2[a:b], np.exp(lR[a:b]))
        out[a:b] = loglik_grad(theta, rep, plant).loglik
    return out


def representable(lt, lR, t2, extra=None, z=None) -> np.ndarray:
    """(M,) bool: the points whose cost (every level) and ``extra`` parameters are finite. Elsewhere the prior
    factor underflows long before, so weight 0 is the integrand's floating-point value, not an approximation."""
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        R = np.exp(lR)
        ok = np.all(np.isfinite(from_normalized(np.exp(lt), t2, R)), axis=(0, 2)) & np.all(R > 0, axis=1)
    if extra is not None and hasattr(extra, "representable"):
        ok &= extra.representable(z)
    return ok


def subject_loglik(post: dict, batch: SegmentBatch, subject_idx, condition_idx, plant: DiscretePlant,
                   rng: np.random.Generator, *, condition_effects: bool = True, M: int = 2000,
                   extra=None) -> SubjectLoglik:
    """``log p(y_i | ψ_s)`` for every subject i and population draw s (module docstring).

    Parameters
    ----------
    post : dict of ndarray
        Flattened draws (S first): population parameters (S,) or (S, L - 1), unit parameters ``log_theta1``,
        ``log_R``, ``theta2`` (S, n_subjects, L), baseline first.
    batch, subject_idx, condition_idx, plant, rng, M, condition_effects
        The fitted segments, each one's subject and level, the wheel; the proposal's generator and points per subject;
        the condition model, or the pooled one.
    extra : optional
        Another human model's per-subject terms (:class:`scioc.models.bayes.delayed_loo.DelayedSubjectTerms`).
    """
    s_idx = np.asarray(subject_idx)
    c_idx = np.asarray(condition_idx)
    lt_all, lR_all, t2_all = (np.asarray(post[k], dtype=float) for k in ("log_theta1", "log_R", "theta2"))
    S, n_subj, L = lt_all.shape

    def per_level(name):  # (S, L - 1): one column per non-baseline level
        return np.asarray(post[name], dtype=float).reshape(S, L - 1)

    mu, sig = post["mu_log_theta1"][:, None], post["sigma_log_theta1"][:, None]
    betR, sigbR = per_level("beta_log_R"), per_level("sigma_beta_log_R")
    # The subjects' baseline log R: N(μ_R, σ_R), or another human model's population (extra).
    base_R = getattr(extra, "baseline_log_R_logpdf", None)
    if base_R is None:
        muR, sigR = post["mu_log_R"][:, None], post["sigma_log_R"][:, None]
    tau = post["tau_theta2"][:, None]
    if condition_effects:
        beta, sigb = per_level("beta"), per_level("sigma_beta")
    tau_lo, tau_hi = np.min(post["tau_theta2"]) + 1e-300, np.max(post["tau_theta2"]) + 1e-300
    taus = np.geomspace(tau_lo, max(tau_hi, tau_lo), TAU_GRID)
    out = np.empty((S, n_subj))
    ess = np.empty(n_subj)
    ess_loo = np.empty(n_subj)
    outside = np.zeros(n_subj, dtype=np.int64)
    for i in range(n_subj):
        # Gaussian-ish block: log θ1 (one, or one per level) and log R of every level.
        if condition_effects:
            cols = [lt_all[:, i, c] for c in range(L)]
        else:
            cols = [lt_all[:, i, 0]]
        cols += [lR_all[:, i, c] for c in range(L)]
        n_cost = len(cols)
        if extra is not None:
            cols += extra.columns(i)
        draws = np.column_stack(cols)
        mean = draws.mean(axis=0)
        cov = np.cov(draws, rowvar=False) * INFLATE**2 + 1e-12 * np.eye(draws.shape[1])
        x, chol = _mvt_draw(rng, mean, cov, M)
        logq = _mvt_logpdf(x, mean, chol)
        if hasattr(extra, "prior_grid_draw"):
            # Half the points draw these columns from their population; the other columns keep the t's marginal.
            g = n_cost + np.asarray(extra.grid_columns)
            rest = np.setdiff1d(np.arange(x.shape[1]), g)
            from_grid = rng.uniform(size=M) < 0.5
            x[np.ix_(from_grid, g)] = extra.prior_grid_draw(rng, M)[from_grid]
            chol_rest = np.linalg.cholesky(cov[np.ix_(rest, rest)])
            logq = np.logaddexp(_mvt_logpdf(x, mean, chol),
                                _mvt_logpdf(x[:, rest], mean[rest], chol_rest)
                                + extra.prior_grid_logpdf(x[:, g])) - np.log(2.0)
        # θ2 >= 0, every level: defensive mixture of fitted half-t's and the prior on the τ grid.
        scales = INFLATE * np.sqrt(np.mean(t2_all[:, i, :] ** 2, axis=0)) + 1e-300
        from_fit = rng.uniform(size=M) < 0.5
        k = rng.integers(0, TAU_GRID, M)
        t2 = np.where(from_fit[:, None], np.abs(scales * rng.standard_t(NU, (M, L))),
                      np.abs(taus[k][:, None] * rng.standard_normal((M, L))))
        log_fit = np.sum(np.log(2.0) + stats.t.logpdf(t2, NU, scale=scales), axis=1)
        grid = _halfnorm(t2[:, None, 0], taus[None, :])
        for c in range(1, L):
            grid = grid + _halfnorm(t2[:, None, c], taus[None, :])
        log_prior = special.logsumexp(grid, axis=1) - np.log(TAU_GRID)
        logq += np.logaddexp(log_fit, log_prior) - np.log(2.0)
        if condition_effects:
            lt = x[:, :L]
        else:
            lt = np.column_stack([x[:, 0]] * L)
        lR = x[:, n_cost - L : n_cost]
        ok = representable(lt, lR, t2, extra, x[:, n_cost:])
        outside[i] = M - int(ok.sum())
        ll = np.where(ok, 0.0, -np.inf)
        for j in np.flatnonzero(s_idx == i):
            c = int(c_idx[j])
            if extra is None:
                ll[ok] += _segment_loglik(batch, j, plant, lt[ok, c], lR[ok, c], t2[ok, c])
            else:
                ll[ok] += extra.segment_loglik(j, lt[ok, c], lR[ok, c], t2[ok, c], x[ok, n_cost:])
        # Conditional prior of the subject's unit parameters under each population draw (S, M).
        lp = _norm(lt[None, :, 0], mu, sig)
        if condition_effects:
            for c in range(1, L):
                lp = lp + _norm(lt[None, :, c], lt[None, :, 0] + beta[:, c - 1 : c], sigb[:, c - 1 : c])
        lp = lp + (_norm(lR[None, :, 0], muR, sigR) if base_R is None else base_R(lR[:, 0]))
        for c in range(1, L):
            lp = lp + _norm(lR[None, :, c], lR[None, :, 0] + betR[:, c - 1 : c], sigbR[:, c - 1 : c])
        for c in range(L):
            lp = lp + _halfnorm(t2[None, :, c], tau)
        if extra is not None:
            lp = lp + extra.log_prior(x[:, n_cost:])
        logw = lp + (ll - logq)[None, :]
        out[:, i] = special.logsumexp(logw, axis=1) - np.log(M)
        w = np.exp(logw - logw.max(axis=1, keepdims=True))
        wsum = w.sum(axis=1, keepdims=True)
        ess[i] = float(np.min(wsum[:, 0] ** 2 / np.sum(w * w, axis=1)))
        v = np.exp(out[:, i].min() - out[:, i])  # the leave-one-out weights 1 / p(y_i | ψ_s), unnormalized
        pooled = (v / v.sum()) @ (w / wsum)  # (M,), sums to 1
        ess_loo[i] = float(1.0 / np.sum(pooled * pooled))
    return SubjectLoglik(out, ess, outside, ess_loo)


def norm_logpdf(x, m, s):
    """log N(x; m, s²), broadcasting (the conditional priors of the unit parameters)."""
    return _norm(x, m, s)


def halfnorm_logpdf(x, s):
    """log HalfNormal(x; s) for x >= 0, broadcasting."""
    return _halfnorm(x, s)


__all__ = ["SubjectLoglik", "subject_loglik", "representable", "NU", "INFLATE", "halfnorm_logpdf", "norm_logpdf"]
