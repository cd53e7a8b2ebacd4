"""The tests' configuration: process settings, shared fixtures, and the validation tier's report.

Two tiers (README "Tests"): ``make test`` runs every test not marked ``validation`` (exactness against the dense
references, gradients, invariants, input validation, the CLI, one small shared fit); ``make validate`` runs the
``validation`` tests (false-alarm budgets, SBC smoke runs, delayed fits, recovery) and writes their report with
``--validation-report docs/validation.md``: each test's outcome, time and the numbers it measured (the ``measured``
fixture), stamped with the commit.
"""

import datetime
import os
import platform
from pathlib import Path

import numpy as np
import pytest

import scioc

scioc.configure()  # before any kernel compiles: numba's cache, PyTensor's fast-math off


ROOT = Path(__file__).resolve().parents[1]


def pytest_addoption(parser):
    parser.addoption("--validation-report", metavar="PATH", default=None,
                     help="write the report of the tests run (outcome, time, measured numbers) to PATH (Markdown)")


_RESULTS: dict = {}  # nodeid -> {"outcome", "seconds", "measured": [...]}


@pytest.fixture
def measured(request):
    """Record a number this test measured for the validation report: ``measured(what, value, limit=None)``.

    ``limit`` is the test's pass condition as text (e.g. ``"<= 0.05"``); the report shows it beside the value.
    """
    rows = _RESULTS.setdefault(request.node.nodeid, {}).setdefault("measured", [])

    def record(what: str, value, limit: str | None = None):
        value = float(value) if isinstance(value, (int, float, np.integer, np.floating)) else value
        rows.append({"what": what, "value": value, "limit": limit})

    return record


def pytest_runtest_logreport(report):
    row = _RESULTS.setdefault(report.nodeid, {})
    row["seconds"] = row.get("seconds", 0.0) + report.duration
    if (report.when == "call" or report.outcome != "passed") and row.get("outcome") in (None, "passed"):
        row["outcome"] = report.outcome


def _fmt(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def pytest_sessionfinish(session, exitstatus):
    path = session.config.getoption("--validation-report")
    if not path:
        return
    from scioc.pipelines.provenance import commit_stamp, replace_section

    ran = {k: v for k, v in _RESULTS.items() if "outcome" in v}
    n_failed = sum(v["outcome"] != "passed" for v in ran.values())
    lines = ["## Validation (`make validate`)", "",
             f"- commit: `{commit_stamp(ROOT)}`",
             f"- generated: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
             f"- machine: {platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}",
             f"- tests: {len(ran)}, failed: {n_failed}, total time {sum(v['seconds'] for v in ran.values()) / 60:.1f} "
             "min", "",
             "### Measured", "", "| test | what | value | pass condition |", "|---|---|---|---|"]
    for nodeid, v in sorted(ran.items()):
        for m in v.get("measured", []):
            lines.append(f"| `{nodeid}` | {m['what']} | {_fmt(m['value'])} | {m['limit'] or ''} |")
    lines += ["", "### Every test", "", "| test | outcome | seconds |", "|---|---|---|"]
    for nodeid, v in sorted(ran.items()):
        lines.append(f"| `{nodeid}` | {v['outcome']} | {v['seconds']:.1f} |")
    replace_section(path, "validation", "\n".join(lines))
