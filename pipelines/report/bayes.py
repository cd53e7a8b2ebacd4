"""The report's Bayesian section, from the artifacts of ``scioc fit`` (never refits).

Reads ``fit/posterior.json``, ``fit/contrasts.json``, ``fit/ppc.parquet``, ``compare.json`` and, for
simulated studies, ``data/truth.parquet``; the per-contrast parts are in :mod:`scioc.pipelines.report.contrasts`.
"""

from __future__ import annotations

import pandas as pd
from markupsafe import Markup

from scioc.models.design import STUDY, Design
from scioc.pipelines.fit.diagnostics import smaller_ess
from scioc.pipelines.fit.summary import fit_remedies
from scioc.pipelines.report import figures
from scioc.pipelines.report.contrasts import blocks, label, section_forest, section_methods, section_truth_check
from scioc.pipelines.report.levels import assisted, joined, window_noun
from scioc.pipelines.report.render import RunParts, figure, number, render, table

#: The two fitted models as the report names them.
MODELS = {"condition": "with condition effects", "pooled": "pooled (β = 0)"}


def _n_a(v) -> str:
    """A number to one decimal, or "n/a" where it is undefined (stored as null: e.g. an SE from one subject)."""
    return number(v, ".1f", "n/a")


def section_diagnostics(side: dict, design: Design = STUDY) -> Markup:
    """Per-parameter convergence diagnostics of both fits, and the verdict."""
    crit = side["criteria"]
    rows = []
    for name, model in MODELS.items():
        d = side["diagnostics"][name]
        sec = side["seconds"][name]
        sm = d["sampler"]
        rows.append({
            "model": model, "divergences": sm["divergences"],
            "max R-hat": d["worst"]["rhat"], "min ESS (parameter)": f"{d['worst']['ess']:.0f} ({d['worst']['ess_parameter']})",
            "min E-BFMI": min(sm["ebfmi"]), "max tree depth": sm["max_tree_depth"],
            "steps/draw": sm["mean_steps_per_draw"], "warm-up steps/draw": sm.get("tuning_mean_steps_per_draw"),
            "sampling (s)": sec["sample_s"],
            "compile + sample (s)": sec["compile_and_sample_s"], "min ESS/s": d["worst"]["min_ess_bulk_per_s"],
        })
    d = side["diagnostics"]["condition"]
    prow = [{"parameter": label(v, design), "R-hat": p["rhat"], "bulk ESS": p["ess_bulk"], "tail ESS": p["ess_tail"],
             "bulk ESS/s": p["ess_bulk_per_s"],
             "meets criteria": "yes" if (p["rhat"] is not None and p["rhat"] <= crit["rhat_max"]  # None: one chain
                                         and smaller_ess(p) >= crit["ess_bulk_and_tail_min"]) else "NO"}
            for v, p in d["population"].items()]
    urow = [{"unit quantity (subject × condition)": v, **u} for v, u in d["units"].items()]
    units = pd.DataFrame(urow).rename(columns={"rhat_max": "max R-hat", "ess_bulk_min": "min bulk ESS",
                                               "ess_tail_min": "min tail ESS",
                                               "pooling_factor": "pooling factor of the baseline"})
    return render("diagnostics.html.j2", s=side["sampler"], seed=side["seed"], crit=crit,
                  verdicts=list(side["diagnostics"].items()), remedies=fit_remedies(side),
                  models=table(pd.DataFrame(rows), left=("model", "min ESS (parameter)")),
                  population=table(pd.DataFrame(prow), fmt={"bulk ESS": lambda v: f"{v:.0f}",
                                                            "tail ESS": lambda v: f"{v:.0f}"}, left=("parameter",)),
                  units=table(units, left=("unit quantity (subject × condition)",)))


def _loo_rows(loo: dict, elpd: str, extra) -> pd.DataFrame:
    rows = []
    for name, model in MODELS.items():
        m = loo[name]
        k = m["pareto_k"]
        rows.append({"model": model, elpd: m["elpd_loo"], "SE": m["se"], **extra(m, k)})
    return pd.DataFrame(rows)


def _k_over(k: dict) -> str:
    return f"{k['n_gt_threshold']} of {k['n']} (threshold {k['threshold']:.2f})"


