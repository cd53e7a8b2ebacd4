"""The report's sections on the identification: θ1 histogram, the paper's test, Fig. 6, cross-prediction, details.

Every section takes the run's experiment (:class:`scioc.models.design.Design`): one histogram colour,
Wilcoxon test, Fig. 6 column and cross-prediction per level.
"""

from __future__ import annotations

import pandas as pd
from markupsafe import Markup

from scioc.models.design import STUDY, Design
from scioc.models.identify import PLAUSIBLE_THETA1
from scioc.pipelines.report import figures
from scioc.pipelines.report.levels import contrast_label, joined, key, paper_labels
from scioc.pipelines.report.render import figure, number, render, table

#: The tested parameters as the tables name them.
PARAMETERS = {"theta1": "θ1 = q11/R", "theta2": "θ2 = q22/R"}


def section_histogram(est: pd.DataFrame, design: Design = STUDY) -> Markup:
    """Histogram of the identified θ1 per level (Fig. 5)."""
    levels = design.ordered_levels
    where = " and ".join(levels) if len(levels) == 2 else joined(levels)
    return figure(figures.theta1_histogram(est, levels),
                  f"Histogram of the identified normalized angle weight θ1 in {where} (Fig. 5).")


def tests_by_level(cmp: dict, design: Design) -> dict:
    """``{contrast level: {"theta1": test, "theta2": test}}`` from ``compare.json`` (two levels: at its top)."""
    if "contrasts" in cmp:
        return cmp["contrasts"]
    return {design.contrasts[0]: {col: cmp[col] for col in PARAMETERS}}


def section_wilcoxon(cmp: dict, design: Design = STUDY) -> Markup:
    """The paper's Wilcoxon test of θ1 and θ2 of each level against the baseline (``compare.json``), with Holm."""
    tests = tests_by_level(cmp, design)
    many = "contrasts" in cmp
    rows = []
    for level, t in tests.items():
        for col in PARAMETERS:
            r = t[col]
            row = {"contrast": contrast_label(design, level)} if many else {}
            row.update({
                "parameter": PARAMETERS[col],
                "pairs": r["n_pairs"], "N (non-zero)": r["n"], "W+": r["w_plus"], "W−": r["w_minus"], "T": r["T"],
                "exact p (two-sided)": r["p_value"],
                f"critical T at α = {r['alpha']:g}": "–" if r["critical_value"] is None else r["critical_value"],
                "reject H0": "yes" if r["reject"] else "no",
            })
            if many:
                row.update({"Holm p": r.get("p_holm"),
                            "reject (Holm)": "–" if r.get("reject_holm") is None else
                            "yes" if r["reject_holm"] else "no"})
            row.update({"rank-biserial r": r["rank_biserial"],
                        ("median difference" if many else f"median {contrast_label(design, level)}"):
                            r["median_difference"]})
            rows.append(row)
    p = lambda v: number(v, ".3g")  # noqa: E731
    return render("wilcoxon.html.j2", unpaired=cmp.get("unpaired_subjects"), paper=paper_labels(design),
                  contrasts=[contrast_label(design, v) for v in tests], base=design.baseline,
                  tested=list(tests), multiplicity=cmp.get("multiplicity"),
                  table=table(pd.DataFrame(rows), fmt={"exact p (two-sided)": p, "Holm p": p},
                              left=("contrast", "parameter")))


def section_fig6(traj: pd.DataFrame, subject: str, design: Design = STUDY, reconstructed: bool = True) -> Markup:
    """One subject's measured trajectories beside forward optimal control with each level's θ (Fig. 6)."""
    d = traj[traj.subject == subject]
    if d.empty:
        return render("note.html.j2", text=f"Subject {subject} is not in the study.")
    levels = design.ordered_levels
    thetas = [f"θ_{v}" for v in levels]
    trials = " (the first trial of each condition)" if "trial" in d.columns else ""
    return figure(figures.trajectories(d, subject, levels, reconstructed),
                  f"Subject {subject}: measured trajectories{trials} beside those that forward optimal control "
                  f"generates with {' and '.join(thetas) if len(thetas) == 2 else joined(thetas)} (Fig. 6).")


def section_cross_prediction(val: pd.DataFrame, design: Design = STUDY) -> Markup:
    """RMSE of angle and torque when each level's data are predicted with each level's θ (``validation.parquet``).

    With trials, a unit's trials are averaged first, so every subject counts once.
    """
    levels, base, others = design.ordered_levels, design.baseline, design.contrasts
    columns = [f"rmse_{q}_theta_{key(v)}" for v in levels for q in ("angle", "uH")]
    missing = [c for c in columns if c not in val.columns]
    if missing:
        return render("note.html.j2", text=f"validation.parquet has no column {missing[0]}: it was written for "
                                           "another experiment than the one recorded in this run.")
    units = val[["subject", "condition", *columns]].dropna()
    units = units.groupby(["subject", "condition"], sort=False).mean().reset_index()
    by = {v: units[units.condition == v] for v in levels}
    worse = []
    for v in others:
        d = by[v]
        share = lambda q: float((d[f"rmse_{q}_theta_{key(base)}"] > d[f"rmse_{q}_theta_{key(v)}"]).mean()) \
            if len(d) else float("nan")  # noqa: E731
        worse.append({"level": v, "u": share("uH"), "angle": share("angle")})
    rows = []
    for data in (*others, base):
        for pred in levels:
            rows.append({"data": data, "prediction": f"θ_{pred}",
                         "angle RMSE (rad)": by[data][f"rmse_angle_theta_{key(pred)}"].mean(),
                         "u_H RMSE (N·m)": by[data][f"rmse_uH_theta_{key(pred)}"].mean()})
    per = None
    for v in others:
        names = {f"rmse_{q}_theta_{key(p)}": f"{v} {label}, θ_{p} ({unit})"
                 for q, label, unit in (("angle", "angle", "rad"), ("uH", "u_H", "N·m")) for p in (base, v)}
        part = by[v][["subject", *names]].rename(columns=names)
        per = part if per is None else per.merge(part, on="subject", how="outer")
    return render("cross_prediction.html.j2", worse=worse, base=base, trials="trial" in val.columns,
                  summary=table(pd.DataFrame(rows), left=("data", "prediction")),
                  per_subject=table(per, left=("subject",)), data_of=joined(others))


def section_identification(est: pd.DataFrame, meta: dict | None) -> Markup:
    """Convergence, the segments that did not converge or ended at the edge of the search (as
    :func:`scioc.pipelines.identify.format_identify` lists them), and every estimate."""
    cols = ["subject", "condition", *(["trials"] if "trials" in est else []), "theta1", "se_log_theta1", "theta2",
            "R", "se_log_R", "loglik", "converged", "iterations"]
    implausible = est["implausible"] if "implausible" in est else pd.Series(False, index=est.index)
    return render("identification.html.j2", converged=int(est.converged.sum()), n=len(est),
                  timing=(meta or {}).get("timing_s"),
                  not_converged=est.loc[~est.converged.astype(bool), ["subject", "condition", "message"]]
                  .to_dict("records"),
                  implausible=est.loc[implausible.astype(bool), ["subject", "condition", "theta1"]].to_dict("records"),
                  plausible=PLAUSIBLE_THETA1, table=table(est[cols], left=("subject", "condition")))
