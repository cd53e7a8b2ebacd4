"""``scioc fit`` with the ``delayed`` human (:func:`scioc.pipelines.fit.stage.fit_to_dir`, ``human_model="delayed"``).

The model is :func:`scioc.models.bayes.delayed_model.build_delayed_model`: the max-ent model's cost blocks, plus each
subject's neuromuscular lag and motor noise. Each subject's perceptual delay is fixed at the maximum of its units'
summed profile log-likelihoods (:func:`unit_delays`; docs/decisions/delayed-plugin-delay.md) or sampled. No pooled
model is fitted: the comparison with the max-ent human is :func:`scioc.pipelines.fit.human_models.compare_human_models`.
"""

from __future__ import annotations

import time
from dataclasses import asdict, replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from scioc.models.bayes.angle_model import OBSERVED as ANGLE_OBSERVED
from scioc.models.bayes.angle_model import build_angle_model
from scioc.models.bayes.delayed_blocks import SIGNED_FORMS, ridge_pivots
from scioc.models.bayes.delayed_model import (
    DELAY_INDEX,
    DELAYED_POPULATION_PARAMETERS,
    DelayedForm,
    DelayedPriors,
    build_delayed_model,
    delay_step,
    nutpie_options,
)
from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS
from scioc.models.delayed.identify import delay_grid, identify_unit_delayed
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.segment import prepare_batch
from scioc.pipelines.adequacy import assess_study, not_checked
from scioc.pipelines.fit.checks import mixedlm_check, motor_truth, posterior_point, truth_check, unit_theta
from scioc.pipelines.fit.contrasts import contrasts
from scioc.pipelines.fit.delayed_forms import (
    LOG_R_FORMS,
    THETA2_FORM,
    choose_delayed_form,
    choose_R_population,
    log_R_form,
)
from scioc.pipelines.fit.diagnostics import diagnostics
from scioc.pipelines.fit.loo import psis_summary
from scioc.pipelines.fit.ppc import PPC_DRAWS, posterior_predictive, ppc_coverage
from scioc.pipelines.fit.sampling import sample_model
from scioc.pipelines.fit.start import scale_sources, start_point
from scioc.pipelines.fit.warmup import pilot_runs
from scioc.pipelines.fit.whiten import sample_whitened
from scioc.pipelines.human_model.registry import FitContext, FitOutcome
from scioc.pipelines.io import InputDataError
from scioc.pipelines.prepare import angle_windows, from_angles

#: Unit-level quantities of the delayed model whose diagnostics are reported.
DELAYED_UNITS = ("log_theta1", "log_R", "theta2", "tau_nm", "sigma_m")


class Delays(NamedTuple):
    """The plug-in delay of every segment (``samples``, shape (n_segments,), in samples), per unit (``by_unit``:
    "subject/condition" -> ``delay_samples``, ``delay_s``), where they came from (``source``) and the per-unit ML
    estimates when computed here (``estimates``, else None)."""

    samples: np.ndarray
    by_unit: dict
    source: str
    estimates: pd.DataFrame | None = None


def likelihood_of(prepared) -> str:
    """``torques`` where every window has its recorded torque, else ``angles``: the fit then scores every window by
    its encoder's angles (a reconstructed torque is smoothed, which the torque likelihood would read as lag)."""
    return "angles" if from_angles(prepared.segments, range(len(prepared.segments))) else "torques"


def check_angle_fit(prepared, delay_mode: str) -> None:
    """Refuse what the angle fit does not do (InputDataError): sampled delays, an encoder without resolution."""
    if delay_mode != "profile":
        raise InputDataError(f"{prepared.path}: the fit from the encoder's angles fixes each subject's delay at its "
                             "profile maximum; delay = \"sampled\" needs the recorded torque")
    if not prepared.settings.design.encoder_sd > 0:
        raise InputDataError(f"{prepared.path}: the angle likelihood needs the encoder's resolution (the "
                             "experiment file's encoder.counts_per_rev > 0)")


