"""Lineage by content: the SHA-256 of what an artifact was made from, and the check that artifacts belong together.

A sidecar's ``inputs`` holds per input it read ``{"path", "sha256"}`` (:func:`entry`). The hash of a file is that
of its bytes; of a study of several files, that of the ``HASH  NAME`` lines of its files sorted by name (as
``sha256sum`` prints them; names relative to their common folder); of a folder artifact, that of its sidecar
(:data:`SIDECARS`); of an experiment, that of its canonical form as analysed
(:func:`experiment_entry`). A stage folder's sidecar also records the hash of each file
it wrote (``outputs``). Commands that combine artifacts compare hashes, never paths (:func:`require_same`): a
mismatch is a :class:`LineageError` (exit 3) naming both files and what differs.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from scioc.pipelines.experiment import experiment_hash
from scioc.pipelines.io import InputDataError, StudyFileError, study_files

#: The sidecar that stands for a folder artifact, by the stage that wrote it.
SIDECARS = {"fit": "posterior.json", "identify": "identify.json", "simulate": "simulation.json"}
#: Hex digits of a hash shown in messages (the sidecars hold all 64).
SHOWN = 12


class LineageError(InputDataError):
    """Artifacts that were not made from each other: exit 3, naming both files."""


def file_sha256(path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def study_entry(path) -> dict:
    """The ``inputs`` entry of a study (a file, a folder or a glob): its hash and, for several files, each file's."""
    files = study_files(path)
    for f in files:
        if not f.is_file():
            raise StudyFileError(f, "no such file")
    if len(files) == 1:
        return {"path": str(path), "sha256": file_sha256(files[0])}
    common = Path(os.path.commonpath([f.resolve().parent for f in files]))
    listed = sorted((f.resolve().relative_to(common).as_posix(), file_sha256(f)) for f in files)
    text = "".join(f"{digest}  {name}\n" for name, digest in listed)
    return {"path": str(path), "sha256": hashlib.sha256(text.encode()).hexdigest(),
            "files": [{"name": name, "sha256": digest} for name, digest in listed]}


def artifact_sha256(path) -> str:
    """The hash of an artifact: a file's, or a folder's sidecar's (:data:`SIDECARS`)."""
    path = Path(path)
    if path.is_dir():
        for name in SIDECARS.values():
            if (path / name).is_file():
                return file_sha256(path / name)
        raise LineageError(f"{path}: no sidecar ({', '.join(SIDECARS.values())}): not a folder a scioc stage wrote")
    return file_sha256(path)


def entry(path, sha256: str | None = None) -> dict:
    """``{"path", "sha256"}`` of an input (the hash computed with :func:`artifact_sha256` unless given)."""
    return {"path": str(path), "sha256": artifact_sha256(path) if sha256 is None else sha256}


def experiment_entry(design, source) -> dict:
    """The ``inputs`` entry of an experiment: its file (None: the paper's study) and the hash of its canonical form
    without ``[simulation]`` (:func:`scioc.pipelines.experiment.experiment_hash`)."""
    return {"path": None if source is None else str(source), "sha256": experiment_hash(design, analysis=True)}


def outputs(folder, names) -> dict:
    """``{name: SHA-256}`` of the files ``names`` a stage wrote into ``folder``, for its sidecar's ``outputs``."""
    return {name: file_sha256(Path(folder) / name) for name in names}


def read_sidecar(path) -> dict:
    """A sidecar's JSON (LineageError naming it if unreadable)."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise LineageError(f"{path}: not readable as a scioc sidecar ({exc})") from None


def recorded(side: dict, key: str, sidecar, *, where: str = "inputs") -> dict | str:
    """``side[where][key]``: what the sidecar at ``sidecar`` records; LineageError if it records nothing."""
    found = (side.get(where) or {}).get(key) if isinstance(side, dict) else None
    if not found:
        raise LineageError(f"{sidecar}: records no {where[:-1]} {key!r} with its SHA-256 (written by a scioc that did "
                           "not record what artifacts are made from); make it again with this scioc")
    return found


def short(sha256: str | None) -> str:
    return "none" if not sha256 else sha256[:SHOWN]


def files_difference(theirs: dict, ours: dict) -> str:
    """What differs between two study entries' files ('' where either is one file)."""
    a = {f["name"]: f["sha256"] for f in theirs.get("files", [])}
    b = {f["name"]: f["sha256"] for f in ours.get("files", [])}
    if not a or not b:
        return ""
    parts = [f"{n} differs" for n in sorted(a.keys() & b.keys()) if a[n] != b[n]]
    parts += [f"{n} is not in it" for n in sorted(a.keys() - b.keys())]
    parts += [f"{n} is new" for n in sorted(b.keys() - a.keys())]
    return "; " + ", ".join(parts[:3]) + (f" and {len(parts) - 3} more" if len(parts) > 3 else "") if parts else ""


