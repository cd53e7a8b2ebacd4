"""The report's model-adequacy parts: the opening verdict, the caveat beside every cost result, the section.

The verdict judges the *human model* (:mod:`scioc.models.adequacy`): whether the recorded data
look like data the fitted model produces through the same acquisition chain. It is not
the sampler's convergence verdict, and the report says which is which.
"""

from __future__ import annotations

import pandas as pd
from markupsafe import Markup

from scioc.pipelines.adequacy import CHECK_TEXT
from scioc.pipelines.report.render import render, table

#: Flagged segments listed by name before "and N more".
FLAGGED_LISTED = 40


def _failed_names(adequacy: dict) -> str:
    return "; ".join(CHECK_TEXT.get(k, k) for k in adequacy.get("failed_checks", []))


def headline(adequacy: dict | None, fit_adequacy: dict | None = None,
             chain: str = "the same encoder and reconstruction") -> Markup:
    """The box the report opens with; ``chain`` names the acquisition the checks repeat
    (:func:`scioc.pipelines.report.levels.acquisition`)."""
    verdict = (adequacy or {}).get("verdict", "not checked")
    fit_verdict = (fit_adequacy or {}).get("verdict")
    return render("adequacy_headline.html.j2", verdict=verdict, a=adequacy,
                  reason=None if not adequacy else adequacy.get("reason", ""),
                  failed=_failed_names(adequacy or {}), chain=chain,
                  fit_verdict=None if fit_verdict in (None, "not checked") else fit_verdict,
                  fit_point=(fit_adequacy or {}).get("point", {}).get("what"))


def caveat(adequacy: dict | None) -> Markup:
    """One paragraph to put next to a cost result; empty when the model passed."""
    if adequacy and adequacy.get("verdict") == "pass":
        return Markup("")
    verdict = "not checked" if not adequacy or adequacy.get("verdict") == "not checked" else "fail"
    return render("adequacy_caveat.html.j2", verdict=verdict, failed=_failed_names(adequacy or {}))


def section(est: pd.DataFrame, adequacy: dict | None, power: dict | None,
            chain: str = "quantized by the same encoder and reconstructed by the same smoother") -> Markup:
    """The model-adequacy section: per-check results, flagged segments, and the power table.

    ``chain`` says how the bootstrap's data sets pass the acquisition
    (:func:`scioc.pipelines.report.levels.acquisition`).
    """
    checked = adequacy and adequacy.get("verdict") != "not checked"
    rows, flagged = [], []
    if checked:
        for k, p in adequacy["combined_p"].items():
            mean = adequacy.get("null_statistic_means", {}).get(k, {})
            obs, mod = mean.get("observed"), mean.get("model")
            scalar = isinstance(obs, (int, float))
            rows.append({"check": CHECK_TEXT.get(k, k), "combined p": p,
                         "result": "FAIL" if k in adequacy["failed_checks"] else "ok",
                         "segments with p ≤ 0.05": int((est[f"adequacy_p_{k}"] <= 0.05).sum())
                         if f"adequacy_p_{k}" in est else "–",
                         "recorded (mean over segments)": f"{obs:.3f}" if scalar else "vector",
                         "model (mean over segments)": f"{mod:.3f}" if scalar else "vector"})
        flagged = adequacy.get("flagged_segments", [])
    return render("adequacy.html.j2", a=adequacy if checked else None, chain=chain,
                  table=table(pd.DataFrame(rows), fmt={"combined p": lambda v: f"{v:.3g}"},
                              left=("check", "result", "recorded (mean over segments)",
                                    "model (mean over segments)")) if rows else None,
                  flagged=flagged[:FLAGGED_LISTED], more=max(0, len(flagged) - FLAGGED_LISTED),
                  power=power_table(power) if power else None)


def power_table(power: dict) -> Markup:
    """The false-alarm and power table of ``scioc power`` (``power.json``)."""
    rows = []
    for h, r in power["humans"].items():
        rows.append({"simulated human": h, "studies": r["studies"],
                     "adequacy verdict fails": f"{r['verdict_fail']} of {r['studies']}",
                     "segments flagged": f"{r['segment_flag_rate']:.1%}",
                     "Wilcoxon rejects (α = 0.1 %)": f"{r['wilcoxon_reject']} of {r['studies']}",
                     "median Wilcoxon p": f"{r['median_wilcoxon_p']:.2g}",
                     "mean estimated shift of log θ1": f"{r['mean_shift_log_theta1']:+.2f}",
                     "true shift": "–" if r["true_mean_shift_log_theta1"] is None
                     else f"{r['true_mean_shift_log_theta1']:+.2f}"})
    return render("power.html.j2", s=power["settings"], table=table(pd.DataFrame(rows), left=("simulated human",)))