def unit_delays(prepared, estimates: pd.DataFrame | None, plant, estimates_path=None) -> Delays:
    """Each segment's delay: its subject's maximum of the summed profile log-likelihoods of its units.

    The profiles (over :func:`scioc.models.delayed.identify.delay_grid`) come from the estimates' ``profile_loglik``
    or are computed here (:func:`scioc.models.delayed.identify.identify_unit_delayed`, a unit's trials together);
    estimates with ``delay_s`` but no profile give each unit its own. A unit without recorded torques is profiled on
    its angles.
    """
    dt = float(plant.dt)
    units = prepared.units
    grid = delay_grid(dt)
    profiles, per_unit = {}, {}
    if estimates is not None and "profile_loglik" in estimates.columns:
        for r in estimates.itertuples():
            prof = np.asarray(r.profile_loglik, dtype=float)
            if prof.shape != grid.shape or not np.isfinite(prof).any():
                raise InputDataError(f"{estimates_path}: profile_loglik of subject {r.subject!r}, condition "
                                     f"{r.condition!r} does not cover the delay grid of {grid.size} delays")
            profiles[(str(r.subject), str(r.condition))] = prof
        source = (f"estimates file {estimates_path}: each subject's maximum of the summed profile_loglik of its "
                  "units (scioc identify --human-model delayed)")
    elif estimates is not None and "delay_s" in estimates.columns:
        for r in estimates.itertuples():
            v = float(r.delay_s)
            if not (np.isfinite(v) and v >= 0):
                raise InputDataError(f"{estimates_path}: delay_s of subject {r.subject!r}, condition {r.condition!r} "
                                     f"is {v!r}; need a delay >= 0 s (scioc identify --human-model delayed)")
            per_unit[(str(r.subject), str(r.condition))] = int(round(v / dt))
        source = f"estimates file {estimates_path}: each unit's delay_s (no profile_loglik), rounded to samples"
    else:
        rows = []
        for (s, c), idx in units.items():
            angles = angle_windows(prepared.segments, idx) if from_angles(prepared.segments, idx) else None
            est = identify_unit_delayed([prepare_batch(plant, [prepared.segments[i].segment]) for i in idx], plant,
                                        params=prepared.settings.design.wheel,
                                        tau0=[[prepared.segments[i].warmup] for i in idx], angles=angles,
                                        sigma_y=prepared.settings.design.encoder_sd,
                                        delay_search="grid")  # the whole profile, as scioc identify writes it
            profiles[(str(s), str(c))] = np.asarray(est.profile, dtype=float)
            # The unit's ML point at its own best delay, as identify writes it: the start's targets.
            rows.append({"subject": s, "condition": c, "theta1": est.theta1, "se_log_theta1": est.se_log_theta1,
                         "R": est.theta[2], "se_log_R": est.se_log_R, "theta2": est.theta2,
                         "se_theta2": est.se_theta2, "tau_nm": est.tau_nm, "se_tau_nm": est.se_tau_nm,
                         "sigma_m": est.sigma_m, "se_sigma_m": est.se_sigma_m})
        estimates = pd.DataFrame(rows)
        source = ("computed here: each subject's maximum of the summed profile log-likelihoods of its units over "
                  "0-300 ms (models.delayed.identify.identify_unit_delayed; no estimates given)")
    if profiles:
        for subject in dict.fromkeys(s for s, _ in units):
            total = sum(np.nan_to_num(profiles[(str(subject), str(c))], nan=-np.inf) for s, c in units
                        if s == subject)
            d = int(grid[int(np.argmax(total))])  # the smallest such delay on a tie, as identify
            per_unit.update({(str(s), str(c)): d for s, c in units if s == subject})
    samples = np.array([per_unit[(str(p.data.subject), str(p.data.condition))] for p in prepared.segments],
                       dtype=np.int64)
    by_unit = {f"{s}/{c}": {"delay_samples": per_unit[(str(s), str(c))], "delay_s": per_unit[(str(s), str(c))] * dt}
               for s, c in units}
    return Delays(samples, by_unit, source, estimates)


def tau0_function(prepared, plant):
    """(segment position, τ_nm) -> the arm torque at that window's start, N·m (from its warm-up; 0 at rest)."""
    warmups = [p.warmup for p in prepared.segments]
    params = prepared.settings.design.wheel

    def at(pos: int, tau_nm: float) -> float:
        lag = lag_coefficients(float(tau_nm), plant.dt, params)
        return float(window_tau0([warmups[pos]], lag.a, lag.alpha)[0][0])

    return at


class DelayedFit(NamedTuple):
    """What the delayed path of ``scioc fit`` hands back to :func:`scioc.pipelines.fit.stage.fit_to_dir`."""

    idata: object
    diagnostics: dict
    timing: dict
    delays: Delays
    sidecar: dict
    likelihood: str = "torques"


