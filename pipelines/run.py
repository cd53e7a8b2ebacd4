"""``scioc run``: the whole workflow on the built-in simulated study, ending with the report.

Stages, each also a command of its own: simulate → identify (from angles, like a lab) →
identify from the true torques (what reconstruction costs; also with the paper's exogenous-u_A
likelihood) → compare → fit → report. With the ``delayed`` human model (:func:`default_human_models`)
the run adds ``identify_delayed/`` and ``compare_delayed.json``, ``fit_delayed/`` and the leave-one-subject-out
comparison ``human_models.json`` (:func:`scioc.pipelines.fit.human_models.compare_human_models`), all from one
prepared study; where the torques are reconstructed, also ``fit_angles/`` (the max-ent human fitted to the angles,
which the comparison then scores).
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd

from scioc.models.design import STUDY, Design
from scioc.models.runtime import configure
from scioc.models.simulate import Population
from scioc.pipelines import lineage
from scioc.pipelines.compare import compare_to_file
from scioc.pipelines.experiment import find_experiment
from scioc.pipelines.export import convention
from scioc.pipelines.human_model.registry import ALTERNATIVE, PRIMARY
from scioc.pipelines.identify import format_identify, identify_study, identify_to_dir
from scioc.pipelines.io import load_study, validate_table
from scioc.pipelines.prepare import IdentifySettings, from_angles, prepare_study
from scioc.pipelines.report import build_report
from scioc.pipelines.report.human_models import ANGLE_FIT, ANGLE_ONLY, RUN_FILE
from scioc.pipelines.simulate import DEFAULT_SEED, simulate_to_dir
from scioc.pipelines.storage import (
    check_output_dir,
    refuse_inputs_inside,
    staged_dir,
    write_table_atomic,
    write_text_atomic,
)

DEFAULT_NAME = "default-study"


def log(msg: str) -> None:
    print(msg, flush=True)


def identify_with_truth(study_path, truth_traj_path, out, settings: IdentifySettings) -> dict:
    """Identify from the simulator's true velocity and u_H (no reconstruction) for comparison."""
    study = pd.read_parquet(study_path)
    truth = pd.read_parquet(truth_traj_path)
    df = study.assign(velocity=truth["velocity"].to_numpy(), u_H=truth["u_H"].to_numpy(),
                      angle=truth["angle"].to_numpy())
    study = validate_table(df, f"{study_path} + true torques", design=settings.design)
    est, traj, val, timing, adequacy = identify_study(study, settings)
    out = Path(out)
    write_table_atomic(est, out / "estimates.parquet")
    write_table_atomic(val, out / "validation.parquet")
    meta = {"timing_s": timing, "source": "true velocity and u_H", "adequacy": adequacy,
            "inputs": {"study": lineage.study_entry(study_path), "truth_trajectories": lineage.entry(truth_traj_path)},
            "outputs": lineage.outputs(out, ["estimates.parquet", "validation.parquet"])}
    write_text_atomic(out / "identify.json", json.dumps(meta) + "\n")
    return {"estimates": str(out / "estimates.parquet")}


def default_human_models(design: Design, maxent_verdict: str | None) -> tuple[tuple[str, ...], str]:
    """The human models ``scioc run`` analyses a design with by default, and why.

    The max-ent model always; the ``delayed`` model too unless ``maxent_verdict`` (at identify) is
    "pass". See docs/decisions/run-human-models.md.
    """
    verdict = maxent_verdict or "not checked"
    if verdict == "pass":
        return (PRIMARY,), ("the max-ent human model passes its adequacy checks, so the delayed human model was not "
                             "run (--human-model maxent,delayed runs it beside the max-ent model)")
    angles = "" if design.torque_sensor else f"; {ANGLE_ONLY}"
    return (PRIMARY, ALTERNATIVE), (f"the max-ent human model's adequacy verdict is '{verdict}', so the delayed human "
                                   f"model was run beside it{angles}")