def section_loo(loo: dict, loso: dict | None = None, trials: bool = False) -> Markup:
    """PSIS-LOO of both models, the ELPD difference and the Pareto k counts; then leave-one-subject-out.

    The per-segment k plot is in the diagnostics notebook, which has the pointwise log-likelihood.
    ``trials``: a segment is one of several trials of its unit.
    """
    seg = _loo_rows(loo, "ELPD (LOO)", lambda m, k: {"p_loo": m["p_loo"], "max Pareto k": k["max"],
                                                      "median k": k["median"], "k > threshold": _k_over(k),
                                                      "k > 1": k["n_gt_1"]})
    loso_table = None
    if loso:
        loso_table = table(_loo_rows(loso, "ELPD (LOSO)", lambda m, k: {
            "max Pareto k": k["max"], "k > threshold": _k_over(k),
            **({"IS ESS (LOO) min / median": f"{m['is_ess_loo_min']:.0f} / {m['is_ess_loo_median']:.0f}"}
               if "is_ess_loo_min" in m else {}),  # not in every fit's contrasts.json
            "IS ESS worst draw min / median": f"{m['is_ess_min']:.0f} / {m['is_ess_median']:.0f}"}),
            fmt={"ELPD (LOSO)": lambda v: f"{v:.1f}", "SE": _n_a},
            left=("model", "k > threshold", "IS ESS (LOO) min / median", "IS ESS worst draw min / median"))
    return render("loo.html.j2", d=loo["difference"], trials=trials, loso=(loso or {}).get("difference"), loso_table=loso_table,
                  table=table(seg, fmt={"ELPD (LOO)": lambda v: f"{v:.1f}", "SE": _n_a, "p_loo": lambda v: f"{v:.1f}"},
                              left=("model", "k > threshold")))


def section_ppc(ppc: pd.DataFrame, meta: dict, design: Design = STUDY, reconstructed: bool = True) -> Markup:
    """Posterior predictive Fig. 6: angle, tracking error and torque with 5-95 % bands for one subject, per level."""
    subject = meta["subject"]
    first = " (the first trial of each condition)" if "trial" in ppc.columns else ""
    return render("ppc.html.j2", meta={**meta, "coverage_5_95": meta.get("coverage_5_95", {})},
                  helped=joined(assisted(design)), reconstructed=reconstructed,
                  figure=figure(figures.predictive_bands(ppc, subject, design.ordered_levels, reconstructed),
                                f"Posterior predictive check for subject {subject} (Fig. 6 with bands): angle, "
                                f"tracking error and human torque over {window_noun(design)}{first}."))


def section_bayes(run, design: Design = STUDY, reconstructed: bool = True, trials: bool = False) -> Markup:
    """HTML of the Bayesian section of a run folder or its parts (no level-2 heading; a note if there is no fit).

    ``design``: the run's experiment; ``reconstructed``: u_H was reconstructed from the angle (not
    recorded); ``trials``: units have several trials, each a segment of its own.
    """
    run = RunParts.of(run)
    fit = run.root / "fit"
    side = run.read("fit/posterior.json")
    res = run.read("fit/contrasts.json")
    if side is None or res is None:
        return render("bayes.html.j2", missing=True, fit_dir=str(fit), study=str(run.root / "data" / "study.parquet"),
                      left_out=run.left_out.get("fit"))
    missing = [name for name in MODELS if name not in side["diagnostics"]]
    if missing:  # the comparison of this section needs both models: a fit of another human model has one
        return render("bayes.html.j2", missing=True, fit_dir=str(fit), study=None,
                      left_out=f"{fit / 'posterior.json'} is a fit of the {side.get('human_model')} human model, "
                               f"without the {' and '.join(missing)} model this section compares with")
    truth = run.read("data/truth.parquet")
    if truth is not None and not truth["theta1"].notna().any():
        truth = None  # a simulated human without a cost θ (the crossover operator)
    ppc = run.read("fit/ppc.parquet")
    found = blocks(res, design)
    return render("bayes.html.j2", missing=False, levels=len(design.levels),
                  no_blocks=None if found is not None else
                  f"{fit / 'contrasts.json'} has no per-level block (\"contrasts\") for the {len(design.contrasts)} "
                  "levels against the baseline: the Bayesian contrasts are not shown (refit with this scioc).",
                  methods=section_methods(run.read("compare.json"), res, design),
                  diagnostics=section_diagnostics(side, design), forest=section_forest(res, truth, design),
                  loo=section_loo(res["loo"], res.get("loo_subject"), trials),
                  ppc=section_ppc(ppc, res["ppc"], design, reconstructed) if ppc is not None and res.get("ppc")
                  else None,
                  truth=section_truth_check(res["truth"], design, reconstructed) if res.get("truth") else None)
