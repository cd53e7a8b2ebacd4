"""Benchmark of the identification of the default study, its reconstruction and its adequacy checks."""

from __future__ import annotations

import time

from scioc.models.identify import identify_segment
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.adequacy import assess_study
from scioc.pipelines.prepare import IdentifySettings


def bench_identify(study: dict) -> dict:
    """Wall time of maximum-likelihood identification of every segment, of its reconstruction, and of the
    model-adequacy checks (bootstrap included) at the default settings, as a fraction of the two."""
    plant = discretize(DT_HUMAN)
    out = {}
    for preview in (0.0, 2.0):
        batches = [prepare_batch(plant, [p.segment]) for p in study[preview]]
        identify_segment(batches[0], plant)  # compile
        t0 = time.perf_counter()
        ests = [identify_segment(b, plant) for b in batches]
        out[f"preview_{preview:g}s"] = {
            "segments": len(batches),
            "identify_s": time.perf_counter() - t0,
            "reconstruct_s": study[f"reconstruct_s_{preview}"],
            "converged": int(sum(e.converged for e in ests)),
        }
    settings = IdentifySettings()
    assess_study(study[2.0][:2], [e.theta for e in ests[:2]], plant, settings)  # compile
    t0 = time.perf_counter()
    _, verdict = assess_study(study[2.0], [e.theta for e in ests], plant, settings)
    r = out["preview_2s"]
    r["adequacy_s"] = time.perf_counter() - t0
    r["adequacy_boot"] = settings.adequacy_boot
    r["adequacy_verdict"] = verdict["verdict"]
    r["adequacy_fraction_of_identify"] = r["adequacy_s"] / (r["identify_s"] + r["reconstruct_s"])
    return out


def format_identify(res: dict) -> str:
    lines = ["", "Identification of every segment of the default study (SLSQP, exact gradient, one core)"]
    for key, r in res.items():
        lines.append(
            f"  {key}: {r['segments']} segments in {r['identify_s']:.2f} s ({r['converged']} converged); "
            f"reconstruction from the angle beforehand: {r['reconstruct_s']:.2f} s"
        )
        if "adequacy_s" in r:
            lines.append(
                f"    model adequacy ({r['adequacy_boot']} bootstrap data sets per segment, verdict "
                f"{r['adequacy_verdict']}): {r['adequacy_s']:.2f} s = {r['adequacy_fraction_of_identify']:.0%} of "
                f"reconstruction + identification (goal: <= 50 %)")
    return "\n".join(lines)
