"""The report's Bayesian section, from the artifacts of ``scioc fit`` (never refits).

Reads ``root/fit/posterior.json``, ``root/fit/contrasts.json``, ``root/fit/ppc.parquet``,
``root/compare.json`` (the paper's Wilcoxon test) and, for simulated studies,
``root/data/truth.parquet``. :func:`section_bayes` returns the HTML that
:func:`pipelines.report.build.build_report` places under its own heading.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from markupsafe import Markup

from models.design import MANUAL, SHARED
from pipelines.report import figures
from pipelines.report.render import figure, number, read_artifact, render, table

#: Names of the population parameters as the report prints them.
LABELS = {
    "mu_log_theta1": "μ: MC mean of log θ1",
    "beta": "β: mean SC change of log θ1",
    "sigma_log_theta1": "σ: subject SD of log θ1",
    "sigma_beta": "σ_β: subject SD of the change",
    "mu_log_R": "μ_R: MC mean of log R",
    "beta_log_R": "β_R: mean SC change of log R",
    "sigma_log_R": "σ_R: subject SD of log R",
    "sigma_beta_log_R": "σ_βR: subject SD of the R change",
    "tau_theta2": "τ: scale of θ2",
}
#: The two fitted models as the report names them.
MODELS = {"condition": "with condition effects", "pooled": "pooled (β = 0)"}


def _interval(iv, spec: str = ".3f") -> str:
    return "[" + ", ".join(format(v, spec) for v in iv) + "]"


def _n_a(v) -> str:
    """A number to one decimal, or "n/a" where it is undefined (stored as null: e.g. an SE from one subject)."""
    return number(v, ".1f", "n/a")


def section_methods(cmp: dict | None, res: dict) -> Markup:
    """The paper's test, the Bayesian contrast and the mixed model, side by side."""
    b, r, mm = res["beta"], res["ratio"], res.get("mixedlm")
    w = (cmp or {}).get("theta1")
    rows = [
        ("question", "do θ1 of MC and SC differ? (H0: symmetric around 0)",
         "how large is the mean SC change β of log θ1?", "fixed SC effect on log θ1 (random subject intercept)"),
        ("data", "per-segment ML estimates of θ1", "the torques of every segment (likelihood, paper Eq. 8)",
         "log of the per-segment ML estimates of θ1"),
    ]
    if w:
        w_est = f"T = {w['T']:g} (W+ = {w['w_plus']:g}, W− = {w['w_minus']:g}, N = {w['n']})"
        w_int = f"critical T = {w['critical_value']} at α = {w['alpha']:g}" if w["critical_value"] is not None else "–"
        w_ev = f"exact p = {w['p_value']:.3g}"
        w_dec = f"reject H0: {'yes' if w['reject'] else 'no'}"
        w_ratio = f"median SC − MC of θ1: {w['median_difference']:.3g} rad⁻²"
    else:
        w_est = w_int = w_ev = w_dec = w_ratio = "no compare.json"
    b_est = f"β = {b['mean']:.3f} ± {b['sd']:.3f} (posterior mean ± SD)"
    b_int = f"94 % HDI {_interval(b['hdi'])}"
    b_ratio = f"exp(β) = {r['median']:.3f}, 94 % HDI {_interval(r['hdi'])}"
    b_ev = f"P(β < 0) = {b['p_negative']:.4f}"
    b_dec = "HDI excludes 0" if (b["hdi"][1] < 0 or b["hdi"][0] > 0) else "HDI contains 0"
    if mm:
        m_est = f"coef = {mm['coef']:.3f} ± {mm['se']:.3f} (estimate ± SE)"
        m_int = f"95 % CI {_interval(mm['ci95'])}"
        m_ratio = f"exp(coef) = {mm['ratio']:.3f}, 95 % CI {_interval(mm['ratio_ci95'])}"
        m_ev = f"Wald p = {mm['p_value']:.3g}"
        m_dec = "CI excludes 0" if (mm["ci95"][1] < 0 or mm["ci95"][0] > 0) else "CI contains 0"
    else:
        m_est = m_int = m_ratio = m_ev = m_dec = "no estimates.parquet"
    rows += [("estimate", w_est, b_est, m_est), ("interval", w_int, b_int, m_int),
             ("SC / MC", w_ratio, b_ratio, m_ratio), ("evidence", w_ev, b_ev, m_ev),
             ("decision", w_dec, b_dec, m_dec)]
    df = pd.DataFrame(rows, columns=["", "paper's test (Wilcoxon)", "Bayesian contrast (hierarchical model)",
                                     "mixed model (statsmodels MixedLM)"])
    return render("methods.html.j2", table=table(df, left=tuple(df.columns)))


