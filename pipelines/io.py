"""Reading and validating study files in the data convention (writing results: :mod:`scioc.pipelines.storage`).

The convention (README "Data format"): a long table at the experiment's rate with columns ``subject``,
``condition``, ``t`` (s), ``angle`` (rad), ``angle_ref`` (rad), ``u_A`` (N·m) and optionally ``trial``,
``velocity`` (rad/s) and ``u_H`` (N·m); Parquet, or CSV or MATLAB ``.mat`` on input. Rows k = 0..K of one
(subject, condition, trial) segment give x_k = (angle_k, velocity_k); u_H,k and u_A,k act from t_k to
t_{k+1}, so the last row's torques are unused. Trials of one subject × condition are replicates of that unit.

A study is one file or several (a folder's study files, or a glob such as ``exports/*.csv``), read as
their concatenation in name order. A lab's own column names and units are the design's
(:mod:`scioc.pipelines.export`); values are converted to scioc's units before the plausibility checks.

Validation happens here, once: every error names the file, the column as the file names it, and the
first bad row (0-based within that file; for CSV also the line). Plausibility limits catch degrees for
radians and N·mm for N·m. Angles that are the experiment's encoder counts to within :data:`ON_GRID`
are put on its grid exactly, where scioc's encoder model has them; others are kept as they are.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.io import loadmat

from scioc.models.design import STUDY, Design
from scioc.pipelines.export import CONVENTION, QUANTITY, ExportFormat, export_of

REQUIRED = ("subject", "condition", "t", "angle", "angle_ref", "u_A")
OPTIONAL = ("trial", "velocity", "u_H")
NUMERIC = ("t", "angle", "angle_ref", "u_A", "velocity", "u_H")
#: The file types a study is read from; a folder's files of these types form its study.
STUDY_SUFFIXES = (".parquet", ".pq", ".csv", ".mat")
#: Allowed deviation of a time step from the experiment's sample time, s (recording clocks print rounded times).
DT_TOL = 1e-6
#: Largest plausible |angle| and |angle_ref|, rad: one full turn (the study's reference stays within ±0.6 rad).
MAX_ANGLE = 2 * np.pi
#: Largest plausible |velocity|, rad/s: about 1700 °/s, beyond the fastest human steering (about 1000 °/s).
MAX_VELOCITY = 30.0
#: Largest plausible |u_H| and |u_A|, N·m: more than a person exerts on a steering wheel with both hands.
MAX_TORQUE = 50.0
#: Largest distance of an angle from the experiment's encoder grid, in counts, at which the angles are put on it
#: exactly: a unit conversion leaves encoder counts a few ulps (about 1e-12 counts) off scioc's grid k·2π/counts.
ON_GRID = 1e-9


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
    first_row: int  # row of the segment's first sample in its file
    trial: str | None = None  # the ``trial`` label, if the file has that column
    source: str | None = None  # the file of the segment's first sample

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
    """A validated study: its segments in file order, the experiment it was read with, and the files read."""

    path: str  # as given: a file, a folder or a glob
    segments: tuple[SegmentData, ...]
    design: Design = STUDY
    files: tuple[str, ...] = ()

    @property
    def has_velocity_and_torque(self) -> bool:
        return all(s.velocity is not None and s.u_H is not None for s in self.segments)


def read_table(path, export: ExportFormat = CONVENTION) -> pd.DataFrame:
    """Read one Parquet, CSV or MATLAB ``.mat`` file into a DataFrame (no validation).

    ``export`` names the label columns a CSV file keeps as text (``subject``, ``condition``, or the
    lab's names of them), so that "007" stays "007".
    """
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
            return pd.read_csv(p, dtype={export.name(c): str for c in ("subject", "condition")}, keep_default_na=True)
        if suffix == ".mat":
            return _read_mat(p)
    except StudyFileError:
        raise
    except Exception as exc:  # the reader's own message says what is wrong
        raise StudyFileError(p, f"cannot be read as {suffix[1:]}: {exc}") from exc
    raise StudyFileError(p, f"unknown file type '{suffix}': use {', '.join(STUDY_SUFFIXES)}")


def _read_mat(path: Path) -> pd.DataFrame:
    """A MATLAB file's variables, or the fields of its one struct, as the columns of a table: equal-length vectors."""
    data = {k: v for k, v in loadmat(path, simplify_cells=True).items() if not k.startswith("__")}
    if len(data) == 1 and isinstance(next(iter(data.values())), dict):
        data = next(iter(data.values()))
    columns = {}
    for name, value in data.items():
        values = np.asarray(value)
        if values.ndim != 1:
            raise StudyFileError(path, f"variable '{name}' has shape {values.shape}; every variable must be a vector "
                                       "of one value per sample")
        columns[name] = values
    lengths = {name: v.shape[0] for name, v in columns.items()}
    if len(set(lengths.values())) > 1:
        raise StudyFileError(path, "the variables differ in length ("
                             + ", ".join(f"{k}: {n}" for k, n in lengths.items()) + "); each is one column of a table")
    return pd.DataFrame(columns)


def study_files(path) -> tuple[Path, ...]:
    """The files of a study, in name order: ``path`` itself, a folder's files of :data:`STUDY_SUFFIXES`, or the
    files a glob pattern (``exports/*.csv``, ``**`` for subfolders) matches. StudyFileError when there are none."""
    p = Path(path)
    if p.is_dir():
        files = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in STUDY_SUFFIXES
                       and not q.name.startswith("."))
        if not files:
            raise StudyFileError(p, f"is a directory without study files ({', '.join(STUDY_SUFFIXES)}); give a "
                                    "study file, a folder of them or a glob pattern")
        return tuple(files)
    if p.exists() or not glob.has_magic(str(path)):
        return (p,)
    files = sorted(Path(q) for q in glob.glob(str(path), recursive=True) if Path(q).is_file())
    if not files:
        raise StudyFileError(path, "no file matches this pattern")
    return tuple(files)


