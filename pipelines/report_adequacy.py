"""The report's model-adequacy parts: the opening verdict, the caveat beside every cost result, the section.

The verdict judges the *human model* (:mod:`models.adequacy`): whether the recorded data
look like data the fitted model produces through the same acquisition chain. It is not
the sampler's convergence verdict, and the report says which is which.
"""

from __future__ import annotations

import html

import pandas as pd

from pipelines.adequacy import CHECK_TEXT


def _failed_names(adequacy: dict) -> str:
    return "; ".join(html.escape(CHECK_TEXT.get(k, k)) for k in adequacy.get("failed_checks", []))


def headline(adequacy: dict | None, fit_adequacy: dict | None = None) -> str:
    """The box the report opens with."""
    if not adequacy or adequacy.get("verdict") == "not checked":
        reason = "" if not adequacy else f" ({html.escape(adequacy.get('reason', ''))})"
        return ("<div class='verdict warn'><b>Model adequacy: not checked</b>" + reason + ". Nothing below says "
                "whether the max-ent human model describes these data; read every cost and every difference between "
                "conditions with that in mind.</div>")
    if adequacy["verdict"] == "fail":
        txt = ("<div class='verdict bad'><b>Model adequacy: FAIL.</b> The max-ent human model does not describe "
               "these data. The identified costs, and any difference between the conditions (the Wilcoxon test, β "
               "and its HDI, the mixed model, LOO), may be artifacts of model misfit and are not evidence about "
               f"the human's cost. Failed checks: {_failed_names(adequacy)}. "
               f"{adequacy['segments_flagged']} of {adequacy['segments']} segments are flagged individually "
               f"(about {adequacy['segments_flagged_expected_by_chance']:.1f} expected by chance).")
    else:
        txt = ("<div class='verdict ok'><b>Model adequacy: pass.</b> No check found the recorded data unlike "
               "data the fitted max-ent model produces through the same encoder and reconstruction "
               f"({len(adequacy['combined_p'])} checks, family-wise false-alarm rate "
               f"{adequacy['study_alpha']:.0%}). This does not prove the model right; it found no evidence "
               "against it.")
    if fit_adequacy and fit_adequacy.get("verdict") not in (None, "not checked"):
        txt += (f" At the hierarchical fit's posterior θ the verdict is <b>{html.escape(fit_adequacy['verdict'])}"
                "</b>.")
    return txt + " (Section <a href='#adequacy'>Model adequacy</a>.)</div>"


def caveat(adequacy: dict | None) -> str:
    """One paragraph to put next to a cost result; empty when the model passed."""
    if adequacy and adequacy.get("verdict") == "pass":
        return ""
    if not adequacy or adequacy.get("verdict") == "not checked":
        return ("<p class='bad'>Caveat: model adequacy was not checked; these numbers assume the max-ent human "
                "model fits.</p>")
    return ("<p class='bad'>Caveat: the human model fails its adequacy checks (" + _failed_names(adequacy) + "). "
            "These numbers may be artifacts of model misfit, not a change of the human's cost.</p>")


def section(est: pd.DataFrame, adequacy: dict | None, power: dict | None) -> str:
    """The model-adequacy section: per-check results, flagged segments, and the power table."""
    parts = ["<h2 id='adequacy'>Model adequacy</h2>"]
    if not adequacy or adequacy.get("verdict") == "not checked":
        parts.append("<p class='note'>Not checked in this run.</p>")
    else:
        b = adequacy["bootstrap"]
        parts.append(
            "<p>Each segment is checked at its identified θ by a parametric bootstrap through the same acquisition "
            f"chain: {b['replicates_per_segment']} data sets drawn from the fitted max-ent model with the same "
            "reference and assistant, quantized by the same encoder and reconstructed by the same smoother "
            "(<code>models/adequacy.py</code>). A per-check p-value compares the recorded segment with them; a "
            f"segment is flagged when the min-P combination over the checks is ≤ {adequacy['segment_alpha']:.0%}. "
            "The study verdict combines the segments per check by Fisher's method and fails when any check's "
            f"combined p is ≤ {adequacy['per_check_level']:.2g} (Bonferroni: family-wise false-alarm rate "
            f"{adequacy['study_alpha']:.0%}).</p>")
        rows = []
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
        df = pd.DataFrame(rows)
        parts.append(df.to_html(index=False, escape=True, float_format=lambda v: f"{v:.3g}", classes="adq"))
        flagged = adequacy.get("flagged_segments", [])
        if flagged:
            txt = ", ".join(f"{html.escape(f['subject'])} {html.escape(f['condition'])} (p = {f['p']:.2g}: "
                            f"{html.escape(', '.join(f['checks_at_5_percent']) or 'combined')})" for f in flagged[:40])
            more = f" and {len(flagged) - 40} more" if len(flagged) > 40 else ""
            parts.append(f"<p class='note'>Flagged segments: {txt}{more}.</p>")
    if power:
        parts.append(power_table(power))
    return "".join(parts)


def power_table(power: dict) -> str:
    """The false-alarm and power table of ``scioc power`` (``power.json``)."""
    s = power["settings"]
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
    return ("<h3>False alarms and power (<code>scioc power</code>)</h3>"
            f"<p>{s['studies']} simulated studies per human, {s['subjects']} subjects each, default design, encoder "
            f"angles only, true mean SC shift of log θ1 = {s['beta']:g} (the cost does not change). "
            "<code>maxent</code> is the model's own human: its row is the false-alarm rate. Every other human is "
            "not the max-ent LQ agent (<code>models/humans.py</code>): its row is the power, and its Wilcoxon "
            "column shows what the paper's analysis concludes without the check.</p>"
            + pd.DataFrame(rows).to_html(index=False, escape=True))
