"""``scioc compare``: the paper's hypothesis test (Section IV-G, V-A) on identified parameters.

Wilcoxon matched-pairs signed-rank test of θ1 = q11/R (and θ2 = q22/R) between MC and
SC over subjects with both conditions: N non-zero differences, W+ and W−, T = min(W+,
W−), the exact two-sided p-value and the critical value at the chosen α from the exact
null distribution of T (Siegel & Castellan 1988; for N = 42 and α = 0.1 % two-sided it is
195, the paper's P(0.1; 42)), and the matched-pairs rank-biserial effect size
r = (W+ − W−) / (W+ + W−). Zero differences are dropped (Wilcoxon's convention); tied
absolute differences get average ranks, in which case the exact null (which assumes
no ties) is approximate.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import rankdata

from pipelines.io import StudyFileError, read_table, write_text_atomic

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
    """Exact two-sided Wilcoxon matched-pairs signed-rank test of SC − MC.

    Parameters
    ----------
    mc, sc : array_like, shape (n_pairs,)
        Paired values per subject.
    parameter : str
        Name for the report.
    alpha : float
        Two-sided significance level.

    Returns
    -------
    WilcoxonResult
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
    cdf = null_cdf(n)
    p = min(1.0, 2.0 * cdf[int(np.floor(T))])
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


def paired(estimates: pd.DataFrame, column: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """MC and SC values of ``column`` for subjects that have both conditions."""
    wide = estimates.pivot_table(index="subject", columns="condition", values=column, aggfunc="first")
    for c in ("MC", "SC"):
        if c not in wide.columns:
            raise ValueError(f"no {c} estimates: the matched-pairs test needs both conditions")
    wide = wide.dropna(subset=["MC", "SC"])
    return wide["MC"].to_numpy(), wide["SC"].to_numpy(), list(wide.index)


def compare_estimates(estimates: pd.DataFrame, *, alpha: float = ALPHA) -> dict:
    """Signed-rank tests of θ1 and θ2 between MC and SC.

    Returns
    -------
    dict
        ``theta1`` and ``theta2`` results and the subjects left out for lacking a condition.
    """
    out = {}
    subjects_all = sorted(estimates["subject"].unique())
    for col in ("theta1", "theta2"):
        mc, sc, subjects = paired(estimates, col)
        out[col] = asdict(wilcoxon_signed_rank(mc, sc, parameter=col, alpha=alpha))
    out["unpaired_subjects"] = sorted(set(subjects_all) - set(subjects))
    return out


def compare_to_file(estimates_path, out_path, *, alpha: float = ALPHA) -> dict:
    """Read ``estimates.parquet``, test, write ``compare.json`` atomically."""
    df = read_table(estimates_path)
    for col in ("subject", "condition", "theta1", "theta2"):
        if col not in df.columns:
            raise StudyFileError(estimates_path, "required column is missing", column=col)
    res = compare_estimates(df, alpha=alpha)
    write_text_atomic(Path(out_path), json.dumps(res, indent=2) + "\n")
    return res


def format_compare(res: dict) -> str:
    lines = ["Wilcoxon matched-pairs signed-rank test, SC − MC (exact two-sided)"]
    lines.append(f"{'':>10} {'N':>4} {'W+':>8} {'W−':>8} {'T':>8} {'p':>10} {'crit':>6} {'reject':>7} {'r_rb':>7}")
    for col in ("theta1", "theta2"):
        r = res[col]
        crit = "-" if r["critical_value"] is None else str(r["critical_value"])
        lines.append(
            f"{col:>10} {r['n']:>4} {r['w_plus']:>8.1f} {r['w_minus']:>8.1f} {r['T']:>8.1f} {r['p_value']:>10.3g} "
            f"{crit:>6} {str(r['reject']):>7} {r['rank_biserial']:>7.3f}"
        )
    lines.append(f"α = {res['theta1']['alpha']:g}; reject H0 when T <= crit")
    if res["unpaired_subjects"]:
        lines.append(f"left out (one condition only): {', '.join(res['unpaired_subjects'])}")
    return "\n".join(lines)
