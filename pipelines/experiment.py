"""The experiment file, ``experiment.toml``: a study's rig and protocol as data.

Found beside the study file or named with ``--experiment PATH``; read with :mod:`tomllib` and
validated here, once, into a :class:`scioc.models.design.Design`. Every error is an
:class:`ExperimentFileError` (exit 3) naming the file, the dotted key, what was given and what is
allowed. Every key is optional (no file gives :data:`scioc.models.design.STUDY`); unknown keys are
refused; an integer key refuses 40000.0; a boolean is never a number. ``[columns]`` and ``[units]``
describe a lab's export (:mod:`scioc.pipelines.export`); with either, the design is an
:class:`scioc.pipelines.export.ExportDesign`. ``[simulation]`` is read by ``scioc simulate`` and
``scioc run`` only.

Keys: ``section.key`` unit, default: meaning
--------------------------------------------
``sampling.rate_hz``          Hz, 100.0: sampling rate > 0; ``t`` steps by 1/rate_hz within a trial.
``wheel.inertia``             kg·m², 0.04: rotational inertia of the wheel (paper Eq. 18), > 0.
``wheel.spring``              N·m/rad, 1.146: spring constant, > 0.
``wheel.damper``              N·m·s/rad, 0.286: damping constant, > 0.
``encoder.counts_per_rev``    per revolution (integer), 40000: angle quantization; 0: none.
``conditions.levels``         labels, ["MC", "SC"]: all levels in the data, baseline included, >= 2.
``conditions.baseline``       label, "MC": every contrast is taken against it; one of the levels.
``conditions.assistant``      table, SC = the paper's MPC: ``level = { kind = ..., ... }`` per
                              assisted level; a level without an entry has u_A = 0. Entry keys:
``kind``                      "mpc" or "linear", required.
``theta``                     [q11, q22, R], [5.0, 0.0, 1.0] (mpc): cost θ_A, >= 0 with R > 0.
``horizon``                   steps (integer), 50 (mpc): prediction horizon N_P, >= 1.
``step_s``                    s, 0.02 (mpc): prediction step T_C, a whole multiple of 1/rate_hz.
``period_s``                  s, 0.01 (mpc): how often it re-solves, a whole multiple of 1/rate_hz.
``gain``                      [N·m/rad, N·m·s/rad], required (linear): u_A = -gain[0]·angle
                              - gain[1]·velocity + reference_gain·angle_ref.
``reference_gain``            N·m/rad, required (linear): the gain on angle_ref.
``analysis.window_start_s``   s, 210.0: start of the analysis window on the trial's own t axis, >= 0.
``analysis.window_s``         s, 15.0: length of the analysis window, > 0.
``analysis.whole``            true/false, false: analyse every trial whole instead of one window
                              (refused together with a window key: a conflict).
``analysis.preview_s``        s, 2.0: how far ahead the human sees the reference, 0 to 60; 0: the paper's horizon.
``columns.KEY``               text, KEY: the file's name of scioc's column KEY, one of ``columns.subject``,
                              ``columns.condition``, ``columns.trial``, ``columns.t``, ``columns.angle``,
                              ``columns.angle_ref``, ``columns.u_A``, ``columns.velocity``, ``columns.u_H``.
``columns.from_file_name``    regular expression, none: the whole of each file's name without extension
                              matches it; its named groups subject, condition, trial give those columns.
``units.angle``               "rad": the unit of angle and angle_ref, "rad" or "deg".
``units.velocity``            "rad/s": the unit of velocity, "rad/s" or "deg/s".
``units.torque``              "N*m": the unit of u_A and u_H, "N*m", "N*cm" or "N*mm" (also N·cm, Ncm).
``units.time``                "s": the unit of t, "s" or "ms".
``simulation.run_s``          s, 240.0: one simulated run, > 0 (a window outside it is refused when analysed).
``simulation.subjects``       integer, 42: subjects of a simulated study, >= 1.
``simulation.trials``         integer, 1: runs per subject × condition of a simulated study, >= 1.
``simulation.torque_sensor``  true/false, false: the simulated rig also records u_H (a torque sensor).
``simulation.beta``           number or list, -0.7: true mean shift of log θ1 to each other level.

Rules
-----
* Without ``conditions.assistant`` the table is ``SC = { kind = "mpc" }`` if "SC" is a level, else
  empty, so other labels get no assistant by accident; a given table (``{}`` for none) replaces it.
* ``kind = "mpc"`` takes missing keys from the paper's MPC; ``kind = "linear"`` needs ``gain`` and
  ``reference_gain``. Only the keys of the entry's kind are allowed.
* The baseline defaults to "MC" if that is a level, else must be named. It is the unassisted
  reference of every contrast, so an assistant for it is refused.
* A file column holds one of scioc's columns; ``from_file_name`` takes no column ``[columns]`` names.
* :func:`resolved` writes every applicable key out (``[columns]`` and ``[units]`` where they differ
  from the convention); :func:`experiment_hash` hashes its canonical JSON, so equal designs share a
  hash however written, and a file without ``[columns]`` and ``[units]`` keeps its hash. Both
  :func:`parse_experiment` of it and :func:`load_experiment` of :func:`to_toml` give back the design.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import tomllib
from pathlib import Path

from scioc.models.design import (
    ASSISTANT_KINDS,
    MAX_PREVIEW,
    PAPER_ASSISTANT,
    STUDY,
    AssistantSpec,
    Design,
    WheelParameters,
)
from scioc.pipelines.export import (
    COLUMNS,
    FILE_NAME_GROUPS,
    QUANTITY,
    UNITS,
    ExportFormat,
    canonical_unit,
    export_of,
    with_export,
)
from scioc.pipelines.io import InputDataError
from scioc.pipelines.storage import write_text_atomic

#: The name of the experiment file beside a study file.
EXPERIMENT_FILE = "experiment.toml"
#: The sections of the file and their keys, in the order :func:`to_toml` writes them.
SECTIONS = {"sampling": ("rate_hz",), "wheel": ("inertia", "spring", "damper"), "encoder": ("counts_per_rev",),
            "conditions": ("baseline", "levels", "assistant"),
            "analysis": ("window_start_s", "window_s", "whole", "preview_s"),
            "columns": (*COLUMNS, "from_file_name"), "units": tuple(UNITS),
            "simulation": ("run_s", "subjects", "trials", "torque_sensor", "beta")}
#: The keys of an assistant entry of each kind.
ASSISTANT_KEYS = {"mpc": ("kind", "theta", "horizon", "step_s", "period_s"),
                  "linear": ("kind", "gain", "reference_gain")}
# Comments of to_toml (ASCII: the file is written in the locale's encoding).
_NOTES = {"rate_hz": "Hz; the t column steps by 1/rate_hz within a trial", "inertia": "kg*m^2 (paper Eq. 18)",
    "spring": "N*m/rad", "damper": "N*m*s/rad", "counts_per_rev": "per revolution; 0: the angle is not quantized",
    "baseline": "every contrast is taken against this level", "levels": "all levels in the data, baseline included",
    "window_start_s": "s, on the trial's own t axis", "window_s": "s", "whole": "true: every trial whole",
    "preview_s": "s; 0: the paper's horizon", "run_s": "s", "subjects": "simulated subjects",
    "trials": "runs per subject x condition", "torque_sensor": "true: the rig also records u_H",
    "beta": "true mean shift of log theta1 per non-baseline level",
    "from_file_name": "named groups subject, condition, trial from each file's name"}
# The section of each Design field, for the backstop's errors.
_FIELD_SECTION = dict.fromkeys(("dt",), "sampling") | {"wheel": "wheel", "encoder_counts": "encoder"} | dict.fromkeys(
    ("levels", "baseline", "assistants"), "conditions") | dict.fromkeys(
    ("window_start", "window_seconds", "whole", "preview"), "analysis") | dict.fromkeys(
    ("run_seconds", "subjects", "trials", "torque_sensor", "effects"), "simulation")


class ExperimentFileError(InputDataError):
    """An experiment file scioc cannot use; ``key`` is the dotted key (``conditions.assistant.SC.theta``) or None."""

    def __init__(self, path, message, key=None):
        super().__init__(f"{path}, key '{key}': {message}" if key else f"{path}: {message}")
        self.path = str(path)
        self.key = key


def _quote(text: str) -> str:
    """A TOML basic string, ASCII only."""
    out = []
    for ch in text:
        o = ord(ch)
        out.append("\\" + ch if ch in '"\\' else ch if 0x20 <= o < 0x7F else
                   f"\\u{o:04X}" if o <= 0xFFFF else f"\\U{o:08X}")
    return '"' + "".join(out) + '"'


def _key(prefix, *parts) -> str:
    """The dotted key ``prefix.part...``: ``prefix`` is one already (or None), parts are quoted where TOML needs it."""
    quoted = [p if re.fullmatch(r"[A-Za-z0-9_-]+", p) else _quote(p) for p in map(str, parts)]
    return ".".join(([prefix] if prefix else []) + quoted)


def _show(value) -> str:
    """``value`` as TOML writes it."""
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(map(_show, value)) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(None, k)} = {_show(v)}" for k, v in value.items()) + " }"
    return ("true" if value else "false") if isinstance(value, bool) else _quote(value) if isinstance(value, str) \
        else repr(value) if isinstance(value, float) else str(value)


class _Reader:
    """Typed reads of one file's values; every failure names the file and the key."""

    def __init__(self, path):
        self.path = str(path)

    def fail(self, key, message):
        raise ExperimentFileError(self.path, message, key)

    def table(self, value, key, allowed, what=""):
        if not isinstance(value, dict):
            self.fail(key, f"must be a table; got {_show(value)}")
        for k in value:
            if k not in allowed:
                self.fail(_key(key, k), f"unknown {'key' if key else 'section'}{what}; allowed: {', '.join(allowed)}")
        return value

    def number(self, value, key, lo=None, strict=True) -> float:
        ok = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
        if not ok or (lo is not None and not (value > lo if strict else value >= lo)):
            bound = "" if lo is None else f" {'>' if strict else '>='} {lo:g}"
            self.fail(key, f"must be a finite number{bound}; got {_show(value)}")
        return float(value)

    def integer(self, value, key, lo) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < lo:
            self.fail(key, f"must be an integer >= {lo} (no decimal point); got {_show(value)}")
        return int(value)

    def flag(self, value, key) -> bool:
        return value if isinstance(value, bool) else self.fail(key, f"must be true or false; got {_show(value)}")

    def numbers(self, value, key, n, what, lo=None) -> tuple:
        good = isinstance(value, (list, tuple)) and len(value) == n and all(
            not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
            and (lo is None or v >= lo) for v in value)
        if not good:
            self.fail(key, f"must be {what}; got {_show(value)}")
        return tuple(float(v) for v in value)


