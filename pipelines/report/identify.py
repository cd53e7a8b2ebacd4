"""The report's sections on the identification: θ1 histogram, the paper's test, Fig. 6, cross-prediction, details."""

from __future__ import annotations

import pandas as pd
from markupsafe import Markup

from models.design import MANUAL, SHARED
from models.identify import PLAUSIBLE_THETA1
from pipelines.report import figures
from pipelines.report.render import figure, render, table


def section_histogram(est: pd.DataFrame) -> Markup:
    """Histogram of the identified θ1 in MC and SC (Fig. 5)."""
    return figure(figures.theta1_histogram(est),
                  "Histogram of the identified normalized angle weight θ1 in MC and SC (Fig. 5).")


def section_wilcoxon(cmp: dict) -> Markup:
    """The paper's Wilcoxon test of θ1 and θ2 (``compare.json``)."""
    rows = []
    for col in ("theta1", "theta2"):
        r = cmp[col]
        rows.append({
            "parameter": {"theta1": "θ1 = q11/R", "theta2": "θ2 = q22/R"}[col],
            "pairs": r["n_pairs"], "N (non-zero)": r["n"], "W+": r["w_plus"], "W−": r["w_minus"], "T": r["T"],
            "exact p (two-sided)": r["p_value"],
            f"critical T at α = {r['alpha']:g}": "–" if r["critical_value"] is None else r["critical_value"],
            "reject H0": "yes" if r["reject"] else "no",
            "rank-biserial r": r["rank_biserial"],
            "median SC − MC": r["median_difference"],
        })
    return render("wilcoxon.html.j2", unpaired=cmp.get("unpaired_subjects"),
                  table=table(pd.DataFrame(rows), fmt={"exact p (two-sided)": lambda v: f"{v:.3g}"},
                              left=("parameter",)))


def section_fig6(traj: pd.DataFrame, subject: str) -> Markup:
    """One subject's measured trajectories beside forward optimal control with θ_MC and θ_SC (Fig. 6)."""
    d = traj[traj.subject == subject]
    if d.empty:
        return render("note.html.j2", text=f"Subject {subject} is not in the study.")
    return figure(figures.trajectories(d, subject),
                  f"Subject {subject}: measured trajectories beside those that forward optimal control generates "
                  "with θ_MC and θ_SC (Fig. 6).")


def section_cross_prediction(val: pd.DataFrame) -> Markup:
    """RMSE of angle and torque when each condition's data are predicted with θ_MC and with θ_SC."""
    sc = val[val.condition == SHARED].dropna()
    mc = val[val.condition == MANUAL].dropna()
    worse_u = float((sc.rmse_uH_theta_mc > sc.rmse_uH_theta_sc).mean()) if len(sc) else float("nan")
    worse_a = float((sc.rmse_angle_theta_mc > sc.rmse_angle_theta_sc).mean()) if len(sc) else float("nan")
    rows = []
    for data, d in ((SHARED, sc), (MANUAL, mc)):
        for pred, key in (("θ_MC", "mc"), ("θ_SC", "sc")):
            rows.append({"data": data, "prediction": pred, "angle RMSE (rad)": d[f"rmse_angle_theta_{key}"].mean(),
                         "u_H RMSE (N·m)": d[f"rmse_uH_theta_{key}"].mean()})
    per = sc[["subject", "rmse_angle_theta_mc", "rmse_angle_theta_sc", "rmse_uH_theta_mc", "rmse_uH_theta_sc"]]
    per = per.rename(columns={"rmse_angle_theta_mc": "SC angle, θ_MC (rad)", "rmse_angle_theta_sc": "SC angle, θ_SC (rad)",
                              "rmse_uH_theta_mc": "SC u_H, θ_MC (N·m)", "rmse_uH_theta_sc": "SC u_H, θ_SC (N·m)"})
    return render("cross_prediction.html.j2", worse_u=worse_u, worse_a=worse_a,
                  summary=table(pd.DataFrame(rows), left=("data", "prediction")),
                  per_subject=table(per, left=("subject",)))


def section_identification(est: pd.DataFrame, meta: dict | None) -> Markup:
    """Convergence, the segments that did not converge or ended at the edge of the search, and every estimate.

    The same lists as the console summary of ``scioc identify``
    (:func:`pipelines.identify.format_identify`), from the estimates' ``converged``,
    ``message`` and ``implausible`` columns.
    """
    cols = ["subject", "condition", "theta1", "se_log_theta1", "theta2", "R", "se_log_R", "loglik", "converged",
            "iterations"]
    implausible = est["implausible"] if "implausible" in est else pd.Series(False, index=est.index)
    return render("identification.html.j2", converged=int(est.converged.sum()), n=len(est),
                  timing=(meta or {}).get("timing_s"),
                  not_converged=est.loc[~est.converged.astype(bool), ["subject", "condition", "message"]]
                  .to_dict("records"),
                  implausible=est.loc[implausible.astype(bool), ["subject", "condition", "theta1"]].to_dict("records"),
                  plausible=PLAUSIBLE_THETA1, table=table(est[cols], left=("subject", "condition")))