def load_study(path, design: Design = STUDY) -> Study:
    """Read a study in ``design``'s export format, convert it to scioc's units and validate it.

    Parameters
    ----------
    path : str or Path
        A ``.parquet``/``.pq``, ``.csv`` or ``.mat`` file, a folder of them, or a glob pattern
        (:func:`study_files`); several files are read as their concatenation.
    design : Design
        The experiment (:func:`validate_table`); an :class:`scioc.pipelines.export.ExportDesign` also
        gives the files' column names and units.

    Returns
    -------
    Study
        Its segments in file order, in rad, rad/s, N·m and s.

    Raises
    ------
    StudyFileError
        Naming the file, its column and the first bad row.
    """
    export = export_of(design)
    files = study_files(path)
    frames = [_file_labels(read_table(f, export), f, export) for f in files]
    origin = _Origin(path, files, [len(f) for f in frames], export)
    if len(frames) > 1:
        _same_columns(frames, origin)
    df = frames[0] if len(frames) == 1 else pd.concat(frames, ignore_index=True)
    return _validate(df, origin, design)


def _file_labels(df: pd.DataFrame, path: Path, export: ExportFormat) -> pd.DataFrame:
    """``df`` with the columns ``[columns] from_file_name`` takes from the name of its file ``path``."""
    labels = export.file_labels(path.stem)
    if labels is None:
        raise StudyFileError(path, f"the file name '{path.stem}' does not match the experiment's [columns] "
                                   f"from_file_name = '{export.from_file_name}'")
    for column, value in labels.items():
        if column in df.columns:
            raise StudyFileError(path, "the file has this column, and [columns] from_file_name takes it from the "
                                       "file name too: rename one of them", column=column)
        if not value.strip():
            raise StudyFileError(path, f"[columns] from_file_name gives an empty {column} for this file name")
    return df.assign(**labels)


