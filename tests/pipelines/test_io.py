import os
import signal
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scioc.pipelines.io import MAX_ANGLE, MAX_TORQUE, MAX_VELOCITY, StudyFileError, load_study, segments_to_table
from scioc.pipelines.storage import staged_dir, write_table_atomic, write_text_atomic


def _paper_law(angle, velocity, angle_ref):
    """u_A of the paper's MPC on the given states (the law the SC human plans with)."""
    from scioc.models.assistant import design_assistant, feedforward

    a = design_assistant()
    u = -(a.gain[0] * angle + a.gain[1] * velocity)
    u[:-1] += feedforward(a, angle_ref)
    u[-1] = u[-2]
    return u


def small_table(K=20, with_state=True):
    rows = []
    for subject in ("s1", "s2"):
        for cond in ("MC", "SC"):
            t = np.arange(K + 1) * 0.01
            angle, velocity, ref = 0.1 * np.sin(t), 0.1 * np.cos(t), 0.1 * np.sin(t + 0.1)
            d = {
                "subject": subject,
                "condition": cond,
                "t": t,
                "angle": angle,
                "angle_ref": ref,
                "u_A": np.zeros(K + 1) if cond == "MC" else _paper_law(angle, velocity, ref),
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
    _expect_error(tmp_path, df, "u_A", 3, "level MC, which the experiment declares unassisted")


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


@pytest.fixture()
def umask():
    """Set the process umask for one test and restore it afterwards."""
    old = os.umask(0o022)
    yield lambda mask: os.umask(mask)
    os.umask(old)


@pytest.mark.parametrize("mask, mode", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_written_files_follow_the_umask(tmp_path, umask, mask, mode):
    umask(mask)
    text = write_text_atomic(tmp_path / "a.json", "{}")
    table = write_table_atomic(small_table(K=3), tmp_path / "t.parquet")
    assert stat.S_IMODE(text.stat().st_mode) == mode
    assert stat.S_IMODE(table.stat().st_mode) == mode


def _folder(path):
    return {p.name: p.read_text() for p in sorted(path.iterdir())}


def test_staged_dir_creates_and_replaces_a_folder_as_a_whole(tmp_path, umask):
    umask(0o022)
    out = tmp_path / "identify"
    with staged_dir(out) as tmp:
        (tmp / "estimates.txt").write_text("run 1")
        (tmp / "compare.json").write_text("run 1")
        assert not out.exists()  # nothing visible until the stage succeeds
    assert _folder(out) == {"compare.json": "run 1", "estimates.txt": "run 1"}
    assert stat.S_IMODE(out.stat().st_mode) == 0o755
    with staged_dir(out, force=True) as tmp:
        (tmp / "estimates.txt").write_text("run 2")
    assert _folder(out) == {"estimates.txt": "run 2"}  # the stale compare.json went with run 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["identify"]


def test_staged_dir_refuses_an_existing_folder_without_force(tmp_path):
    out = tmp_path / "fit"
    out.mkdir()
    with staged_dir(out) as tmp:  # an empty folder holds nothing to lose
        (tmp / "posterior.json").write_text("new")
    with pytest.raises(FileExistsError, match="already holds results; use --force"):
        with staged_dir(out):
            pass
    (tmp_path / "file").write_text("x")
    with pytest.raises(FileExistsError, match="not a folder"):
        with staged_dir(tmp_path / "file", force=True):
            pass


@pytest.mark.parametrize("error", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_staged_dir_keeps_the_old_folder_when_the_stage_fails(tmp_path, error):
    out = tmp_path / "fit"
    with staged_dir(out) as tmp:
        (tmp / "posterior.json").write_text("old")
    with pytest.raises(type(error)):
        with staged_dir(out, force=True) as tmp:
            (tmp / "posterior.json").write_text("new")
            raise error
    assert _folder(out) == {"posterior.json": "old"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fit"]


_KILLED_WRITER = """
import sys, time
from pathlib import Path
from scioc.pipelines.storage import staged_dir
with staged_dir(sys.argv[1], force=True) as tmp:
    (tmp / "posterior.nc").write_text("new seed")
    print("writing", flush=True)
    time.sleep(60)  # killed here, mid-write
    (tmp / "posterior.json").write_text("new seed")
"""


def test_a_run_killed_mid_write_leaves_the_old_folder_intact(tmp_path):
    out = tmp_path / "fit"
    with staged_dir(out) as tmp:
        for name in ("posterior.nc", "posterior.json", "ppc.parquet"):
            (tmp / name).write_text("old seed")
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.Popen([sys.executable, "-c", _KILLED_WRITER, str(out)], stdout=subprocess.PIPE, cwd=root,
                            env={**os.environ, "PYTHONPATH": str(root)})
    try:
        assert proc.stdout.readline().strip() == b"writing"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)
    assert _folder(out) == {"posterior.json": "old seed", "posterior.nc": "old seed", "ppc.parquet": "old seed"}
    leftovers = [p.name for p in tmp_path.iterdir() if p.name != "fit"]
    assert len(leftovers) == 1 and leftovers[0].startswith(".fit.") and leftovers[0].endswith(".tmp")


def _degrees(df, *cols):
    return df.assign(**{c: np.degrees(df[c]) for c in cols})


def _wide_table():
    """small_table with study-sized angles (peaks ±0.6 rad), so that degrees exceed one turn."""
    df = small_table()
    return df.assign(angle=6 * df["angle"], angle_ref=6 * df["angle_ref"])


@pytest.mark.parametrize("cols, column", [(("angle", "angle_ref"), "angle"), (("angle",), "angle"),
                                          (("angle_ref",), "angle_ref")])
def test_angles_in_degrees_are_refused(tmp_path, cols, column):
    df = _degrees(_wide_table(), *cols)
    row = int(np.flatnonzero(np.abs(df[column]) > 2 * np.pi)[0])
    msg = _expect_error(tmp_path, df, column, row, "beyond the plausible")
    assert "radians (not degrees)" in msg


# velocity: ten times the table's in degrees/s; torques in N·mm (u_A made study-sized first, peaks ±0.4 N·m)
@pytest.mark.parametrize("column, factor, unit", [("velocity", 57.3 * 10, "rad/s"), ("u_H", 1000, "N·m"),
                                                  ("u_A", 8 * 1000, "N·m")])
def test_implausible_velocity_and_torque_are_refused(tmp_path, column, factor, unit):
    df = small_table()
    df[column] = df[column] * factor
    bound = {"velocity": MAX_VELOCITY, "u_H": MAX_TORQUE, "u_A": MAX_TORQUE}[column]
    row = int(np.flatnonzero(np.abs(df[column]) > bound)[0])
    msg = _expect_error(tmp_path, df, column, row, "beyond the plausible")
    assert f"±{bound:g} {unit}" in msg


def test_plausible_bounds_hold_the_simulated_study():
    # The bounds sit far outside what the study produces (reference peaks about ±0.6 rad).
    from scioc.models.reference import reference_trajectory

    assert np.abs(reference_trajectory().angle).max() < MAX_ANGLE / 5


@pytest.mark.parametrize("kind", ["datetime", "datetime-tz", "timedelta"])
def test_datetime_time_is_converted_to_seconds_from_the_segment_start(tmp_path, kind):
    df = small_table()
    start = pd.Timestamp("2026-03-01 09:30:00", tz="Europe/Berlin" if kind == "datetime-tz" else None)
    seconds = pd.to_timedelta(df["t"], unit="s").dt.round("ms")
    df["t"] = seconds if kind == "timedelta" else start + seconds + pd.to_timedelta(np.repeat([0, 60, 120, 180], 21),
                                                                                    unit="s")
    study = load_study(write_table_atomic(df, tmp_path / "dt.parquet"))
    for seg in study.segments:
        np.testing.assert_allclose(seg.t, np.arange(21) * 0.01, atol=1e-12)


def test_time_in_milliseconds_is_named(tmp_path):
    df = small_table().assign(t=lambda d: d["t"] * 1000)
    _expect_error(tmp_path, df, "t", 1, "is t in milliseconds")


def test_float32_time_on_a_perfect_grid_is_accepted(tmp_path):
    df = small_table(K=24000)  # 240 s: float32 resolves t only to about 1.5e-5 s there
    df["t"] = df["t"].astype(np.float32)
    study = load_study(write_table_atomic(df, tmp_path / "f32.parquet"))
    assert study.segments[0].K == 24000
    df.loc[500, "t"] += np.float32(0.004)  # a real glitch is still caught
    _expect_error(tmp_path, df, "t", 500, "uniform 0.01 s")


def test_a_directory_is_named_as_one(tmp_path):
    (tmp_path / "x.parquet").mkdir()
    with pytest.raises(StudyFileError, match=r"x.parquet: is a directory"):
        load_study(tmp_path / "x.parquet")
