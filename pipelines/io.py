"""Reading and validating study files in the data convention (writing results: :mod:`scioc.pipelines.storage`).

The convention (README "Data format"): a long table at the experiment's rate with columns ``subject``,
``condition``, ``t`` (s), ``angle`` (rad), ``angle_ref`` (rad), ``u_A`` (N·m) and optionally ``trial``,
``velocity`` (rad/s) and ``u_H`` (N·m); Parquet, or CSV on input. Rows k = 0..K of one (subject,
condition, trial) segment give x_k = (angle_k, velocity_k); u_H,k and u_A,k act from t_k to t_{k+1}, so
the last row's torques are unused. Trials of one subject × condition are replicates of that unit.

Validation happens here, once: every error names the file, the column and the first bad row
(0-based; for CSV also the line). Plausibility limits catch degrees for radians and N·mm for N·m.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.models.design import STUDY, Design

REQUIRED = ("subject", "condition", "t", "angle", "angle_ref", "u_A")
OPTIONAL = ("trial", "velocity", "u_H")
NUMERIC = ("t", "angle", "angle_ref", "u_A", "velocity", "u_H")
#: Allowed deviation of a time step from the experiment's sample time, s (recording clocks print rounded times).
DT_TOL = 1e-6
#: Largest plausible |angle| and |angle_ref|, rad: one full turn (the study's reference stays within ±0.6 rad).
MAX_ANGLE = 2 * np.pi
#: Largest plausible |velocity|, rad/s: about 1700 °/s, beyond the fastest human steering (about 1000 °/s).
MAX_VELOCITY = 30.0
#: Largest plausible |u_H| and |u_A|, N·m: more than a person exerts on a steering wheel with both hands.
MAX_TORQUE = 50.0


class InputDataError(ValueError):
    """Input data scioc cannot use (missing, unreadable, implausible): ``scioc`` exits 3 (2 on usage errors)."""


class StudyFileError(InputDataError):
    """A study file (or another input table) that breaks the data convention; ``row`` is 0-based."""

    def __init__(self, path, message, column=None, row=None, csv=False):
        where = [str(path)]
        if column is not None:
            where.append(f"column '{column}'")
        if row is not None:
            where.append(f"row {row}" + (f" (line {row + 2})" if csv else ""))
        super().__init__(": ".join([", ".join(where), message]))
        self.path = str(path)
        self.column = column
        self.row = row


@dataclass(frozen=True)
class SegmentData:
    """One (subject, condition, trial) segment as recorded; arrays have shape (K + 1,)."""

    subject: str
    condition: str  # one of the experiment's levels
    t: np.ndarray  # s
    angle: np.ndarray  # rad
    angle_ref: np.ndarray  # rad
    u_A: np.ndarray  # N·m, last entry unused
    velocity: np.ndarray | None  # rad/s, None if not recorded
    u_H: np.ndarray | None  # N·m, last entry unused; None if not recorded
    first_row: int  # row of the segment's first sample in the file
    trial: str | None = None  # the ``trial`` label, if the file has that column

    @property
    def K(self) -> int:
        return int(self.t.shape[0] - 1)

    @property
    def label(self) -> str:
        """``(subject, condition)`` or ``(subject, condition, trial)``, for messages."""
        parts = [self.subject, self.condition] + ([self.trial] if self.trial is not None else [])
        return f"({', '.join(parts)})"


@dataclass(frozen=True)
class Study:
    """A validated study file: its segments in file order, and the experiment it was read with."""

    path: str
    segments: tuple[SegmentData, ...]
    design: Design = STUDY

    @property
    def has_velocity_and_torque(self) -> bool:
        return all(s.velocity is not None and s.u_H is not None for s in self.segments)


def read_table(path) -> pd.DataFrame:
    """Read a Parquet or CSV file into a DataFrame (no validation)."""
    p = Path(path)
    if not p.exists():
        raise StudyFileError(p, "no such file")
    if p.is_dir():
        raise StudyFileError(p, "is a directory, not a file; give the path of the study file")
    suffix = p.suffix.lower()
    try:
        if suffix in (".parquet", ".pq"):
            return pd.read_parquet(p)
        if suffix == ".csv":
            return pd.read_csv(p, dtype={"subject": str, "condition": str}, keep_default_na=True)
    except Exception as exc:  # the reader's own message says what is wrong
        raise StudyFileError(p, f"cannot be read as {suffix[1:]}: {exc}") from exc
    raise StudyFileError(p, f"unknown file type '{suffix}': use .parquet or .csv")


def load_study(path, design: Design = STUDY) -> Study:
    """Read a ``.parquet``/``.pq`` or ``.csv`` study file and validate it against ``design``: :func:`validate_table`."""
    df = read_table(path)
    return validate_table(df, path, csv=Path(path).suffix.lower() == ".csv", design=design)


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def validate_table(df: pd.DataFrame, path="<table>", *, csv: bool = False, design: Design = STUDY) -> Study:
    """Validate a table in the data convention and split it into segments; StudyFileError names the first problem.

    ``design`` gives the sample time, the levels (each must appear) and the unassisted levels (u_A = 0
    there); ``path`` is named in errors, with CSV line numbers if ``csv``.
    """

    def fail(msg, column=None, row=None):
        raise StudyFileError(path, msg, column=column, row=row, csv=csv)

    for col in REQUIRED:
        if col not in df.columns:
            fail(f"required column is missing (columns present: {', '.join(map(str, df.columns))})", column=col)
    if len(df) == 0:
        fail("the table has no rows")
    cols = {}
    labels = ("subject", "condition", "trial") if "trial" in df.columns else ("subject", "condition")
    for col in labels:
        raw = df[col]
        bad = raw.isna().to_numpy()
        if bad.any():
            fail("empty value", column=col, row=_first(bad))
        cols[col] = raw.astype(str).str.strip().to_numpy()
        bad = cols[col] == ""
        if bad.any():
            fail("empty value", column=col, row=_first(bad))
    levels = design.levels
    bad = ~np.isin(cols["condition"], levels)
    if bad.any():
        i = _first(bad)
        fail(f"unknown condition label '{cols['condition'][i]}' (the experiment's levels: {', '.join(levels)})",
             column="condition", row=i)
    missing = [v for v in levels if v not in set(cols["condition"])]
    if missing:
        fail(f"no {', '.join(missing)} segments at all (the experiment's levels: {', '.join(levels)}); every level "
             "needs data: give the experiment file the levels of this study", column="condition")
    # Segments: rows of one (subject, condition[, trial]) in file order.
    keys = pd.MultiIndex.from_arrays([cols[c] for c in labels])
    codes, uniques = pd.factorize(keys)
    present = [c for c in NUMERIC if c in df.columns]
    for col in present:
        raw = df[col]
        if pd.api.types.is_bool_dtype(raw):  # True/False would pass as 1/0 and give a wrong result silently
            fail("holds true/false values; expected numbers", column=col, row=0)
        if col == "t" and (pd.api.types.is_datetime64_any_dtype(raw) or pd.api.types.is_timedelta64_dtype(raw)):
            raw = _seconds_from_segment_start(raw, codes)
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            i = _first(bad)
            fail(f"not a finite number: {df[col].iloc[i]!r}", column=col, row=i)
        cols[col] = values
    _check_plausible(cols, fail)
    has_opt = {c: c in df.columns for c in OPTIONAL}
    dt = design.dt
    # float32 cannot hold t = 240.01 s to 1e-6 s: allow its own rounding (two ulps at the largest |t|).
    dt_tol = DT_TOL
    if df["t"].dtype == np.float32:
        dt_tol += 2 * float(np.spacing(np.float32(np.abs(cols["t"]).max())))
    segments = []
    for code in range(len(uniques)):
        rows = np.flatnonzero(codes == code)
        subject, condition, *trial = uniques[code]
        trial = str(trial[0]) if trial else None
        label = f"segment ({', '.join(map(str, uniques[code]))})"
        if rows.shape[0] < 2:
            fail(f"{label} has a single sample; a segment needs at least two", column="t", row=int(rows[0]))
        t = cols["t"][rows]
        steps = np.diff(t)
        bad = np.abs(steps - dt) > dt_tol
        if bad.any():
            j = _first(bad)
            fail(
                f"{label}: time step {steps[j]:.6g} s from the previous row; samples must be uniform "
                f"{dt:g} s apart ({design.rate_hz:g} Hz, the experiment's sampling.rate_hz) in increasing "
                f"order{_unit_hint(steps, dt)}",
                column="t",
                row=int(rows[j + 1]),
            )
        if design.assistant(condition) is None:
            bad = cols["u_A"][rows] != 0.0
            if bad.any():
                j = _first(bad)
                fail(f"{label}: u_A must be 0 throughout level {condition}, which the experiment declares "
                     "unassisted (no [conditions.assistant] entry)", column="u_A", row=int(rows[j]))
        segments.append(
            SegmentData(
                subject=str(subject),
                condition=str(condition),
                t=t,
                angle=cols["angle"][rows],
                angle_ref=cols["angle_ref"][rows],
                u_A=cols["u_A"][rows],
                velocity=cols["velocity"][rows] if has_opt["velocity"] else None,
                u_H=cols["u_H"][rows] if has_opt["u_H"] else None,
                first_row=int(rows[0]),
                trial=trial,
            )
        )
    return Study(path=str(path), segments=tuple(segments), design=design)


def _seconds_from_segment_start(t: pd.Series, codes: np.ndarray) -> pd.Series:
    """A datetime ``t`` as seconds since its segment's first sample; a timedelta ``t`` as seconds."""
    if pd.api.types.is_datetime64_any_dtype(t):
        t = t - t.groupby(codes).transform("first")
    return t.dt.total_seconds()


