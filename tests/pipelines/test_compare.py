import numpy as np
import pandas as pd
import pytest
from scipy.stats import wilcoxon

from pipelines.compare import compare_estimates, critical_value, null_cdf, wilcoxon_signed_rank


def test_paper_critical_value():
    # Section V-A: N = 42, α = 0.1 % two-sided -> P(0.1; 42) = 195.
    assert critical_value(42, 0.001) == 195


@pytest.mark.parametrize("n, alpha, table", [(10, 0.05, 8), (20, 0.05, 52), (25, 0.01, 68), (6, 0.05, 0)])
def test_critical_values_match_published_tables(n, alpha, table):
    # Two-sided critical values of T from standard tables (e.g. Siegel & Castellan 1988, Table H).
    assert critical_value(n, alpha) == table


def test_exact_null_is_a_distribution():
    cdf = null_cdf(12)
    assert cdf[-1] == pytest.approx(1.0)
    assert np.all(np.diff(cdf) >= 0)


@pytest.mark.parametrize("seed", range(5))
def test_p_value_matches_scipy_exact(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=18)
    b = a + rng.normal(0.4, 1.0, 18)
    ours = wilcoxon_signed_rank(a, b)
    ref = wilcoxon(b - a, method="exact")
    assert ours.p_value == pytest.approx(ref.pvalue, rel=1e-12)
    assert ours.T == ref.statistic
    assert ours.rank_biserial == pytest.approx((ours.w_plus - ours.w_minus) / (18 * 19 / 2))


def test_all_decreasing_pairs():
    res = wilcoxon_signed_rank(np.arange(1, 43) + 10.0, np.arange(1, 43) * 0.5)
    assert res.T == 0 and res.w_minus == 903 and res.reject and res.rank_biserial == -1.0


def test_zero_differences_are_dropped():
    res = wilcoxon_signed_rank(np.zeros(10), np.zeros(10))
    assert res.n == 0 and not res.reject and res.p_value == 1.0


def _estimates(subjects, conds=("MC", "SC")):
    rows = [{"subject": s, "condition": c, "theta1": 10.0 + i + (5 if c == "MC" else 0), "theta2": 0.0}
            for i, s in enumerate(subjects) for c in conds]
    return pd.DataFrame(rows)


def test_subject_without_a_condition_is_left_out_and_named():
    df = _estimates([f"S{i}" for i in range(8)])
    df = df[~((df.subject == "S3") & (df.condition == "SC"))]
    res = compare_estimates(df)
    assert res["unpaired_subjects"] == ["S3"]
    assert res["theta1"]["n_pairs"] == 7


def test_no_shared_control_is_an_error():
    with pytest.raises(ValueError, match="no SC estimates"):
        compare_estimates(_estimates(["S1", "S2"], conds=("MC",)))