def _assistant(r: _Reader, entry, key: str, dt: float, note: str = "") -> AssistantSpec:
    """One ``[conditions.assistant]`` entry."""
    if not isinstance(entry, dict):
        r.fail(key, 'must be a table such as { kind = "mpc" } or { kind = "linear", gain = [6.0, 0.3], '
                    f"reference_gain = 6.0 }}; got {_show(entry)}")
    kind = entry.get("kind")
    if not isinstance(kind, str) or kind not in ASSISTANT_KINDS:
        got = "nothing (kind is required)" if "kind" not in entry else _show(kind)
        r.fail(_key(key, "kind"), f"must be one of {', '.join(map(_quote, ASSISTANT_KINDS))}; got {got}")
    r.table(entry, key, ASSISTANT_KEYS[kind], what=f' for kind = "{kind}"')
    if kind == "mpc":
        p = PAPER_ASSISTANT  # the defaults of an mpc entry
        theta = r.numbers(entry.get("theta", p.theta), _key(key, "theta"), 3,
                          "three finite numbers [q11, q22, R] >= 0 with R > 0", lo=0.0)
        if not theta[2] > 0:
            r.fail(_key(key, "theta"), f"R = theta[2] must be > 0; got {_show(entry['theta'])}")
        horizon = r.integer(entry.get("horizon", p.horizon), _key(key, "horizon"), 1)
        times = {}
        for name in ("step_s", "period_s"):
            value = times[name] = r.number(entry.get(name, getattr(p, name)), _key(key, name), lo=0.0)
            n = round(value / dt)
            if n < 1 or abs(n * dt - value) > 1e-9 * max(1.0, value):
                r.fail(_key(key, name), f"must be a whole multiple of the sample time 1/sampling.rate_hz = {dt!r} s; "
                                        f"got {value!r}{note}")
        spec = dict(kind=kind, theta=theta, horizon=horizon, **times)
    else:
        for name in ("gain", "reference_gain"):
            if name not in entry:
                r.fail(_key(key, name), 'is required for kind = "linear" (the paper has no default for it)')
        gain = r.numbers(entry["gain"], _key(key, "gain"), 2, "two finite numbers [on angle, on velocity]")
        spec = dict(kind=kind, gain=gain, reference_gain=r.number(entry["reference_gain"], _key(key, "reference_gain")))
    try:
        return AssistantSpec(**spec)
    except ValueError as exc:  # backstop: the checks above should have said it first
        return r.fail(key, str(exc))


