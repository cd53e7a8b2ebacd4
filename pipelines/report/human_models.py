"""The report's "Human models" section: which human model the data support, and what it says about the costs.

Per model (:data:`MODEL_ARTIFACTS`, never refit): the adequacy verdicts at identify and at the fit's
posterior θ, the Wilcoxon test and β per contrast, and the leave-one-subject-out (LOSO) ELPD of its fit
(``human_models.json``). A model is supported (:func:`supported`) if it passes its adequacy checks and a
reliable LOSO comparison (docs/decisions/loso-reliability.md) does not prefer the other by :data:`LOSO_Z`
SE or more. A cost conclusion (:func:`conclusion`) is only ever
that of a supported model, with its adequacy verdict beside it.
"""

from __future__ import annotations

from typing import NamedTuple

import pandas as pd
from markupsafe import Markup

from scioc.models.design import STUDY, Design
from scioc.pipelines.fit.summary import fit_remedies
from scioc.pipelines.human_model.registry import ALTERNATIVE, PRIMARY
from scioc.pipelines.report.contrasts import blocks
from scioc.pipelines.report.identify import tests_by_level
from scioc.pipelines.report.levels import contrast_label, joined
from scioc.pipelines.report.render import RunParts, number, render, table

#: Per human model: its identify folder, its Wilcoxon tests and its fit folder, under the run folder.
MODEL_ARTIFACTS = {PRIMARY: ("identify", "compare.json", "fit"),
                   ALTERNATIVE: ("identify_delayed", "compare_delayed.json", "fit_delayed")}
#: The models as the prose names them.
NAMES = {PRIMARY: "max-ent", ALTERNATIVE: "delayed"}
#: A LOSO difference of at least this many standard errors is read as a preference (the loo package's
#: usual reading: a difference within 2 SE is not distinguished from noise).
LOSO_Z = 2.0
#: The file in a run folder where ``scioc run`` records which human models it analysed and why
#: (:func:`scioc.pipelines.run.default_human_models`).
RUN_FILE = "run.json"
#: Where ``scioc run`` fits the max-ent human to the encoder's angles, for the comparison without a torque sensor.
ANGLE_FIT = "fit_angles"
#: How ``scioc run`` compares the models without a torque sensor (docs/decisions/run-human-models.md).
ANGLE_ONLY = ("without a torque sensor both human models are fitted to the encoder's angles for their comparison "
              f"(the max-ent one in {ANGLE_FIT}/, beside its fit of the reconstructed torques in fit/)")


class ModelRun(NamedTuple):
    """One human model's results in a run folder (None where the artifact is missing)."""

    name: str
    identify: dict | None  # adequacy verdict at identify (identify.json)
    posterior: dict | None  # adequacy verdict at the fit's posterior θ (contrasts.json); None: no fit
    tests: dict | None  # compare.json
    fit: dict | None  # contrasts.json
    convergence: str | None = None  # the sampler-convergence verdict of the fit with condition effects (posterior.json)
    remedies: tuple = ()  # what to try where that verdict fails (pipelines.fit.summary.fit_remedies)
    population: str | None = None  # the delayed fit's population of R and why (posterior.json), :func:`population_words`


def read_models(run) -> dict[str, ModelRun]:
    """The human models a run folder (or its :class:`~scioc.pipelines.report.render.RunParts`) holds (those with an
    identify folder), in :data:`MODEL_ARTIFACTS`' order."""
    run = RunParts.of(run)
    out = {}
    for name, (ident, tests, fit) in MODEL_ARTIFACTS.items():
        meta = run.read(f"{ident}/identify.json")
        if meta is None:
            continue
        res = run.read(f"{fit}/contrasts.json")
        side = run.read(f"{fit}/posterior.json")
        out[name] = ModelRun(name, meta.get("adequacy"), None if res is None else res.get("adequacy") or {},
                             run.read(tests), res,
                             None if side is None else (side.get("convergence_verdict") or {}).get("condition"),
                             () if side is None else tuple(t for m, t in fit_remedies(side) if m == "condition"),
                             population_words(side))
    return out


def population_words(side: dict | None) -> str | None:
    """A delayed fit's population of the subjects' baseline R, with ρ's form under the policy scale, and why
    (``delayed_priors``, ``R_population_reason``, ``delayed_form`` of its posterior.json); None for another fit."""
    if not side or "delayed_priors" not in side:
        return None
    population = side["delayed_priors"]["R_population"]
    rho = f", ρ = R^(-1/2) {side['delayed_form']['rho']}" if population == "policy_scale" else ""
    reason = side.get("R_population_reason", "given")
    return f"{population}{rho} ({'given' if reason == 'given' else 'chosen by the estimates: ' + reason})"


def passes(m: ModelRun) -> bool:
    """Whether a model passes its adequacy checks: a verdict that was checked, and none that fails."""
    checked = [a["verdict"] for a in (m.identify, m.posterior) if a and a.get("verdict") in ("pass", "fail")]
    return bool(checked) and all(v == "pass" for v in checked)