def section_diagnostics(side: dict) -> Markup:
    """Per-parameter convergence diagnostics of both fits, and the verdict."""
    crit = side["criteria"]
    rows = []
    for name, label in MODELS.items():
        d = side["diagnostics"][name]
        sec = side["seconds"][name]
        sm = d["sampler"]
        rows.append({
            "model": label, "divergences": sm["divergences"],
            "max R-hat": d["worst"]["rhat"], "min ESS (parameter)": f"{d['worst']['ess']:.0f} ({d['worst']['ess_parameter']})",
            "min E-BFMI": min(sm["ebfmi"]), "max tree depth": sm["max_tree_depth"],
            "steps/draw": sm["mean_steps_per_draw"], "sampling (s)": sec["sample_s"],
            "compile + sample (s)": sec["compile_and_sample_s"], "min ESS/s": d["worst"]["min_ess_bulk_per_s"],
        })
    d = side["diagnostics"]["condition"]
    prow = [{"parameter": LABELS.get(v, v), "R-hat": p["rhat"], "bulk ESS": p["ess_bulk"], "tail ESS": p["ess_tail"],
             "bulk ESS/s": p["ess_bulk_per_s"],
             "meets criteria": "yes" if (p["rhat"] <= crit["rhat_max"]
                                         and min(p["ess_bulk"], p["ess_tail"]) >= crit["ess_bulk_and_tail_min"]) else "NO"}
            for v, p in d["population"].items()]
    urow = [{"unit quantity (subject × condition)": v, **u} for v, u in d["units"].items()]
    units = pd.DataFrame(urow).rename(columns={"rhat_max": "max R-hat", "ess_bulk_min": "min bulk ESS",
                                               "ess_tail_min": "min tail ESS"})
    return render("diagnostics.html.j2", s=side["sampler"], seed=side["seed"], crit=crit,
                  verdicts=list(side["diagnostics"].items()),
                  models=table(pd.DataFrame(rows), left=("model", "min ESS (parameter)")),
                  population=table(pd.DataFrame(prow), fmt={"bulk ESS": lambda v: f"{v:.0f}",
                                                            "tail ESS": lambda v: f"{v:.0f}"}, left=("parameter",)),
                  units=table(units, left=("unit quantity (subject × condition)",)))


def section_forest(res: dict, truth: pd.DataFrame | None) -> Markup:
    """Forest plot of the per-subject MC→SC contrasts of log θ1, with β and (if known) the truth."""
    subj = res["subjects"]
    true = None
    if truth is not None:
        w = truth.pivot_table(index="subject", columns="condition", values="theta1")
        true = np.log(w[SHARED] / w[MANUAL]).reindex([s["subject"] for s in subj]).to_numpy()
    fig = figures.forest(subj, res["beta"], true)
    return render("forest.html.j2", below=res["subjects_with_hdi_below_zero"], n=len(subj),
                  figure=figure(fig, "Per-subject MC→SC change of log θ1 (forest plot). Blue band: the population "
                                     "mean change β with its 94 % HDI; dotted: no change."))


def _loo_rows(loo: dict, elpd: str, extra) -> pd.DataFrame:
    rows = []
    for name, label in MODELS.items():
        m = loo[name]
        k = m["pareto_k"]
        rows.append({"model": label, elpd: m["elpd_loo"], "SE": m["se"], **extra(m, k)})
    return pd.DataFrame(rows)


def _k_over(k: dict) -> str:
    return f"{k['n_gt_threshold']} of {k['n']} (threshold {k['threshold']:.2f})"


