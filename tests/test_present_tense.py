"""The code speaks in the present tense: no ISO date or commit hash in the docstrings and comments of models/ and
pipelines/ or in any ``--help`` text, and prose (docstring and whole-line comment lines) is at most a fifth of their
lines. History lives in git and CHANGELOG.md; measured numbers in docs/validation.md."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "pipelines")
#: The largest share of prose lines over all lines of models/ and pipelines/.
MAX_PROSE_SHARE = 0.20
ISO_DATE = re.compile(r"\b(19|20)\d\d-[01]\d-[0-3]\d\b")
#: 7 to 40 hexadecimal characters with at least one digit and one letter: how git abbreviates a commit.
COMMIT = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def prose_lines(source: str) -> dict:
    """{line number: text} of the docstrings (module, class, function, and attribute docstrings) and whole-line
    comments of ``source``."""
    tree = ast.parse(source)
    lines = source.split("\n")
    found = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if not isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) or not body:
            continue
        for i, stmt in enumerate(body):
            is_text = (isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant)
                       and isinstance(stmt.value.value, str))
            if is_text and (i == 0 or isinstance(node, (ast.Module, ast.ClassDef))):
                found |= set(range(stmt.lineno, stmt.end_lineno + 1))
    found |= {i for i, text in enumerate(lines, 1) if text.lstrip().startswith("#")}
    return {i: lines[i - 1] for i in sorted(found)}


def _sources():
    return sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))


def _stamps(text: str) -> list:
    return [m.group(0) for pattern in (ISO_DATE, COMMIT) for m in pattern.finditer(text)]


def test_no_date_or_commit_hash_in_docstrings_or_comments():
    bad = [f"{p.relative_to(ROOT)}:{i}: {text.strip()[:80]}" for p in _sources()
           for i, text in prose_lines(p.read_text()).items() if _stamps(text)]
    assert not bad, "\n".join(bad)


def test_a_date_or_hash_would_be_found():
    source = '"""Measured 2026-12-06 at 0e997e7."""\n# since c568f96\nx = "2026-12-06"  # ok: code\n'
    found = prose_lines(source)
    assert sorted(found) == [1, 2] and [s for t in found.values() for s in _stamps(t)] == [
        "2026-12-06", "0e997e7", "c568f96"]
    assert not _stamps("decade 1e308 abcdef 1234567")  # no letter-and-digit mix, or too short


def test_no_date_or_commit_hash_in_any_help_text(capsys):
    from scioc.pipelines.cli import build_parser

    parser = build_parser()
    texts = [parser.format_help()]
    for action in parser._subparsers._group_actions:
        texts += [sub.format_help() for sub in action.choices.values()]
    bad = [s for t in texts for s in _stamps(t)]
    assert not bad, bad


def test_prose_is_at_most_a_fifth_of_the_lines():
    total = prose = 0
    for p in _sources():
        source = p.read_text()
        total += len(source.rstrip("\n").split("\n"))
        prose += len(prose_lines(source))
    assert prose / total <= MAX_PROSE_SHARE, f"{prose} of {total} lines are prose ({prose / total:.1%})"