def run_verdicts(root) -> dict:
    """``{human model: adequacy verdict at identify}`` of every human model a run folder holds."""
    root = Path(root)
    found = {PRIMARY: root / "identify" / "identify.json", ALTERNATIVE: root / "identify_delayed" / "identify.json"}
    return {k: json.loads(v.read_text())["adequacy"]["verdict"] for k, v in found.items() if v.exists()}


def _stages(fit: bool, delayed: bool, sensor: bool = True, simulated: bool = True) -> list[str]:
    """The run's stages in order (their numbers in the log); without a torque sensor (``sensor``) the max-ent human
    is also fitted to the angles, which the delayed fit scores."""
    stages = ["simulate", "identify", "true torques", "compare"] if simulated else ["identify", "compare"]
    if delayed:
        stages += ["identify delayed", "compare delayed"]
    if fit:
        stages += ["fit", *([] if sensor else ["fit angles"]), "fit delayed", "human models"] if delayed else ["fit"]
    return stages + ["report"]


def _requested(human_models) -> tuple[str, ...] | None:
    requested = None if human_models is None else tuple(human_models)
    if requested is not None and (PRIMARY not in requested or not set(requested) <= {PRIMARY, ALTERNATIVE}):
        raise ValueError(f"human models must be {PRIMARY}, or {PRIMARY} and {ALTERNATIVE}; got {requested!r}")
    return requested