def _unit_hint(steps: np.ndarray, dt: float) -> str:
    """Name the unit of ``t`` when its steps are ``dt`` in ms, µs or ns, or the rate when they are another."""
    step = float(np.median(steps))
    for unit, factor in (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9)):
        if abs(step / (dt * factor) - 1) < 0.01:
            return f" (the median step is {step:g}: is t in {unit}? t must be in seconds)"
    if step > 0 and abs(step - dt) > 0.01 * dt:
        return (f" (the median step is {step:g} s, {1.0 / step:g} Hz: set sampling.rate_hz in the experiment "
                "file to the recording's rate)")
    return ""


def _check_plausible(cols: dict, fail) -> None:
    """Refuse values no hand-turned wheel produces: usually degrees for radians, or N·mm for N·m."""
    limits = (("angle", MAX_ANGLE, "rad", "radians (not degrees)"),
              ("angle_ref", MAX_ANGLE, "rad", "radians (not degrees)"),
              ("velocity", MAX_VELOCITY, "rad/s", "rad/s (not degrees/s)"),
              ("u_H", MAX_TORQUE, "N·m", "N·m (not N·cm or N·mm)"),
              ("u_A", MAX_TORQUE, "N·m", "N·m (not N·cm or N·mm)"))
    for col, limit, unit, wanted in limits:
        if col in cols:
            bad = np.abs(cols[col]) > limit
            if bad.any():
                i = _first(bad)
                fail(f"{cols[col][i]:g} {unit} is beyond the plausible ±{limit:.4g} {unit} for a steering wheel; "
                     f"the column must be in {wanted}", column=col, row=i)


def segments_to_table(segments) -> pd.DataFrame:
    """Inverse of :func:`validate_table`: a long table in the data convention."""
    frames = []
    for s in segments:
        d = {
            "subject": np.full(s.t.shape[0], s.subject, dtype=object),
            "condition": np.full(s.t.shape[0], s.condition, dtype=object),
            "t": s.t,
            "angle": s.angle,
            "angle_ref": s.angle_ref,
            "u_A": s.u_A,
        }
        if s.trial is not None:
            d["trial"] = np.full(s.t.shape[0], s.trial, dtype=object)
        if s.velocity is not None:
            d["velocity"] = s.velocity
        if s.u_H is not None:
            d["u_H"] = s.u_H
        frames.append(pd.DataFrame(d))
    return pd.concat(frames, ignore_index=True)
