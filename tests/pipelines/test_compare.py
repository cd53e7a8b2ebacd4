import json

import numpy as np
import pandas as pd
import pytest
from scipy.stats import wilcoxon

from scioc.pipelines.cli import main
from scioc.pipelines.compare import compare_estimates, compare_to_file, format_compare
from scioc.pipelines.io import StudyFileError
from scioc.pipelines.signed_rank import critical_value, null_cdf, wilcoxon_signed_rank


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


def test_statistic_and_p_value_equal_scipy_on_the_papers_sample_size():
    # N = 42 pairs, as in the paper; T and the two-sided exact p-value are scipy's own.
    rng = np.random.default_rng(42)
    mc = rng.lognormal(3.0, 0.5, 42)
    sc = mc * rng.lognormal(-0.1, 0.3, 42)
    ours = wilcoxon_signed_rank(mc, sc)
    ref = wilcoxon(sc - mc, method="exact")
    assert ours.n == 42 and not ours.ties
    assert ours.T == ref.statistic
    assert ours.p_value == ref.pvalue
    assert ours.critical_value == 195 and ours.reject == (ours.T <= 195)


def _write(tmp_path, df, name="estimates.parquet"):
    path = tmp_path / name
    df.to_parquet(path, index=False)
    return path


def test_duplicated_subject_condition_is_an_error_naming_file_and_rows(tmp_path):
    df = _estimates([f"S{i}" for i in range(6)])
    df = pd.concat([df, df.iloc[[2]]], ignore_index=True)  # S1 MC again, as row 12
    path = _write(tmp_path, df)
    with pytest.raises(StudyFileError, match=r"S1, condition MC appears in rows 2, 12") as info:
        compare_to_file(path, tmp_path / "compare.json")
    assert str(path) in str(info.value)
    assert not (tmp_path / "compare.json").exists()


@pytest.mark.parametrize("value, reason", [(np.nan, "theta1 = nan is not a finite positive number"),
                                           (-3.0, "theta1 = -3 is not a finite positive number"),
                                           (0.0, "theta1 = 0 is not a finite positive number"),
                                           (np.inf, "theta1 = inf is not a finite positive number")])
def test_bad_theta1_leaves_the_unit_out_with_its_reason(value, reason):
    df = _estimates([f"S{i}" for i in range(8)])
    df.loc[(df.subject == "S3") & (df.condition == "SC"), "theta1"] = value
    res = compare_estimates(df)
    assert res["excluded"] == [{"subject": "S3", "condition": "MC", "reason": "its SC estimate is left out"},
                               {"subject": "S3", "condition": "SC", "reason": reason}]
    assert res["theta1"]["n_pairs"] == res["theta2"]["n_pairs"] == 7


def test_nonconverged_units_are_left_out_unless_asked_for():
    df = _estimates([f"S{i}" for i in range(8)]).assign(converged=True, message="ok")
    df.loc[(df.subject == "S5") & (df.condition == "MC"), ["converged", "message"]] = (False, "iteration limit")
    res = compare_estimates(df)
    assert {"subject": "S5", "condition": "MC", "reason": "identification did not converge (iteration limit)"} \
        in res["excluded"]
    assert res["theta1"]["n_pairs"] == 7 and not res["include_nonconverged"]
    res = compare_estimates(df, include_nonconverged=True)
    assert res["excluded"] == [] and res["theta1"]["n_pairs"] == 8 and res["include_nonconverged"]


def test_exclusions_are_in_the_json_and_printed(tmp_path, capsys):
    df = _estimates([f"S{i}" for i in range(8)]).assign(converged=True)
    df.loc[3, "converged"] = False  # S1 SC
    path = _write(tmp_path, df)
    assert main(["compare", str(path)]) == 0
    out = capsys.readouterr().out
    assert "left out of the test (2 units)" in out and "S1 SC: identification did not converge" in out
    res = json.loads((tmp_path / "compare.json").read_text())
    assert res["excluded"][1] == {"subject": "S1", "condition": "SC", "reason": "identification did not converge"}
    assert main(["compare", str(path), "--include-nonconverged", "--out", str(tmp_path / "all.json")]) == 0
    assert json.loads((tmp_path / "all.json").read_text())["theta1"]["n_pairs"] == 8


def test_no_nonzero_difference_gives_valid_json(tmp_path):
    df = _estimates(["S1", "S2"]).assign(theta1=5.0)
    path = _write(tmp_path, df)
    res = compare_to_file(path, tmp_path / "c.json")
    assert res["theta1"]["rank_biserial"] is None
    json.loads((tmp_path / "c.json").read_text())  # strict JSON: no NaN


def test_compare_refuses_to_overwrite_its_input(tmp_path, capsys):
    path = _write(tmp_path, _estimates(["S1", "S2", "S3"]))
    before = path.read_bytes()
    assert main(["compare", str(path), "--out", str(path)]) == 2
    assert "is the estimates file itself" in capsys.readouterr().err
    (tmp_path / "link.parquet").symlink_to(path)
    assert main(["compare", str(tmp_path / "link.parquet"), "--out", str(path)]) == 2
    assert path.read_bytes() == before


def test_unknown_condition_in_estimates_names_the_row(tmp_path, capsys):
    df = _estimates(["S1", "S2"])
    df.loc[1, "condition"] = "shared"
    path = _write(tmp_path, df)
    assert main(["compare", str(path)]) == 3
    err = capsys.readouterr().err
    assert str(path) in err and "column 'condition', row 1" in err


def test_adequacy_columns_give_the_identify_verdict_and_bad_ones_are_named():
    from scioc.models.adequacy import STATISTICS, study_verdict

    est = _estimates([f"S{i}" for i in range(6)])
    rng = np.random.default_rng(3)
    p = {k: rng.integers(1, 51, len(est)) / 50 for k in STATISTICS}
    est = est.assign(adequacy_p=rng.integers(1, 51, len(est)) / 50, **{f"adequacy_p_{k}": v for k, v in p.items()})
    res = compare_estimates(est)
    expected = study_verdict(p, est["adequacy_p"].to_numpy())
    assert {k: res["adequacy"][k] for k in expected} == expected
    assert res["adequacy"]["human_model"] == "maxent" and "residual whiteness" in res["adequacy"]["checks"]["whiteness"]
    # the human model behind the estimates is named, with the wording of its checks
    delayed = compare_estimates(est.assign(human_model="delayed"))["adequacy"]
    assert delayed["human_model"] == "delayed" and "innovation" in delayed["checks"]["whiteness"]
    assert "human model: delayed" in format_compare(compare_estimates(est.assign(human_model="delayed")))
    with pytest.raises(ValueError, match="mix human models"):
        compare_estimates(est.assign(human_model=["maxent", "delayed"] * (len(est) // 2)))
    bad = est.copy()
    bad.loc[2, "adequacy_p_xcorr"] = 1.5
    with pytest.raises(StudyFileError, match=r"est\.parquet, column 'adequacy_p_xcorr', row 2"):
        compare_estimates(bad, path="est.parquet")
    assert compare_estimates(est.drop(columns=["adequacy_p"]))["adequacy"]["verdict"] == "not checked"