def _conditions(r: _Reader, c: dict, dt: float):
    """levels, baseline and assistants of the ``[conditions]`` table."""
    levels = c.get("levels", list(STUDY.levels))
    if (not isinstance(levels, (list, tuple)) or len(levels) < 2
            or not all(isinstance(v, str) and v.strip() for v in levels) or len(set(levels)) != len(levels)):
        r.fail("conditions.levels", f'must be a list of two or more distinct non-empty labels, e.g. ["MC", "SC"]; '
                                    f"got {_show(levels)}")
    levels = tuple(levels)
    if "baseline" in c:
        baseline = c["baseline"]
        if not isinstance(baseline, str) or baseline not in levels:
            r.fail("conditions.baseline", f"must be one of the levels {_show(levels)}; got {_show(baseline)}")
    elif STUDY.baseline in levels:
        baseline = STUDY.baseline
    else:
        r.fail("conditions.baseline", f"is not given, and the levels {_show(levels)} have no {_quote(STUDY.baseline)} "
                                      "to default to: name the level every contrast is taken against")
    if "assistant" in c:
        table = c["assistant"]
        if not isinstance(table, dict):
            r.fail("conditions.assistant", f"must be a table of level = {{ kind = ... }} entries; got {_show(table)}")
        entries = {}
        for level, entry in table.items():
            key = _key("conditions", "assistant", level)
            if level not in levels:
                r.fail(key, f"names no level: an entry's name must be one of the levels {_show(levels)}")
            if level == baseline:
                r.fail(key, f"{_quote(level)} is the baseline (conditions.baseline), the unassisted reference of every "
                            "contrast: remove this entry or make another level the baseline")
            entries[level] = _assistant(r, entry, key, dt)
    else:
        entries = {lv: _assistant(r, {"kind": spec.kind}, _key("conditions", "assistant", lv), dt,
                                  " (the default entry: the paper's MPC, implied without [conditions.assistant])")
                   for lv, spec in STUDY.assistants if lv in levels}
        if baseline in entries:
            r.fail("conditions.baseline", f"{_quote(baseline)} is the baseline, which is unassisted, but without a "
                                          "[conditions.assistant] table it gets the paper's MPC: write the table "
                                          "(an empty one for no assistant)")
    return levels, baseline, tuple((lv, entries[lv]) for lv in levels if lv in entries)


