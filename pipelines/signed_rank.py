"""The exact Wilcoxon matched-pairs signed-rank test and Holm's correction, for ``scioc compare``.

The two-sided p-value is scipy's ``wilcoxon(method="exact")``; scipy has no critical values, so the
one at α comes from the exact null of T here (Siegel & Castellan 1988; N = 42, α = 0.1 %: 195, the
paper's P(0.1; 42)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import rankdata, wilcoxon

#: Default significance level (two-sided), as in the paper.
ALPHA = 0.001


def signed_rank_null_counts(n: int) -> np.ndarray:
    """Number of sign assignments giving each rank sum W+ = 0..n(n+1)/2 (exact null).

    Dynamic programming over ranks: O(n³) integers, exact for any n used in practice.
    """
    top = n * (n + 1) // 2
    counts = np.zeros(top + 1, dtype=object)  # Python ints: 2**42 overflows nothing
    counts[0] = 1
    for r in range(1, n + 1):
        counts[r:] = counts[r:] + counts[: top + 1 - r].copy()
    return counts


def null_cdf(n: int) -> np.ndarray:
    """P(W+ <= w) for w = 0..n(n+1)/2 under H0 (symmetric about zero differences)."""
    c = signed_rank_null_counts(n)
    cum = np.cumsum(c)
    return np.array([float(x) / float(2**n) for x in cum])


def critical_value(n: int, alpha: float) -> int | None:
    """Largest T with P(T <= t) <= alpha/2 per tail (two-sided): reject H0 if T <= it.

    Returns None when even T = 0 is not significant (small n).
    """
    cdf = null_cdf(n)
    ok = np.flatnonzero(cdf <= alpha / 2.0)
    return int(ok[-1]) if ok.size else None


@dataclass(frozen=True)
class WilcoxonResult:
    """The signed-rank test of one parameter, SC minus MC."""

    parameter: str
    n_pairs: int
    n: int
    w_plus: float
    w_minus: float
    T: float
    p_value: float
    alpha: float
    critical_value: int | None
    reject: bool
    rank_biserial: float
    median_difference: float
    ties: bool


def wilcoxon_signed_rank(mc, sc, *, parameter: str = "theta1", alpha: float = ALPHA) -> WilcoxonResult:
    """Exact two-sided Wilcoxon matched-pairs signed-rank test of SC − MC at ``alpha``.

    ``mc`` and ``sc``: shape (n_pairs,), one pair per subject; ``parameter`` names the result.
    """
    mc = np.asarray(mc, dtype=float)
    sc = np.asarray(sc, dtype=float)
    if mc.shape != sc.shape or mc.ndim != 1:
        raise ValueError("mc and sc must be 1-D arrays of equal length (one pair per subject)")
    if not 0 < alpha < 1:
        raise ValueError(f"alpha must be in (0, 1); got {alpha!r}")
    d = sc - mc
    nz = d[d != 0]
    n = int(nz.size)
    if n == 0:
        return WilcoxonResult(parameter, int(d.size), 0, 0.0, 0.0, 0.0, 1.0, alpha, None, False, float("nan"),
                              float(np.median(d)) if d.size else float("nan"), False)
    ranks = rankdata(np.abs(nz))
    ties = bool(np.unique(np.abs(nz)).size < n)
    w_plus = float(ranks[nz > 0].sum())
    w_minus = float(ranks[nz < 0].sum())
    T = min(w_plus, w_minus)
    p = wilcoxon(nz, method="exact").pvalue
    crit = critical_value(n, alpha)
    return WilcoxonResult(
        parameter=parameter,
        n_pairs=int(d.size),
        n=n,
        w_plus=w_plus,
        w_minus=w_minus,
        T=T,
        p_value=float(p),
        alpha=float(alpha),
        critical_value=crit,
        reject=bool(crit is not None and T <= crit),
        rank_biserial=(w_plus - w_minus) / (w_plus + w_minus),
        median_difference=float(np.median(d)),
        ties=ties,
    )


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjusted p-values (family-wise error control for any dependence)."""
    p = np.asarray(p_values, dtype=float)
    order = np.argsort(p, kind="stable")
    adj = np.empty_like(p)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (p.size - rank) * p[i]))
        adj[i] = running
    return adj


__all__ = ["ALPHA", "WilcoxonResult", "critical_value", "holm", "null_cdf", "signed_rank_null_counts",
           "wilcoxon_signed_rank"]
