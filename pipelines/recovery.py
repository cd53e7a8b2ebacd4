"""Parameter recovery on a simulated study: ``scioc identify``'s estimates against the simulator's truth.

``scioc recovery ESTIMATES --truth TRUTH`` reports per level the error and Spearman correlation of
θ1, per contrast the bias of the mean change of log θ1, and for ``delayed`` estimates (against any
simulated human) how often the delay is exact and the errors of the delay, τ_nm and σ_m.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from scipy.stats import spearmanr

from scioc.pipelines import lineage
from scioc.pipelines.compare import estimates_design, human_model_of
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.io import StudyFileError, read_table
from scioc.pipelines.lineage import LineageError
from scioc.pipelines.simulate import read_truth


def _wide(df: pd.DataFrame, column: str) -> pd.DataFrame:
    return df.drop_duplicates(["subject", "condition"]).pivot(index="subject", columns="condition", values=column)


def recovery(estimates: pd.DataFrame, truth: pd.DataFrame, levels, baseline: str) -> dict:
    """Recovery of θ1, its condition effects and (for ``delayed``) the delay, lag and motor noise.

    ``estimates`` from ``scioc identify``, ``truth`` from ``scioc simulate`` (an LQ human: θ1 finite),
    ``levels`` of the experiment with ``baseline`` among them.
    """
    e, t = np.log(_wide(estimates, "theta1")), np.log(_wide(truth, "theta1"))
    if t.isna().all().all():
        raise ValueError("the truth has no θ1 (a crossover operator has no cost to recover)")
    t = t.loc[e.index]
    out = {"human_model": human_model_of(estimates), "subjects": int(e.shape[0]), "levels": {}, "contrasts": {}}
    for v in levels:
        err = e[v] - t[v]
        out["levels"][v] = {"mean_error_log_theta1": float(err.mean()),
                            "mean_abs_error_log_theta1": float(err.abs().mean()),
                            "spearman_theta1": float(spearmanr(e[v], t[v]).statistic)}
    for v in levels:
        if v == baseline:
            continue
        est, true = (e[v] - e[baseline]).mean(), (t[v] - t[baseline]).mean()
        out["contrasts"][v] = {"mean_estimated_change_log_theta1": float(est), "mean_true_change_log_theta1": float(true),
                               "bias": float(est - true)}
    out.update(get(out["human_model"]).recovery(estimates, truth))
    return out


def format_recovery(res: dict) -> str:
    """The recovery as a few lines of text."""
    lines = [f"recovery of the {res['human_model']} model's estimates ({res['subjects']} subjects)"]
    for v, r in res["levels"].items():
        lines.append(f"  {v}: log theta1 error mean {r['mean_error_log_theta1']:+.3f}, mean |error| "
                     f"{r['mean_abs_error_log_theta1']:.3f}; Spearman {r['spearman_theta1']:.2f}")
    for v, r in res["contrasts"].items():
        lines.append(f"  change of log theta1 to {v}: estimated {r['mean_estimated_change_log_theta1']:+.3f}, true "
                     f"{r['mean_true_change_log_theta1']:+.3f}, bias {r['bias']:+.3f}")
    d = res.get("delayed")
    if d:
        lines.append(f"  delay exact in {d['delay_exact']} of {d['units']} units; error mean {d['delay_mean_error_s']:+.4f} s, "
                     f"mean |error| {d['delay_mean_abs_error_s']:.4f} s")
        lines.append(f"  tau_nm error mean {d['tau_nm_mean_error_s']:+.4f} s, mean |error| {d['tau_nm_mean_abs_error_s']:.4f} s;"
                     f" sigma_m mean {d['sigma_m_mean']:.3f} (motor noise SD {d['motor_sd_true_mean']:.3f}) N·m")
    p = res.get("delay_profile")
    if p:
        within = "; ".join(f"{k} nats: median {w['median']:g} ({w['min']}-{w['max']})" for k, w in p["within"].items())
        lines.append(f"  grid delays (of {p['grid_delays']}) within a drop of each subject's summed profile: {within}")
    return "\n".join(lines)


def recovery_of_files(estimates_path, truth_path) -> dict:
    """:func:`recovery` of an ``estimates.parquet`` against a ``truth.parquet``, with the levels identify recorded,
    after checking by content that the truth is of the study the estimates were identified from (their sidecars,
    ``identify.json`` and ``simulation.json``; LineageError naming both otherwise)."""
    for path, what in ((estimates_path, "estimates"), (truth_path, "truth")):
        if not Path(path).is_file():
            raise StudyFileError(path, f"no such {what} file")
    found = lineage.identification(estimates_path)
    if found is None:
        raise LineageError(f"{estimates_path}: no identify.json beside it, so the study it was identified from is not "
                           "known; give the estimates.parquet that scioc identify wrote, in its folder")
    identified = (found[0], lineage.recorded(found[1], "study", found[0]))
    lineage.require_one("study", identified, lineage.simulated_study(truth_path))
    design, _ = estimates_design(estimates_path)
    return recovery(read_table(estimates_path), read_truth(truth_path), design.ordered_levels, design.baseline)


__all__ = ["recovery", "recovery_of_files", "format_recovery"]
