"""``scioc power``: how often the adequacy verdict fails, per simulated human, and what the paper's test says.

Per simulated human (:data:`scioc.models.humans.HUMANS`), ``studies`` default studies (encoder angles
only) are identified with their adequacy checks and tested with the paper's Wilcoxon test. On
``maxent`` the verdict's failure rate is its false-alarm rate, on the others its power. Study ``i``
uses ``SeedSequence([seed, i])`` for every human, so the humans differ only in how they steer.
Artifacts: ``studies/`` (a JSON per human × study; a rerun with the same settings resumes),
``power.json`` (the table) and ``power.parquet`` (one row per human × study).
"""

from __future__ import annotations

import hashlib
import json
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.models.adequacy import N_BOOT
from scioc.models.design import MANUAL, SHARED
from scioc.models.humans import HUMANS
from scioc.models.runtime import configure
from scioc.models.simulate import Population, simulate_study
from scioc.pipelines.compare import compare_estimates
from scioc.pipelines.identify import identify_study
from scioc.pipelines.io import InputDataError, validate_table
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.provenance import versions
from scioc.pipelines.simulate import study_table
from scioc.pipelines.storage import refuse_file_on_path, write_table_atomic, write_text_atomic

DEFAULT_HUMANS = tuple(HUMANS)


def one_study(human: str, i: int, seed: int, n_subjects: int, beta: float, n_boot: int) -> dict:
    """Simulate study ``i`` with ``human``, identify it, test it; a JSON-ready row."""
    configure()  # may run in a worker process
    t0 = time.perf_counter()
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(i)]))
    t, segs = simulate_study(int(n_subjects), rng, Population(beta=beta), 240.0, human=human)
    study = validate_table(study_table(t, segs), f"<simulated {human} study {i}>")
    settings = IdentifySettings(adequacy_boot=n_boot)
    ident = identify_study(study, settings, show_progress=False)
    est = ident.estimates
    cmp = compare_estimates(est)["theta1"]
    wide = est.pivot(index="subject", columns="condition", values="theta1")
    shift = np.log(wide[SHARED]) - np.log(wide[MANUAL])
    truth = {(s.subject, s.condition): s.theta[0] / s.theta[2] for s in segs}
    true_shift = [np.log(truth[(s, SHARED)]) - np.log(truth[(s, MANUAL)]) for s in wide.index]
    lq = HUMANS[human].kind == "lq"
    a = ident.adequacy
    return {
        "human": human, "study": int(i), "verdict": a["verdict"], "failed_checks": a["failed_checks"],
        "segments": a["segments"], "segments_flagged": a["segments_flagged"],
        "combined_p": a["combined_p"],
        "wilcoxon_T": cmp["T"], "wilcoxon_p": cmp["p_value"], "wilcoxon_reject": bool(cmp["reject"]),
        "mean_shift_log_theta1": float(np.mean(shift)),
        "true_mean_shift_log_theta1": float(np.mean(true_shift)) if lq else None,
        "converged": int(est["converged"].sum()),
        "seconds": time.perf_counter() - t0,
    }