def _export(r: _Reader, columns: dict, units: dict) -> ExportFormat:
    """The lab's export of the ``[columns]`` and ``[units]`` tables."""
    names = {}
    for key, value in columns.items():
        if not isinstance(value, str) or not value.strip():
            r.fail(_key("columns", key), f"must be a name in the file, a non-empty string; got {_show(value)}")
        if key != "from_file_name":
            names[key] = value
    for key, value in names.items():  # where scioc reads each of its columns: one file column each
        other = [c for c in COLUMNS if c != key and names.get(c, c) == value]
        if other:
            why = (f"columns.{other[0]} names it too; a file column holds one of scioc's columns" if other[0] in names
                   else f"scioc reads {other[0]} from a column of that name: give columns.{other[0]} too")
            r.fail(_key("columns", key), f"names the column {_quote(value)}, but {why}")
    pattern = columns.get("from_file_name")
    if pattern is not None:
        key = "columns.from_file_name"
        try:
            groups = tuple(re.compile(pattern).groupindex)
        except re.error as exc:
            r.fail(key, f"is not a regular expression: {exc}; got {_show(pattern)}")
        if not groups or set(groups) - set(FILE_NAME_GROUPS):
            r.fail(key, f"needs named groups among {', '.join(FILE_NAME_GROUPS)}, such as '(?P<subject>.+)' (the "
                        f"file name is the subject); got {_show(pattern)}")
        for group in groups:
            if group in names:
                r.fail(key, f"takes {group} from the file name, but columns.{group} names a column for it: drop one")
    found = {}
    for key, value in units.items():
        found[key] = canonical_unit(key, value) if isinstance(value, str) else None
        if found[key] is None:
            cols = ", ".join(c for c, q in QUANTITY.items() if q == key)
            r.fail(_key("units", key), f"the unit of {cols} must be one of {', '.join(map(_quote, UNITS[key]))}; "
                                       f"got {_show(value)}")
    return ExportFormat(columns=tuple(names.items()), units=tuple(found.items()), from_file_name=pattern)