def verdict_words(a: dict | None, counts: bool = True) -> str:
    """One verdict: "fail (whiteness, xcorr; 84 of 84 segments flagged)"; without ``counts``: "fail (whiteness, xcorr)".
    """
    v = (a or {}).get("verdict", "not checked")
    if v not in ("pass", "fail"):
        return "not checked"
    flagged = f"{a['segments_flagged']} of {a['segments']} segments flagged" if counts and "segments" in a else ""
    details = "; ".join(x for x in (", ".join(a.get("failed_checks", [])), flagged) if x)
    return f"{v} ({details})" if details else v


def adequacy_words(m: ModelRun) -> str:
    """A model's adequacy verdicts, short: "pass at identify, fail (xcorr) at the posterior θ"."""
    post = "no fit" if m.posterior is None else f"{verdict_words(m.posterior, False)} at the posterior θ"
    return f"{verdict_words(m.identify, False)} at identify, {post}"


def _wilcoxon(r: dict | None) -> str:
    if not r:
        return "no test"
    holm = "p_holm" in r
    p, reject = (r["p_holm"], r["reject_holm"]) if holm else (r["p_value"], r["reject"])
    return (f"T = {number(r['T'], 'g')}, {'Holm p' if holm else 'p'} = {number(p, '.2g')}, "
            f"{'rejects' if reject else 'does not reject'} H0 (no change) at α = {r['alpha']:g}")


def _beta(b: dict | None, convergence: str | None = None) -> str:
    """β with its HDI; flagged when the fit's sampler did not converge (its draws are then not a result)."""
    if not b:
        return "no fit"
    lo, hi = b["beta"]["hdi"]
    flag = ("" if not convergence or convergence == "pass" else
            f"; but the sampler did not converge ({convergence}), so this β is not a result to rely on")
    return (f"β = {b['beta']['mean']:+.3f}, 94 % HDI [{lo:+.3f}, {hi:+.3f}] "
            f"({'excludes' if hi < 0 or lo > 0 else 'contains'} 0){flag}")


def cost_words(m: ModelRun, design: Design) -> str:
    """What a model says about the change of θ1 per contrast: the Wilcoxon test and β, each with its decision."""
    tests = tests_by_level(m.tests, design) if m.tests else {}
    found = (blocks(m.fit, design) or {}) if m.fit else {}
    parts = [f"{contrast_label(design, v)}: Wilcoxon on θ1 {_wilcoxon((tests.get(v) or {}).get('theta1'))}"
             + (f"; {_beta(found.get(v), m.convergence)}" if m.fit else " (no Bayesian fit)") for v in design.contrasts]
    return "; ".join(parts)


def loso_preference(hm: dict | None) -> str | None:
    """The model a reliable LOSO comparison prefers by at least :data:`LOSO_Z` SE, else None."""
    d = (hm or {}).get("difference")
    if not d or not d.get("reliable") or d.get("z") is None:
        return None
    return None if abs(d["z"]) < LOSO_Z else (ALTERNATIVE if d["z"] > 0 else PRIMARY)


def _loso_words(hm: dict | None) -> str:
    d = (hm or {}).get("difference")
    if not d:
        return "leave-one-subject-out was not computed (no fits of both models)"
    what = (f"elpd(delayed) − elpd(max-ent) = {d['elpd_diff']:+.1f} ± {number(d.get('se'), '.1f')}, "
            f"z = {number(d.get('z'), '.2f')}")
    if not d.get("reliable"):
        why = "; ".join(d.get("unreliable_because") or ["Pareto k above the threshold"])
        return f"leave-one-subject-out is unreliable ({why}; {what})"
    pref = loso_preference(hm)
    if pref is None:
        return f"leave-one-subject-out does not separate the models ({what}; |z| < {LOSO_Z:g})"
    return f"leave-one-subject-out prefers the {NAMES[pref]} model ({what})"


def supported(models: dict[str, ModelRun], hm: dict | None) -> tuple[str, ...]:
    """The models the data support: passing adequacy, and not beaten by a reliable LOSO preference (see the module)."""
    ok = tuple(k for k, m in models.items() if passes(m))
    pref = loso_preference(hm)
    if pref is None:
        return ok
    return (pref,) if pref in ok else ()


def conclusion(models: dict[str, ModelRun], hm: dict | None, design: Design = STUDY) -> str:
    """One sentence: the model the data support and, from it, the cost conclusion with its adequacy verdict beside it."""
    chosen = supported(models, hm)
    loso = _loso_words(hm)
    verdicts = "; ".join(f"{NAMES[k]}: {adequacy_words(m)}" for k, m in models.items())
    if not chosen:
        ok = [k for k, m in models.items() if passes(m)]
        if not ok:
            return (f"Neither human model passes its adequacy checks ({verdicts}), so these data support no "
                    "conclusion about the costs.")
        other = loso_preference(hm)
        return (f"The data single out no human model: the {NAMES[ok[0]]} model passes its adequacy checks but "
                f"{loso}, and the {NAMES[other]} model fails them ({verdicts}); so no conclusion about the costs is "
                "supported.")
    if len(chosen) == 1:
        k = chosen[0]
        others = [f"the {NAMES[o]} model: {adequacy_words(m)}" for o, m in models.items() if o != k]
        return (f"The data support the {NAMES[k]} human model: it passes its adequacy checks "
                f"({adequacy_words(models[k])}{'; ' + '; '.join(others) if others else ''}) and {loso}; "
                f"by it, {cost_words(models[k], design)}.")
    return (f"Both human models pass their adequacy checks and {loso}: "
            + "; ".join(f"by the {NAMES[k]} model ({adequacy_words(models[k])}), {cost_words(models[k], design)}"
                        for k in chosen) + ".")


