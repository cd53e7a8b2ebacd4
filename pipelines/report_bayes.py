"""The report's Bayesian section, from the artifacts of ``scioc fit`` (never refits).

Reads ``root/fit/posterior.json``, ``root/fit/contrasts.json``, ``root/fit/ppc.parquet``,
``root/compare.json`` (the paper's Wilcoxon test) and, for simulated studies,
``root/data/truth.parquet``. :func:`section_bayes` returns the HTML that
:func:`pipelines.report.build_report` places under its own heading.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from pipelines.report import MC_COLOR, SC_COLOR, _fig_html, _table

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


def _num(v, spec: str = ".1f") -> str:
    """A number, or "n/a" where it is undefined (stored as null: e.g. an SE from one subject)."""
    return "n/a" if v is None else format(v, spec)


def _ok(flag: bool, yes: str = "yes", no: str = "no") -> str:
    return f'<span class="{"ok" if flag else "bad"}">{yes if flag else no}</span>'


def _interval(iv, fmt="{:.3f}") -> str:
    return "[" + ", ".join(fmt.format(v) for v in iv) + "]"


def _read_json(path: Path):
    return json.loads(path.read_text()) if path.exists() else None


def section_methods(cmp: dict | None, res: dict) -> str:
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
    txt = ("<p>Three answers to the paper's question, whether the normalized angle weight θ1 = q11/R changes from "
           "manual to shared control. The Wilcoxon test only rejects symmetry; the hierarchical model and the mixed "
           "model estimate the size of the change, as a log ratio (exp(β): the factor by which SC multiplies θ1).</p>")
    return txt + _table(df, left=tuple(df.columns))


def section_diagnostics(side: dict) -> str:
    """Per-parameter convergence diagnostics of both fits, and the verdict."""
    parts = []
    s = side["sampler"]
    crit = side["criteria"]
    parts.append(
        f"<p>nutpie, {s['chains']} chains × {s['draws']} draws after {s['tune']} warm-up draws, seed {side['seed']}. "
        f"Criteria for every population parameter: no divergence, R-hat ≤ {crit['rhat_max']}, bulk and tail ESS ≥ "
        f"{crit['ess_bulk_and_tail_min']}. ESS per second is bulk ESS over nutpie's sampling time (warm-up "
        "included, compilation not); wall times come from a shared machine and are noisy.</p>")
    rows = []
    for name in ("condition", "pooled"):
        d = side["diagnostics"][name]
        sec = side["seconds"][name]
        sm = d["sampler"]
        rows.append({
            "model": {"condition": "with condition effects", "pooled": "pooled (β = 0)"}[name],
            "verdict": d["convergence_verdict"], "divergences": sm["divergences"],
            "max R-hat": d["worst"]["rhat"], "min ESS (parameter)": f"{d['worst']['ess']:.0f} ({d['worst']['ess_parameter']})",
            "min E-BFMI": min(sm["ebfmi"]), "max tree depth": sm["max_tree_depth"],
            "steps/draw": sm["mean_steps_per_draw"], "sampling (s)": sec["sample_s"],
            "compile + sample (s)": sec["compile_and_sample_s"], "min ESS/s": d["worst"]["min_ess_bulk_per_s"],
        })
    df = pd.DataFrame(rows)
    verdicts = "; ".join(f"{m}: {_ok(d['passed'], 'passes', 'fails')}" for m, d in side["diagnostics"].items())
    parts.append(f"<p>Sampler convergence (this judges the sampler, not whether the human model describes the "
                 f"data: that is the model-adequacy verdict) — {verdicts}.</p>")
    parts.append(_table(df.drop(columns=["verdict"]), left=("model", "min ESS (parameter)")))
    d = side["diagnostics"]["condition"]
    prow = [{"parameter": LABELS.get(v, v), "R-hat": p["rhat"], "bulk ESS": p["ess_bulk"], "tail ESS": p["ess_tail"],
             "bulk ESS/s": p["ess_bulk_per_s"],
             "meets criteria": "yes" if (p["rhat"] <= crit["rhat_max"]
                                         and min(p["ess_bulk"], p["ess_tail"]) >= crit["ess_bulk_and_tail_min"]) else "NO"}
            for v, p in d["population"].items()]
    parts.append("<p>Population parameters of the model with condition effects:</p>")
    parts.append(_table(pd.DataFrame(prow), fmt={"bulk ESS": lambda v: f"{v:.0f}", "tail ESS": lambda v: f"{v:.0f}"},
                        left=("parameter",)))
    urow = [{"unit quantity (subject × condition)": v, **u} for v, u in d["units"].items()]
    parts.append(_table(pd.DataFrame(urow).rename(columns={"rhat_max": "max R-hat", "ess_bulk_min": "min bulk ESS",
                                                           "ess_tail_min": "min tail ESS"}),
                        left=("unit quantity (subject × condition)",)))
    return "".join(parts)


def section_forest(res: dict, truth: pd.DataFrame | None) -> str:
    """Forest plot of the per-subject MC→SC contrasts of log θ1, with β and (if known) the truth."""
    subj = res["subjects"]
    n = len(subj)
    fig, ax = plt.subplots(figsize=(7.5, 0.18 * n + 1.6))
    y = np.arange(n)[::-1]
    mean = np.array([s["mean"] for s in subj])
    lo = np.array([s["hdi"][0] for s in subj])
    hi = np.array([s["hdi"][1] for s in subj])
    b = res["beta"]
    ax.axvspan(*b["hdi"], color="#cfe3f3", label=f"β, 94 % HDI {_interval(b['hdi'], '{:.2f}')}")
    ax.axvline(b["mean"], color="#1f77b4", lw=1)
    ax.axvline(0.0, color="#555", lw=0.8, ls=":")
    ax.hlines(y, lo, hi, color=SC_COLOR, lw=1.4)
    ax.plot(mean, y, "o", color=SC_COLOR, ms=3.5, label="subject: posterior mean, 94 % HDI")
    if truth is not None:
        w = truth.pivot_table(index="subject", columns="condition", values="theta1")
        true = np.log(w["SC"] / w["MC"]).reindex([s["subject"] for s in subj]).to_numpy()
        ax.plot(true, y, "x", color="k", ms=4, label="true change (simulation)")
    ax.set_yticks(y, [s["subject"] for s in subj], fontsize=7)
    ax.set_xlabel("change of log θ1 from MC to SC: log(θ1[SC] / θ1[MC]) (dimensionless)")
    ax.set_ylabel("subject")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    txt = (f"<p>{res['subjects_with_hdi_below_zero']} of {n} subjects have a 94 % HDI of their change entirely "
           "below 0. The subjects' changes are partially pooled towards β.</p>")
    return txt + _fig_html(fig, "Per-subject MC→SC change of log θ1 (forest plot). Blue band: the population mean "
                                "change β with its 94 % HDI; dotted: no change.")


def section_loo(loo: dict, loso: dict | None = None) -> str:
    """PSIS-LOO of both models, the ELPD difference and the Pareto k summary; then leave-one-subject-out."""
    rows = []
    for name, label in (("condition", "with condition effects"), ("pooled", "pooled (β = 0)")):
        m = loo[name]
        k = m["pareto_k"]
        rows.append({"model": label, "ELPD (LOO)": m["elpd_loo"], "SE": m["se"], "p_loo": m["p_loo"],
                     "max Pareto k": k["max"], "median k": k["median"],
                     "k > threshold": f"{k['n_gt_threshold']} of {k['n']} (threshold {k['threshold']:.2f})",
                     "k > 1": k["n_gt_1"]})
    d = loo["difference"]
    txt = (f"<p>Expected log predictive density of a left-out segment, estimated by Pareto-smoothed importance "
           f"sampling (PSIS-LOO), summed over segments. Difference (condition effects − pooled): "
           f"<b>{d['elpd_diff']:.1f} ± {_num(d['se'])}</b> (z = {_num(d['z'])}), in favour of the "
           f"{'model with condition effects' if d['preferred'] == 'condition' else 'pooled model'}. "
           f"Reliable: {_ok(d['reliable'])}. {html.escape(d['note'])}. Each segment holds all the data on its "
           "subject × condition, so leaving one out moves that unit's θ a long way, which PSIS cannot reweight "
           "well; the difference is then indicative only.</p>")
    out = txt + _table(pd.DataFrame(rows), fmt={"ELPD (LOO)": lambda v: f"{v:.1f}", "SE": _num,
                                                "p_loo": lambda v: f"{v:.1f}"}, left=("model", "k > threshold"))
    if loso:
        out += section_loo_subject(loso)
    return out


def section_loo_subject(loso: dict) -> str:
    """Leave-one-subject-out by integrated PSIS: the reliable model comparison."""
    rows = []
    for name, label in (("condition", "with condition effects"), ("pooled", "pooled (β = 0)")):
        m = loso[name]
        k = m["pareto_k"]
        rows.append({"model": label, "ELPD (LOSO)": m["elpd_loo"], "SE": m["se"], "max Pareto k": k["max"],
                     "k > threshold": f"{k['n_gt_threshold']} of {k['n']} (threshold {k['threshold']:.2f})",
                     "IS ESS min / median": f"{m['is_ess_min']:.0f} / {m['is_ess_median']:.0f}"})
    d = loso["difference"]
    txt = (f"<p>Leaving out whole subjects instead, with each subject's own parameters integrated out "
           "(importance sampling per subject, then PSIS over the population draws only, which one subject of "
           f"many barely moves): difference <b>{d['elpd_diff']:.1f} ± {_num(d['se'])}</b> (z = {_num(d['z'])}) in favour "
           f"of the {'model with condition effects' if d['preferred'] == 'condition' else 'pooled model'}, "
           f"{d['n_favouring_condition']} of {d['n']} subjects predicted better by it. Reliable: "
           f"{_ok(d['reliable'])} (every Pareto k below the threshold). “IS ESS” is the effective sample size of "
           "the inner integral, its smallest over the population draws (min and median over subjects).</p>")
    return txt + _table(pd.DataFrame(rows), fmt={"ELPD (LOSO)": lambda v: f"{v:.1f}", "SE": _num},
                        left=("model", "k > threshold", "IS ESS min / median"))


def section_ppc(ppc: pd.DataFrame, meta: dict) -> str:
    """Posterior predictive Fig. 6: angle, tracking error and torque with 5-95 % bands for one subject."""
    subject = meta["subject"]
    conds = [c for c in ("MC", "SC") if c in set(ppc.condition)]
    fig, axes = plt.subplots(3, len(conds), figsize=(6 * len(conds), 8.5), sharex="col", squeeze=False)
    for j, cond in enumerate(conds):
        s = ppc[ppc.condition == cond]
        t = s["t"].to_numpy()
        ref = s["angle_ref"].to_numpy()
        col = MC_COLOR if cond == "MC" else SC_COLOR
        band = {"color": col, "alpha": 0.3, "lw": 0, "label": "posterior predictive 5-95 %"}
        ax = axes[0, j]
        ax.plot(t, ref, color="#999", lw=0.8, label="reference φ_ref")
        ax.fill_between(t, s.angle_q05, s.angle_q95, **band)
        ax.plot(t, s.angle, color="k", lw=0.7, label="measured angle")
        ax.set_ylabel("angle φ (rad)")
        ax.set_title(f"{subject}, {cond}")
        ax = axes[1, j]
        ax.fill_between(t, s.angle_q05 - ref, s.angle_q95 - ref, **band)
        ax.plot(t, s.angle_q50 - ref, color=col, lw=0.9, ls="--", label="predictive median")
        ax.plot(t, s.angle - ref, color="k", lw=0.7, label="measured")
        ax.axhline(0.0, color="#999", lw=0.6)
        ax.set_ylabel("tracking error φ − φ_ref (rad)")
        ax = axes[2, j]
        ax.plot(t, s.u_H, color="#777", lw=0.4, label="u_H (reconstructed from the angle)")
        ax.fill_between(t, s.u_H_q05, s.u_H_q95, **band)
        ax.plot(t, s.u_H_opt, color="k", lw=1.1, label="optimal control at the posterior median θ")
        ax.set_ylabel("human torque u_H (N·m)")
        ax.set_xlabel("time t (s)")
    for i in range(3):
        handles, labels = axes[i, -1].get_legend_handles_labels()
        axes[i, -1].legend(handles, labels, fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    cov = meta.get("coverage_5_95", {})
    cov_txt = "; ".join(f"{c}: torque {v['u_H']:.0%}, angle {v['angle']:.0%}" for c, v in cov.items())
    txt = (f"<p>{meta['draws']} posterior draws of subject {html.escape(subject)}'s θ, each simulated exactly from "
           "the max-ent model the likelihood assumes (in SC, with the default assistant model, the human planning "
           "with the assistant's law in closed loop). Share of the data inside "
           f"the pointwise 5-95 % band: {cov_txt}. A model that fits puts about 90 % of the samples inside; the "
           "reconstructed torque is smoother than the true one, so its coverage need not be exactly 90 %.</p>")
    return txt + _fig_html(fig, f"Posterior predictive check for subject {subject} (Fig. 6 with bands): angle, "
                                "tracking error and human torque over the 15-s window.")


def section_truth_check(tr: dict) -> str:
    """The simulator's population against the posterior; β in particular."""
    b = tr["beta"]
    rows = [{"parameter": LABELS.get(v, v), "truth": p["truth"], "posterior mean": p["mean"],
             "interval": _interval(p["interval"]), "kind": p["interval_kind"],
             "truth inside": "yes" if p["in_interval"] else "NO"} for v, p in tr["population"].items()]
    txt = (f"<p>The true β = {b['truth']:g} is {_ok(b['in_hdi'], 'inside', 'outside')} the 94 % HDI "
           f"{_interval(b['hdi'])}; the posterior mean misses it by {b['discrepancy']:+.3f} "
           f"({b['discrepancy_in_sd']:+.1f} posterior SD). The {tr['subjects']['n']} simulated subjects' own mean change is "
           f"{b['realized_mean_change']:.3f}. {tr['subjects']['true_change_in_hdi']} of {tr['subjects']['n']} "
           "per-subject HDIs hold the subject's true change.")
    if "ml_log_error" in tr:
        e = tr["ml_log_error"]
        txt += (f" The ML estimates the same likelihood gives are off by {e['MC']:+.3f} (MC) and {e['SC']:+.3f} (SC) "
                f"in mean log θ1, {e['SC_minus_MC']:+.3f} on the SC change.")
    txt += (" Known causes of misses: the reconstructed torque is smoother than the true one, and R is the "
            "precision of the torque's variability, so log R (μ_R) comes out too high from angles (the ground-truth "
            "section measures it; θ1 and β are ratios within a unit and barely affected). With the paper's "
            "exogenous-u_A likelihood (<code>--assistant-model exogenous</code>) the SC θ1, and so β, would be "
            "biased as well, because the recorded u_A reacts to the human's own variability; the ground-truth "
            "section's rows “u_A exogenous (paper)” measure by how much.</p>")
    return txt + _table(pd.DataFrame(rows), left=("parameter", "interval", "kind"))