def parse_experiment(mapping: dict, path="<experiment>") -> Design:
    """Validate an experiment file's tables (from :func:`tomllib.loads` or :func:`resolved`) into a Design.

    Raises ExperimentFileError, naming ``path`` and the key, for anything the module docstring does not allow.
    """
    r = _Reader(path)
    doc = r.table(mapping, None, SECTIONS)
    scioc_names = ' (a key is scioc\'s column name, its value the file\'s: subject = "Proband")'
    sec = {name: r.table(doc.get(name, {}), name, keys, what=scioc_names if name == "columns" else "")
           for name, keys in SECTIONS.items()}
    export = _export(r, sec["columns"], sec["units"])
    s, w, e, a, m = (sec[k] for k in ("sampling", "wheel", "encoder", "analysis", "simulation"))
    dt = 1.0 / r.number(s["rate_hz"], "sampling.rate_hz", lo=0.0) if "rate_hz" in s else STUDY.dt
    wheel = WheelParameters(*(r.number(w.get(k, default), _key("wheel", k), lo=0.0)
                              for k, default in zip(SECTIONS["wheel"], STUDY.wheel)))
    counts = r.integer(e.get("counts_per_rev", STUDY.encoder_counts), "encoder.counts_per_rev", 0)
    levels, baseline, assistants = _conditions(r, sec["conditions"], dt)
    whole = r.flag(a.get("whole", STUDY.whole), "analysis.whole")
    window = " and ".join(f"analysis.{k}" for k in ("window_start_s", "window_s") if k in a)
    if whole and window:
        r.fail("analysis.whole", f"whole = true analyses every trial whole, but the file also sets {window}: "
                                 "drop the window or set whole = false")
    start = r.number(a.get("window_start_s", STUDY.window_start), "analysis.window_start_s", lo=0.0, strict=False)
    length = r.number(a.get("window_s", STUDY.window_seconds), "analysis.window_s", lo=0.0)
    preview = r.number(a.get("preview_s", STUDY.preview), "analysis.preview_s", lo=0.0, strict=False)
    if preview > MAX_PREVIEW:
        r.fail("analysis.preview_s", f"how far the human plans past the window must be at most {MAX_PREVIEW:g} s; "
                                     f"got {_show(preview)} (milliseconds for seconds?)")
    run = r.number(m.get("run_s", STUDY.run_seconds), "simulation.run_s", lo=0.0)
    subjects = r.integer(m.get("subjects", STUDY.subjects), "simulation.subjects", 1)
    trials = r.integer(m.get("trials", STUDY.trials), "simulation.trials", 1)
    sensor = r.flag(m.get("torque_sensor", STUDY.torque_sensor), "simulation.torque_sensor")
    n, beta = len(levels) - 1, m.get("beta", [])
    effects = (r.numbers(beta, "simulation.beta", n, f"{n} numbers, one per non-baseline level") if beta else ()) \
        if isinstance(beta, list) else (r.number(beta, "simulation.beta"),) * n
    try:
        design = Design(wheel=wheel, dt=dt, encoder_counts=counts, levels=levels, baseline=baseline,
                        assistants=assistants, run_seconds=run, subjects=subjects, trials=trials, torque_sensor=sensor,
                        effects=effects, window_start=start, window_seconds=length, whole=whole, preview=preview)
    except ValueError as exc:  # backstop: the checks above should have said it first
        found = re.search(r"Design\.(\w+)", str(exc))
        r.fail(_FIELD_SECTION.get(found.group(1)) if found else None, str(exc))
    return with_export(design, export)


def load_experiment(path) -> Design:
    """Read and validate an experiment file; :class:`ExperimentFileError` if it is missing, unreadable or invalid."""
    r = _Reader(path)
    try:
        text = Path(path).read_bytes().decode("utf-8")
    except FileNotFoundError:
        r.fail(None, "no such experiment file")
    except OSError as exc:
        r.fail(None, f"cannot read the experiment file: {exc.strerror or exc}")
    except UnicodeDecodeError as exc:
        r.fail(None, f"not UTF-8 text (byte {exc.start}); a TOML file is UTF-8")
    try:
        mapping = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        r.fail(None, f"not valid TOML: {exc}")
    return parse_experiment(mapping, path)


def _rate(dt: float) -> float:
    """The rate whose reciprocal is exactly ``dt``, preferring a round number."""
    exact = 1.0 / dt
    for rate in (round(exact), round(exact, 6), exact, math.nextafter(exact, math.inf), math.nextafter(exact, 0.0)):
        if rate > 0 and 1.0 / rate == dt:
            return float(rate)
    return exact