def section_loo(loo: dict, loso: dict | None = None) -> Markup:
    """PSIS-LOO of both models, the ELPD difference and the Pareto k summary; then leave-one-subject-out.

    The Pareto k are summarized in a table (counts above the threshold); the per-segment
    k plot (``arviz_plots.plot_khat``) is in the diagnostics notebook, which has the
    pointwise log-likelihood at hand.
    """
    seg = _loo_rows(loo, "ELPD (LOO)", lambda m, k: {"p_loo": m["p_loo"], "max Pareto k": k["max"],
                                                      "median k": k["median"], "k > threshold": _k_over(k),
                                                      "k > 1": k["n_gt_1"]})
    loso_table = None
    if loso:
        loso_table = table(_loo_rows(loso, "ELPD (LOSO)", lambda m, k: {
            "max Pareto k": k["max"], "k > threshold": _k_over(k),
            "IS ESS min / median": f"{m['is_ess_min']:.0f} / {m['is_ess_median']:.0f}"}),
            fmt={"ELPD (LOSO)": lambda v: f"{v:.1f}", "SE": _n_a},
            left=("model", "k > threshold", "IS ESS min / median"))
    return render("loo.html.j2", d=loo["difference"], loso=(loso or {}).get("difference"), loso_table=loso_table,
                  table=table(seg, fmt={"ELPD (LOO)": lambda v: f"{v:.1f}", "SE": _n_a, "p_loo": lambda v: f"{v:.1f}"},
                              left=("model", "k > threshold")))


def section_ppc(ppc: pd.DataFrame, meta: dict) -> Markup:
    """Posterior predictive Fig. 6: angle, tracking error and torque with 5-95 % bands for one subject."""
    subject = meta["subject"]
    return render("ppc.html.j2", meta={**meta, "coverage_5_95": meta.get("coverage_5_95", {})},
                  figure=figure(figures.predictive_bands(ppc, subject),
                                f"Posterior predictive check for subject {subject} (Fig. 6 with bands): angle, "
                                "tracking error and human torque over the 15-s window."))


def section_truth_check(tr: dict) -> Markup:
    """The simulator's population against the posterior; β in particular."""
    rows = [{"parameter": LABELS.get(v, v), "truth": p["truth"], "posterior mean": p["mean"],
             "interval": _interval(p["interval"]), "kind": p["interval_kind"],
             "truth inside": "yes" if p["in_interval"] else "NO"} for v, p in tr["population"].items()]
    return render("truth_check.html.j2", b=tr["beta"], subjects=tr["subjects"], ml=tr.get("ml_log_error"),
                  table=table(pd.DataFrame(rows), left=("parameter", "interval", "kind")))


def section_bayes(root) -> Markup:
    """HTML of the Bayesian section from ``root/fit/`` (and ``root/compare.json``).

    Parameters
    ----------
    root : str or Path
        Run folder (as ``scioc run`` writes it), with ``fit/`` from ``scioc fit``.

    Returns
    -------
    Markup
        HTML (no heading of its own level 2); a note if no fit is there.
    """
    root = Path(root)
    fit = root / "fit"
    side = read_artifact(fit / "posterior.json")
    res = read_artifact(fit / "contrasts.json")
    if side is None or res is None:
        return render("bayes.html.j2", missing=True, fit_dir=str(fit), study=str(root / "data" / "study.parquet"))
    truth = read_artifact(root / "data" / "truth.parquet")
    if truth is not None and not truth["theta1"].notna().any():
        truth = None  # a simulated human without a cost θ (the crossover operator)
    ppc = read_artifact(fit / "ppc.parquet")
    return render("bayes.html.j2", missing=False,
                  methods=section_methods(read_artifact(root / "compare.json"), res),
                  diagnostics=section_diagnostics(side), forest=section_forest(res, truth),
                  loo=section_loo(res["loo"], res.get("loo_subject")),
                  ppc=section_ppc(ppc, res["ppc"]) if ppc is not None and res.get("ppc") else None,
                  truth=section_truth_check(res["truth"]) if res.get("truth") else None)