def _table(models: dict[str, ModelRun], hm: dict | None, design: Design) -> Markup:
    rows = [("adequacy at identify", {k: verdict_words(m.identify) for k, m in models.items()}),
            ("adequacy at the posterior θ (fit)",
             {k: "no fit" if m.posterior is None else verdict_words(m.posterior) for k, m in models.items()}),
            ("sampler convergence (fit)", {k: m.convergence or "no fit" for k, m in models.items()})]
    if any(m.population for m in models.values()):
        rows.append(("population of the subjects' R (fit)",
                     {k: m.population or ("lognormal (the paper's model's)" if m.fit else "no fit")
                      for k, m in models.items()}))
    if any(m.remedies for m in models.values()):
        rows.append(("what to try (fit's sampler)", {k: "; ".join(m.remedies) or "—" for k, m in models.items()}))
    for v in design.contrasts:
        label = contrast_label(design, v)
        rows.append((f"Wilcoxon on θ1, {label}",
                     {k: _wilcoxon((tests_by_level(m.tests, design).get(v) or {}).get("theta1")) if m.tests
                      else "no test" for k, m in models.items()}))
        rows.append((f"β, {label}", {k: _beta((blocks(m.fit, design) or {}).get(v), m.convergence) if m.fit
                                     else "no fit" for k, m in models.items()}))
    if hm:
        n, k_del = hm["difference"]["n"], hm["difference"]["n_preferring_delayed"]
        rows.append(("LOSO ELPD (sum over subjects ± SE)",
                     {k: f"{hm[k]['elpd_loo']:.1f} ± {number(hm[k].get('se'), '.1f')}" for k in models}))
        rows.append(("subjects better predicted (LOSO)",
                     {"maxent": f"{n - k_del} of {n}", "delayed": f"{k_del} of {n}"}))
    df = pd.DataFrame([{"": name, **{f"{NAMES[k]} human": cells[k] for k in models}} for name, cells in rows])
    return table(df, left=tuple(df.columns))


def _per_subject(hm: dict) -> dict:
    """Subjects with elpd(delayed) − elpd(max-ent), grouped by the model that predicts them better."""
    by = hm.get("by_subject", {})
    return {k: [f"{s} ({v['difference']:+.1f})" for s, v in by.items() if v["preferred"] == k] for k in NAMES}


def section(run, design: Design = STUDY) -> Markup:
    """The "Human models" section of a run folder or its parts."""
    run = RunParts.of(run)
    models = read_models(run)
    if ALTERNATIVE not in models:
        chosen = run.read(RUN_FILE)  # scioc run's choice of human models and its reason
        if chosen and chosen.get("requested") is None:
            why = chosen["why"][0].upper() + chosen["why"][1:] + "."
        else:
            why = ("The delayed human model was not requested in this run (scioc run --human-model maxent,delayed "
                   "runs it beside the max-ent model).")
        return render("human_models.html.j2", both=False, why=why)
    hm = run.read("human_models.json")
    note = ("The delayed human model has no Bayesian fit here." if models[ALTERNATIVE].fit is None else
            f"The leave-one-subject-out comparison scores the encoder's angles: {ANGLE_ONLY}."
            if (hm or {}).get("fits", {}).get(PRIMARY) == ANGLE_FIT else None)
    return render("human_models.html.j2", both=True, table=_table(models, hm, design), note=note,
                  d=(hm or {}).get("difference"), per=_per_subject(hm) if hm else None, loso=_loso_words(hm),
                  ok=bool(supported(models, hm)), conclusion=conclusion(models, hm, design), loso_z=LOSO_Z,
                  contrasts=joined(contrast_label(design, v) for v in design.contrasts))


def headline(run, design: Design = STUDY) -> Markup:
    """The conclusion box under the adequacy headline, when the run has both models; else nothing."""
    run = RunParts.of(run)
    models = read_models(run)
    if ALTERNATIVE not in models:
        return Markup("")
    hm = run.read("human_models.json")
    return render("human_models_headline.html.j2", ok=bool(supported(models, hm)),
                  conclusion=conclusion(models, hm, design))


__all__ = ["ANGLE_FIT", "ANGLE_ONLY", "LOSO_Z", "MODEL_ARTIFACTS", "RUN_FILE", "ModelRun", "adequacy_words", "conclusion",
           "cost_words", "headline", "loso_preference", "passes", "population_words", "read_models", "section",
           "supported", "verdict_words"]