def _entry(spec: AssistantSpec) -> dict:
    if spec.kind == "mpc":
        return {"kind": "mpc", "theta": [float(v) for v in spec.theta], "horizon": int(spec.horizon),
                "step_s": float(spec.step_s), "period_s": float(spec.period_s)}
    return {"kind": "linear", "gain": [float(v) for v in spec.gain], "reference_gain": float(spec.reference_gain)}


def resolved(design: Design) -> dict:
    """Every applicable key of the experiment file for ``design``, as its nested tables (module docstring)."""
    d = design
    window = {} if d.whole else {"window_start_s": float(d.window_start), "window_s": float(d.window_seconds)}
    export = export_of(d)
    pattern = {} if export.from_file_name is None else {"from_file_name": export.from_file_name}
    data = ({"columns": {**dict(export.columns), **pattern}} if export.columns or pattern else {}) | (
        {"units": dict(export.units)} if export.units else {})
    return {
        "sampling": {"rate_hz": _rate(d.dt)},
        "wheel": {k: float(v) for k, v in zip(SECTIONS["wheel"], d.wheel)},
        "encoder": {"counts_per_rev": int(d.encoder_counts)},
        "conditions": {"baseline": d.baseline, "levels": list(d.levels),
                       "assistant": {lv: _entry(d.assistant(lv)) for lv in d.levels if d.assistant(lv)}},
        "analysis": {**window, "whole": bool(d.whole), "preview_s": float(d.preview)},
        **data,
        "simulation": {"run_s": float(d.run_seconds), "subjects": int(d.subjects), "trials": int(d.trials),
                       "torque_sensor": bool(d.torque_sensor), "beta": [float(v) for v in d.effects]},
    }


def experiment_hash(design: Design, *, analysis: bool = False) -> str:
    """SHA-256 (hex) of the canonical JSON (sorted keys, no spaces) of :func:`resolved`; with ``analysis``, of every
    section but ``[simulation]``, which only simulating reads (what artifacts of one study must share)."""
    tables = {k: v for k, v in resolved(design).items() if not (analysis and k == "simulation")}
    text = json.dumps(tables, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def to_toml(design: Design) -> str:
    """An experiment file (ASCII) that :func:`load_experiment` reads back to ``design``, relying on no default."""
    lines = ["# scioc experiment file: every key is described in pipelines/experiment.py"]
    for section, table in resolved(design).items():
        lines += ["", f"[{section}]"]
        for key, value in table.items():
            if key != "assistant":
                lines.append(f"{_key(None, key)} = {_show(value)}  # {_note(section, key)}")
        if section == "conditions":
            lines += ["", "[conditions.assistant]  # one entry per assisted level; other levels have u_A = 0"]
            lines += [f"{_key(None, lv)} = {_show(entry)}" for lv, entry in table["assistant"].items()] or [
                "# none: no level is assisted"]
        if section == "analysis" and design.whole:
            lines.append("# window_start_s, window_s: not used with whole = true")
    return "\n".join(lines) + "\n"


def _note(section: str, key: str) -> str:
    """The comment :func:`to_toml` writes beside ``section.key``."""
    if section == "columns" and key != "from_file_name":
        return f"the file's column holding {key}"
    if section == "units":
        return "unit of " + ", ".join(c for c, q in QUANTITY.items() if q == key)
    return _NOTES[key]


def write_experiment(design: Design, path) -> None:
    """Write :func:`to_toml` of ``design`` to ``path`` atomically."""
    write_text_atomic(path, to_toml(design))


def find_experiment(study_path, explicit=None) -> tuple[Design, str | None]:
    """``(Design, path)`` of ``explicit`` (``--experiment``), else of ``experiment.toml`` beside ``study_path``
    (a file or a glob pattern's files) or inside it (a folder); ``(STUDY, None)`` when there is neither."""
    if explicit is not None:
        return load_experiment(explicit), str(explicit)
    if study_path is not None:
        folder = Path(study_path) if Path(study_path).is_dir() else Path(study_path).parent
        beside = folder / EXPERIMENT_FILE
        if beside.exists():
            return load_experiment(beside), str(beside)
    return STUDY, None


def sidecar(design: Design, source: str | None) -> dict:
    """The experiment's fields of an artifact's JSON sidecar: resolved form, hash and source file."""
    return {"experiment": resolved(design), "experiment_sha256": experiment_hash(design),
            "experiment_file": None if source is None else str(source)}

