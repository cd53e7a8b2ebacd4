import numpy as np
import pandas as pd
import pytest

from pipelines.io import StudyFileError, load_study, segments_to_table, write_table_atomic, write_text_atomic


def small_table(K=20, with_state=True):
    rows = []
    for subject in ("s1", "s2"):
        for cond in ("MC", "SC"):
            t = np.arange(K + 1) * 0.01
            d = {
                "subject": subject,
                "condition": cond,
                "t": t,
                "angle": 0.1 * np.sin(t),
                "angle_ref": 0.1 * np.sin(t + 0.1),
                "u_A": np.zeros(K + 1) if cond == "MC" else 0.05 * np.cos(t),
            }
            if with_state:
                d["velocity"] = 0.1 * np.cos(t)
                d["u_H"] = 0.2 * np.sin(3 * t)
            rows.append(pd.DataFrame(d))
    return pd.concat(rows, ignore_index=True)


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_round_trip(tmp_path, suffix):
    df = small_table()
    path = write_table_atomic(df, tmp_path / f"study{suffix}")
    study = load_study(path)
    assert [(s.subject, s.condition) for s in study.segments] == [("s1", "MC"), ("s1", "SC"), ("s2", "MC"), ("s2", "SC")]
    assert study.segments[1].K == 20
    back = segments_to_table(study.segments)
    pd.testing.assert_frame_equal(back, df, check_dtype=False)


def _expect_error(tmp_path, df, column, row, match, suffix=".parquet"):
    path = tmp_path / f"bad{suffix}"
    if suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        df.to_parquet(path, index=False)
    with pytest.raises(StudyFileError, match=match) as info:
        load_study(path)
    msg = str(info.value)
    assert str(path) in msg
    if column is not None:
        assert f"column '{column}'" in msg
    if row is not None:
        assert f"row {row}" in msg
    return msg


def test_missing_required_column(tmp_path):
    _expect_error(tmp_path, small_table().drop(columns=["angle_ref"]), "angle_ref", None, "missing")


def test_unknown_condition_label(tmp_path):
    df = small_table()
    df.loc[30, "condition"] = "XX"
    _expect_error(tmp_path, df, "condition", 30, "unknown condition label 'XX'")


def test_non_numeric_value_in_csv_names_line(tmp_path):
    df = small_table().astype({"angle": object})
    df.loc[7, "angle"] = "oops"
    msg = _expect_error(tmp_path, df, "angle", 7, "not a finite number", suffix=".csv")
    assert "line 9" in msg


def test_nan_value(tmp_path):
    df = small_table()
    df.loc[12, "u_H"] = np.nan
    _expect_error(tmp_path, df, "u_H", 12, "not a finite number")


def test_non_uniform_time(tmp_path):
    df = small_table()
    df.loc[25:, "t"] += 0.005  # a glitch inside the second segment (rows 21..41)
    _expect_error(tmp_path, df, "t", 25, "uniform 0.01 s")


def test_assistant_torque_in_manual_control(tmp_path):
    df = small_table()
    df.loc[3, "u_A"] = 0.1
    _expect_error(tmp_path, df, "u_A", 3, "manual control")


def test_empty_subject(tmp_path):
    df = small_table()
    df.loc[4, "subject"] = None
    _expect_error(tmp_path, df, "subject", 4, "empty")


def test_unknown_file_type(tmp_path):
    p = tmp_path / "study.xlsx"
    p.write_text("x")
    with pytest.raises(StudyFileError, match="unknown file type"):
        load_study(p)


def test_missing_file(tmp_path):
    with pytest.raises(StudyFileError, match="no such file"):
        load_study(tmp_path / "nope.parquet")


def test_atomic_write_keeps_old_file_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    write_text_atomic(target, "old")

    class Boom(pd.DataFrame):
        def to_parquet(self, *a, **k):
            raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_table_atomic(Boom({"a": [1]}), target)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]