def require_same(what: str, sidecar, theirs: dict, given, ours: dict) -> None:
    """LineageError unless the ``what`` that ``sidecar`` records (``theirs``) has the hash of ``given`` (``ours``).

    Examples
    --------
    >>> require_same("study", "fit/posterior.json", {"path": "a.csv", "sha256": "1" * 64},
    ...              "b.csv", {"sha256": "2" * 64})  # doctest: +IGNORE_EXCEPTION_DETAIL
    Traceback (most recent call last):
    LineageError: b.csv is not the study fit/posterior.json was made from: ...
    """
    if theirs.get("sha256") == ours.get("sha256"):
        return
    raise LineageError(f"{given} is not the {what} {sidecar} was made from: that {what} ({theirs.get('path')}) has "
                       f"SHA-256 {short(theirs.get('sha256'))}, this one {short(ours.get('sha256'))}"
                       f"{files_difference(theirs, ours)}")


def require_one(what: str, first: tuple, second: tuple) -> None:
    """LineageError unless two sidecars' records of a ``what`` have one hash; ``(sidecar, entry)`` each."""
    (a, theirs), (b, ours) = first, second
    if theirs.get("sha256") != ours.get("sha256"):
        raise LineageError(f"{a} and {b} are not of the same {what}: {a} records {theirs.get('path')} (SHA-256 "
                           f"{short(theirs.get('sha256'))}), {b} records {ours.get('path')} (SHA-256 "
                           f"{short(ours.get('sha256'))}){files_difference(theirs, ours)}")


def simulated_study(truth_path) -> tuple[Path, dict]:
    """``simulation.json`` beside ``truth_path`` (checked by :func:`simulation`) and the entry of the study it wrote."""
    meta_path, meta = simulation(truth_path)
    wrote = recorded(meta, "study.parquet", meta_path, where="outputs")
    return meta_path, {"path": str(meta_path.parent / "study.parquet"), "sha256": wrote}


def _written_by(path: Path, meta_path: Path, what: str, hint: str = "") -> dict:
    """The sidecar at ``meta_path``, after checking that it wrote ``path`` as it is (LineageError naming both)."""
    meta = read_sidecar(meta_path)
    wrote = recorded(meta, path.name, meta_path, where="outputs")
    have = file_sha256(path)
    if wrote != have:
        raise LineageError(f"{path} is not the {what} {meta_path} records: it wrote {path.name} with SHA-256 "
                           f"{short(wrote)}, this file has {short(have)}{hint}")
    return meta


def identification(estimates_path) -> tuple[Path, dict] | None:
    """``identify.json`` beside ``estimates_path`` and its content, after checking that it wrote these estimates
    (LineageError naming both otherwise); None where there is no ``identify.json``."""
    estimates_path = Path(estimates_path)
    meta_path = estimates_path.parent / SIDECARS["identify"]
    if not meta_path.is_file():
        return None
    return meta_path, _written_by(estimates_path, meta_path, "estimates",
                                  " (replaced or edited since); identify again, or give the estimates and "
                                  "identify.json written together")


def simulation(truth_path) -> tuple[Path, dict]:
    """``simulation.json`` beside ``truth_path`` and its content, after checking that it wrote this truth
    (LineageError naming both otherwise, or when there is none)."""
    truth_path = Path(truth_path)
    meta_path = truth_path.parent / SIDECARS["simulate"]
    if not meta_path.is_file():
        raise LineageError(f"{truth_path}: no {meta_path.name} beside it, so which simulated study it is the truth of "
                           "is not known; give the truth.parquet scioc simulate wrote, in its folder")
    return meta_path, _written_by(truth_path, meta_path, "truth")


__all__ = ["LineageError", "SIDECARS", "artifact_sha256", "entry", "experiment_entry", "file_sha256",
           "files_difference", "identification", "outputs", "read_sidecar", "recorded", "require_one", "require_same",
           "short", "simulated_study", "simulation", "study_entry"]