def _analyse(tmp: Path, study_path, prepared, settings: IdentifySettings, source, *, seed: int, fit: bool,
             requested, stages: list, truth=None, title: str) -> None:
    """Every stage after the data into the staged run folder ``tmp``: identify, (with ``truth``, the simulator's
    ``{"dir", "trajectories"}``: identify from the true torques), compare, the choice of human models, the delayed
    model's stages, the fits, leave-one-subject-out, the report."""
    design = settings.design
    sensor = not from_angles(prepared.segments, range(len(prepared.segments)))  # every torque recorded
    delayed = ALTERNATIVE in requested if requested is not None else True
    at = lambda stage: f"[{stages.index(stage) + 1}/{len(stages)}]"  # noqa: E731
    log(f"{at('identify')} identifying every subject × condition from the recorded "
        f"{'angle and torque' if sensor else 'encoder angle'}")
    identify_to_dir(study_path, tmp / "identify", settings, prepared=prepared, experiment_file=source)
    log(format_identify(tmp / "identify"))
    if truth is not None:
        log(f"{at('true torques')} identifying again from the true torques (the cost of reconstruction)")
        identify_with_truth(study_path, truth["trajectories"], tmp / "identify_true_torque", settings)
        # The paper's likelihood (recorded u_A as a known input) on the same torques: its SC bias.
        identify_with_truth(study_path, truth["trajectories"], tmp / "identify_true_torque_exogenous",
                            replace(settings, assistant_model="exogenous"))
    log(f"{at('compare')} Wilcoxon matched-pairs tests against {design.baseline}")
    compare_to_file(tmp / "identify" / "estimates.parquet", tmp / "compare.json")
    if requested is None:
        human_models, why = default_human_models(design, run_verdicts(tmp).get(PRIMARY))
        log(f"human models: {', '.join(human_models)}: {why}")
        if ALTERNATIVE not in human_models and delayed:  # the stages counted for it are not needed: said so, in order
            delayed = False
            for st in ("identify delayed", "compare delayed"):
                log(f"{at(st)} {st}: not needed")
    else:
        human_models, why = requested, "requested (--human-model)"
    write_text_atomic(tmp / RUN_FILE, json.dumps({"human_models": list(human_models), "why": why,
                                                  "requested": None if requested is None else list(requested)},
                                                 indent=1) + "\n")
    truth_dir = None if truth is None else truth["dir"]
    if delayed:
        # The same prepared segments: preparing does not depend on the human model.
        delayed_prepared = replace(prepared, settings=replace(settings, human_model=ALTERNATIVE))
        log(f"{at('identify delayed')} identifying again with the delayed human model (delay, lag, motor noise)")
        identify_to_dir(study_path, tmp / "identify_delayed", delayed_prepared.settings, prepared=delayed_prepared,
                        experiment_file=source)
        log(format_identify(tmp / "identify_delayed"))
        log(f"{at('compare delayed')} Wilcoxon matched-pairs tests of the delayed model's estimates")
        compare_to_file(tmp / "identify_delayed" / "estimates.parquet", tmp / "compare_delayed.json")
    if fit:
        from scioc.pipelines.fit import fit_to_dir  # imports PyMC (seconds): not for --skip-fit

        log(f"{at('fit')} hierarchical Bayesian fit (nutpie, 4 chains; the condition model and the pooled one)")
        fit_to_dir(study_path, tmp / "fit", seed=seed, settings=settings, truth_dir=truth_dir,
                   estimates_path=tmp / "identify" / "estimates.parquet", show_progress=True, prepared=prepared,
                   experiment_file=source)
    for st in ("fit angles", "fit delayed", "human models"):  # counted, and not needed after all
        if st in stages and not delayed:
            log(f"{at(st)} {st}: not needed")
    if fit and delayed:
        from scioc.pipelines.fit.human_models import compare_human_models, format_human_models

        maxent_fit = tmp / "fit"
        if not sensor:  # the comparison scores the same data: the angles, which the delayed fit scores
            maxent_fit = tmp / ANGLE_FIT
            log(f"{at('fit angles')} hierarchical Bayesian fit of the max-ent human model to the encoder's angles "
                "(nutpie, 4 chains)")
            fit_to_dir(study_path, maxent_fit, seed=seed, settings=settings, truth_dir=truth_dir,
                       estimates_path=tmp / "identify" / "estimates.parquet", show_progress=True, prepared=prepared,
                       experiment_file=source, likelihood="angles")
        log(f"{at('fit delayed')} hierarchical Bayesian fit of the delayed human model (nutpie, 4 chains)")
        fit_to_dir(study_path, tmp / "fit_delayed", seed=seed, settings=delayed_prepared.settings,
                   truth_dir=truth_dir, estimates_path=tmp / "identify_delayed" / "estimates.parquet",
                   show_progress=True, prepared=delayed_prepared, experiment_file=source)
        log(f"{at('human models')} leave-one-subject-out: max-ent against delayed")
        log(format_human_models(compare_human_models(maxent_fit, tmp / "fit_delayed", prepared=prepared,
                                                     seed=seed, out=tmp, relative_to=tmp)))
    log(f"{at('report')} writing the report")
    build_report(tmp, title=title)