def _same_columns(frames: list, origin: _Origin) -> None:
    """Refuse a study whose files differ in the columns scioc reads, or a file without rows."""
    for i, frame in enumerate(frames):
        if len(frame) == 0:
            raise StudyFileError(origin.files[i], "the file has no rows")
    for column in (*REQUIRED, *OPTIONAL):
        name = origin.export.name(column)
        has = [name in f.columns for f in frames]
        if any(has) and not all(has):
            i = has.index(False)
            raise StudyFileError(origin.files[i], f"column is missing here, but {origin.files[has.index(True)]} has "
                                                  "it; every file of a study needs the same columns", column=name)


class _Origin:
    """Where the rows of a study's table come from (its files, in order) and the names the files give its columns."""

    def __init__(self, path, files, lengths, export: ExportFormat = CONVENTION, csv=None):
        self.path = str(path)
        self.files = [str(f) for f in files]
        self.starts = np.cumsum([0, *lengths])[:-1]
        self.csv = [Path(f).suffix.lower() == ".csv" for f in self.files] if csv is None else [csv]
        self.export = export

    def locate(self, row: int) -> tuple[int, int]:
        """(file index, row within that file) of the table's ``row``."""
        i = int(np.searchsorted(self.starts, row, side="right")) - 1
        return i, int(row - self.starts[i])

    def error(self, message, column=None, row=None) -> StudyFileError:
        """The error at the table's ``row`` (None: the whole study), naming ``column`` as the files do."""
        name = None if column is None else self.export.name(column)
        if row is None:
            return StudyFileError(self.path if len(self.files) > 1 else self.files[0], message, column=name)
        i, local = self.locate(row)
        return StudyFileError(self.files[i], message, column=name, row=local, csv=self.csv[i])


def _first(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def validate_table(df: pd.DataFrame, path="<table>", *, csv: bool = False, design: Design = STUDY) -> Study:
    """Validate a table in the data convention and split it into segments; StudyFileError names the first problem.

    ``design`` gives the sample time, the levels (each must appear) and the unassisted levels (u_A = 0
    there); its export format is not applied (the table is in scioc's names and units). ``path`` is
    named in errors, with CSV line numbers if ``csv``.
    """
    return _validate(df, _Origin(path, [path], [len(df)], csv=csv), design)


def _validate(df: pd.DataFrame, origin: _Origin, design: Design) -> Study:
    """:func:`validate_table` of a table in ``origin.export``'s names and units, converting to scioc's units."""
    export = origin.export

    def fail(msg, column=None, row=None):
        raise origin.error(msg, column=column, row=row)

    def renamed(col):  # where [columns] renames it, the missing column's key
        return f"; the experiment's [columns] {col} names it" if export.name(col) != col else ""

    present = f"columns present: {', '.join(map(str, df.columns))}"
    for col in REQUIRED:
        if export.name(col) not in df.columns:
            fail(f"required column is missing{renamed(col)} ({present})", column=col)
    for col, name in export.columns:
        if name not in df.columns:
            fail(f"column is missing{renamed(col)} ({present})", column=col)
    if len(df) == 0:
        fail("the table has no rows")
    # A file column named like one of scioc's that [columns] takes from another column is not that column.
    shadowed = [col for col, _ in export.columns if col in df.columns and col not in dict(export.columns).values()]
    df = df.drop(columns=shadowed).rename(columns={name: col for col, name in export.columns})
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
    given = {}  # the numeric columns in the file's units
    for col in (c for c in NUMERIC if c in df.columns):
        raw = df[col]
        if pd.api.types.is_bool_dtype(raw):  # True/False would pass as 1/0 and give a wrong result silently
            fail("holds true/false values; expected numbers", column=col, row=0)
        if col == "t" and (pd.api.types.is_datetime64_any_dtype(raw) or pd.api.types.is_timedelta64_dtype(raw)):
            if export.converts("t"):
                fail(f"holds dates or durations, which are read in seconds; the experiment's [units] time = "
                     f"\"{export.unit('t')}\" applies to numbers only: remove it", column=col, row=0)
            raw = _seconds_from_segment_start(raw, codes)
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values)
        if bad.any():
            i = _first(bad)
            value = df[col].iloc[i]  # a NumPy scalar as Python's, so the message reads nan, not np.float64(nan)
            fail(f"not a finite number: {(value.item() if isinstance(value, np.generic) else value)!r}", column=col,
                 row=i)
        given[col] = values
        cols[col] = export.to_scioc(col, values)
    _check_plausible(cols, given, export, fail)
    cols["angle"] = _on_grid(cols["angle"], design.encoder_step)
    has_opt = {c: c in df.columns for c in OPTIONAL}
    dt = design.dt
    # float32 cannot hold t = 240.01 s to 1e-6 s: allow its own rounding (two ulps at the largest |t|).
    dt_tol = DT_TOL
    if df["t"].dtype == np.float32:
        dt_tol += float(export.to_scioc("t", 2 * np.spacing(np.float32(np.abs(given["t"]).max()))))
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
                f"order{_unit_hint(steps, dt, export)}",
                column="t",
                row=int(rows[j + 1]),
            )
        if design.assistant(condition) is None:
            bad = cols["u_A"][rows] != 0.0
            if bad.any():
                j = _first(bad)
                fail(f"{label}: u_A must be 0 throughout level {condition}, which the experiment declares "
                     "unassisted (no [conditions.assistant] entry)", column="u_A", row=int(rows[j]))
        source, first_row = origin.locate(int(rows[0]))
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
                first_row=first_row,
                trial=trial,
                source=origin.files[source],
            )
        )
    return Study(path=origin.path, segments=tuple(segments), design=design, files=tuple(origin.files))


