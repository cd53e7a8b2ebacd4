"""Simulation-based calibration statistics (Talts et al. 2018) on plain arrays.

The rank of the truth among L thinned posterior draws (simuk's: draws strictly below it) is uniform on
{0, ..., L} if simulator, likelihood and sampler are right; the PIT ``(rank + U) / (L + 1)``, U uniform
from the replication's seed, is exactly Uniform(0, 1), so a KS test has its stated size.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats

#: Central interval levels whose coverage is reported.
COVERAGE_LEVELS = (0.5, 0.8, 0.9, 0.95)


def ess_basic(draws: np.ndarray) -> float:
    """ESS of a (chains, draws) array by Geyer's initial positive sequence (no rank normalisation: for thinning)."""
    x = np.asarray(draws, dtype=float)
    if x.ndim == 1:
        x = x[None, :]
    m, n = x.shape
    if n < 4 or not np.all(np.isfinite(x)):
        return float("nan")
    xc = x - x.mean(axis=1, keepdims=True)
    f = np.fft.rfft(xc, n=2 * n, axis=1)
    acov = np.fft.irfft(f * np.conj(f), axis=1)[:, :n] / n  # biased autocovariance per chain
    W = x.var(axis=1, ddof=1).mean()
    B_over_n = x.mean(axis=1).var(ddof=1) if m > 1 else 0.0
    var_plus = W * (n - 1) / n + B_over_n
    if var_plus <= 0:
        return float(m * n)
    rho = 1.0 - (W - acov.mean(axis=0)) / var_plus  # Stan's multi-chain autocorrelation
    rho[0] = 1.0
    total = 0.0
    t = 0
    while t + 1 < n:
        pair = rho[t] + rho[t + 1]
        if pair <= 0:
            break
        total += pair
        t += 2
    tau = -1.0 + 2.0 * total
    return float(m * n / max(tau, 1e-3))


def thin(draws: np.ndarray, L: int) -> tuple[np.ndarray, float]:
    """``(kept, ess)``: L draws, evenly spaced among every ``ceil(N / ESS)``-th of the concatenated chains.

    With ``ess < L`` the kept draws are still autocorrelated; the caller flags the replication.
    """
    x = np.asarray(draws, dtype=float)
    if x.ndim == 1:
        x = x[None, :]
    ess = ess_basic(x)
    flat = x.reshape(-1)
    N = flat.shape[0]
    step = int(np.ceil(N / ess)) if np.isfinite(ess) and ess > 0 else 1
    pool = flat[::max(step, 1)]
    if pool.shape[0] < L:
        pool = flat
    idx = np.round(np.linspace(0, pool.shape[0] - 1, L)).astype(int)
    return pool[idx], float(ess)


def rank(kept: np.ndarray, true: float) -> int:
    """simuk's rank: how many posterior draws lie strictly below the truth."""
    return int(np.sum(np.asarray(kept) < true))


def pit_from_rank(r, L: int, u) -> np.ndarray:
    """Continuous PIT ``(rank + u) / (L + 1)`` with ``u`` uniform on [0, 1)."""
    return (np.asarray(r, dtype=float) + np.asarray(u, dtype=float)) / (L + 1)


def central_coverage(kept: np.ndarray, true: float, levels=COVERAGE_LEVELS) -> np.ndarray:
    """Whether the truth lies in each central interval of the posterior draws."""
    kept = np.asarray(kept, dtype=float)
    out = np.empty(len(levels), dtype=bool)
    for i, lev in enumerate(levels):
        lo, hi = np.quantile(kept, [(1 - lev) / 2, (1 + lev) / 2])
        out[i] = lo <= true <= hi
    return out


class UniformityResult(NamedTuple):
    """Kolmogorov-Smirnov test of PIT values against Uniform(0, 1)."""

    statistic: float
    p_value: float
    alpha: float
    passed: bool


def uniformity_test(pit, alpha: float) -> UniformityResult:
    """Exact KS test of PIT values; ``passed`` if p > alpha (false-failure rate alpha)."""
    pit = np.asarray(pit, dtype=float)
    res = stats.kstest(pit, "uniform")
    return UniformityResult(float(res.statistic), float(res.pvalue), float(alpha), bool(res.pvalue > alpha))


def ecdf_band(n: int, alpha: float = 0.05, *, n_grid: int = 200, n_sim: int = 2000, seed: int = 0):
    """Simultaneous (1 - alpha) band ``(z, lower, upper)`` for ``ECDF(z) - z`` of n uniforms, on a grid of n_grid.

    Säilynoja, Bürkner & Vehtari (2022): the pointwise binomial level γ at which the band holds everywhere
    with probability 1 - alpha, found by simulation with a fixed seed.
    """
    z = (np.arange(1, n_grid + 1)) / (n_grid + 1)
    rng = np.random.default_rng(seed)
    sims = np.sort(rng.uniform(size=(n_sim, n)), axis=1)
    counts = np.stack([np.searchsorted(s, z, side="right") for s in sims])  # (n_sim, n_grid)
    # Smallest pointwise tail probability each simulated ECDF reaches.
    cdf_lo = stats.binom.cdf(counts, n, z)
    cdf_hi = stats.binom.sf(counts - 1, n, z)
    extreme = np.minimum(cdf_lo, cdf_hi).min(axis=1)
    gamma = float(np.quantile(extreme, alpha))
    lower = stats.binom.ppf(gamma / 2, n, z) / n - z
    upper = stats.binom.ppf(1 - gamma / 2, n, z) / n - z
    return z, lower, upper


def contraction(prior_var: float, post_var: np.ndarray) -> float:
    """Mean posterior contraction ``1 - Var_post / Var_prior`` over replications."""
    return float(np.mean(1.0 - np.asarray(post_var, dtype=float) / prior_var))
