"""The Makefile's test commands work in a fresh checkout: the tier's options are known to pytest there too.

``--validation-report`` is defined in ``tests/conftest.py``. Before that file is loaded, pytest reads an unknown
option's value (``docs/validation.md``) as a path to test, and loads only the conftest files beside that path: the
option stays unknown. The commands therefore name ``tests`` and join the option to its value with ``=``.
"""

import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _recipe(target: str) -> list[str]:
    text = (ROOT / "Makefile").read_text()
    match = re.search(rf"^{target}:.*\n((?:\t.*\n)+)", text, flags=re.M)
    assert match, f"Makefile has no target {target!r}"
    lines = [line.strip() for line in match.group(1).splitlines() if "pytest" in line]
    assert len(lines) == 1, f"target {target!r} should run pytest once: {lines}"
    return shlex.split(lines[0])


def _checkout(tmp_path: Path) -> Path:
    """pyproject.toml, tests/ and docs/validation.md, without caches."""
    copy = tmp_path / "checkout"
    (copy / "docs").mkdir(parents=True)
    shutil.copy(ROOT / "pyproject.toml", copy)
    shutil.copy(ROOT / "docs" / "validation.md", copy / "docs")
    shutil.copytree(ROOT / "tests", copy / "tests", ignore=shutil.ignore_patterns("__pycache__", ".pytest_cache"))
    return copy


@pytest.mark.parametrize("target", ["test", "validate"])
def test_the_tiers_command_collects_in_a_checkout_without_pytest_cache(target, tmp_path):
    copy = _checkout(tmp_path)
    argv = _recipe(target)
    assert argv[:3] == ["$(VENV)/bin/python", "-m", "pytest"], argv
    done = subprocess.run([sys.executable, "-m", "pytest", *argv[3:], "--collect-only", "-q"],
                          cwd=copy, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert re.search(r"\d+/\d+ tests collected|\d+ tests collected", done.stdout), done.stdout[-500:]


def test_the_negative_control_an_unknown_option_fails_without_naming_tests(tmp_path):
    """Without ``tests`` on the command line the option is unknown in a fresh checkout (the failure CI met)."""
    copy = _checkout(tmp_path)
    done = subprocess.run([sys.executable, "-m", "pytest", "-m", "validation", "--validation-report",
                           "docs/validation.md", "--collect-only", "-q"],
                          cwd=copy, capture_output=True, text=True, timeout=600)
    assert done.returncode != 0 and "--validation-report" in done.stderr