def _on_grid(angle: np.ndarray, step: float) -> np.ndarray:
    """``angle`` on the encoder grid (as :func:`scioc.models.simulate.quantize` reads an encoder) when every value
    lies within :data:`ON_GRID` counts of it, else unchanged; ``step`` in rad (0: no encoder)."""
    if step > 0:
        counts = np.round(angle / step)
        if np.all(np.abs(angle / step - counts) <= ON_GRID):
            return counts * step
    return angle


def _seconds_from_segment_start(t: pd.Series, codes: np.ndarray) -> pd.Series:
    """A datetime ``t`` as seconds since its segment's first sample; a timedelta ``t`` as seconds."""
    if pd.api.types.is_datetime64_any_dtype(t):
        t = t - t.groupby(codes).transform("first")
    return t.dt.total_seconds()


def _unit_hint(steps: np.ndarray, dt: float, export: ExportFormat = CONVENTION) -> str:
    """Name the unit of ``t`` when its steps are ``dt`` in ms, µs or ns, or the rate when they are another."""
    step = float(np.median(steps))
    for unit, factor in (("milliseconds", 1e3), ("microseconds", 1e6), ("nanoseconds", 1e9)):
        if abs(step / (dt * factor) - 1) < 0.01:
            declare = ', or say [units] time = "ms" in the experiment file' if factor == 1e3 else ""
            return (f" (the median step is {step:g}: is t in {unit}? t must be in seconds"
                    f"{declare if not export.converts('t') else ''})")
    if step > 0 and abs(step - dt) > 0.01 * dt:
        return (f" (the median step is {step:g} s, {1.0 / step:g} Hz: set sampling.rate_hz in the experiment "
                "file to the recording's rate)")
    return ""


def _check_plausible(cols: dict, given: dict, export: ExportFormat, fail) -> None:
    """Refuse values no hand-turned wheel produces: usually degrees for radians, or N·mm for N·m.

    ``cols`` in scioc's units, ``given`` in the file's (``export``'s ``[units]``), for the message.
    """
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
                where = f"[units] {QUANTITY[col]}"
                if export.converts(col):
                    fail(f"{given[col][i]:g} {export.unit(col)} ({cols[col][i]:.4g} {unit}) is beyond the plausible "
                         f"±{limit:.4g} {unit} for a steering wheel; is the column in {export.unit(col)}, as the "
                         f"experiment's {where} says?", column=col, row=i)
                fail(f"{cols[col][i]:g} {unit} is beyond the plausible ±{limit:.4g} {unit} for a steering wheel; "
                     f"the column must be in {wanted}, or its unit given in the experiment file's {where}",
                     column=col, row=i)


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
