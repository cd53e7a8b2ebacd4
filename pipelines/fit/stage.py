"""``scioc fit``: the hierarchical Bayesian model of a study, its diagnostics and contrasts.

The segments are cut as ``scioc identify`` cuts them; then nutpie samples two models of
:func:`scioc.models.bayes.hierarchical.build_model`: with condition effects (β, the mean SC change of log θ1, is the
paper's question) and pooled, which only serves the LOO comparison. The delayed human has one model
(:mod:`scioc.pipelines.fit.delayed`). Artifacts in ``--out DIR``: ``posterior.nc`` (the condition model's DataTree,
with ``log_likelihood``, ``observed_data``, one subject's ``posterior_predictive`` and ``constant_data``),
``posterior_pooled.nc``, ``posterior.json`` (the sidecar: seeds, settings, priors, diagnostics and verdict, times,
inputs, experiment, versions), ``contrasts.json`` (β, contrasts, LOO, cross-checks, adequacy) and ``ppc.parquet``
(predictive bands). The same root seed gives the same draws (:func:`scioc.pipelines.fit.sampling.child_seeds`).
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.models.bayes.delayed_blocks import DelayedPriors
from scioc.models.bayes.hierarchical import Parameterization, Priors, build_model
from scioc.models.identify import identify_unit
from scioc.models.plant import discretize
from scioc.models.runtime import configure
from scioc.models.segment import prepare_batch
from scioc.pipelines.experiment import sidecar as experiment_fields
from scioc.pipelines.fit.artifacts import require_netcdf, strict_json, write_netcdf
from scioc.pipelines.fit.checks import ADEQUACY_POINTS, mixedlm_check, posterior_adequacy, truth_check
from scioc.pipelines.fit.contrasts import contrasts
from scioc.pipelines.fit.delayed import (
    DELAY_MODES,
    delayed_adequacy,
    delayed_results,
    sample_delayed_model,
    unit_delays,
)
from scioc.pipelines.fit.diagnostics import EBFMI_MIN, ESS_MIN, NUTPIE_TARGET_ACCEPT, RHAT_MAX, diagnostics
from scioc.pipelines.fit.loo import loo_comparison, subject_loo_comparison
from scioc.pipelines.fit.ppc import PPC_DRAWS, constant_data, posterior_predictive, ppc_coverage
from scioc.pipelines.fit.sampling import child_seeds, sample_model
from scioc.pipelines.fit.warmup import default_tune
from scioc.pipelines.io import InputDataError, load_study
from scioc.pipelines.prepare import IdentifySettings, PreparedStudy, check_design, check_human_model, prepare_study
from scioc.pipelines.provenance import versions
from scioc.pipelines.storage import (
    check_output_dir,
    refuse_inputs_inside,
    staged_dir,
    write_table_atomic,
    write_text_atomic,
)


def default_inputs(study_path: Path, estimates_path, truth_dir):
    """Inputs beside the study in ``scioc run``'s folder layout when not given; the estimates only if
    ``<run>/identify/identify.json`` says they come from this very study file."""
    if estimates_path is None:
        guess = study_path.parent.parent / "identify"
        try:
            meta = json.loads((guess / "identify.json").read_text())
            same = (guess / meta["study_relative"]).resolve() == study_path.resolve()
        except (OSError, ValueError, KeyError, TypeError):
            same = False
        estimates_path = guess / "estimates.parquet" if same and (guess / "estimates.parquet").exists() else None
    if truth_dir is None:
        folder = study_path.parent
        if (folder / "simulation.json").exists() and (folder / "truth.parquet").exists():
            truth_dir = folder
    return estimates_path, truth_dir


#: Fewest draws in all chains: PSIS-LOO fits its Pareto tail to min(0.2 S, 3 √S) draws and needs 5.
MIN_TOTAL_DRAWS = 25


#: The median SE of the units' ML log θ1 at or below which the log θ1 blocks are centred: the data then outweigh the
#: population spread of the changes (docs/decisions/maxent-parameterization.md).
CENTRED_SE_LOG_THETA1 = 0.08


def unit_se_log_theta1(prepared, plant) -> pd.DataFrame:
    """``se_log_theta1`` of every unit's ML estimate (its trials together), as ``scioc identify`` computes it."""
    segs = prepared.segments
    return pd.DataFrame({"se_log_theta1": [identify_unit([prepare_batch(plant, [segs[i].segment]) for i in idx],
                                                         plant).se_log_theta1
                                           for idx in prepared.units.values()]})