#: How the delayed fit treats the delays: ``profile`` fixes each subject's at its profile maximum (nutpie);
#: ``sampled`` samples them (PyMC's NUTS beside :class:`scioc.models.bayes.delay_step.DelayMetropolis`).
DELAY_MODES = ("profile", "sampled")


def sampled_delays(idata, prepared, dt: float, grid: np.ndarray) -> Delays:
    """The posterior of each subject's sampled delay: its mode per segment (for the checks), and per unit a summary."""
    index = idata["posterior"][DELAY_INDEX]
    by_subject = {}
    for s in index["subject"].values:
        d = grid[np.asarray(index.sel(subject=s).values, dtype=int).ravel()]
        values, counts = np.unique(d, return_counts=True)
        by_subject[str(s)] = {"delay_samples": int(values[np.argmax(counts)]),  # the mode (smallest on a tie)
                              "mean_s": float(d.mean() * dt), "q03_s": float(np.quantile(d, 0.03) * dt),
                              "q97_s": float(np.quantile(d, 0.97) * dt)}
    by_unit = {f"{s}/{c}": {**by_subject[str(s)], "delay_s": by_subject[str(s)]["delay_samples"] * dt}
               for s, c in prepared.units}
    samples = np.array([by_subject[str(p.data.subject)]["delay_samples"] for p in prepared.segments], dtype=np.int64)
    source = ("sampled: one delay per subject, uniform over 0-300 ms, updated by DelayMetropolis beside NUTS; "
              "delay_samples is each subject's posterior mode (used by the posterior predictive, the adequacy check "
              "at the posterior and leave-one-subject-out), mean_s and q03_s-q97_s its posterior")
    return Delays(samples, by_unit, source, None)


class DelayedChoices(NamedTuple):
    """The delayed fit's coordinates, populations and sampler settings, and why (:func:`delayed_choices`)."""

    whiten: bool
    delayed_priors: DelayedPriors
    R_population_reason: str
    delayed_form: DelayedForm
    form_reason: str
    log_R: str
    log_R_reason: str
    nuts: dict


def delayed_choices(prepared, plant, delays: Delays, *, estimates: pd.DataFrame | None = None,
                    delay_mode: str = "profile", delayed_priors: DelayedPriors | None = None,
                    delayed_form: DelayedForm | None = None, rho_form: str | None = None,
                    log_R: str | None = None, target_accept: float | None = None) -> DelayedChoices:
    """What :func:`sample_delayed_model` samples with: the options given, the rest chosen by the ML estimates
    (given, or the fit's own profile's) as :mod:`scioc.pipelines.fit.delayed_forms` says, each with its reason."""
    if delay_mode not in DELAY_MODES:
        raise ValueError(f"delay_mode must be one of {', '.join(DELAY_MODES)}; got {delay_mode!r}")
    whiten = delay_mode == "profile"
    if log_R is not None and log_R not in LOG_R_FORMS:
        raise ValueError(f"log_R must be one of {', '.join(LOG_R_FORMS)}; got {log_R!r}")
    ml = estimates if estimates is not None else delays.estimates  # the ML estimates: given, or the fit's own profile's
    subjects = list(dict.fromkeys(str(s) for s in prepared.subjects))  # the model's order (models.units.index_study)
    if delayed_priors is None:
        population, population_reason = choose_R_population(ml, subjects)
        delayed_priors = DelayedPriors(R_population=population)
    else:
        population_reason = "given"
    if delayed_form is None:
        delayed_form, form_reason = choose_delayed_form(ml, subjects)
    else:
        form_reason = "given"
    log_R, R_reason = log_R_form(delayed_form) if log_R is None else (log_R, "given")
    if rho_form is not None:
        delayed_form = replace(delayed_form, rho=rho_form)
    rho_signed = delayed_priors.R_population == "policy_scale" and delayed_form.rho in SIGNED_FORMS
    nuts = nutpie_options(rho_signed) | ({} if target_accept is None else {"target_accept": float(target_accept)})
    return DelayedChoices(whiten, delayed_priors, population_reason, delayed_form, form_reason, log_R, R_reason, nuts)


