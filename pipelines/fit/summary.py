"""The few lines ``scioc fit`` prints: a fit folder's sidecar and contrasts, the adequacy verdict first."""

from __future__ import annotations

import json
from pathlib import Path

from scioc.pipelines.adequacy import format_adequacy, not_checked
from scioc.pipelines.fit.diagnostics import remedies
from scioc.pipelines.fit.loo import reliability_words
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.prepare import IdentifySettings


def _beta_lines(b: dict, r: dict, what: str) -> list:
    return [f"beta ({what}): {b['mean']:.3f} ± {b['sd']:.3f}, 94 % HDI "
            f"[{b['hdi'][0]:.3f}, {b['hdi'][1]:.3f}], P(beta < 0) = {b['p_negative']:.3f}",
            f"exp(beta): {r['median']:.3f} (94 % HDI {r['hdi'][0]:.3f}-{r['hdi'][1]:.3f})"]


def _truth_line(t: dict, level: str = "") -> str:
    return (f"true beta{level} {t['truth']:g}: {'inside' if t['in_hdi'] else 'outside'} the HDI "
            f"(posterior mean - truth = {t['discrepancy']:+.3f})")


def fit_remedies(side: dict) -> list[tuple[str, str]]:
    """``(model, remedy)`` for each fitted model of a sidecar whose convergence verdict fails
    (:func:`scioc.pipelines.fit.diagnostics.remedies`, at the fit's own chains, draws and target acceptance)."""
    s = side.get("sampler")
    if s is None or "diagnostics" not in side:
        return []
    return [(name, text) for name, d in side["diagnostics"].items()
            for text in remedies(d, chains=s["chains"], draws=s["draws"], target_accept=s.get("target_accept"))]


def format_fit(out) -> str:
    """A few lines summarizing a fit folder's sidecar and contrasts, the adequacy verdict first (β and exp(β) of
    every non-baseline level)."""
    out = Path(out)
    side = json.loads((out / "posterior.json").read_text())
    res = json.loads((out / "contrasts.json").read_text())
    loo = res["loo"].get("difference")
    conv = side["convergence_verdict"]
    adequacy = res.get("adequacy") or not_checked("not in this fit's contrasts.json")
    lines = [format_adequacy(adequacy)]
    if adequacy["verdict"] == "fail":
        lines.append("CAVEAT: the numbers below assume a human model that fails its adequacy checks; "
                     "beta may be an artifact of model misfit")
    lines += get(side.get("human_model", IdentifySettings.human_model)).fit_summary_lines(side)
    lines.append(f"sampler convergence: condition model {conv['condition']}"
                 + (f"; pooled model {conv['pooled']}" if "pooled" in conv else ""))
    lines += [f"  to try ({name} model): {text}" for name, text in fit_remedies(side)]
    if "contrasts" in res:
        for level, c in res["contrasts"].items():
            lines += _beta_lines(c["beta"], c["ratio"], f"mean change of log theta1, {level} against {res['baseline']}")
    else:
        cond = side.get("experiment", {}).get("conditions", {"levels": ["MC", "SC"], "baseline": "MC"})
        other = next(v for v in cond["levels"] if v != cond["baseline"])
        lines += _beta_lines(res["beta"], res["ratio"], f"mean {other} change of log theta1")
    if loo is not None:
        lines.append(f"LOO: elpd(condition) - elpd(pooled) = {loo['elpd_diff']:.1f} ± {loo['se']:.1f} "
                     f"({'reliable' if loo['reliable'] else 'Pareto k high: unreliable'})")
    if res.get("loo_subject"):
        ls = res["loo_subject"]["difference"]
        se = "n/a (one subject)" if ls.get("se") is None else f"{ls['se']:.1f}"
        lines.append(f"leave-one-subject-out: elpd(condition) - elpd(pooled) = {ls['elpd_diff']:.1f} ± {se} "
                     f"({reliability_words(ls)})")
    truth = res.get("truth")
    if truth and "contrasts" in truth:
        lines += [_truth_line(c["beta"], f" ({level})") for level, c in truth["contrasts"].items()]
    elif truth:
        lines.append(_truth_line(truth["beta"]))
    for k, unit in (("tau_nm", "s"), ("sigma_m", "N·m")):
        m = ((truth or {}).get("motor") or {}).get(k, {})
        if "truth_in_interval" in m:  # the delayed fit of a simulated study
            lines.append(f"{k}: truth (up to {m['truth_max']:.3g} {unit}) inside for {m['truth_in_interval']} of "
                         f"{m['n']} subjects; median posterior median {m['median_posterior_median']:.3g} {unit}, "
                         f"largest upper end {m['largest_upper']:.3g} {unit}")
    return "\n".join(lines)


__all__ = ["fit_remedies", "format_fit"]