def sampler_record(human_model: str, delay_mode: str, nutpie_options: dict | None = None,
                   whitening: dict | None = None) -> dict:
    """Which sampler a fit used and its mass matrix, for the sidecar (the delayed fit's ``nutpie_options`` and
    ``whitening`` record)."""
    if human_model == "delayed" and delay_mode == "sampled":
        return {"name": "PyMC NUTS + DelayMetropolis", "via": "pymc.sample(step=[DelayMetropolis])",
                "adaptation": "diag (PyMC's NUTS)"}
    return {"name": "nutpie", "via": "pymc.sample(nuts_sampler='nutpie')",
            "adaptation": f"{nutpie_options['adaptation']} (nutpie)"
            + (", per-subject whitened" if whitening is not None else "")
            + (", curved along " + curved_along(whitening["curved_along"])
               if whitening and "curved_along" in whitening else "")
            + (", measured again on a pilot run's draws" if whitening and whitening.get("pilot") else "")
            if human_model == "delayed" else
            "diag (nutpie default)"}


def curved_along(counts: dict) -> str:
    """A curved whitening's pivots for the sidecar: the name alone, or each with its number of subjects."""
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{name} ({n} subjects)" for name, n in counts.items())


def choose_parameterization(estimates) -> tuple[Parameterization, str]:
    """The form of the log θ1 blocks for these data, and why: centred where the estimates' median ``se_log_theta1``
    is at most :data:`CENTRED_SE_LOG_THETA1`, else (and without estimates) the default :class:`Parameterization`."""
    if estimates is None or "se_log_theta1" not in estimates.columns:
        return Parameterization(), "default (no estimates to measure the data per unit)"
    se = float(pd.to_numeric(estimates["se_log_theta1"], errors="coerce").median())
    if np.isfinite(se) and se <= CENTRED_SE_LOG_THETA1:
        return (Parameterization(theta1_mc="centred", theta1_sc="centred"),
                f"centred log θ1: the median SE of log θ1 per unit is {se:.3g} <= {CENTRED_SE_LOG_THETA1}")
    return Parameterization(), f"default: the median SE of log θ1 per unit is {se:.3g} > {CENTRED_SE_LOG_THETA1}"


