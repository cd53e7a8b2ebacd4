"""Adequacy statistics against direct computations, and the combination of p-values."""

import numpy as np
import pytest
from scipy import stats as sps
from statsmodels.tsa.stattools import acf

from scioc.models import adequacy as adq


def test_autocorrelation_matches_statsmodels():
    x = np.random.default_rng(1).standard_normal((3, 200)).cumsum(axis=1)
    got = adq.autocorrelation(x, 7)
    for row, g in zip(x, got):
        np.testing.assert_allclose(g, acf(row, nlags=7, fft=False)[1:], rtol=1e-12, atol=1e-14)


def test_cross_correlation_matches_direct_sum():
    rng = np.random.default_rng(2)
    e, u = rng.standard_normal((2, 4, 97))
    got = adq.cross_correlation(e, u, 12)
    for i in range(4):
        ec, uc = e[i] - e[i].mean(), u[i] - u[i].mean()
        den = np.sqrt(np.sum(ec**2) * np.sum(uc**2))
        want = [sum(ec[k - lag] * uc[k] for k in range(lag, 97)) / den for lag in range(13)]
        np.testing.assert_allclose(got[i], want, rtol=1e-12, atol=1e-14)


def test_band_log_power_matches_explicit_dft():
    rng = np.random.default_rng(3)
    u = rng.standard_normal((2, 64))
    dt = 0.01
    got = adq.band_log_power(u, dt, bands=((0.0, 10.0), (10.0, 25.0), (25.0, 50.0)))
    freq = np.arange(33) / (64 * dt)
    k = np.arange(64)
    for i in range(2):
        uc = u[i] - u[i].mean()
        power = np.array([abs(np.sum(uc * np.exp(-2j * np.pi * m * k / 64))) ** 2 for m in range(33)])
        for j, (lo, hi) in enumerate(((0.0, 10.0), (10.0, 25.0), (25.0, 50.0))):
            sel = (freq > lo) & (freq <= hi)
            assert got[i, j] == pytest.approx(np.log(power[sel].sum() / 64), rel=1e-12)


def test_coverage_matches_ranks():
    x = np.random.default_rng(4).standard_normal((20, 50))
    got = adq.coverage(x, 0.9)
    ranks = np.argsort(np.argsort(x, axis=0), axis=0)  # continuous data: no ties
    np.testing.assert_allclose(got, ((ranks >= 1) & (ranks <= 18)).mean(axis=1))
    assert got.mean() == pytest.approx(18 / 20)  # every sample has exactly 18 rows inside


def test_discrepancy_and_exceedance():
    s = np.array([0.0, 1.0, 2.0, 3.0, 10.0])
    T = adq.discrepancy(s)  # |s - 3.2|
    np.testing.assert_allclose(T, [3.2, 2.2, 1.2, 0.2, 6.8])
    np.testing.assert_allclose(adq.exceedance(T), [0.4, 0.6, 0.8, 1.0, 0.2])
    v = np.array([[0.0, 0.0], [1.0, 2.0], [2.0, 4.0]])
    np.testing.assert_allclose(adq.discrepancy(v), [2.0, 0.0, 2.0])  # standardized per column


def test_fisher_matches_scipy():
    p = np.array([0.02, 0.5, 0.9, 0.04])
    assert adq.fisher(p) == pytest.approx(sps.combine_pvalues(p, method="fisher").pvalue, rel=1e-12)


def test_study_verdict_bonferroni():
    ok = {k: np.full(10, 0.5) for k in adq.STATISTICS}
    assert adq.study_verdict(ok, np.full(10, 0.5))["verdict"] == "pass"
    bad = dict(ok, xcorr=np.full(10, 0.02))
    res = adq.study_verdict(bad, np.full(10, 0.5))
    assert res["verdict"] == "fail" and res["failed_checks"] == ["xcorr"]