def sample_delayed_model(prepared, batch, plant, priors, form, delays: Delays, *, seed: int, chains: int, draws: int,
                         tune: int, cores, show_progress: bool, delayed_priors: DelayedPriors | None = None,
                         delayed_form: DelayedForm | None = None, estimates: pd.DataFrame | None = None,
                         delay_mode: str = "profile", rho_form: str | None = None, log_R: str | None = None,
                         target_accept: float | None = None, likelihood: str = "torques") -> DelayedFit:
    """Build and sample the delayed model of the prepared study (with the pointwise log-likelihood).

    ``form``: the log θ1 blocks' forms; θ2 takes ``THETA2_FORM``, the log R blocks ``log_R``. None for ``log_R``,
    ``delayed_priors`` or ``delayed_form``: chosen by the data (:mod:`scioc.pipelines.fit.delayed_forms`).
    ``delay_mode``: ``profile`` samples each subject's whitened coordinates, curved along its ridge, after a pilot run
    (:func:`scioc.pipelines.fit.whiten.sample_whitened`); ``sampled`` samples one delay per subject (the returned
    delays: its posterior modes). ``rho_form`` replaces ρ's form; ``target_accept`` (None: :func:`nutpie_options`'s)
    the rate. ``likelihood``: the recorded torques, or the encoder's ``angles``.
    """
    c = delayed_choices(prepared, plant, delays, estimates=estimates, delay_mode=delay_mode,
                        delayed_priors=delayed_priors, delayed_form=delayed_form, rho_form=rho_form,
                        log_R=log_R, target_accept=target_accept)
    whiten, delayed_priors, delayed_form = c.whiten, c.delayed_priors, c.delayed_form
    population_reason, form_reason, R_reason, nuts = c.R_population_reason, c.form_reason, c.log_R_reason, c.nuts
    form = replace(form, R_mc=c.log_R, R_sc=c.log_R, theta2=THETA2_FORM)
    levels = prepared.settings.design.ordered_levels
    ml = estimates if estimates is not None else delays.estimates
    subjects = list(dict.fromkeys(str(s) for s in prepared.subjects))
    t0 = time.perf_counter()
    sampled = delay_mode == "sampled"
    n_subjects = len(subjects)
    pivots = ridge_pivots(delayed_priors, delayed_form, n_subjects) if whiten else None
    grid = delay_grid(float(plant.dt))
    design = prepared.settings.design
    if likelihood == "angles":
        check_angle_fit(prepared, delay_mode)
        model = build_angle_model(prepared.subjects, prepared.conditions,
                                  angle_windows(prepared.segments, range(len(prepared.segments))), plant,
                                  delay=delays.samples, sigma_y=design.encoder_sd, priors=priors,
                                  delayed_priors=delayed_priors, parameterization=form, delayed_form=delayed_form,
                                  segment_ids=prepared.labels, levels=levels, params=design.wheel)
    else:
        model = build_delayed_model(prepared.subjects, prepared.conditions, batch, plant,
                                    delay=None if sampled else delays.samples, delay_grid=grid if sampled else None,
                                    tau0=[p.warmup for p in prepared.segments], priors=priors,
                                    delayed_priors=delayed_priors, parameterization=form, delayed_form=delayed_form,
                                    segment_ids=prepared.labels, levels=levels, params=design.wheel)
    start = start_point(model, ml)
    sources = scale_sources(model, ml) if start else {}  # where each held population scale starts
    t1 = time.perf_counter()
    if sampled:
        idata, sec = sample_model(model, seed=seed, chains=chains, draws=draws, tune=tune, cores=cores,
                                  show_progress=show_progress, steps=[delay_step(model, mode="NUMBA")],
                                  initvals=start, target_accept=target_accept)
        delays = sampled_delays(idata, prepared, float(plant.dt), grid)
    else:
        idata, sec, whitening = sample_whitened(model, start, seed=seed, chains=chains, draws=draws, tune=tune,
                                                cores=cores, show_progress=show_progress, nuts=nuts, pivots=pivots,
                                                pilot=pilot_runs(delay_mode, tune, draws, chains))
    timing = {"build_s": t1 - t0, **{f"{k}_s": v for k, v in sec.items()}}
    diag = diagnostics(idata, sec["sample"], POPULATION_PARAMETERS + DELAYED_POPULATION_PARAMETERS, DELAYED_UNITS)
    side = {"delay": {"mode": delay_mode, "source": delays.source, "by_unit": delays.by_unit,
                      "note": ("sampled per subject (the other parameters' draws are delay-marginal)" if sampled else
                               "fixed per subject at the profile maximum (plug-in), not sampled: "
                               "models/bayes/delayed_model.py says what that costs")},
            "tau0": "each window's arm torque follows from the torques before it (PreparedSegment.warmup) "
                    "at every τ_nm",
            "start": ("the chains start near the ML estimates (pipelines/fit/start.py), the population scales held at "
                      "their units' spread (start_scales), jittered" if start else
                      "the chains start at PyMC's initial point (no ML estimates), jittered")
            + ("; whitened: from there the mode with the population scales held, jittered U(-1, 1) in whitened "
               "coordinates (pipelines/fit/whiten.py)" if whiten else "")
            + (f"; each subject's coordinates curved along its ridge in {' or '.join(whitening['curved_along'])}"
               + (" (per subject: the signed one whose fold the mode is nearest)"
                  if len(whitening["curved_along"]) > 1 else "")
               + " (models/bayes/whiten.py, ridge_curvature; models/bayes/delayed_blocks.py, ridge_pivots)"
               if pivots else "")
            + ("; then measured again on a pilot run's draws (models/bayes/whiten_draws.py), the kept run starting at "
               "its first chain's last draw, jittered" if whiten and whitening.get("pilot") else ""),
            "start_scales": {k: np.asarray(start[k]).tolist() for k in sources},
            **({"start_scales_from": sources} if start else {}),
            "delayed_priors": {k: getattr(delayed_priors, k) for k in delayed_priors.__dataclass_fields__},
            "R_population_reason": population_reason,
            "delayed_parameterization": {**asdict(form), "log_R_reason": R_reason},
            **({"delay_sampler": "PyMC NUTS (diagonal mass matrix) beside DelayMetropolis, numba-compiled",
                "pymc_nuts_options": {} if target_accept is None else {"target_accept": float(target_accept)}}
               if sampled else {"nutpie_options": dict(nuts)}),
            "delayed_form": {**asdict(delayed_form), "reason": form_reason},
            **({"whitening": whitening} if whiten else {})}
    return DelayedFit(idata, diag, timing, delays, side, likelihood)


