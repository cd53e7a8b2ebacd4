"""The report's sections that need the simulator's ground truth: the reconstruction's error, truth vs estimates.

Per level of the run's experiment. A ``truth.parquet`` with a ``trial`` column repeats its
unit's θ once per trial: one truth per unit (subject × condition) is used.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from markupsafe import Markup
from scipy.stats import spearmanr

from scioc.models.design import STUDY, Design
from scioc.pipelines.report import figures
from scioc.pipelines.report.levels import assisted, contrast_label, joined
from scioc.pipelines.report.render import figure, render, table

#: Length of the stretch of torque the reconstruction figure shows, s.
SHOWN_SECONDS = 3.0


def unit_truth(truth: pd.DataFrame) -> pd.DataFrame:
    """One row of true parameters per subject × condition (the trials of a unit share its θ)."""
    return truth.drop_duplicates(["subject", "condition"]).drop(columns=["trial"], errors="ignore")


def section_reconstruction(traj: pd.DataFrame, truth_traj: pd.DataFrame | None, design: Design = STUDY,
                           torque_measured: bool = False) -> Markup:
    """Errors of the reconstructed (or derived) velocity and torque against the true ones (simulated studies)."""
    if truth_traj is None:
        return render("reconstruction.html.j2", table=None)
    on = ["subject", "condition", *(["trial"] if "trial" in traj and "trial" in truth_traj else []), "t"]
    truth_traj = truth_traj.rename(columns={"angle": "true_angle", "velocity": "true_velocity", "u_H": "true_u_H"})
    if "trial" in on:  # trajectories.parquet stores the trial as text or objects; the truth as integers
        traj = traj.assign(trial=traj["trial"].astype(str))
        truth_traj = truth_traj.assign(trial=truth_traj["trial"].astype(str))
    m = traj.merge(truth_traj, on=on, how="left")
    rows = []
    per_segment = ["subject", *(["trial"] if "trial" in on else [])]
    for c in design.ordered_levels:
        s = m[m.condition == c]
        per = s.groupby(per_segment)
        e_v = per.apply(lambda g: np.sqrt(np.mean((g.velocity - g.true_velocity) ** 2)), include_groups=False)
        e_u = per.apply(lambda g: np.sqrt(np.mean((g.u_H.iloc[:-1] - g.true_u_H.iloc[:-1]) ** 2)), include_groups=False)
        sd_u = per.apply(lambda g: g.true_u_H.iloc[:-1].std(), include_groups=False)
        sd_r = per.apply(lambda g: g.u_H.iloc[:-1].std(), include_groups=False)
        corr = per.apply(lambda g: np.corrcoef(g.u_H.iloc[:-1], g.true_u_H.iloc[:-1])[0, 1], include_groups=False)
        rows.append({"condition": c, "velocity RMSE (rad/s)": e_v.mean(), "u_H RMSE (N·m)": e_u.mean(),
                     "true u_H SD (N·m)": sd_u.mean(),
                     ("recorded u_H SD (N·m)" if torque_measured else "reconstructed u_H SD (N·m)"): sd_r.mean(),
                     "correlation": corr.mean()})
    shown = None
    if not torque_measured:
        level = design.contrasts[0]
        first = m[m.condition == level]
        s = figures.first_segment(first).iloc[: design.steps(SHOWN_SECONDS)]
        source = "the encoder angle" if design.encoder_counts else "the angle"
        below = ("the torque variability whose effect stays below the encoder's resolution is not recovered; "
                 if design.encoder_counts else "")
        segment = "trial" if design.whole else "window"
        shown = figure(figures.reconstructed_torque(s, source, figures.level_colors(design.ordered_levels)[level]),
                       f"First {SHOWN_SECONDS:g} s of one {level} {segment}: {below}"
                       "the reconstruction is smoother than the truth.")
    return render("reconstruction.html.j2", table=table(pd.DataFrame(rows), left=("condition",)), figure=shown,
                  measured=torque_measured, quantized=bool(design.encoder_counts),
                  span="over the whole trial" if design.whole else "in the analysis window")


def section_truth(est: pd.DataFrame, truth: pd.DataFrame, est_true: pd.DataFrame | None,
                  est_paper: pd.DataFrame | None = None, design: Design = STUDY,
                  torque_measured: bool = False) -> Markup:
    """Estimates (from the angle, from the true torques, with the paper's exogenous u_A) against the truth, per level.

    ``torque_measured``: the study recorded u_H (a torque sensor), so the estimates from the
    data are those from the true torques.
    """
    truth = unit_truth(truth)
    merged = lambda e: e.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))  # noqa: E731
    levels, base = design.ordered_levels, design.baseline
    recorded = "from recorded angle and torque" if torque_measured else \
        "from encoder angle" if design.encoder_counts else "from the angle"
    sources = [(recorded, merged(est))]
    if est_true is not None:
        sources.append(("from true torques", merged(est_true)))
    extra = [] if est_paper is None else [("from true torques, u_A exogenous (paper)", merged(est_paper))]
    rows = []
    for label, d in sources + extra:
        for c in levels:
            s = d[d.condition == c]
            rows.append({
                "estimates": label, "condition": c,
                "Spearman θ1": spearmanr(s.theta1, s.theta1_true)[0],
                "mean log(θ1/θ1_true)": np.mean(np.log(s.theta1 / s.theta1_true)),
                "mean log(R/R_true)": np.mean(np.log(s.R / s.R_true)),
                "θ2 > 0 (of N)": f"{int((s.theta2 > 0).sum())} of {len(s)}",
                "median SE log θ1": np.median(s.se_log_theta1),
            })
        w = d.pivot_table(index="subject", columns="condition", values=["theta1", "theta1_true"])
        present = set(w.columns.get_level_values(1))
        for c in design.contrasts:
            if not {base, c} <= present:
                continue
            shift = np.log(w[("theta1", c)] / w[("theta1", base)]).mean()
            shift_true = np.log(w[("theta1_true", c)] / w[("theta1_true", base)]).mean()
            # Only the shift is defined for the difference of the conditions: the other columns print "–".
            rows.append({"estimates": label, "condition": contrast_label(design, c),
                         "mean log(θ1/θ1_true)": shift - shift_true,
                         "Spearman θ1": np.nan, "mean log(R/R_true)": np.nan, "θ2 > 0 (of N)": "",
                         "median SE log θ1": np.nan})
    helped = assisted(design)
    return render("truth.html.j2", table=table(pd.DataFrame(rows), left=("estimates", "condition")),
                  shifts=[contrast_label(design, c) for c in design.contrasts], helped=joined(helped),
                  one=len(helped) == 1,
                  exogenous=est_paper is not None, measured=torque_measured,
                  figure=figure(figures.truth_scatter(sources, levels),
                                "True vs estimated θ1 per subject and condition."))
