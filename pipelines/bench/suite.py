"""``scioc bench``: the parts of :mod:`scioc.pipelines.bench` in order; all ratios are measured in the same run."""

from __future__ import annotations

import builtins
import datetime
import json
from pathlib import Path

from scioc.pipelines.bench.common import default_study_segments, machine_info
from scioc.pipelines.bench.identify import bench_identify, format_identify
from scioc.pipelines.bench.likelihood import bench_likelihood, format_likelihood
from scioc.pipelines.provenance import commit_stamp, replace_section
from scioc.pipelines.storage import write_text_atomic

#: The parts of ``scioc bench``, in the order they run.
PARTS = ("likelihood", "delayed", "identify", "fit", "fit_delayed", "fit_angles", "sbc", "example")
#: The parts run when none are named: all but the long workflows.
DEFAULT_PARTS = ("likelihood", "delayed", "identify", "fit", "sbc", "example")


def report_section(parts) -> str:
    """The report section a run of ``parts`` writes: ``speed`` for the default parts, else one named by its parts,
    so a run of other parts keeps the default run's tables."""
    return "speed" if tuple(parts) == DEFAULT_PARTS else "speed-" + "-".join(parts)


def run_bench(json_path=None, *, quick: bool = False, parts=DEFAULT_PARTS, humans=None, keep=None,
              report=None) -> dict:
    """Run the benchmarks; print tables; optionally write JSON (atomically) and the tables as a section of the
    Markdown report ``report`` (docs/validation.md; :func:`report_section`), stamped with the commit.

    ``quick``: small sizes to test the command, without the fits and SBC. ``parts``: any of :data:`PARTS`
    (the fit's dense comparison needs ``likelihood``). ``humans``: the ``fit_delayed`` and ``fit_angles`` parts'
    simulated humans (default :data:`scioc.pipelines.bench.delayed_workflow.WORKFLOW_HUMANS` and
    :data:`~scioc.pipelines.bench.delayed_workflow.ANGLE_WORKFLOW_HUMANS`), whose study, estimates and fits ``keep``
    keeps in ``keep/<human>/`` (``keep/angles-<human>/``).
    """
    unknown = set(parts) - set(PARTS)
    if unknown:
        raise ValueError(f"unknown benchmark part(s) {sorted(unknown)}; choose from {', '.join(PARTS)}")
    if keep is not None:  # refused before the long parts run
        from scioc.pipelines.bench.delayed_workflow import (
            ANGLE_WORKFLOW_EFFECTS,
            ANGLE_WORKFLOW_HUMANS,
            WORKFLOW_HUMANS,
            refuse_used_folder,
        )

        for human in (WORKFLOW_HUMANS if humans is None else humans) if "fit_delayed" in parts else ():
            refuse_used_folder(Path(keep) / human)
        for human in (ANGLE_WORKFLOW_HUMANS if humans is None else humans) if "fit_angles" in parts else ():
            for effect in ANGLE_WORKFLOW_EFFECTS:
                refuse_used_folder(Path(keep) / f"angles-{human}-{effect:g}")
    kw = {"dense_k": (50, 100), "long_k": 2000} if quick else {}
    study = default_study_segments(n_subjects=2 if quick else 42)
    result = {"machine": machine_info(), "quick": quick}
    tables = []

    def print(text, flush=True):  # the console, and the report's section
        tables.append(text)
        builtins.print(text, flush=flush)
    if "likelihood" in parts:
        result["likelihood"] = bench_likelihood(study, **kw)
        print(format_likelihood(result["likelihood"]), flush=True)
    if "delayed" in parts:
        from scioc.pipelines.bench.delayed import bench_angles, bench_delayed, format_angles, format_delayed

        result["delayed"] = bench_delayed(study)
        print(format_delayed(result["delayed"]), flush=True)
        result["delayed_angles"] = bench_angles(study)
        print(format_angles(result["delayed_angles"]), flush=True)
    if "identify" in parts:
        result["identify"] = bench_identify(study)
        print(format_identify(result["identify"]), flush=True)
    if "fit" in parts and not quick:
        from scioc.pipelines.bench.fit import bench_fit, format_fit  # lazy: PyMC takes seconds to import

        lik = result.get("likelihood", {})
        dense = {r["K"]: r["dense_s"] for r in lik.get("rows", [])}
        K = study[2.0][0].segment.K
        result["fit"] = bench_fit(study, dense_s_per_segment=dense.get(K),
                                  linear_s_per_batch=lik.get("batch_preview", {}).get("linear_s"))
        print(format_fit(result["fit"]), flush=True)
    if "fit_delayed" in parts and not quick:
        from scioc.pipelines.bench.delayed_workflow import (
            WORKFLOW_HUMANS,
            bench_delayed_workflow,
            format_delayed_workflow,
        )
        from scioc.pipelines.bench.fit_delayed import bench_delay_profile, format_delay_profile

        result["fit_delayed"] = {"profile": bench_delay_profile(), "workflow": {}}
        print(format_delay_profile(result["fit_delayed"]["profile"]), flush=True)
        for human in WORKFLOW_HUMANS if humans is None else humans:
            result["fit_delayed"]["workflow"][human] = bench_delayed_workflow(
                human=human, keep=None if keep is None else Path(keep) / human)
            print(format_delayed_workflow(result["fit_delayed"]["workflow"][human]), flush=True)
    if "fit_angles" in parts and not quick:
        from scioc.pipelines.bench.delayed_workflow import (
            ANGLE_WORKFLOW_EFFECTS,
            ANGLE_WORKFLOW_HUMANS,
            bench_angle_workflow,
            format_angle_workflow,
        )

        result["fit_angles"] = {}
        for human in ANGLE_WORKFLOW_HUMANS if humans is None else humans:
            for effect in ANGLE_WORKFLOW_EFFECTS:
                name = f"{human}-{effect:g}"
                result["fit_angles"][name] = bench_angle_workflow(
                    human=human, effect=effect, keep=None if keep is None else Path(keep) / f"angles-{name}")
                print(format_angle_workflow(result["fit_angles"][name]), flush=True)
    if "sbc" in parts and not quick:
        from scioc.pipelines.bench.sbc import bench_sbc, format_sbc  # lazy: Dask and PyMC take seconds to import

        result["sbc"] = bench_sbc()
        print(format_sbc(result["sbc"]), flush=True)
    if "example" in parts:
        from scioc.pipelines.bench.example import bench_example, format_example  # lazy: the fit imports PyMC

        result["example"] = bench_example(fit=not quick)
        print(format_example(result["example"]), flush=True)
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(result, indent=2) + "\n")
    if report is not None:
        machine = ", ".join(f"{k} {v}" for k, v in result["machine"].items())
        section = report_section(parts)
        heading = "`make bench`" if section == "speed" else f"`scioc bench --parts {','.join(parts)}`"
        replace_section(report, section, "\n".join([
            f"## Speed ({heading})", "", f"- commit: `{commit_stamp()}`",
            f"- generated: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC",
            f"- parts: {', '.join(parts)}{' (quick sizes: not quotable)' if quick else ''}", f"- machine: {machine}",
            "", "```text", *tables, "```"]))
    return result