def fit_to_dir(study_path, out, *, seed: int = 2018, chains: int = 4, draws: int = 1000, tune: int | None = None,
               settings: IdentifySettings = IdentifySettings(), subject: str | None = None,
               estimates_path=None, truth_dir=None, cores: int | None = None, show_progress: bool = False,
               force: bool = False, prepared: PreparedStudy | None = None, experiment_file: str | None = None,
               human_model: str | None = None, delay_mode: str = "profile",
               delayed_priors: DelayedPriors | None = None, rho_form: str | None = None,
               adaptation: str | None = None, log_R_form: str | None = None, adequacy_at: str = "draw",
               target_accept: float | None = None) -> dict:
    """Fit the hierarchical model(s) to a study file and write every artifact (module docstring).

    Parameters
    ----------
    study_path, out : str or Path
        Study file in the data convention; output folder (created; ``force`` replaces a non-empty one as a whole).
    seed, chains, draws, tune : int
        Root seed; chains, and draws kept per chain after ``tune`` warm-up draws (default
        :func:`scioc.pipelines.fit.warmup.default_tune`).
    settings : IdentifySettings
        Window, preview and reconstruction, as for ``scioc identify``, and the experiment (``settings.design``).
    subject : str, optional
        Subject of the predictive bands (default: the third in sorted order, the report's Fig. 6).
    estimates_path, truth_dir : str or Path, optional
        ``scioc identify``'s ``estimates.parquet``; a simulated study's folder (defaults: :func:`default_inputs`).
    cores : int, optional
        Chains sampled in parallel (default ``os.cpu_count()``); the draws do not depend on it.
    prepared : PreparedStudy, optional
        The study already prepared with ``settings`` (``scioc run`` shares the identification's).
    experiment_file : str, optional
        Where ``settings.design`` came from (None: the built-in study), for the sidecar.
    human_model, delay_mode, delayed_priors, rho_form, adaptation, log_R_form
        ``maxent`` or ``delayed`` (default ``settings.human_model``); the rest as
        :func:`scioc.pipelines.fit.delayed.sample_delayed_model` takes them.
    adequacy_at : {"draw", "means"}
        The posterior point of the adequacy check (:data:`scioc.pipelines.fit.checks.ADEQUACY_POINTS`).
    target_accept : float, optional
        The sampler's target acceptance rate in (0, 1); None: the fit's own (docs/decisions/delayed-target-accept.md).

    Returns
    -------
    dict
        Paths of the written files.

    Raises
    ------
    ValueError
        For a bad study design, a malformed file or an unknown ``subject``; nothing is written then.
    """
    configure()
    require_netcdf()
    human_model = settings.human_model if human_model is None else human_model
    check_human_model(human_model)
    if delay_mode not in DELAY_MODES or (delay_mode != "profile" and human_model != "delayed"):
        raise ValueError(f"delay_mode must be one of {', '.join(DELAY_MODES)} ('sampled' for the delayed human only); "
                         f"got {delay_mode!r} with {human_model!r}")
    if log_R_form is not None and human_model != "delayed":
        raise ValueError(f"log_R_form is the delayed fit's option; got {log_R_form!r} with {human_model!r}")
    if adaptation is not None and human_model != "delayed":
        raise ValueError(f"adaptation (nutpie's mass matrix) is the delayed fit's option; got {adaptation!r} with "
                         f"{human_model!r}")
    if target_accept is not None and not 0.0 < target_accept < 1.0:
        raise ValueError(f"--target-accept must lie between 0 and 1; got {target_accept!r}")
    if adequacy_at not in ADEQUACY_POINTS:
        raise ValueError(f"--adequacy-at must be one of {', '.join(ADEQUACY_POINTS)}; got {adequacy_at!r}")
    if human_model != settings.human_model and settings.human_model != "maxent":
        raise ValueError(f"human_model {human_model!r} contradicts the settings' {settings.human_model!r}")
    if tune is None:
        tune = default_tune(human_model, delay_mode, adaptation)
    for name, v, low in (("seed", seed, 0), ("chains", chains, 1), ("draws", draws, 1), ("tune", tune, 1)):
        if int(v) != v or v < low:
            raise ValueError(f"--{name} must be an integer >= {low}; got {v!r}")
    if chains * draws < MIN_TOTAL_DRAWS:
        raise ValueError(f"--chains × --draws must be at least {MIN_TOTAL_DRAWS} (PSIS-LOO smooths a tail of "
                         f"0.2 × draws, which needs 5 draws); got {chains} × {draws}")
    study_path, out = Path(study_path), Path(out)
    estimates_path, truth_dir = default_inputs(study_path, estimates_path, truth_dir)
    refuse_inputs_inside(out, study_path, estimates_path, truth_dir)
    check_output_dir(out, force=force)  # before minutes of sampling, not after
    t_start = time.perf_counter()
    design = settings.design
    levels = design.ordered_levels
    if prepared is None:
        study = load_study(study_path, design)
        check_design(study.path, [s.subject for s in study.segments], [s.condition for s in study.segments],
                     levels=levels)
        prepared = prepare_study(study, settings, show_progress=show_progress)
    elif prepared.settings != settings:
        raise ValueError("the prepared study was cut with other settings than these")
    else:
        check_design(prepared.path, prepared.subjects, prepared.conditions, levels=levels)
    subjects = sorted(dict.fromkeys(prepared.subjects))
    subject = subject or (subjects[2] if len(subjects) > 2 else subjects[0])
    if subject not in subjects:
        raise ValueError(f"--subject {subject!r} is not in the study (subjects: {', '.join(subjects)})")
    t_prepared = time.perf_counter()
    plant = discretize(design.dt, design.wheel)
    priors = Priors.for_design(design)
    batch = prepare_batch(plant, [p.segment for p in prepared.segments])
    estimates = pd.read_parquet(estimates_path) if estimates_path is not None else None
    if estimates is not None:  # before minutes of sampling, not after
        units = set(zip(prepared.subjects, prepared.conditions))
        theirs = set(zip(estimates["subject"].astype(str), estimates["condition"].astype(str)))
        if units != theirs:
            raise InputDataError(
                f"{estimates_path}: its subjects × conditions ({len(theirs)}) are not those of {study_path} "
                f"({len(units)}); e.g. {sorted(units ^ theirs)[:3]}. Pass the estimates identified from this study "
                "with --estimates")
    form, form_reason = choose_parameterization(estimates if estimates is not None
                                                else unit_se_log_theta1(prepared, plant))
    seeds = child_seeds(seed)
    fits, timing = {}, {"prepare_s": t_prepared - t_start}
    extra = {}
    if human_model == "delayed":
        delays = unit_delays(prepared, estimates, plant, estimates_path)
        fit = sample_delayed_model(prepared, batch, plant, priors, form, delays, seed=seeds["condition"], chains=chains,
                                   draws=draws, tune=tune, cores=cores, show_progress=show_progress,
                                   estimates=estimates, delay_mode=delay_mode, delayed_priors=delayed_priors,
                                   rho_form=rho_form, adaptation=adaptation, log_R=log_R_form,
                                   target_accept=target_accept)
        delays = fit.delays  # sampled: each subject's posterior mode
        fits, diag, extra = {"condition": fit.idata}, {"condition": fit.diagnostics}, fit.sidecar
        timing["condition"] = fit.timing
        t0 = time.perf_counter()
        res, ppc, ppc_draws = delayed_results(fit, prepared, plant, estimates, truth_dir, subject,
                                              np.random.default_rng(seeds["ppc"]), n_draws=PPC_DRAWS)
        timing["contrasts_and_ppc_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        res["adequacy"] = delayed_adequacy(fit.idata, prepared, plant, delays, at=adequacy_at)
        timing["adequacy_s"] = time.perf_counter() - t0
    else:
        for name, effects in (("condition", True), ("pooled", False)):
            t0 = time.perf_counter()
            model = build_model(prepared.subjects, prepared.conditions, batch, plant, segment_ids=prepared.labels,
                                condition_effects=effects, priors=priors, levels=levels, parameterization=form)
            t1 = time.perf_counter()
            idata, sec = sample_model(model, seed=seeds[name], chains=chains, draws=draws, tune=tune, cores=cores,
                                      show_progress=show_progress, target_accept=target_accept)
            fits[name] = idata
            timing[name] = {"build_s": t1 - t0, **{f"{k}_s": v for k, v in sec.items()}}
        diag = {name: diagnostics(d, timing[name]["sample_s"]) for name, d in fits.items()}

        t0 = time.perf_counter()
        res = {"model": "hierarchical max-ent, condition effects on log θ1 and log R (models.bayes.hierarchical)",
               **contrasts(fits["condition"])}
        res["loo"] = loo_comparison(fits["condition"], fits["pooled"])
        res["loo_subject"] = subject_loo_comparison(fits["condition"], fits["pooled"], batch, prepared.subjects,
                                                    prepared.conditions, plant, np.random.default_rng(seeds["loso"]),
                                                    levels=levels)
        res["mixedlm"] = mixedlm_check(estimates, levels) if estimates is not None else None
        res["truth"] = truth_check(fits["condition"], truth_dir, estimates, design) if truth_dir is not None else None
        assisted = ", ".join(v for v in levels if design.assistant(v) is not None) or "no level"
        ppc, ppc_draws = posterior_predictive(fits["condition"], prepared, subject, np.random.default_rng(seeds["ppc"]))
        res["ppc"] = {"subject": subject, "draws": int(min(PPC_DRAWS, chains * draws)),
                      "coverage_5_95": ppc_coverage(ppc),
                      "note": f"exact max-ent draws of the human the likelihood assumes (in {assisted}: "
                              + settings.assistant_model + " assistant model); "
                              "u_H is the reconstructed torque where the file has none"}
        timing["contrasts_and_ppc_s"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        res["adequacy"] = posterior_adequacy(fits["condition"], prepared, plant, at=adequacy_at)
        timing["adequacy_s"] = time.perf_counter() - t0

    timing["total_s"] = time.perf_counter() - t_start
    if res.get("truth") is not None:  # the truth and the study from the fit folder: true after a run moves it
        res["truth"]["source"] = os.path.relpath(truth_dir, out)
    sidecar = {
        "study": str(study_path),
        "study_relative": os.path.relpath(study_path.resolve(), out.resolve()),
        "truth_relative": None if res.get("truth") is None else res["truth"]["source"],
        "human_model": human_model, "seed": int(seed), "seeds": seeds,
        "sampler": {**sampler_record(human_model, delay_mode, extra.get("nutpie_options"), extra.get("whitening")),
                    "chains": int(chains), "draws": int(draws), "tune": int(tune),
                    "cores": int(min(chains, cores or os.cpu_count() or 1)),
                    "target_accept": (target_accept if target_accept is not None else
                                      (extra.get("nutpie_options") or {}).get("target_accept", NUTPIE_TARGET_ACCEPT))},
        "identify_settings": settings.as_dict(),
        "priors": asdict(priors),
        "parameterization": {**asdict(form), "reason": form_reason},
        "n_segments": len(prepared.segments),
        "n_subjects": len(subjects),
        "K": int(batch.K),
        "criteria": {"divergences": 0, "rhat_max": RHAT_MAX, "ess_bulk_and_tail_min": ESS_MIN,
                     "applies_to": "population parameters", "ebfmi_min_advisory": EBFMI_MIN},
        "diagnostics": diag,
        "convergence_verdict": {name: d["convergence_verdict"] for name, d in diag.items()},
        "seconds": timing,
        "inputs": {"estimates": None if estimates_path is None else str(estimates_path),
                   "truth_dir": None if truth_dir is None else str(truth_dir)},
        "note_timing": "wall-clock times on a shared machine: other jobs may have competed for the CPU",
        **experiment_fields(design, experiment_file),
        **extra,
        "versions": versions(),
    }
    fits["condition"]["posterior_predictive"] = ppc_draws
    fits["condition"]["constant_data"] = constant_data(prepared)
    # Everything or nothing: the folder holds this fit's files, or what it held before.
    with staged_dir(out, force=force) as tmp:
        write_netcdf(fits["condition"], tmp / "posterior.nc")
        if "pooled" in fits:
            write_netcdf(fits["pooled"], tmp / "posterior_pooled.nc")
        write_table_atomic(ppc, tmp / "ppc.parquet")
        write_text_atomic(tmp / "posterior.json", strict_json(sidecar))
        write_text_atomic(tmp / "contrasts.json", strict_json(res))
    names = {"posterior": "posterior.nc", "posterior_pooled": "posterior_pooled.nc", "ppc": "ppc.parquet",
             "sidecar": "posterior.json", "contrasts": "contrasts.json"}
    return {k: str(out / v) for k, v in names.items() if k != "posterior_pooled" or "pooled" in fits}
