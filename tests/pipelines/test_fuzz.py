"""Fuzz-style tests: malformed study tables through ``validate_table`` and ``scioc loglik``.

Each case applies one to three seeded mutations to a clean table (column drops, type
changes, NaN and inf injections, shuffles, duplications, unit changes) and asserts one of
two outcomes: a one-line error naming the file with exit status 3 (bad input data), or
exactly the clean table's result. Anything else (a traceback, another exit status, a
different result with exit 0) fails the test. The whole module runs in well under a minute.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scioc.pipelines.cli import main
from scioc.pipelines.io import InputDataError, segments_to_table, validate_table
from tests.pipelines.test_io import small_table

THETA = "60,0.1,1"
#: Generated cases per run (seeded: the same cases every run).
N_CASES = 200
#: Relative change of the log-likelihood allowed after storing the data as float32
#: (float32 keeps about 7 digits of each sample; the rest of the cases must match exactly).
FLOAT32_RTOL = 1e-3


def clean_table() -> pd.DataFrame:
    """small_table at the study's scale (angles and rates peaking near 0.6 rad and 0.6 rad/s,
    torques near 0.2 N·m), so that degrees and N·mm are implausible."""
    df = small_table(K=40)
    return df.assign(angle=6 * df["angle"], angle_ref=6 * df["angle_ref"], velocity=6 * df["velocity"],
                     u_A=6 * df["u_A"])  # the assistant law is linear: it follows the scaled states


NUMERIC = ["t", "angle", "angle_ref", "u_A", "velocity", "u_H"]
COLUMNS = ["subject", "condition", *NUMERIC]


# Mutations: (df, rng) -> (df, approx). approx is True when values changed within float32 precision.
def drop_column(df, rng):
    return df.drop(columns=[rng.choice(COLUMNS)]), False


def extra_column(df, rng):
    return df.assign(note="x"), False


def inject(value):
    def mutate(df, rng):
        df = df.copy()
        col = rng.choice([c for c in COLUMNS if c in df.columns])
        row = int(rng.integers(len(df)))
        if pd.api.types.is_float_dtype(df[col]):
            df.loc[row, col] = value
        else:  # labels, text, times or booleans: a missing value is what such a column can hold
            df[col] = df[col].astype(object)
            df.loc[row, col] = None
        return df, False

    mutate.__name__ = f"inject_{value}"
    return mutate


def _float_column(df, rng):
    """A numeric column still held as plain floats, or None."""
    cols = [c for c in NUMERIC if c in df.columns and pd.api.types.is_float_dtype(df[c])]
    return rng.choice(cols) if cols else None


def numbers_as_text(df, rng):
    col = _float_column(df, rng)
    return (df if col is None else df.assign(**{col: df[col].map(repr)})), False


def to_float32(df, rng):
    col = _float_column(df, rng)
    return (df if col is None else df.assign(**{col: df[col].astype(np.float32)})), col is not None


def to_bool(df, rng):
    col = _float_column(df, rng)
    return (df if col is None else df.assign(**{col: df[col] > 0})), False


def _relabel(df, col, f):
    if col not in df.columns:
        return df
    return df.assign(**{col: df[col].astype(object).map(lambda v: f(v) if isinstance(v, str) else v)})


def labels_as_category(df, rng):
    return df.astype({c: "category" for c in ("subject", "condition") if c in df.columns}), False


def padded_labels(df, rng):
    return _relabel(df, "subject", lambda v: f" {v} "), False


def lowercase_condition(df, rng):
    return _relabel(df, "condition", str.lower), False


def shuffle_rows(df, rng):
    return df.iloc[rng.permutation(len(df))].reset_index(drop=True), False


def shuffle_segments(df, rng):
    keys = [c for c in ("subject", "condition") if c in df.columns]
    if not keys:
        return df, False
    blocks = [g for _, g in df.groupby(keys, sort=False, dropna=False, observed=True)]
    return pd.concat([blocks[i] for i in rng.permutation(len(blocks))], ignore_index=True), False


def interleave_segments(df, rng):
    t = _seconds(df)
    if t is None:
        return df, False
    return df.iloc[np.argsort(t.to_numpy(), kind="stable")].reset_index(drop=True), False


def duplicate_row(df, rng):
    i = int(rng.integers(len(df)))
    return pd.concat([df.iloc[: i + 1], df.iloc[i:]], ignore_index=True), False


def drop_inner_row(df, rng):
    t = _seconds(df)
    if t is None or len(df) < 3:
        return df, False
    i = int(rng.integers(1, len(df) - 1))
    keep = np.ones(len(df), bool)
    keep[i] = t.iloc[i] == 0 or t.iloc[i + 1] == 0  # a segment's first or last row may go
    return df[keep].reset_index(drop=True), False


def duplicate_segment(df, rng):
    if not {"subject", "condition"} <= set(df.columns):
        return df, False
    keys = df[["subject", "condition"]].drop_duplicates()
    key = keys.iloc[int(rng.integers(len(keys)))]
    seg = df[(df["subject"] == key["subject"]) & (df["condition"] == key["condition"])]
    return pd.concat([df, seg], ignore_index=True), False


def _numbers(df, col):
    values = df[col]
    if pd.api.types.is_bool_dtype(values):
        return values
    return pd.to_numeric(values, errors="coerce")


def to_degrees(df, rng):
    cols = [c for c in ("angle", "angle_ref", "velocity") if rng.uniform() < 0.6] or ["angle"]
    return df.assign(**{c: np.degrees(_numbers(df, c)) for c in cols if c in df.columns}), False


def torque_in_nmm(df, rng):
    col = rng.choice(["u_H", "u_A"])
    if col not in df.columns:
        return df, False
    return df.assign(**{col: _numbers(df, col) * 1000}), False


def _seconds(df):
    """t in seconds as numbers, or None when an earlier mutation dropped it or changed its kind."""
    if "t" not in df.columns or pd.api.types.is_datetime64_any_dtype(df["t"]) \
            or pd.api.types.is_timedelta64_dtype(df["t"]) or pd.api.types.is_bool_dtype(df["t"]):
        return None
    t = pd.to_numeric(df["t"], errors="coerce")
    return t.where(np.isfinite(t))  # an injected inf stays missing (NaT) in a time type


def time_in_ms(df, rng):
    t = _seconds(df)
    return (df if t is None else df.assign(t=t * 1000)), False


def time_as_timedelta(df, rng):
    t = _seconds(df)
    return (df if t is None else df.assign(t=pd.to_timedelta(t.round(6), unit="s"))), False


def time_as_datetime(df, rng):
    t = _seconds(df)
    return (df if t is None else df.assign(t=pd.Timestamp("2026-01-05 10:00") + pd.to_timedelta(t.round(6), unit="s"))), \
        False


def assistant_in_manual_control(df, rng):
    if not ({"condition", "u_A"} <= set(df.columns) and pd.api.types.is_float_dtype(df["u_A"])):
        return df, False
    df = df.copy()
    rows = np.flatnonzero(df["condition"].astype(str).str.strip() == "MC")
    if rows.size:
        df.loc[int(rng.choice(rows)), "u_A"] = 0.1
    return df, False


def single_sample_segment(df, rng):
    first = df.iloc[[0]].assign(subject="lonely")
    return pd.concat([df, first], ignore_index=True), False


def no_rows(df, rng):
    return df.iloc[:0], False


MUTATIONS = [drop_column, extra_column, inject(np.nan), inject(np.inf), inject(None), numbers_as_text, to_float32,
             to_bool, labels_as_category, padded_labels, lowercase_condition, shuffle_rows, shuffle_segments,
             interleave_segments, duplicate_row, drop_inner_row, duplicate_segment, to_degrees, torque_in_nmm,
             time_in_ms, time_as_timedelta, time_as_datetime, assistant_in_manual_control, single_sample_segment,
             no_rows]


def cases():
    rng = np.random.default_rng(20260310)
    out = [[m] for m in MUTATIONS]  # every mutation alone once, then random combinations
    while len(out) < N_CASES:
        out.append(list(rng.choice(MUTATIONS, size=int(rng.integers(1, 4)))))
    return [(i, muts, np.random.default_rng([20260310, i])) for i, muts in enumerate(out)]


def mutate(muts, rng):
    df, approx = clean_table(), False
    for m in muts:
        if len(df) == 0:  # nothing left to mutate
            break
        df, a = m(df, rng)
        approx |= a
    return df, approx


def _write(df, path):
    if path.suffix == ".csv":
        df.to_csv(path, index=False)
    else:
        df.to_parquet(path, index=False)
    return path


def _by_segment(records):
    return {(r["subject"], r["condition"]): r["loglik"] for r in records}


@pytest.fixture(scope="module")
def clean_result(tmp_path_factory):
    path = _write(clean_table(), tmp_path_factory.mktemp("clean") / "study.parquet")
    return _by_segment(_loglik(path)[2])


def _loglik(path):
    """(exit status, stderr, records) of ``scioc loglik`` run in-process."""
    import contextlib
    import io

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(["loglik", str(path), "--theta", THETA, "--format", "json"])
    return code, err.getvalue(), json.loads(out.getvalue()) if code == 0 else None


@pytest.mark.parametrize("i, muts, rng", cases(), ids=lambda v: "+".join(m.__name__ for m in v) if isinstance(v, list)
                         else None)
def test_loglik_on_a_malformed_table_fails_clearly_or_gives_the_clean_result(tmp_path, clean_result, i, muts, rng):
    df, approx = mutate(muts, rng)
    path = _write(df, tmp_path / ("study.csv" if i % 3 == 2 else "study.parquet"))
    code, err, records = _loglik(path)
    if code == 0:
        got = _by_segment(records)
        assert got.keys() == clean_result.keys()
        for key, value in clean_result.items():
            assert got[key] == pytest.approx(value, rel=FLOAT32_RTOL if approx else 1e-12), key
    else:
        assert code == 3, err
        assert err.startswith(f"scioc loglik: error: {path}") and err.count("\n") == 1, err


@pytest.mark.parametrize("i, muts, rng", cases(), ids=lambda v: "+".join(m.__name__ for m in v) if isinstance(v, list)
                         else None)
def test_validate_table_on_a_malformed_table_fails_clearly_or_reads_the_clean_data(i, muts, rng):
    df, approx = mutate(muts, rng)
    clean = segments_to_table(validate_table(clean_table(), "clean").segments)
    try:
        study = validate_table(df, "fuzz.parquet")
    except InputDataError as exc:
        assert str(exc).startswith("fuzz.parquet") and "\n" not in str(exc)
        return
    got = segments_to_table(study.segments)
    got = got.sort_values(["subject", "condition", "t"], key=lambda s: s.str.strip() if s.dtype == object else s)
    want = clean.sort_values(["subject", "condition", "t"])
    assert list(got["subject"].str.strip()) == list(want["subject"])
    for col in NUMERIC:
        np.testing.assert_allclose(got[col].to_numpy(), want[col].to_numpy(), rtol=1e-6 if approx else 0,
                                   atol=1e-6 if approx else 1e-12, err_msg=col)


@pytest.mark.parametrize("mutation", [to_degrees, inject(np.nan), drop_column, duplicate_row])
def test_console_script_never_prints_a_traceback(tmp_path, mutation):
    df, _ = mutation(clean_table(), np.random.default_rng(1))
    path = _write(df, tmp_path / "study.parquet")
    exe = Path(sys.executable).parent / "scioc"
    res = subprocess.run([exe, "loglik", str(path), "--theta", THETA], capture_output=True, text=True, timeout=120)
    assert res.returncode == 3 and res.stdout == ""
    assert "Traceback" not in res.stderr and res.stderr.startswith("scioc loglik: error:")
