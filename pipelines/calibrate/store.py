"""Where a calibration keeps its results: one JSON file per replication, the configuration, the summary.

``OUT/reps/rep_NNNNN.json`` is written atomically when a replication finishes; a rerun skips those
that exist. ``OUT/config.json`` holds the fingerprint (another configuration is refused) and
``OUT/summary.json`` the summary (a rerun with fewer replications is refused rather than replacing it).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

from scioc.pipelines.calibrate.config import CalibrationConfig
from scioc.pipelines.io import InputDataError
from scioc.pipelines.storage import write_text_atomic

#: The fields every replication file holds.
REPLICATION_FIELDS = frozenset({"ranks", "pit_u", "ess", "contraction", "seconds", "truth", "thinned"})


def rep_path(out_dir, i: int) -> Path:
    return Path(out_dir) / "reps" / f"rep_{i:05d}.json"


def read_json(path, what: str = "replication") -> dict:
    """Read one of the calibration's JSON files; a damaged one is named, with the way out."""
    try:
        return json.loads(Path(path).read_text())
    except (ValueError, UnicodeDecodeError) as exc:  # JSONDecodeError is a ValueError
        raise InputDataError(f"{path}: damaged {what} file ({exc}); delete it and rerun to recompute it") from None


def prepare_out(config: CalibrationConfig, out_dir: Path) -> None:
    cfg_path = out_dir / "config.json"
    d = asdict(config)
    if cfg_path.exists():
        old = read_json(cfg_path, "configuration")
        old_fp = old.get("fingerprint")
        if old_fp != config.fingerprint():
            raise ValueError(
                f"{cfg_path}: this folder holds replications of a different configuration "
                f"(fingerprint {old_fp} vs {config.fingerprint()}); use another --out"
            )
        return
    write_text_atomic(cfg_path, json.dumps({**d, "fingerprint": config.fingerprint()}, indent=2) + "\n")


def earlier_summary(config: CalibrationConfig, out_dir) -> dict:
    """The summary already in ``out_dir`` ({} if none); ValueError if it covers more replications than ``config``."""
    path = Path(out_dir) / "summary.json"
    earlier = read_json(path, "summary") if path.exists() else {}
    if earlier.get("replications", 0) > config.replications:
        raise ValueError(
            f"{path} summarizes {earlier['replications']} replications; this run asks for "
            f"{config.replications} and would replace it: use --replications {earlier['replications']} "
            "(or more), or another --out")
    return earlier


def load_replications(out_dir, config: CalibrationConfig) -> list[dict]:
    """The first ``config.replications`` replication files, each checked: its fields, that it is replication i of this
    configuration (its ``index`` and ``fingerprint``), and every rank in 0..L with the first file's quantities."""
    n, fingerprint = config.replications, config.fingerprint()
    missing = [i for i in range(n) if not rep_path(out_dir, i).exists()]
    if missing:
        raise FileNotFoundError(f"{out_dir}: {len(missing)} replications missing (first {missing[0]}); rerun to resume")
    reps = [read_json(rep_path(out_dir, i)) for i in range(n)]
    names = set(reps[0].get("ranks", {})) if isinstance(reps[0], dict) else set()
    for i, rep in enumerate(reps):
        path = rep_path(out_dir, i)
        if not (isinstance(rep, dict) and REPLICATION_FIELDS <= rep.keys() and isinstance(rep["ranks"], dict)):
            raise InputDataError(f"{path}: damaged replication file (fields missing); delete it and rerun to "
                                 "recompute it")
        if rep.get("index") != i:
            raise InputDataError(f"{path}: key 'index' is {rep.get('index')!r}: it holds another replication than {i} "
                                 "(copied under another name?); delete it and rerun to recompute it")
        if rep.get("fingerprint") != fingerprint:
            raise InputDataError(f"{path}: key 'fingerprint' is {rep.get('fingerprint')!r}, this calibration's "
                                 f"{fingerprint} ({out_dir / 'config.json'}): a replication of another configuration; "
                                 "delete it and rerun to recompute it")
        if set(rep["ranks"]) != names:
            raise InputDataError(f"{path}: key 'ranks' ranks {', '.join(sorted(rep['ranks']))}, "
                                 f"{rep_path(out_dir, 0)} {', '.join(sorted(names))}: delete it and rerun")
        for name, r in rep["ranks"].items():
            if isinstance(r, bool) or not isinstance(r, int) or not 0 <= r <= config.L:
                raise InputDataError(f"{path}: key 'ranks.{name}' is {r!r}; a rank among L = {config.L} draws is an "
                                     f"integer from 0 to {config.L}: delete it and rerun to recompute it")
    return reps


def write_replication(out_dir, res: dict) -> None:
    """Write one finished replication's file (atomically)."""
    write_text_atomic(rep_path(out_dir, res["index"]), json.dumps(res) + "\n")
