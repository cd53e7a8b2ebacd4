"""``scioc fit``: the hierarchical Bayesian model of a study, its diagnostics and contrasts.

The segments are cut as ``scioc identify`` cuts them; then nutpie samples two models of
:func:`scioc.models.bayes.hierarchical.build_model`: with condition effects (β, the mean SC change of log θ1, is the
paper's question) and pooled, which only serves the LOO comparison. The delayed human has one model
(:mod:`scioc.pipelines.fit.delayed`). Artifacts in ``--out DIR``: ``posterior.nc`` (the condition model's DataTree,
with ``log_likelihood``, ``observed_data``, one subject's ``posterior_predictive`` and ``constant_data``),
``posterior_pooled.nc``, ``posterior.json`` (the sidecar: seeds, settings, priors, diagnostics and verdict, times,
inputs with their SHA-256, experiment, versions), ``contrasts.json`` (β, contrasts, LOO, cross-checks, adequacy) and
``ppc.parquet`` (predictive bands). The same root seed gives the same draws
(:func:`scioc.pipelines.fit.sampling.child_seeds`).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from scioc.models.bayes.hierarchical import Parameterization, Priors
from scioc.models.identify import identify_unit
from scioc.models.plant import discretize
from scioc.models.runtime import configure
from scioc.models.segment import prepare_batch
from scioc.pipelines import lineage
from scioc.pipelines.experiment import find_experiment
from scioc.pipelines.experiment import sidecar as experiment_fields
from scioc.pipelines.fit.artifacts import require_netcdf, strict_json, write_netcdf
from scioc.pipelines.fit.checks import ADEQUACY_POINTS
from scioc.pipelines.fit.diagnostics import EBFMI_MIN, ESS_MIN, NUTPIE_TARGET_ACCEPT, RHAT_MAX
from scioc.pipelines.fit.ppc import constant_data
from scioc.pipelines.fit.sampling import child_seeds
from scioc.pipelines.human_model.registry import FitContext, get
from scioc.pipelines.identify import identification_settings
from scioc.pipelines.io import InputDataError, load_study
from scioc.pipelines.lineage import LineageError
from scioc.pipelines.prepare import IdentifySettings, PreparedStudy, check_design, prepare_study
from scioc.pipelines.provenance import versions
from scioc.pipelines.storage import (
    check_output_dir,
    refuse_inputs_inside,
    staged_dir,
    write_table_atomic,
    write_text_atomic,
)


class FitInputs(NamedTuple):
    """What :func:`default_inputs` finds: the estimates and the simulation's folder a fit reads (None: none), and
    why a proposed one is not read."""

    estimates: Path | None
    truth_dir: Path | None
    notes: dict  # "estimates" / "truth": why the one proposed is not read


def estimates_of(estimates_path, study_path, study: dict, experiment_file=None, design=None) -> Path:
    """``identify.json`` of ``estimates_path`` after checking by content that it identified this study with this
    experiment (``design`` from ``experiment_file``, else the file ``--experiment``, else the one beside the study, if
    any): LineageError naming both files otherwise."""
    if not Path(estimates_path).is_file():
        raise InputDataError(f"{estimates_path}: no such estimates file")
    found = lineage.identification(estimates_path)
    if found is None:
        raise LineageError(f"{estimates_path}: no identify.json beside it, so the study it was identified from is not "
                           "known; give the estimates.parquet that scioc identify wrote, in its folder")
    meta_path, meta = found
    lineage.require_same("study", meta_path, lineage.recorded(meta, "study", meta_path), study_path, study)
    source = experiment_file
    if design is None:
        design, source = find_experiment(study_path, experiment_file)
    if source is not None:
        lineage.require_same("experiment", meta_path, lineage.recorded(meta, "experiment", meta_path), source,
                             lineage.experiment_entry(design, source))
    return meta_path


def truth_of(truth_dir, study_path, study: dict) -> None:
    """LineageError naming both files unless ``truth_dir`` holds the truth of the simulation that wrote this study."""
    meta_path, simulated = lineage.simulated_study(Path(truth_dir) / "truth.parquet")
    lineage.require_same("study", meta_path, simulated, study_path, study)


def default_inputs(study_path: Path, estimates_path, truth_dir, experiment_file=None, *, study: dict | None = None,
                   out=None, design=None) -> FitInputs:
    """The estimates and the simulation's folder a fit of ``study_path`` into ``out`` reads, checked by content.

    Given ones must belong to the study (:func:`estimates_of`, :func:`truth_of`). Else the estimates beside the fit's
    folder (``out/../identify/``, ``out/../``) or in the study's run folder (``../identify/``) and the simulation in
    the study's folder are proposed, and read only where their sidecars record this study; ``notes`` says why none
    is. ``study``: :func:`scioc.pipelines.lineage.study_entry` of ``study_path``; ``design``: the experiment the fit
    reads, from ``experiment_file`` (default: read from that file, or found beside the study).
    """
    study_path = Path(study_path)
    study = lineage.study_entry(study_path) if study is None else study
    notes = {}
    if estimates_path is not None:
        estimates_of(estimates_path, study_path, study, experiment_file, design)
    else:
        near = [] if out is None else [Path(out).parent / "identify", Path(out).parent]
        guesses = [f / "estimates.parquet" for f in dict.fromkeys([*near, study_path.parent.parent / "identify"])]
        why = []
        for guess in (g for g in guesses if g.is_file()):
            try:
                estimates_of(guess, study_path, study, experiment_file, design)
                estimates_path = guess
                break
            except InputDataError as exc:
                why.append(str(exc))
        if estimates_path is None:
            notes["estimates"] = ("the fit identifies every unit itself, as it needs the estimates, and has no "
                                  "mixed-model cross-check: " + ("; ".join(why) or "no estimates given (--estimates) "
                                                                 f"nor at {' or '.join(map(str, guesses))}"))
    if truth_dir is not None:
        truth_of(truth_dir, study_path, study)
    elif (study_path.parent / "simulation.json").exists() and (study_path.parent / "truth.parquet").exists():
        try:
            truth_of(study_path.parent, study_path, study)
            truth_dir = study_path.parent
        except InputDataError as exc:
            notes["truth"] = f"no ground-truth check: {exc}"
    return FitInputs(None if estimates_path is None else Path(estimates_path),
                     None if truth_dir is None else Path(truth_dir), notes)


def resolve_settings(study_path: Path, estimates_path, settings, experiment_file, human_model):
    """The fit's settings, their experiment file and where they came from: ``settings`` as given, else the
    identification's whose estimates the fit reads (:func:`estimates_of` checked its experiment), else the
    experiment's ``[analysis]``."""
    if settings is not None:
        return settings, experiment_file, "given"
    found = identification_settings(estimates_path) if estimates_path is not None else None
    if found is not None:
        settings, source = found
        if human_model is not None:
            settings = replace(settings, human_model=human_model)
        return settings, source, f"the identification of {estimates_path}"
    design, source = find_experiment(study_path, experiment_file)
    settings = IdentifySettings.for_design(design, **({} if human_model is None else {"human_model": human_model}))
    return settings, source, "the experiment's [analysis]" if source else "the paper's study"


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
               settings: IdentifySettings | None = None, subject: str | None = None,
               estimates_path=None, truth_dir=None, cores: int | None = None, show_progress: bool = False,
               force: bool = False, prepared: PreparedStudy | None = None, experiment_file: str | None = None,
               human_model: str | None = None, sampler_options: dict | None = None,
               target_accept: float | None = None, likelihood: str | None = None, plan_only: bool = False) -> dict:
    """Fit the human model's hierarchical model(s) to a study file and write every artifact (module docstring).

    Parameters
    ----------
    study_path, out : str or Path
        Study file in the data convention; output folder (replaced as a whole with ``force``).
    seed : int
        Root seed (split into the samplers' and the predictive draws' seeds).
    chains, draws, tune : int
        Chains, and draws kept per chain after ``tune`` warm-up draws (None: the human model's default).
    settings : IdentifySettings, optional
        Window, preview, reconstruction and the experiment (``settings.design``), as for ``scioc identify``.
        Default: the identification's whose estimates the fit reads, else the experiment's ``[analysis]``
        (``experiment_file``, or ``experiment.toml`` beside the study, or the paper's study).
    subject : str, optional
        Subject of the posterior predictive bands (default: the third in sorted order).
    estimates_path, truth_dir : optional
        ``estimates.parquet`` of ``scioc identify`` (mixed-model check, starts, the delayed model's delays) and
        a simulation's folder (truth check). Default: those :func:`default_inputs` finds that belong to this study.
    cores : int, optional
        Chains sampled in parallel (default: every CPU); the draws do not depend on it.
    prepared : PreparedStudy, optional
        The study already prepared with ``settings`` (``scioc run`` shares the identification's).
    experiment_file : str, optional
        Where ``settings.design`` came from, recorded in the sidecar.
    human_model : str, optional
        A registered human model (default ``settings.human_model``; :mod:`scioc.pipelines.human_model`).
    sampler_options : dict, optional
        Research settings (``--sampler-config``): ``adequacy_at`` ("draw" or "means") and the human model's
        :attr:`~scioc.pipelines.human_model.HumanModel.sampler_keys`.
    target_accept : float, optional
        The sampler's target acceptance rate in (0, 1) (None: the model's own, recorded in the sidecar).
    likelihood : str, optional
        What the fit scores: ``torques`` or ``angles`` (None: the human model's default for these recordings,
        :meth:`~scioc.pipelines.human_model.HumanModel.fit_likelihood`).
    plan_only : bool
        Return the plan (:meth:`~scioc.pipelines.human_model.HumanModel.plan`) without sampling or writing.

    Returns
    -------
    dict
        Paths of the written files (with ``plan_only``: the plan).

    Raises
    ------
    ValueError
        For bad settings, a bad study design or a malformed file (InputDataError); nothing is written then.
    """
    configure()
    require_netcdf()
    study_path, out = Path(study_path), Path(out)
    study_record = lineage.study_entry(study_path)
    estimates_path, truth_dir, notes = default_inputs(study_path, estimates_path, truth_dir, experiment_file,
                                                      study=study_record, out=out,
                                                      design=None if settings is None else settings.design)
    settings, experiment_file, settings_from = resolve_settings(study_path, estimates_path, settings, experiment_file,
                                                            human_model)
    human_model = settings.human_model if human_model is None else human_model
    model = get(human_model)
    options = dict(sampler_options or {})
    adequacy_at = options.pop("adequacy_at", "draw")
    if adequacy_at not in ADEQUACY_POINTS:
        raise ValueError(f"sampler options: adequacy_at must be one of {', '.join(ADEQUACY_POINTS)}; got "
                         f"{adequacy_at!r}")
    options = model.sampler_options(options, "sampler options")
    if target_accept is not None and not 0.0 < target_accept < 1.0:
        raise ValueError(f"--target-accept must lie between 0 and 1; got {target_accept!r}")
    if human_model != settings.human_model and settings.human_model != IdentifySettings.human_model:
        raise ValueError(f"human_model {human_model!r} contradicts the settings' {settings.human_model!r}")
    tune_given = tune is not None
    if tune is None:
        tune = model.default_tune(options)
    for name, v, low in (("seed", seed, 0), ("chains", chains, 1), ("draws", draws, 1), ("tune", tune, 1)):
        if int(v) != v or v < low:
            raise ValueError(f"--{name} must be an integer >= {low}; got {v!r}")
    if chains * draws < MIN_TOTAL_DRAWS:
        raise ValueError(f"--chains × --draws must be at least {MIN_TOTAL_DRAWS} (PSIS-LOO smooths a tail of "
                         f"0.2 × draws, which needs 5 draws); got {chains} × {draws}")
    if not plan_only:  # a plan writes nothing
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
    model.check_fit_data(prepared)
    requested_likelihood = likelihood
    likelihood = model.fit_likelihood(prepared, likelihood)
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
    if show_progress:  # every check passed: what the fit reads, and what it does without
        for note in notes.values():
            print(f"scioc fit: note: {note}", file=sys.stderr, flush=True)
    form, form_reason = choose_parameterization(estimates if estimates is not None
                                                else unit_se_log_theta1(prepared, plant))
    ctx = FitContext(prepared, batch, plant, priors, form, form_reason, estimates, estimates_path, truth_dir, subject,
                     child_seeds(seed), chains, draws, tune, tune_given, cores, show_progress, target_accept,
                     adequacy_at, options, likelihood)
    if plan_only:
        return {"human_model": model.name, "likelihood": {"value": likelihood, "reason": "given" if requested_likelihood
                                                          else "the human model's default for these recordings"},
                **model.plan(ctx)}
    outcome = model.fit(ctx)
    fits, diag, res, extra, ppc, ppc_draws = (outcome.fits, outcome.diagnostics, outcome.results, outcome.sidecar,
                                               outcome.ppc, outcome.ppc_draws)
    timing = {"prepare_s": t_prepared - t_start, **outcome.timing}
    timing["total_s"] = time.perf_counter() - t_start
    if res.get("truth") is not None:  # the truth and the study from the fit folder: true after a run moves it
        res["truth"]["source"] = os.path.relpath(truth_dir, out)
    sidecar = {
        "study": str(study_path),
        "study_relative": os.path.relpath(study_path.resolve(), out.resolve()),
        "truth_relative": None if res.get("truth") is None else res["truth"]["source"],
        "human_model": human_model, "likelihood": likelihood, "seed": int(seed), "seeds": ctx.seeds,
        "sampler": {**model.sampler_record(ctx, outcome),
                    "chains": int(chains), "draws": int(draws), "tune": int(tune),
                    "cores": int(min(chains, cores or os.cpu_count() or 1)),
                    "target_accept": (target_accept if target_accept is not None else
                                      (extra.get("nutpie_options") or {}).get("target_accept", NUTPIE_TARGET_ACCEPT))},
        "identify_settings": settings.as_dict(),
        "identify_settings_from": settings_from,
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
        "inputs": {"study": study_record, "experiment": lineage.experiment_entry(design, experiment_file),
                   "estimates": None if estimates_path is None else {
                       **lineage.entry(estimates_path), "identification": lineage.entry(estimates_path.parent)},
                   "truth": None if truth_dir is None else {
                       **lineage.entry(Path(truth_dir) / "truth.parquet"), "simulation": lineage.entry(truth_dir)}},
        "identified_itself": notes.get("estimates"),
        "input_notes": notes,
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
