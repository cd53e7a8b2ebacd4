"""The report's sections that need the simulator's ground truth: the reconstruction's error, truth vs estimates."""

from __future__ import annotations

import numpy as np
import pandas as pd
from markupsafe import Markup
from scipy.stats import spearmanr

from models.design import CONDITIONS, MANUAL, SHARED
from pipelines.report import figures
from pipelines.report.render import figure, render, table


def section_reconstruction(traj: pd.DataFrame, truth_traj: pd.DataFrame | None) -> Markup:
    """Errors of the reconstructed velocity and torque against the true ones (simulated studies)."""
    if truth_traj is None:
        return render("reconstruction.html.j2", table=None)
    m = traj.merge(truth_traj.rename(columns={"angle": "true_angle", "velocity": "true_velocity", "u_H": "true_u_H"}),
                   on=["subject", "condition", "t"], how="left")
    rows = []
    for c in CONDITIONS:
        s = m[m.condition == c]
        per = s.groupby("subject")
        e_v = per.apply(lambda g: np.sqrt(np.mean((g.velocity - g.true_velocity) ** 2)), include_groups=False)
        e_u = per.apply(lambda g: np.sqrt(np.mean((g.u_H.iloc[:-1] - g.true_u_H.iloc[:-1]) ** 2)), include_groups=False)
        sd_u = per.apply(lambda g: g.true_u_H.iloc[:-1].std(), include_groups=False)
        sd_r = per.apply(lambda g: g.u_H.iloc[:-1].std(), include_groups=False)
        corr = per.apply(lambda g: np.corrcoef(g.u_H.iloc[:-1], g.true_u_H.iloc[:-1])[0, 1], include_groups=False)
        rows.append({"condition": c, "velocity RMSE (rad/s)": e_v.mean(), "u_H RMSE (N·m)": e_u.mean(),
                     "true u_H SD (N·m)": sd_u.mean(), "reconstructed u_H SD (N·m)": sd_r.mean(),
                     "correlation": corr.mean()})
    s = m[(m.subject == m.subject.iloc[0]) & (m.condition == SHARED)].iloc[:300]
    return render("reconstruction.html.j2", table=table(pd.DataFrame(rows), left=("condition",)),
                  figure=figure(figures.reconstructed_torque(s),
                                "First 3 s of one SC window: the torque variability whose effect stays below the "
                                "encoder's resolution is not recovered; the reconstruction is smoother than the truth."))


def section_truth(est: pd.DataFrame, truth: pd.DataFrame, est_true: pd.DataFrame | None,
                  est_paper: pd.DataFrame | None = None) -> Markup:
    """Estimates (from the angle, from the true torques, with the paper's exogenous u_A) against the truth."""
    merged = lambda e: e.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))  # noqa: E731
    sources = [("from encoder angle", merged(est))]
    if est_true is not None:
        sources.append(("from true torques", merged(est_true)))
    extra = [] if est_paper is None else [("from true torques, u_A exogenous (paper)", merged(est_paper))]
    rows = []
    for label, d in sources + extra:
        for c in CONDITIONS:
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
        if set(CONDITIONS) <= set(w.columns.get_level_values(1)):
            shift = np.log(w[("theta1", SHARED)] / w[("theta1", MANUAL)]).mean()
            shift_true = np.log(w[("theta1_true", SHARED)] / w[("theta1_true", MANUAL)]).mean()
            # Only the shift is defined for the difference of the conditions: the other columns print "–".
            rows.append({"estimates": label, "condition": f"{SHARED} − {MANUAL}",
                         "mean log(θ1/θ1_true)": shift - shift_true,
                         "Spearman θ1": np.nan, "mean log(R/R_true)": np.nan, "θ2 > 0 (of N)": "",
                         "median SE log θ1": np.nan})
    return render("truth.html.j2", table=table(pd.DataFrame(rows), left=("estimates", "condition")),
                  figure=figure(figures.truth_scatter(sources), "True vs estimated θ1 per subject and condition."))