def _fingerprint(seed, n_subjects, beta, n_boot) -> str:
    text = json.dumps({"seed": seed, "subjects": n_subjects, "beta": beta, "boot": n_boot, "design": "default-v1"})
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def power_study(out, *, humans=DEFAULT_HUMANS, studies: int = 20, seed: int = 2018, n_subjects: int = 42,
                beta: float = 0.0, n_boot: int = N_BOOT, workers: int = 1, log=print) -> dict:
    """Run the power study (see the module docstring); returns the summary written to ``power.json``."""
    unknown = [h for h in humans if h not in HUMANS]
    if unknown:
        raise ValueError(f"unknown human(s) {', '.join(unknown)}; choose from {', '.join(HUMANS)}")
    out = Path(out)
    refuse_file_on_path(out)  # a resumable folder: refused only where a file stands in its way
    fp = _fingerprint(seed, n_subjects, beta, n_boot)
    done_dir = out / "studies"
    todo, rows = [], {}
    for h in humans:
        for i in range(studies):
            path = done_dir / f"{h}-{i:03d}.json"
            if path.exists():
                try:
                    rec = json.loads(path.read_text())
                except json.JSONDecodeError as exc:
                    raise InputDataError(f"{path}: not a readable result ({exc}); delete it to recompute") from None
                if rec.get("fingerprint") == fp:
                    rows[(h, i)] = rec
                    continue
                raise InputDataError(f"{path} was computed with other settings; use another --out or delete it")
            todo.append((h, i))
    log(f"power: {len(rows)} of {len(humans) * studies} studies already done; {len(todo)} to run")

    def store(h, i, rec):
        rec["fingerprint"] = fp
        write_text_atomic(done_dir / f"{h}-{i:03d}.json", json.dumps(rec, indent=1) + "\n")
        rows[(h, i)] = rec
        log(f"  {h:10s} study {i:3d}: adequacy {rec['verdict']:4s} ({rec['segments_flagged']:2d} segments flagged); "
            f"Wilcoxon T = {rec['wilcoxon_T']:g}, p = {rec['wilcoxon_p']:.2g}; mean shift of log θ1 "
            f"{rec['mean_shift_log_theta1']:+.2f} ({rec['seconds']:.0f} s)")

    args = [(h, i, seed, n_subjects, beta, n_boot) for h, i in todo]
    if workers > 1 and len(args) > 1:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = {pool.submit(one_study, *a): a for a in args}
            for fut, a in futures.items():
                store(a[0], a[1], fut.result())
    else:
        for a in args:
            store(a[0], a[1], one_study(*a))

    table = pd.DataFrame([rows[(h, i)] for h in humans for i in range(studies)])
    summary = {"settings": {"studies": studies, "seed": seed, "subjects": n_subjects, "beta": beta,
                            "adequacy_boot": n_boot, "design": "default study: 240-s runs, window 210 s + 15 s, "
                            "encoder angles only, feedback assistant model"},
               "humans": {}, "versions": versions()}
    for h in humans:
        t = table[table["human"] == h]
        segs, flagged = int(t["segments"].sum()), int(t["segments_flagged"].sum())
        summary["humans"][h] = {
            "studies": int(len(t)),
            "verdict_fail": int((t["verdict"] == "fail").sum()),
            "segments": segs, "segments_flagged": flagged,
            "segment_flag_rate": flagged / segs if segs else None,
            "wilcoxon_reject": int(t["wilcoxon_reject"].sum()),
            "median_wilcoxon_p": float(t["wilcoxon_p"].median()),
            "mean_shift_log_theta1": float(t["mean_shift_log_theta1"].mean()),
            "true_mean_shift_log_theta1": (None if t["true_mean_shift_log_theta1"].isna().all()
                                           else float(t["true_mean_shift_log_theta1"].mean())),
        }
    write_table_atomic(table.drop(columns=["combined_p", "failed_checks"]).assign(
        failed_checks=table["failed_checks"].map(",".join)), out / "power.parquet")
    write_text_atomic(out / "power.json", json.dumps(summary, indent=2) + "\n")
    return summary


def format_power(summary: dict) -> str:
    """The power table as text."""
    s = summary["settings"]
    lines = [f"adequacy verdict and the paper's Wilcoxon test on {s['studies']} simulated studies per human "
             f"({s['subjects']} subjects, true mean SC shift of log θ1 = {s['beta']:g})",
             f"{'human':10s} {'verdict fails':>14s} {'segments flagged':>18s} {'Wilcoxon rejects':>17s} "
             f"{'mean est. shift':>16s} {'true shift':>11s}"]
    for h, r in summary["humans"].items():
        true = "-" if r["true_mean_shift_log_theta1"] is None else f"{r['true_mean_shift_log_theta1']:+.2f}"
        lines.append(f"{h:10s} {r['verdict_fail']:>7d} of {r['studies']:<4d} "
                     f"{r['segment_flag_rate']:>17.1%} {r['wilcoxon_reject']:>9d} of {r['studies']:<4d} "
                     f"{r['mean_shift_log_theta1']:>+16.2f} {true:>11s}")
    return "\n".join(lines)
