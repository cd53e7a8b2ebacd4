"""Writing results safely: atomic files, output folders replaced as a whole, inputs never overwritten.

Every stage writes its artifacts through these functions, so that an interrupted or
failed run leaves the previous results as they were and never a mix of two runs.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import pandas as pd


def _umask() -> int:
    # The only portable way to read the umask is to set it; set it straight back.
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path beside ``path``; rename it onto ``path`` only on success.

    The file gets a plainly created file's permissions (0o666 less the umask), not ``mkstemp``'s 0o600.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def refuse_file_on_path(out) -> None:
    """FileExistsError (exit 2) where ``out`` or a folder above it exists as a file, which no folder can be made in."""
    for p in (Path(out), *Path(out).parents):
        if p.exists() and not p.is_dir():
            raise FileExistsError(f"{p} exists and is not a folder; choose another output folder"
                                  + (f" than {out}" if p != Path(out) else ""))


def check_output_dir(out, *, force: bool = False) -> Path:
    """:func:`staged_dir`'s checks, to run before a long stage: FileExistsError for a non-folder, or a
    non-empty folder without ``force``; ValueError for the current folder or one holding it, which the
    rename that replaces a folder as a whole cannot move."""
    target = Path(out)
    refuse_file_on_path(target)
    here = Path.cwd().resolve()
    if target.resolve() == here or target.resolve() in here.parents:
        raise ValueError(f"the output folder {out} is the current folder or holds it, which replacing it as a whole "
                         "would move away; give a subfolder, or run from another folder")
    if target.is_dir() and any(target.iterdir()) and not force:
        raise FileExistsError(f"{target} already holds results; use --force to replace them as a whole, "
                              "or choose another output folder")
    return target


@contextlib.contextmanager
def staged_dir(out, *, force: bool = False):
    """Yield a fresh temporary folder beside ``out``; on success it replaces ``out`` as a whole.

    On success an existing ``out`` is renamed aside, the new folder renamed to ``out`` and the old one
    deleted, so ``out`` never mixes two runs. On an exception (``KeyboardInterrupt`` included) the
    temporary folder is removed and ``out`` left as it was; SIGKILL leaves ``out`` intact plus a hidden
    ``.NAME.*.tmp`` folder. A non-empty ``out`` is refused (FileExistsError) unless ``force``.

    Examples
    --------
    >>> with staged_dir("results/identify", force=True) as tmp:  # doctest: +SKIP
    ...     write_table_atomic(estimates, tmp / "estimates.parquet")
    """
    target = Path(os.path.abspath(check_output_dir(out, force=force)))  # "x/.." has no name to stage beside
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
    try:
        os.chmod(tmp, 0o777 & ~_umask())
        yield tmp
        if target.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".old", dir=target.parent))
            try:
                os.replace(target, old)  # renames over the empty placeholder folder
            except BaseException:
                os.rmdir(old)
                raise
            try:
                os.replace(tmp, target)
            except BaseException:
                os.replace(old, target)
                raise
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def write_text_atomic(path, text: str) -> Path:
    """Write text to ``path`` through a temporary file and a rename."""
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


def write_table_atomic(df: pd.DataFrame, path) -> Path:
    """Write a DataFrame as Parquet (or CSV for a ``.csv`` path) atomically."""
    with atomic_path(path) as tmp:
        if Path(path).suffix.lower() == ".csv":
            df.to_csv(tmp, index=False)
        else:
            df.to_parquet(tmp, index=False)
    return Path(path)


def refuse_inputs_inside(out, *inputs) -> None:
    """ValueError (a usage error, exit 2) if ``out`` is or holds one of the inputs, which replacing it would delete."""
    target = Path(out).resolve()
    for p in inputs:
        if p is None:
            continue
        q = Path(p).resolve()
        if q == target or target in q.parents:
            raise ValueError(f"the output folder {out} holds the input {p}, which replacing it would delete; "
                             "choose another output folder")


#: The key of a result file that records which command wrote it (:func:`check_output_file`).
WRITTEN_BY = "written_by"


def check_output_file(out, command: str, inputs: dict) -> Path:
    """ValueError (a usage error, exit 2) unless the file ``out`` may be written by ``command`` (``"scioc compare"``).

    An output file never replaces an input: not one of ``inputs`` (``{what: path}``, e.g. ``{"the estimates file":
    path}``), however spelled, nor any existing file that is not an earlier result of the same command (a JSON object
    whose :data:`WRITTEN_BY` is ``command``), so no study, table, posterior, experiment file or another stage's
    result of the run folder it writes into.
    """
    target = Path(out)
    refuse_file_on_path(target.parent)
    if target.is_dir():
        raise ValueError(f"--out {out} is a folder; give a file name")
    for what, p in inputs.items():
        if p is not None and (target.resolve() == Path(p).resolve()
                              or (target.exists() and Path(p).exists() and os.path.samefile(target, p))):
            raise ValueError(f"--out {out} is {what} itself, an input of this command; write the result elsewhere")
    if target.exists():
        try:
            earlier = json.loads(target.read_text()).get(WRITTEN_BY)
        except (OSError, ValueError, AttributeError):
            earlier = None
        if earlier != command:
            raise ValueError(f"--out {out} exists and is not an earlier result of {command}: writing would overwrite "
                             "it (an input of the run folder, or another command's result); choose another --out")
    return target
