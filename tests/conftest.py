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

from scioc.models.plant import discretize  # noqa: E402
from scioc.models.segment import Feedback, Segment  # noqa: E402


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



@pytest.fixture(scope="session")
def plant():
    return discretize(0.01)


def random_segment(rng: np.random.Generator, K: int, shared: bool) -> Segment:
    """A segment with a smooth random reference, random x0, random torques; random u_A in SC."""
    t = np.arange(K + 1) * 0.01
    ref = rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
    u_A = rng.normal(0.0, 0.3, K) if shared else np.zeros(K)
    return Segment(rng.normal(0.0, 0.1, 2), ref, rng.normal(0.0, 0.5, K), u_A)


def random_window_inputs(rng: np.random.Generator, plant, K: int, M: int, mode: str):
    """A window's inputs for the delayed human's tests: a smooth random reference over K + M + 1 samples, x0, the
    assistant's law and a random u_A (K + M); ``kw`` gives the assistant ``mode`` says ("MC", "SC feedback",
    "SC exogenous") as sample_delayed's keywords. Returns (ref, x0, feedback, u_A, kw)."""
    t = np.arange(K + M + 1) * plant.dt
    ref = rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
    x0 = rng.normal(0.0, 0.1, 2)
    fb = Feedback(np.array([rng.uniform(0.5, 5.0), rng.uniform(0.0, 0.5)]), rng.normal(0.0, 0.3, K + M))
    u_A = rng.normal(0.0, 0.3, K + M)
    kw = {"feedback": fb} if mode == "SC feedback" else {"u_A": u_A} if mode == "SC exogenous" else {}
    return ref, x0, fb, u_A, kw


def random_theta(rng: np.random.Generator, q22_zero: bool) -> np.ndarray:
    return np.array([rng.uniform(1.0, 300.0), 0.0 if q22_zero else rng.uniform(0.01, 2.0), rng.uniform(0.1, 5.0)])
