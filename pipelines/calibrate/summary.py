"""The statistics of a calibration from its replication files, and their plain-text form.

Per ranked quantity: the uniformity verdict (docs/decisions/sbc-ks-verdict.md), ArviZ's ``pot_c``
test beside it, coverage of central intervals and posterior contraction. :func:`sbc_tree` gathers the
replications into one DataTree in simuk's layout, which ArviZ's and simuk's tools read.
"""

from __future__ import annotations

from dataclasses import asdict

import numpy as np
import xarray as xr
from arviz_stats.base import array_stats

from scioc.models.sbc import COVERAGE_LEVELS, pit_from_rank, uniformity_test
from scioc.pipelines.calibrate.config import CalibrationConfig
from scioc.pipelines.calibrate.store import load_replications

#: Family-wise false-failure rate of the uniformity tests of one calibration run
#: (Bonferroni over the parameters tested).
FAMILY_ALPHA = 0.01


def pits(reps: list[dict], L: int) -> dict:
    """The randomized PIT ``(rank + U) / (L + 1)`` of every ranked quantity over replications (in order)."""
    return {name: pit_from_rank([rep["ranks"][name] for rep in reps], L, [rep["pit_u"][name] for rep in reps])
            for name in reps[0]["ranks"]}


def summarize(out_dir, config: CalibrationConfig) -> dict:
    """Uniformity tests, coverage and contraction over all replications, per ranked quantity.

    The verdict: KS of the randomized PIT at ``FAMILY_ALPHA / (number of quantities)``; ``pot_c_p_value``:
    ArviZ's ``pot_c`` test of the same values (docs/decisions/sbc-ks-verdict.md).
    """
    reps = load_replications(out_dir, config)
    alpha = FAMILY_ALPHA / len(reps[0]["ranks"])
    params = {}
    for name, pit in pits(reps, config.L).items():
        test = uniformity_test(pit, alpha)
        pot_c = array_stats.uniformity_test(pit, axis=-1, method="pot_c")[0]
        # Coverage of central intervals from the PIT (as ArviZ does): the truth is inside the
        # central `level` interval iff |PIT - 1/2| <= level/2. Exact under calibration, unlike
        # quantiles of only L thinned draws, whose intervals are too narrow for small L.
        cov = np.array([np.mean(np.abs(pit - 0.5) <= lv / 2) for lv in COVERAGE_LEVELS])
        contraction = [rep["contraction"][name] for rep in reps if name in rep["contraction"]]
        params[name] = {
            "ks_statistic": test.statistic,
            "p_value": test.p_value,
            "alpha": alpha,
            "passed": test.passed,
            "pot_c_p_value": float(pot_c),
            "coverage": dict(zip([str(lv) for lv in COVERAGE_LEVELS], cov.tolist())),
            "contraction": float(np.mean(contraction)) if contraction else None,
            "low_ess": int(sum(rep["ess"][name] < config.L for rep in reps)),
        }
    return {
        "level": config.level,
        "negative_control": config.negative_control,
        "replications": config.replications,
        "L": config.L,
        "family_alpha": FAMILY_ALPHA,
        "passed": all(p["passed"] for p in params.values()),
        "parameters": params,
        "divergences": int(sum(rep.get("divergences", 0) for rep in reps)),
        "fit_seconds_total": float(sum(rep["seconds"] for rep in reps)),
        "config": asdict(config),
    }


def sbc_tree(out_dir, config: CalibrationConfig) -> xr.DataTree:
    """Every replication of a calibration as one DataTree in simuk's layout (``chain`` of length 1, ``draw`` =
    replication): ``prior_sbc`` the ranks, ``prior`` the truths, ``pit`` the randomized PIT, and
    ``thinned_posterior`` the L kept draws (dim ``thinned``), to re-rank without refitting."""
    reps = load_replications(out_dir, config)
    names = list(reps[0]["ranks"])
    coords = {"chain": [0], "draw": np.arange(len(reps))}

    def group(values: dict, extra=()) -> xr.Dataset:
        return xr.Dataset({n: (("chain", "draw", *extra), np.asarray(v)[None]) for n, v in values.items()},
                          coords=coords)

    pit = pits(reps, config.L)
    return xr.DataTree.from_dict({
        "prior_sbc": group({n: [rep["ranks"][n] for rep in reps] for n in names}),
        "prior": group({n: [rep["truth"][n] for rep in reps] for n in names}),
        "pit": group(pit),
        "thinned_posterior": group({n: [rep["thinned"][n] for rep in reps] for n in names}, ("thinned",)),
    })


def as_expected(summary: dict) -> bool:
    """Did the check come out as it must: passed for the correct model, failed for a negative control?"""
    return summary["passed"] == (summary["negative_control"] is None)


def format_summary(summary: dict) -> str:
    """A calibration's summary as text: the verdict, then one line per ranked quantity."""
    nc = summary["negative_control"]
    head = f"SBC {summary['level']} level" + (f", negative control '{nc}'" if nc else "")
    verdict = "PASSED" if summary["passed"] else "FAILED (non-uniform ranks)"
    if nc and summary["passed"]:
        verdict += " -- but a negative control must fail: at this size the check cannot tell the wrong model"
    elif nc:
        verdict += ", as a negative control must"
    lines = [f"{head}: {summary['replications']} replications, L = {summary['L']}, "
             f"family false-failure rate {summary['family_alpha']:g} -> {verdict}"]
    for name, p in summary["parameters"].items():
        cov = ", ".join(f"{k}: {v:.2f}" for k, v in p["coverage"].items())
        contraction = "-" if p["contraction"] is None else f"{p['contraction']:.3f}"
        lines.append(f"  {name:>18}: KS p = {p['p_value']:.3g} (alpha {p['alpha']:.3g}) "
                     f"{'ok' if p['passed'] else 'NOT UNIFORM'}; coverage {cov}; contraction {contraction}")
    # The replications' own times survive an interrupted run; the wall times count only finished invocations.
    lines.append(f"  wall time {summary['wall_seconds_this_run']:.0f} s this run, {summary['wall_seconds_total']:.0f} s "
                 f"over the finished invocations; the replications' own fits {summary['fit_seconds_total']:.0f} s; "
                 f"divergences {summary['divergences']}")
    return "\n".join(lines)
