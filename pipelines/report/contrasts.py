"""The report's per-contrast parts of the Bayesian section: three methods side by side, forest plots, truth check.

A contrast is one non-baseline level against the baseline. ``fit/contrasts.json`` holds β
at its top with two levels, and one block per level under ``contrasts`` with more
(:func:`scioc.pipelines.fit.contrasts.contrasts`); :func:`blocks` reads either. ``compare.json``
and the mixed model (``mixedlm``) follow the same rule.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from markupsafe import Markup

from scioc.models.design import STUDY, Design
from scioc.pipelines.report import figures
from scioc.pipelines.report.levels import assisted, joined, paper_labels
from scioc.pipelines.report.render import figure, number, render, table
from scioc.pipelines.report.truth import unit_truth

#: The population parameters as the report prints them; {base}, {level} and {vs} are filled in per contrast.
LABELS = {
    "mu_log_theta1": "μ: {base} mean of log θ1",
    "beta": "β: mean {level} change of log θ1{vs}",
    "sigma_log_theta1": "σ: subject SD of log θ1",
    "sigma_beta": "σ_β: subject SD of the change{vs}",
    "mu_log_R": "μ_R: {base} mean of log R",
    "beta_log_R": "β_R: mean {level} change of log R{vs}",
    "sigma_log_R": "σ_R: subject SD of log R",
    "sigma_beta_log_R": "σ_βR: subject SD of the R change{vs}",
    "tau_theta2": "τ: scale of θ2",
}


def label(name: str, design: Design = STUDY) -> str:
    """A population parameter's name as the report prints it: ``beta`` or ``beta[weak]`` with its levels."""
    base, _, level = name.partition("[")
    level = level.rstrip("]") or design.contrasts[0]
    text = LABELS.get(base)
    if text is None:
        return name
    indexed = name != base
    text = text.format(base=design.baseline, level=level, vs=f" against {design.baseline}" if indexed else "")
    if indexed:  # "β: ..." becomes "β[weak]: ..."
        symbol, _, rest = text.partition(":")
        text = f"{symbol}[{level}]:{rest}"
    return text


def blocks(res: dict, design: Design) -> dict | None:
    """``{level: contrast block}`` of ``contrasts.json``, or None when a fit of more levels has no per-level block."""
    if "contrasts" in res:
        return res["contrasts"]
    if len(design.contrasts) == 1 and "beta" in res:
        return {design.contrasts[0]: res}
    return None


def _interval(iv, spec: str = ".3f") -> str:
    return "[" + ", ".join(format(v, spec) for v in iv) + "]"


def _excludes_zero(iv) -> bool:
    return iv[1] < 0 or iv[0] > 0


def _methods_table(level: str, base: str, w: dict | None, b: dict | None, mm: dict | None) -> Markup:
    rows = [
        ("question", f"do θ1 of {base} and {level} differ? (H0: symmetric around 0)",
         f"how large is the mean {level} change β of log θ1?",
         f"fixed {level} effect on log θ1 (random subject intercept)"),
        ("data", "per-segment ML estimates of θ1", "the torques of every segment (likelihood, paper Eq. 8)",
         "log of the per-segment ML estimates of θ1"),
    ]
    if w:
        w_est = f"T = {w['T']:g} (W+ = {w['w_plus']:g}, W− = {w['w_minus']:g}, N = {w['n']})"
        w_int = ("–" if w["critical_value"] is None
                 else f"critical T = {w['critical_value']} at α = {w['alpha']:g}")
        w_ev = (f"exact p = {number(w['p_value'], '.3g')}"
                + (f", Holm p = {number(w['p_holm'], '.3g')}" if "p_holm" in w else ""))
        w_dec = (f"reject H0 (Holm): {'yes' if w['reject_holm'] else 'no'}" if "reject_holm" in w
                 else f"reject H0: {'yes' if w['reject'] else 'no'}")
        w_ratio = f"median {level} − {base} of θ1: {w['median_difference']:.3g} rad⁻²"
    else:
        w_est = w_int = w_ev = w_dec = w_ratio = "no compare.json"
    if b:
        r, beta = b["ratio"], b["beta"]
        b_est = f"β = {beta['mean']:.3f} ± {beta['sd']:.3f} (posterior mean ± SD)"
        b_int = f"94 % HDI {_interval(beta['hdi'])}"
        b_ratio = f"exp(β) = {r['median']:.3f}, 94 % HDI {_interval(r['hdi'])}"
        b_ev = f"P(β < 0) = {beta['p_negative']:.4f}"
        b_dec = "HDI excludes 0" if _excludes_zero(beta["hdi"]) else "HDI contains 0"
    else:
        b_est = b_int = b_ratio = b_ev = b_dec = "no per-level block in contrasts.json"
    if mm:
        m_est = f"coef = {mm['coef']:.3f} ± {mm['se']:.3f} (estimate ± SE)"
        m_int = f"95 % CI {_interval(mm['ci95'])}"
        m_ratio = f"exp(coef) = {mm['ratio']:.3f}, 95 % CI {_interval(mm['ratio_ci95'])}"
        m_ev = f"Wald p = {mm['p_value']:.3g}"
        m_dec = "CI excludes 0" if _excludes_zero(mm["ci95"]) else "CI contains 0"
    else:
        m_est = m_int = m_ratio = m_ev = m_dec = "no estimates.parquet"
    rows += [("estimate", w_est, b_est, m_est), ("interval", w_int, b_int, m_int),
             (f"{level} / {base}", w_ratio, b_ratio, m_ratio), ("evidence", w_ev, b_ev, m_ev),
             ("decision", w_dec, b_dec, m_dec)]
    df = pd.DataFrame(rows, columns=["", "paper's test (Wilcoxon)", "Bayesian contrast (hierarchical model)",
                                     "mixed model (statsmodels MixedLM)"])
    return table(df, left=tuple(df.columns))


