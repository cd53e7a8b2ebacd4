"""Model adequacy: does the fitted human model describe the recorded data?

Per segment, at the fitted θ, the recorded data against B replicates drawn through the same acquisition
chain (:mod:`scioc.models.bootstrap`; Gelman, Meng & Stern 1996), by ``whiteness`` (autocorrelation of the
standardized residuals ``z_k = v_k √(2 S_k)``, iid N(0, 1) under the model), ``variance`` (log mean z²),
``xcorr`` (tracking error -> torque, where a delay shows), ``spectrum`` (torque band powers) and the
pointwise predictive ``coverage_angle``, ``coverage_torque``. A segment's p-values combine by min-P
(Westfall & Young 1993), segments by Fisher's method per statistic with Bonferroni across
(docs/decisions/maxent-adequacy-bootstrap.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats as sps

from scioc.models.bootstrap import Records

#: Autocorrelation lags of the residuals, s (10 lags at 100 Hz; the count scales with the rate).
WHITENESS_SECONDS = 0.1
#: Cross-correlation lags of tracking error -> torque, s.
XCORR_SECONDS = 0.3
#: Torque spectrum bands, Hz.
BANDS_HZ = ((0.0, 0.5), (0.5, 1.5), (1.5, 4.0), (4.0, 10.0), (10.0, 50.0))
#: Central probability of the pointwise predictive bands.
COVERAGE = 0.9
#: Per-segment false-alarm budget of the min-P combined p-value.
SEGMENT_ALPHA = 0.05
#: Family-wise false-alarm budget of the study verdict (Fisher per statistic, Bonferroni across).
STUDY_ALPHA = 0.01
#: Default number of bootstrap data sets per segment (p-values on a grid of 1/50).
N_BOOT = 49
#: The statistics, in report order.
STATISTICS = ("whiteness", "variance", "xcorr", "spectrum", "coverage_angle", "coverage_torque")



def autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """Sample autocorrelation at lags 1..``lags`` of each row (the biased estimator, as statsmodels' acf)."""
    return cross_correlation(x, x, lags)[..., 1:]


def cross_correlation(e: np.ndarray, u: np.ndarray, lags: int) -> np.ndarray:
    """``corr(e_{k-l}, u_k)`` at lags 0..``lags`` of each row pair (normalized by the full sums; zero-padded FFT)."""
    ec = e - e.mean(axis=-1, keepdims=True)
    uc = u - u.mean(axis=-1, keepdims=True)
    den = np.sqrt(np.sum(ec * ec, axis=-1) * np.sum(uc * uc, axis=-1))
    n = u.shape[-1]
    m = 1 << int(np.ceil(np.log2(n + lags + 1)))  # long enough that lags 0..lags do not wrap around
    c = np.fft.irfft(np.fft.rfft(uc, m, axis=-1) * np.conj(np.fft.rfft(ec, m, axis=-1)), m, axis=-1)
    return c[..., : lags + 1] / den[..., None]


def band_log_power(u: np.ndarray, dt: float, bands=BANDS_HZ) -> np.ndarray:
    """Log of the periodogram's power of each row in each band (demeaned; one-sided, unnormalized sums)."""
    uc = u - u.mean(axis=-1, keepdims=True)
    power = np.abs(np.fft.rfft(uc, axis=-1)) ** 2
    freq = np.fft.rfftfreq(u.shape[-1], dt)
    out = []
    for lo, hi in bands:
        sel = (freq > lo) & (freq <= hi) if lo > 0 else (freq > 0) & (freq <= hi)
        out.append(np.log(np.sum(power[..., sel], axis=-1) / u.shape[-1] + 1e-300))
    return np.stack(out, axis=-1)


def coverage(x: np.ndarray, prob: float = COVERAGE) -> np.ndarray:
    """Fraction of samples at which each row lies inside the pointwise central band of all rows.

    The band runs from the ``lo``-th to the ``(n - 1 - lo)``-th smallest row, ``lo = ⌊(1 - prob) n / 2⌋``:
    a symmetric function of all rows, so exchangeable rows have exchangeable coverages.
    """
    n = x.shape[0]
    lo = int(np.floor(0.5 * (1.0 - prob) * n + 1e-9))
    part = np.partition(np.ascontiguousarray(x.T), (lo, n - 1 - lo), axis=1)  # rows contiguous: faster
    inside = (x >= part[:, lo]) & (x <= part[:, n - 1 - lo])
    return inside.mean(axis=1)


def statistics(rec: Records, dt: float) -> dict:
    """Every statistic of every row: arrays of shape (n,) or (n, d)."""
    return {
        "whiteness": autocorrelation(rec.z, max(1, round(WHITENESS_SECONDS / dt))),
        "variance": np.log(np.mean(rec.z * rec.z, axis=1)),
        "xcorr": cross_correlation(rec.error[:, :-1], rec.torque, max(1, round(XCORR_SECONDS / dt))),
        "spectrum": band_log_power(rec.torque, dt),
        "coverage_angle": coverage(rec.angle),
        "coverage_torque": coverage(rec.torque),
    }


def discrepancy(s: np.ndarray) -> np.ndarray:
    """T per row: the standardized squared distance from the mean over rows (|·| for scalars)."""
    s = np.asarray(s, dtype=float)
    mean = s.mean(axis=0)
    if s.ndim == 1:
        return np.abs(s - mean)
    sd = s.std(axis=0, ddof=1)
    sd = np.where(sd > 0, sd, 1.0)
    return np.sum(((s - mean) / sd) ** 2, axis=1)


def exceedance(T: np.ndarray) -> np.ndarray:
    """p per row: the fraction of rows whose T is at least as large (each row counts itself)."""
    srt = np.sort(T)
    return (T.shape[0] - np.searchsorted(srt, T, side="left")) / T.shape[0]


class SegmentAdequacy(NamedTuple):
    """Adequacy of one segment: per-statistic p-values ``p``, the min-P ``p_segment`` (flag at
    <= :data:`SEGMENT_ALPHA`), the recorded data's statistics ``observed`` and their ``null_mean`` over B + 1."""

    p: dict
    p_segment: float
    observed: dict
    null_mean: dict


def segment_adequacy(rec: Records, dt: float) -> SegmentAdequacy:
    """Per-statistic and combined p-values of row 0 of ``rec`` against the other rows."""
    st = statistics(rec, dt)
    P = np.column_stack([exceedance(discrepancy(st[name])) for name in STATISTICS])
    # Min-P, ties broken by the next smallest p-value (lexicographic: still a symmetric rule).
    key = [tuple(row) for row in np.sort(P, axis=1)]
    p_seg = float(np.mean([k <= key[0] for k in key]))
    return SegmentAdequacy(
        p={name: float(P[0, j]) for j, name in enumerate(STATISTICS)},
        p_segment=p_seg,
        observed={name: np.asarray(st[name][0]).tolist() for name in STATISTICS},
        null_mean={name: np.asarray(st[name].mean(axis=0)).tolist() for name in STATISTICS},
    )


def fisher(p) -> float:
    """Fisher's combined p-value of independent p-values (χ² with 2n degrees of freedom)."""
    p = np.asarray(p, dtype=float)
    return float(sps.chi2.sf(-2.0 * np.sum(np.log(p)), 2 * p.shape[0]))


def study_verdict(p_by_stat: dict, p_segment, *, study_alpha: float = STUDY_ALPHA,
                  segment_alpha: float = SEGMENT_ALPHA) -> dict:
    """Combine segments' p-values (each statistic's and min-P's, arrays of n_segments): Fisher per
    statistic, Bonferroni across. A dict with ``verdict`` ("pass"/"fail"), ``failed_checks``, the combined
    p-values and thresholds, and the flagged segments against those expected by chance."""
    names = list(p_by_stat)
    level = study_alpha / len(names)
    combined = {name: fisher(p_by_stat[name]) for name in names}
    failed = [name for name in names if combined[name] <= level]
    ps = np.asarray(p_segment, dtype=float)
    return {
        "verdict": "fail" if failed else "pass",
        "failed_checks": failed,
        "combined_p": combined,
        "study_alpha": study_alpha,
        "per_check_level": level,
        "segment_alpha": segment_alpha,
        "segments": int(ps.shape[0]),
        "segments_flagged": int(np.sum(ps <= segment_alpha)),
        "segments_flagged_expected_by_chance": float(segment_alpha * ps.shape[0]),
    }