def section_bayes(root) -> str:
    """HTML of the Bayesian section from ``root/fit/`` (and ``root/compare.json``).

    Parameters
    ----------
    root : str or Path
        Run folder (as ``scioc run`` writes it), with ``fit/`` from ``scioc fit``.

    Returns
    -------
    str
        HTML (no heading of its own level 2); a note if no fit is there.
    """
    root = Path(root)
    fit = root / "fit"
    side = _read_json(fit / "posterior.json")
    res = _read_json(fit / "contrasts.json")
    if side is None or res is None:
        return (f"<p class='note'>No Bayesian fit in {html.escape(str(fit))}: run "
                f"<code>scioc fit {html.escape(str(root / 'data' / 'study.parquet'))} --out {html.escape(str(fit))}</code>.</p>")
    cmp = _read_json(root / "compare.json")
    truth_path = root / "data" / "truth.parquet"
    truth = pd.read_parquet(truth_path) if truth_path.exists() else None
    if truth is not None and not truth["theta1"].notna().any():
        truth = None  # a simulated human without a cost θ (the crossover operator)
    parts = ["<p>The hierarchical max-ent model (<code>models/bayes/hierarchical.py</code>): log θ1 and log R per subject "
             "and condition with subject and condition effects, fitted to every segment's torques at once.</p>"]
    parts.append("<h3>The paper's test, the Bayesian contrast and a mixed model</h3>")
    parts.append(section_methods(cmp, res))
    parts.append("<h3>Convergence diagnostics</h3>")
    parts.append(section_diagnostics(side))
    parts.append("<h3>Per-subject contrasts</h3>")
    parts.append(section_forest(res, truth))
    parts.append("<h3>Model comparison: condition effects against pooling (PSIS-LOO)</h3>")
    parts.append(section_loo(res["loo"], res.get("loo_subject")))
    ppc_path = fit / "ppc.parquet"
    if ppc_path.exists() and res.get("ppc"):
        parts.append("<h3>Posterior predictive check (Fig. 6 with bands)</h3>")
        parts.append(section_ppc(pd.read_parquet(ppc_path), res["ppc"]))
    if res.get("truth"):
        parts.append("<h3>Ground truth check</h3>")
        parts.append(section_truth_check(res["truth"]))
    return "".join(parts)


__all__ = ["section_bayes"]