def section_methods(cmp: dict | None, res: dict, design: Design = STUDY) -> Markup:
    """The paper's test, the Bayesian contrast and the mixed model, side by side, per contrast."""
    base = design.baseline
    found = blocks(res, design) or {}
    mm = res.get("mixedlm")
    tables = []
    for level in design.contrasts:
        if cmp and "contrasts" in cmp:
            w = (cmp["contrasts"].get(level) or {}).get("theta1")
        else:
            w = (cmp or {}).get("theta1") if len(design.contrasts) == 1 else None
        m = (mm.get("coefficients") or {}).get(level) if mm and "coefficients" in mm else (
            mm if mm and len(design.contrasts) == 1 else None)
        tables.append((f"{level} − {base}", _methods_table(level, base, w, found.get(level), m)))
    return render("methods.html.j2", tables=tables, paper=paper_labels(design), base=base,
                  others=joined(design.contrasts), multiplicity=(cmp or {}).get("multiplicity"))


def section_forest(res: dict, truth: pd.DataFrame | None, design: Design = STUDY) -> Markup:
    """Forest plot of the per-subject changes of log θ1 per contrast, with β and (if known) the truth."""
    found = blocks(res, design)
    if found is None:
        return render("note.html.j2", text="contrasts.json has no per-level block: no per-subject contrasts.")
    w = None if truth is None else unit_truth(truth).pivot_table(index="subject", columns="condition",
                                                                 values="theta1")
    colors = figures.level_colors(design.ordered_levels)
    parts = []
    for level, c in found.items():
        subj = c["subjects"]
        true = None
        if w is not None and {level, design.baseline} <= set(w.columns):
            true = np.log(w[level] / w[design.baseline]).reindex([s["subject"] for s in subj]).to_numpy()
        fig = figures.forest(subj, c["beta"], true, (design.baseline, level), colors.get(level, figures.SC_COLOR))
        parts.append({"level": level, "below": c["subjects_with_hdi_below_zero"], "n": len(subj),
                      "figure": figure(fig, f"Per-subject {design.baseline}→{level} change of log θ1 (forest plot). "
                                            "Blue band: the population mean change β with its 94 % HDI; "
                                            "dotted: no change.")})
    return render("forest.html.j2", parts=parts, many=len(parts) > 1)


def _ml_text(ml: dict, design: Design) -> str:
    """"off by −0.053 (MC) and −0.014 (SC) in mean log θ1, +0.038 on the SC change"."""
    base = design.baseline
    per = joined(f"{ml[v]:+.3f} ({v})" for v in design.ordered_levels if v in ml)
    shifts = joined(f"{ml[k]:+.3f} on the {v} change" for v in design.contrasts
                    if (k := f"{v}_minus_{base}") in ml)
    return f"off by {per} in mean log θ1" + (f", {shifts}" if shifts else "")


def section_truth_check(tr: dict, design: Design = STUDY, reconstructed: bool = True) -> Markup:
    """The simulator's population against the posterior; β of every contrast in particular."""
    rows = [{"parameter": label(v, design), "truth": p["truth"], "posterior mean": p["mean"],
             "interval": _interval(p["interval"]), "kind": p["interval_kind"],
             "truth inside": "yes" if p["in_interval"] else "NO"} for v, p in tr["population"].items()]
    if "contrasts" in tr:
        found = [{"suffix": f"[{v}]", "of": f" from {design.baseline} to {v}", **c}
                 for v, c in tr["contrasts"].items()]
    elif "beta" in tr:
        found = [{"suffix": "", "of": "", "beta": tr["beta"], "subjects": tr["subjects"]}]
    else:  # several levels without per-level blocks: the table only
        found = []
    ml = tr.get("ml_log_error")
    motor = [{"label": lab, "unit": unit, **tr["motor"][k]}
             for k, lab, unit in (("tau_nm", "τ_nm", "s"), ("sigma_m", "σ_m", "N·m"))
             if "truth_in_interval" in (tr.get("motor") or {}).get(k, {})]  # shown only with these keys
    return render("truth_check.html.j2", blocks=found, ml=_ml_text(ml, design) if ml else None, motor=motor,
                  helped=joined(assisted(design)), one=len(assisted(design)) == 1, reconstructed=reconstructed,
                  table=table(pd.DataFrame(rows), left=("parameter", "interval", "kind")))
