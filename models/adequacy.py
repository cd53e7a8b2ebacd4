"""Model adequacy: does the fitted human model describe the recorded data?

Every cost scioc reports assumes that the human *is* the model it was fitted with. This
module checks that assumption per segment, at the fitted θ, by a parametric bootstrap
through the same acquisition chain (Gelman, Meng & Stern 1996 call the plug-in version of
this a posterior predictive check at the point estimate).

Statistics
----------
Each is computed for the recorded segment and for ``B`` data sets drawn from the fitted
model with the same reference, the same assistant, the same encoder and the same
reconstruction (or, for recorded torques, the same exact measurement):

``whiteness``
    Autocorrelation of the standardized policy residuals ``z_k = v_k √(2 S_k)`` at lags
    from one sample to :data:`WHITENESS_SECONDS` (1..10 at 100 Hz; a portmanteau
    statistic). ``v_k`` is the deviation of the torque from the optimal law at the state driven by the observed torques
    (:mod:`scioc.models.maxent`), so under the model and for the true torque the z_k are iid
    N(0, 1). A reconstructed torque is smoothed, which makes z autocorrelated even under
    the model (lag 1 about 0.3 on the default study); that is why the null comes from the
    bootstrap and the statistic is the standardized distance of the autocorrelation
    vector from the bootstrap's, ``Σ_l ((ρ_l − m_l) / s_l)²`` (Ljung-Box is the special
    case m = 0, s = 1/√n).
``variance``
    ``log mean z²``: the policy noise is as large as R says.
``xcorr``
    Cross-correlation of tracking error (angle − reference) and torque at lags
    0..:data:`XCORR_SECONDS` (0-300 ms: lags 0..30 at 100 Hz): how long after an error the
    torque reacts, which is where a perceptual delay shows.
``spectrum``
    Log power of the torque in the bands :data:`BANDS_HZ`.
``coverage_angle``, ``coverage_torque``
    Plug-in predictive coverage: the fraction of samples at which the recorded angle
    (torque) lies inside the pointwise central :data:`COVERAGE` band of all data sets.

Calibration
-----------
The recorded data set and the B replicates are treated alike: a vector statistic becomes
``T = Σ_j ((s_j − mean_j) / sd_j)²`` with mean and SD over all ``B + 1`` data sets, a
scalar one ``T = |s − mean|``, and each data set's p-value is the fraction of the B + 1
data sets with a T at least as large. If the recorded data are exchangeable with the
replicates (the model holds at θ), that p-value is uniform on {1/(B+1), …, 1} up to ties
(which only make it larger). The per-segment p-value is the single-step min-P
combination over the statistics (Westfall & Young 1993), calibrated by the same B + 1
data sets, so it accounts for the statistics' correlation (ties of the smallest p-value
are broken by the next smallest): a segment is flagged when it
is ≤ :data:`SEGMENT_ALPHA` (false-alarm rate ≤ 5 % per segment). The study verdict
combines the segments per statistic by Fisher's method and fails when any statistic's
combined p-value is ≤ :data:`STUDY_ALPHA` / (number of statistics) (Bonferroni:
family-wise false-alarm rate ≤ 1 %). Fisher's χ² reference is conservative for p-values
on a grid (their mean −log is below 1).

The acquisition chain and its shortcuts are in :mod:`scioc.models.bootstrap`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import stats as sps

from scioc.models.bootstrap import Records

#: Autocorrelation lags of the residuals, s (10 lags of 10 ms at 100 Hz; the lag count scales with the rate).
WHITENESS_SECONDS = 0.1
#: Cross-correlation lags of tracking error -> torque, s (0..300 ms: 30 lags at 100 Hz).
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


# --------------------------------------------------------------------------- statistics


def autocorrelation(x: np.ndarray, lags: int) -> np.ndarray:
    """Sample autocorrelation at lags 1..``lags`` of each row (the biased estimator, as statsmodels' acf)."""
    return cross_correlation(x, x, lags)[..., 1:]


def cross_correlation(e: np.ndarray, u: np.ndarray, lags: int) -> np.ndarray:
    """``corr(e_{k-l}, u_k)`` at lags 0..``lags`` of each row pair (normalized by the full sums).

    Computed for all lags at once with a zero-padded FFT (no circular wrap-around).
    """
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

    The band at each sample runs from the ``lo``-th to the ``(n - 1 - lo)``-th smallest of
    the n rows, ``lo = ⌊(1 - prob) n / 2⌋``. Every row is judged by the same band, a
    symmetric function of all rows, so under exchangeability the rows' coverages are
    exchangeable too (ties, as of encoder angles, only widen the band for everyone).
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
    """Adequacy of one segment.

    Attributes
    ----------
    p : dict
        Bootstrap p-value of each statistic for the recorded data.
    p_segment : float
        Min-P combined p-value (flag when <= :data:`SEGMENT_ALPHA`).
    observed : dict
        The recorded data's statistics (scalars or lists), for the report.
    null_mean : dict
        Their mean over the B + 1 data sets.
    """

    p: dict
    p_segment: float
    observed: dict
    null_mean: dict


def segment_adequacy(rec: Records, dt: float) -> SegmentAdequacy:
    """Per-statistic and combined p-values of row 0 of ``rec`` against the other rows."""
    st = statistics(rec, dt)
    P = np.column_stack([exceedance(discrepancy(st[name])) for name in STATISTICS])
    # Min-P, with ties between equal smallest p-values broken by the next smallest, and so on
    # (a lexicographic order of each data set's sorted p-values: still a symmetric rule).
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
    """Combine segments: Fisher per statistic, Bonferroni across statistics.

    Parameters
    ----------
    p_by_stat : dict of str -> array_like, shape (n_segments,)
    p_segment : array_like, shape (n_segments,)

    Returns
    -------
    dict
        ``verdict`` ("pass" or "fail"), ``failed_checks``, per-statistic combined p-values
        and thresholds, the number of flagged segments and how many are expected by chance.
    """
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
