"""``scioc fit``: the hierarchical Bayesian model of a study, its diagnostics and contrasts.

The segments are cut and reconstructed exactly as ``scioc identify`` does
(:func:`scioc.pipelines.prepare.prepare_study`; ``scioc run`` passes the same prepared study to
both), then two models of
:func:`scioc.models.bayes.hierarchical.build_model` are sampled with nutpie through ``pm.sample``:
the model with condition effects (β, the mean SC change of log θ1, is the paper's
question; with more levels one β per level against the baseline) and the pooled model
without them (log θ1 the same in every level), which only serves the PSIS-LOO comparison.
With ``human_model="delayed"`` the one model is the delayed human's (:mod:`scioc.pipelines.fit.delayed`).

The experiment (:class:`scioc.models.design.Design`, ``settings.design``) gives the wheel and
the sample time of the likelihood, the levels (baseline first) and their assistants, and
the rate of the prior on log R (:meth:`scioc.models.bayes.hierarchical.Priors.for_design`).
Several trials of one subject × level are segments of one unit: they share its θ.

Artifacts in ``--out DIR``:

* ``posterior.nc`` — the posterior of the model with condition effects as one ArviZ
  DataTree (NetCDF): ``posterior``, ``sample_stats``, ``log_likelihood`` (one value per
  segment), ``observed_data`` (``u_H``, segment × step), ``posterior_predictive`` (the
  predictive draws of one subject's segments, same dims) and ``constant_data`` (x0,
  reference, u_A, time and recorded angle per segment).
* ``posterior_pooled.nc`` — the pooled model's posterior (no predictive groups).
* ``posterior.json`` — sidecar: seeds, sampler settings, the priors, diagnostics of both fits
  with a verdict (no divergences, R-hat ≤ 1.01, bulk and tail ESS ≥ 400 for every population
  parameter), wall times, ESS per second, inputs, the experiment (resolved, its hash and
  file) and package versions.
* ``contrasts.json`` — β (mean, SD, 94 % HDI, P(β < 0)), the ratio exp(β) with its HDI,
  per-subject MC→SC contrasts of log θ1 (with more than two levels: ``baseline`` and one
  such block per non-baseline level under ``contrasts``), the LOO comparisons (PSIS over segments, which
  one segment per unit defeats, and integrated PSIS leaving out whole subjects,
  :func:`scioc.pipelines.fit.loo.subject_loo_comparison`), the frequentist mixed-model
  cross-check on the per-segment ML estimates and, for a simulated study, the truth check.
* ``ppc.parquet`` — the report's summary of the predictive draws: 5/50/95 % bands of angle
  and torque of one subject (every level and trial) over exact max-ent draws of the human the
  likelihood assumes (:func:`scioc.models.maxent.sample_maxent`), beside the data.

Randomness: the root ``seed`` is split with ``SeedSequence(seed).spawn(4)`` into the seeds
of the two samplers, of the posterior predictive draws and of the leave-one-subject-out
importance sampling; the same seed gives the same
draws and numbers (file bytes differ only by the time stamps NetCDF attributes carry).
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
    """Inputs beside the study in the run-folder layout of ``scioc run`` when not given.

    The estimates are taken from ``<run>/identify/`` only if its ``identify.json`` says they
    were identified from this very study file.
    """
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


#: Units whose ML log θ1 the data pin down to this standard error (median over units) or better are
#: fitted with centred log θ1 blocks (models/bayes/hierarchical.py, "Parameterization"): the data then
#: outweigh the population spread of the changes (σ_β ≈ 0.2) and the non-centred default mixes slowly.
#: Measured (4 chains × 1000 draws; condition model; worst bulk ESS and R-hat of β): the three-assistants
#: example (median SE 0.021), default 280 / 1.017, centred above 4800 / 1.00 (seed 2018); the default study
#: (0.062), default 625 / 1.015, 658 / 1.002, 733 / 1.006 (seeds 2018, 1, 2: at the edge of R-hat ≤ 1.01),
#: centred 5867 / 1.000, 4799 / 1.000, 4558 / 1.000, no divergences (the condition model of `scioc fit
#: reports/default-study/data/study.parquet --out F --seed S` after `make run`; the default form at commit
#: 1ccbd4b, before the threshold moved from 0.03). The same study cut to 3-s windows (0.30) diverges centred
#: (hierarchical.py's table): the threshold sits just above the largest SE measured to work.
CENTRED_SE_LOG_THETA1 = 0.08


def unit_se_log_theta1(prepared, plant) -> pd.DataFrame:
    """``se_log_theta1`` of every unit's ML estimate (its trials together), as ``scioc identify`` computes it."""
    segs = prepared.segments
    return pd.DataFrame({"se_log_theta1": [identify_unit([prepare_batch(plant, [segs[i].segment]) for i in idx],
                                                         plant).se_log_theta1
                                           for idx in prepared.units.values()]})