def per_segment_motor(point, prepared, plant, delays: Delays, own_delay: bool = False) -> dict:
    """Per segment at a posterior point: its subject's τ_nm and σ_m, its delay (the point's own with ``own_delay``,
    else ``delays.samples``) and its arm torque at the window's start, for the adequacy check."""
    t = np.array([float(point["tau_nm"].sel(subject=s)) for s in prepared.subjects])
    sig = np.array([float(point["sigma_m"].sel(subject=s)) for s in prepared.subjects])
    delay = delays.samples
    if own_delay:
        grid = delay_grid(float(plant.dt))
        delay = np.array([int(grid[int(point[DELAY_INDEX].sel(subject=s))]) for s in prepared.subjects], dtype=np.int64)
    at = tau0_function(prepared, plant)
    return {"tau_nm": t, "sigma_m": sig, "delay": delay, "tau0": np.array([at(i, v) for i, v in enumerate(t)])}


def delayed_adequacy(idata, prepared, plant, delays: Delays, at: str = "draw") -> dict:
    """Model adequacy at one posterior point (``at``, as :func:`scioc.pipelines.fit.checks.posterior_adequacy`) with the
    bootstrap drawn from the delayed human."""
    if prepared.settings.adequacy_boot == 0:
        return not_checked("switched off (adequacy bootstrap size 0)")
    point, described = posterior_point(idata["posterior"], at, prepared.settings.adequacy_seed)
    own = at == "draw" and DELAY_INDEX in point
    _, summary = assess_study(prepared.segments, unit_theta(point, prepared), plant, prepared.settings,
                              delayed=per_segment_motor(point, prepared, plant, delays, own_delay=own))
    summary["theta"] = (f"θ per subject × condition, τ_nm and σ_m per subject at {described['what']}; the delays "
                        + ("of that draw" if own else "plug-in"))
    summary["point"] = described
    return summary


