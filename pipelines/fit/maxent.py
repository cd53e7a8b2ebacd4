"""``scioc fit`` with the ``maxent`` human: the hierarchical max-ent model with condition effects, and the pooled
one that serves the LOO comparison (:func:`scioc.models.bayes.hierarchical.build_model`); or, with ``--likelihood
angles``, the condition model scored by the encoder's angles (:func:`fit_maxent_angles`)."""

from __future__ import annotations

import time

import numpy as np

from scioc.models.bayes.angle_model import OBSERVED, build_angle_model
from scioc.models.bayes.hierarchical import build_model
from scioc.pipelines.fit.checks import mixedlm_check, posterior_adequacy, truth_check
from scioc.pipelines.fit.contrasts import contrasts
from scioc.pipelines.fit.diagnostics import diagnostics
from scioc.pipelines.fit.loo import loo_comparison, psis_summary, subject_loo_comparison
from scioc.pipelines.fit.ppc import PPC_DRAWS, posterior_predictive, ppc_coverage
from scioc.pipelines.fit.sampling import sample_model
from scioc.pipelines.human_model.registry import FitContext, FitOutcome
from scioc.pipelines.prepare import angle_windows


def fit_maxent(ctx: FitContext) -> FitOutcome:
    """Sample the condition and pooled models, then contrasts, LOO, cross-checks, predictive bands and adequacy."""
    if ctx.likelihood == "angles":
        return fit_maxent_angles(ctx)
    prepared, design = ctx.prepared, ctx.prepared.settings.design
    levels = design.ordered_levels
    fits, timing = {}, {}
    for name, effects in (("condition", True), ("pooled", False)):
        t0 = time.perf_counter()
        model = build_model(prepared.subjects, prepared.conditions, ctx.batch, ctx.plant, segment_ids=prepared.labels,
                            condition_effects=effects, priors=ctx.priors, levels=levels, parameterization=ctx.form)
        t1 = time.perf_counter()
        idata, sec = sample_model(model, seed=ctx.seeds[name], chains=ctx.chains, draws=ctx.draws, tune=ctx.tune,
                                  cores=ctx.cores, show_progress=ctx.show_progress, target_accept=ctx.target_accept)
        fits[name] = idata
        timing[name] = {"build_s": t1 - t0, **{f"{k}_s": v for k, v in sec.items()}}
    diag = {name: diagnostics(d, timing[name]["sample_s"]) for name, d in fits.items()}

    t0 = time.perf_counter()
    res = {"model": "hierarchical max-ent, condition effects on log θ1 and log R (models.bayes.hierarchical)",
           **contrasts(fits["condition"])}
    res["loo"] = loo_comparison(fits["condition"], fits["pooled"])
    res["loo_subject"] = subject_loo_comparison(fits["condition"], fits["pooled"], ctx.batch, prepared.subjects,
                                                prepared.conditions, ctx.plant, np.random.default_rng(ctx.seeds["loso"]),
                                                levels=levels)
    _checks(res, fits["condition"], ctx, timing)
    return FitOutcome(fits, diag, res, timing, {}, *res.pop("_ppc"))


def fit_maxent_angles(ctx: FitContext) -> FitOutcome:
    """The condition model scored by the encoder's angles: the delayed human's angle likelihood with no delay, lag or
    motor noise (:func:`scioc.models.bayes.angle_model.build_angle_model` with ``motor=False``), its log R population
    log-normal as the torque fit's; then contrasts, PSIS-LOO of the angles, cross-checks, predictive bands and
    adequacy. No pooled model: leave-one-subject-out against the delayed model scores the same angles."""
    prepared, design = ctx.prepared, ctx.prepared.settings.design
    t0 = time.perf_counter()
    model = build_angle_model(prepared.subjects, prepared.conditions,
                              angle_windows(prepared.segments, range(len(prepared.segments))), ctx.plant, delay=0,
                              sigma_y=design.encoder_sd, motor=False, priors=ctx.priors, parameterization=ctx.form,
                              segment_ids=prepared.labels, levels=design.ordered_levels, params=design.wheel)
    t1 = time.perf_counter()
    idata, sec = sample_model(model, seed=ctx.seeds["condition"], chains=ctx.chains, draws=ctx.draws, tune=ctx.tune,
                              cores=ctx.cores, show_progress=ctx.show_progress, target_accept=ctx.target_accept)
    timing = {"condition": {"build_s": t1 - t0, **{f"{k}_s": v for k, v in sec.items()}}}
    diag = {"condition": diagnostics(idata, timing["condition"]["sample_s"])}
    res = {"model": "hierarchical max-ent, condition effects on log θ1 and log R, scored by the encoder's angles "
                    "(models.bayes.angle_model, motor=False)", "human_model": "maxent", **contrasts(idata)}
    loo, _ = psis_summary(idata, OBSERVED, "segment")
    res["loo"] = {"maxent": loo, "note": "this model alone: no pooled model is fitted to the angles"}
    res["loo_subject"] = None
    _checks(res, idata, ctx, timing)
    return FitOutcome({"condition": idata}, diag, res, timing, {"likelihood": "angles"}, *res.pop("_ppc"))


def _checks(res: dict, idata, ctx: FitContext, timing: dict) -> None:
    """Into ``res``: the mixed-model and truth checks, the predictive bands (``_ppc``: bands, draws) and adequacy."""
    prepared, design = ctx.prepared, ctx.prepared.settings.design
    levels = design.ordered_levels
    t0 = time.perf_counter()
    estimates = ctx.estimates
    res["mixedlm"] = mixedlm_check(estimates, levels) if estimates is not None else None
    res["truth"] = truth_check(idata, ctx.truth_dir, estimates, design) if ctx.truth_dir is not None else None
    assisted = ", ".join(v for v in levels if design.assistant(v) is not None) or "no level"
    ppc, ppc_draws = posterior_predictive(idata, prepared, ctx.subject, np.random.default_rng(ctx.seeds["ppc"]))
    res["ppc"] = {"subject": ctx.subject, "draws": int(min(PPC_DRAWS, ctx.chains * ctx.draws)),
                  "coverage_5_95": ppc_coverage(ppc),
                  "note": f"exact max-ent draws of the human the likelihood assumes (in {assisted}: "
                          + prepared.settings.assistant_model + " assistant model); "
                          "u_H is the reconstructed torque where the file has none"}
    res["_ppc"] = (ppc, ppc_draws)
    timing["contrasts_and_ppc_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res["adequacy"] = posterior_adequacy(idata, prepared, ctx.plant, at=ctx.adequacy_at)
    timing["adequacy_s"] = time.perf_counter() - t0


__all__ = ["fit_maxent", "fit_maxent_angles"]