def run_all(out="reports", *, name: str = DEFAULT_NAME, n_subjects: int | None = None,
            seed: int = DEFAULT_SEED, settings: IdentifySettings | None = None, fit: bool = True,
            human: str = "maxent", population: Population | None = None, design: Design | None = None,
            human_models: tuple[str, ...] | None = None) -> Path:
    """Run every stage on the simulated study; returns the report's path.

    ``fit=False`` skips the hierarchical fits. ``human`` and ``population`` choose the simulated study
    (a negative-control human shows what the report says when the model does not fit); ``design``
    is the experiment (default the paper's) and ``settings`` default to its ``[analysis]``.
    ``human_models``: ``("maxent",)``, ``("maxent", "delayed")``, or None for
    :func:`default_human_models`' choice, recorded in :data:`scioc.pipelines.report.human_models.RUN_FILE`.
    """
    configure()
    design = STUDY if design is None else convention(design)  # the simulated study is in the data convention
    settings = IdentifySettings.for_design(design) if settings is None else settings
    if settings.design != design:
        raise ValueError("the settings were made for another experiment than the one simulated")
    requested = _requested(human_models)
    delayed = ALTERNATIVE in requested if requested is not None else True  # by default counted as if both ran
    sensor = design.torque_sensor and settings.reconstruct != "always"  # the torques recorded and used
    settings = replace(settings, human_model=PRIMARY)
    n_subjects = design.subjects if n_subjects is None else n_subjects
    root = Path(out) / name
    stages = _stages(fit, delayed, sensor)
    levels = "/".join(design.levels)
    trials = f" × {design.trials} trials" if design.trials > 1 else ""
    if requested == (PRIMARY,):
        log("human models: maxent (delayed not requested)")
    elif requested is not None and not sensor:
        log(f"human models: maxent and delayed; {ANGLE_ONLY}")
    t0 = time.perf_counter()
    # Every stage writes into one fresh folder that replaces ``root`` as a whole at the end:
    # an interrupted run leaves the previous results as they were, never a mix of two runs.
    with staged_dir(root, force=True) as tmp:
        log(f"[1/{len(stages)}] simulating {n_subjects} subjects × {len(design.levels)} conditions ({levels}){trials} "
            f"× {design.run_seconds:g} s at {design.rate_hz:g} Hz (seed {seed}, human {human}) -> {root / 'data'}")
        sim = simulate_to_dir(tmp / "data", n_subjects=n_subjects, seed=seed, human=human, population=population,
                              design=design)
        source = str(Path(sim["experiment"]).relative_to(tmp).as_posix())
        prepared = prepare_study(load_study(sim["study"], design), settings, show_progress=True)
        _analyse(tmp, sim["study"], prepared, settings, source, seed=seed, fit=fit, requested=requested,
                 stages=stages, truth={"dir": tmp / "data", "trajectories": sim["truth_trajectories"]}, title=name)
    report = root / "index.html"
    log(f"done in {time.perf_counter() - t0:.0f} s")
    log(f"report: {report}")
    return report


def analyse_to_dir(study, out, *, experiment_file=None, seed: int = DEFAULT_SEED, fit: bool = True,
                   human_models: tuple[str, ...] | None = None, force: bool = False) -> Path:
    """Every stage on a lab's recordings, into the run folder ``out``, ending with its report; returns its path.

    ``study``: a study file, a folder of them or a glob, read with the experiment (``experiment_file``, else
    ``experiment.toml`` beside the study, else the paper's study) and its ``[analysis]``. The folder has the layout
    of ``scioc run`` without the simulation's data and truth: ``identify/``, ``compare.json``, the delayed model's
    stages when the max-ent model fails its adequacy checks (or ``human_models`` asks), ``fit/``..., ``run.json``
    and ``index.html``. It replaces ``out`` as a whole, only with ``force`` when ``out`` is not empty; it never
    writes inside the study's files. A failing adequacy verdict does not stop the analysis.
    """
    configure()
    design, source = find_experiment(study, experiment_file)
    settings = replace(IdentifySettings.for_design(design), human_model=PRIMARY)
    requested = _requested(human_models)
    delayed = ALTERNATIVE in requested if requested is not None else True
    loaded = load_study(study, design)
    out = Path(out)
    refuse_inputs_inside(out, *loaded.files, *([source] if source else []))
    check_output_dir(out, force=force)
    t0 = time.perf_counter()
    log(f"analysing {len(loaded.segments)} segments of {study} (experiment: {source or 'the paper study'}) -> {out}")
    with staged_dir(out, force=force) as tmp:
        prepared = prepare_study(loaded, settings, show_progress=True)
        stages = _stages(fit, delayed, not from_angles(prepared.segments, range(len(prepared.segments))),
                         simulated=False)
        _analyse(tmp, study, prepared, settings, source, seed=seed, fit=fit, requested=requested, stages=stages,
                 title=out.name)
    report = out / "index.html"
    log(f"done in {time.perf_counter() - t0:.0f} s")
    log(f"report: {report}")
    return report


__all__ = ["analyse_to_dir", "default_human_models", "identify_with_truth", "run_all", "run_verdicts"]