def sampler_record(human_model: str, delay_mode: str, nutpie_options: dict | None = None,
                   whitening: dict | None = None) -> dict:
    """Which sampler a fit used and its mass matrix, for the sidecar (``nutpie_options``: the delayed fit's;
    ``whitening``: the record of its whitened coordinates, :mod:`scioc.pipelines.fit.whiten`, if any)."""
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
    """The pivots of a curved whitening (:func:`scioc.pipelines.fit.whiten.whitening`'s ``curved_along``) for the sidecar:
    the name alone, or each with its number of subjects where each subject had its own."""
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{name} ({n} subjects)" for name, n in counts.items())


def choose_parameterization(estimates) -> tuple[Parameterization, str]:
    """The form of the log θ1 blocks for these data, and why (recorded in the sidecar).

    Centred when the estimates' median ``se_log_theta1`` (``scioc identify``'s, or
    :func:`unit_se_log_theta1`) is at most :data:`CENTRED_SE_LOG_THETA1`; the default
    :class:`Parameterization` otherwise, and without estimates.
    """
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
    """Fit both hierarchical models to a study file and write every artifact (see the module docstring).

    Parameters
    ----------
    study_path : str or Path
        Study file in the data convention.
    out : str or Path
        Output folder (created).
    seed : int
        Root seed (split into the samplers' and the predictive draws' seeds).
    chains, draws, tune : int
        nutpie chains, and draws kept per chain after ``tune`` warm-up draws (default
        :func:`scioc.pipelines.fit.warmup.default_tune`: 1000, 150 after the delayed fit's pilot run).
    settings : IdentifySettings
        Window, preview and reconstruction, as for ``scioc identify``, and the experiment
        (``settings.design``: wheel, sample time, levels, assistants).
    subject : str, optional
        Subject of the posterior predictive bands (default: the third in sorted order,
        as in the report's Fig. 6).
    estimates_path : str or Path, optional
        ``estimates.parquet`` of ``scioc identify`` for the mixed-model cross-check
        (default: ``../identify/estimates.parquet`` from the study's folder, if present).
    truth_dir : str or Path, optional
        Folder with ``simulation.json`` and ``truth.parquet`` (default: the study's own
        folder, if it has them).
    cores : int, optional
        Chains sampled in parallel (default: ``os.cpu_count()``); the draws do not
        depend on it.
    show_progress : bool
        Progress bars on standard error.
    force : bool
        Replace an existing non-empty ``out`` (as a whole; see :func:`scioc.pipelines.storage.staged_dir`).
    prepared : PreparedStudy, optional
        The study file already prepared with ``settings`` (``scioc run`` shares the
        identification's); by default it is loaded and prepared here.
    experiment_file : str, optional
        Where ``settings.design`` came from (None: the built-in study), recorded in the
        sidecar beside the resolved experiment and its hash.
    human_model : {"maxent", "delayed"}, optional
        The human model (default ``settings.human_model``): ``maxent`` fits the condition
        and pooled max-ent models as always; ``delayed`` fits
        :func:`scioc.models.bayes.delayed_model.build_delayed_model` alone, with each unit's
        delay from the estimates' ``delay_s`` or the ML profile (:mod:`scioc.pipelines.fit.delayed`;
        no ``posterior_pooled.nc``). ``posterior.json`` records it, and for ``delayed`` the
        delay of every unit and how it was chosen.
    delay_mode, delayed_priors, rho_form, adaptation, log_R_form
        ``delayed`` only, as :func:`scioc.pipelines.fit.delayed.sample_delayed_model` takes them: the delays fixed
        at each subject's profile maximum or sampled, the priors (e.g. the population of R; None: the defaults, the
        population of R chosen by the data), the form of ρ,
        the coordinates and nutpie's mass matrix (None: the first of :data:`scioc.models.bayes.delayed_model.ADAPTATIONS`),
        and the form of the log R blocks (its ``log_R``; None: chosen by the data).
    adequacy_at : {"draw", "means"}
        The posterior point of the adequacy check (:data:`scioc.pipelines.fit.checks.ADEQUACY_POINTS`).
    target_accept : float, optional
        The sampler's target acceptance rate, in (0, 1) (None: the fit's own, recorded in the
        sidecar: nutpie's 0.8, the delayed model's whitened fit 0.9, 0.8 with its pilot run).

    Returns
    -------
    dict
        Paths of the written files.

    Raises
    ------
    ValueError
        For a bad study design (a subject lacking a level, a level with no segment at all:
        the message of :func:`scioc.models.units.index_study`), a malformed file, or an unknown
        ``subject``; nothing is written then.
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
    # Everything or nothing: the folder holds this fit's files only, or what it held before.
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