def delayed_results(fit: DelayedFit, prepared, plant, estimates, truth_dir, subject: str, rng_ppc, *,
                    n_draws: int) -> tuple[dict, object, object]:
    """contrasts.json of the delayed fit (as the max-ent fit's, with PSIS-LOO of this model alone and the truth of
    τ_nm and σ_m), and the posterior predictive (bands, draws) from the delayed human."""
    design = prepared.settings.design
    levels = design.ordered_levels
    idata = fit.idata
    res = {"model": "hierarchical delayed human: the max-ent model's condition effects on log θ1 and log R (command "
                    "cost), τ_nm and σ_m per subject, plug-in delays (models.bayes.delayed_model)",
           "human_model": "delayed", **contrasts(idata)}
    loo, _ = psis_summary(idata, observed_name(fit.likelihood), "segment")
    res["loo"] = {"delayed": loo, "note": "this model alone (no pooled model is fitted for the delayed human)"}
    res["loo_subject"] = None
    res["human_models"] = ("not computed in this fit: pipelines.fit.human_models.compare_human_models compares the "
                           "max-ent and delayed fits of one study by leave-one-subject-out")
    res["mixedlm"] = mixedlm_check(estimates, levels) if estimates is not None else None
    res["truth"] = truth_check(idata, truth_dir, estimates, design) if truth_dir is not None else None
    if res["truth"] is not None:
        res["truth"]["motor"] = motor_truth(idata, truth_dir)
    at = tau0_function(prepared, plant)
    ppc, ppc_draws = posterior_predictive(idata, prepared, subject, rng_ppc, n_draws=n_draws,
                                          delayed={"delay": fit.delays.samples, "tau0": at})
    assisted = ", ".join(v for v in levels if design.assistant(v) is not None) or "no level"
    res["ppc"] = {"subject": subject, "draws": int(ppc_draws.sizes["draw"]), "coverage_5_95": ppc_coverage(ppc),
                  "note": f"exact draws of the delayed human (in {assisted}: {prepared.settings.assistant_model} "
                          "assistant model) at each draw's θ, τ_nm, σ_m and the plug-in delay; u_H is the "
                          "reconstructed torque where the file has none"}
    return res, ppc, ppc_draws


def observed_name(likelihood: str) -> str:
    """The observed variable of a fit that scores ``likelihood``: the recorded angles or torques."""
    return ANGLE_OBSERVED if likelihood == "angles" else "u_H"


def fit_delayed(ctx: FitContext) -> FitOutcome:
    """Sample the delayed model of the prepared study in ``ctx`` with its sampler options (``delay``,
    ``R_population``, ``rho_form``, ``log_R_form``), then contrasts, predictive bands and adequacy."""
    prepared, plant, opts = ctx.prepared, ctx.plant, ctx.options
    delays = unit_delays(prepared, ctx.estimates, plant, ctx.estimates_path)
    population = opts.get("R_population")
    fit = sample_delayed_model(prepared, ctx.batch, plant, ctx.priors, ctx.form, delays, seed=ctx.seeds["condition"],
                               chains=ctx.chains, draws=ctx.draws, tune=ctx.tune, cores=ctx.cores,
                               show_progress=ctx.show_progress, estimates=ctx.estimates,
                               delay_mode=opts.get("delay", "profile"),
                               delayed_priors=None if population is None else DelayedPriors(R_population=population),
                               rho_form=opts.get("rho_form"), log_R=opts.get("log_R_form"),
                               target_accept=ctx.target_accept, likelihood=ctx.likelihood)
    timing = {"condition": fit.timing}
    t0 = time.perf_counter()
    res, ppc, ppc_draws = delayed_results(fit, prepared, plant, ctx.estimates, ctx.truth_dir, ctx.subject,
                                          np.random.default_rng(ctx.seeds["ppc"]), n_draws=PPC_DRAWS)
    timing["contrasts_and_ppc_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res["adequacy"] = delayed_adequacy(fit.idata, prepared, plant, fit.delays, at=ctx.adequacy_at)
    timing["adequacy_s"] = time.perf_counter() - t0
    return FitOutcome({"condition": fit.idata}, {"condition": fit.diagnostics}, res, timing, fit.sidecar, ppc,
                      ppc_draws)


__all__ = ["DELAY_MODES", "DelayedChoices", "check_angle_fit", "likelihood_of", "observed_name", "delayed_choices", "fit_delayed", "sampled_delays", "DELAYED_UNITS", "DelayedFit", "Delays", "delayed_adequacy",
           "delayed_results", "per_segment_motor", "sample_delayed_model", "tau0_function", "unit_delays"]
