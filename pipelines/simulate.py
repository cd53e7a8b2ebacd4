"""``scioc simulate``: write the simulated study in the data convention, with its ground truth apart.

Artifacts in ``--out DIR``: ``study.parquet`` (what a lab records: subject, condition[, trial], t,
encoder angle, angle_ref, u_A, and u_H with ``[simulation] torque_sensor``); ``experiment.toml``
(the experiment simulated, found beside the study by every command); ``truth.parquet`` (per unit:
run order, q11, q22, R, θ1, θ2 and :data:`BODY_COLUMNS`); ``truth_trajectories.parquet`` (true
angle, velocity and u_H per sample); ``simulation.json`` (seed, population, design, the SHA-256 of the experiment
given and of each file written, versions).
"""

from __future__ import annotations

import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.models.design import STUDY, Design
from scioc.models.humans import HUMANS, PAPER_AGENT
from scioc.models.reference import reference_trajectory
from scioc.models.runtime import configure
from scioc.models.simulate import Population, simulate_study
from scioc.pipelines.assistant_check import assistant_alone
from scioc.pipelines.experiment import EXPERIMENT_FILE, resolved, sidecar, write_experiment
from scioc.pipelines.export import convention
from scioc.pipelines.io import read_table
from scioc.pipelines.lineage import experiment_entry, outputs
from scioc.pipelines.provenance import versions
from scioc.pipelines.storage import check_output_dir, staged_dir, write_table_atomic, write_text_atomic

DEFAULT_SEED = 2018
DEFAULT_SUBJECTS = 42
#: The human's own delay (s, on the sample grid), neuromuscular lag (s) and motor-noise SD (N·m) in ``truth.parquet``.
BODY_COLUMNS = ("delay_s", "tau_nm", "motor_sd")


def read_truth(path) -> pd.DataFrame:
    """``truth.parquet``; missing :data:`BODY_COLUMNS` are 0 when ``simulation.json`` names the paper's agent."""
    path = Path(path)
    truth = read_table(path)
    meta = path.parent / "simulation.json"
    if not set(BODY_COLUMNS) <= set(truth.columns) and meta.exists():
        if json.loads(meta.read_text()).get("human", {}).get("name") == PAPER_AGENT:
            truth = truth.assign(**dict.fromkeys(BODY_COLUMNS, 0.0))
    return truth


def _labels(s, n: int) -> dict:
    d = {"subject": np.full(n, s.subject, dtype=object), "condition": np.full(n, s.condition, dtype=object)}
    if s.trial is not None:
        d["trial"] = np.full(n, s.trial, dtype=np.int64)
    return d


def study_table(t, segs, design: Design = STUDY) -> pd.DataFrame:
    """The lab's view of simulated runs: subject, condition[, trial], t, angle (encoder), angle_ref, u_A[, u_H]."""
    ref = reference_trajectory(float(t[-1]), design.dt).angle
    n = t.shape[0]
    frames = []
    for s in segs:
        d = {**_labels(s, n), "t": t, "angle": s.run.angle, "angle_ref": ref, "u_A": s.run.u_A}
        if design.torque_sensor:
            d["u_H"] = s.run.u_H
        frames.append(pd.DataFrame(d))
    return pd.concat(frames, ignore_index=True)


def window_inside_run(design: Design) -> tuple[Design, str | None]:
    """``design`` as simulated, and why it changed: analysed whole where its window does not lie inside its runs."""
    end = design.window_start + design.window_seconds
    if design.whole or end <= design.run_seconds:
        return design, None
    return replace(design, whole=True), (
        f"the experiment's analysis window {design.window_start:g}-{end:g} s lies outside the {design.run_seconds:g}-s "
        "runs, so the experiment written beside the study analyses each run whole ([analysis] whole = true); "
        "scioc identify --window START,SECONDS chooses a window inside the runs")


def simulate_to_dir(
    out, *, n_subjects: int | None = None, seed: int = DEFAULT_SEED, population: Population | None = None,
    seconds: float | None = None, human: str = "maxent", force: bool = False, design: Design | None = None,
    experiment_file: str | None = None,
) -> dict:
    """Simulate the experiment and write its artifacts (module docstring); returns their paths.

    Parameters
    ----------
    out : str or Path
    n_subjects : int, optional
        Default: the design's ``subjects``.
    seed : int
        Root seed; subject i uses the i-th child of ``SeedSequence(seed)``.
    population : Population, optional
        Default: the paper's, with the design's ``effects`` as shifts of log θ1; an explicit
        population's shifts are written into ``experiment.toml``.
    seconds : float, optional
        Length of each run, s (default: the design's ``run_seconds``).
    human : str
        :data:`scioc.models.humans.HUMANS`: ``maxent`` is the paper's agent, the others negative
        controls (the crossover operator has no θ: NaN in the truth).
    force : bool
        Replace a non-empty ``out`` as a whole (:func:`scioc.pipelines.storage.staged_dir`).
    design : Design, optional
        The experiment (default the paper's), written as ``experiment.toml`` as simulated (analysed whole where its
        window lies outside the runs: :func:`window_inside_run`).
    experiment_file : str, optional
        Where ``design`` came from, recorded in ``simulation.json``'s ``inputs``.
    """
    configure()
    design = STUDY if design is None else convention(design)  # simulated studies are in the data convention
    n_subjects = design.subjects if n_subjects is None else n_subjects
    seconds = design.run_seconds if seconds is None else seconds
    if int(n_subjects) != n_subjects or n_subjects < 1:
        raise ValueError(f"--subjects must be a positive integer; got {n_subjects!r}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"--seed must be a non-negative integer; got {seed!r}")
    population = Population(betas=design.effects) if population is None else population
    given = experiment_entry(design, experiment_file)
    design = replace(design, subjects=int(n_subjects), run_seconds=float(seconds),
                     effects=population.effects(len(design.contrasts)))
    design, window_note = window_inside_run(design)
    out = check_output_dir(out, force=force)
    if window_note:
        print(f"scioc simulate: note: {window_note}", file=sys.stderr, flush=True)
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)))
    t, segs = simulate_study(int(n_subjects), rng, population, seconds, human=human, design=design)
    spec = HUMANS[human]
    study = study_table(t, segs, design)
    truth, traj = [], []
    for s in segs:
        n = t.shape[0]
        traj.append(pd.DataFrame({**_labels(s, n), "t": t, "angle": s.run.true_angle,
                                  "velocity": s.run.true_velocity, "u_H": s.run.u_H}))
        q11, q22, R = s.theta if spec.kind == "lq" else (np.nan, np.nan, np.nan)
        trial = {} if s.trial is None else {"trial": s.trial}
        # The human's own delay, lag and motor noise (per subject for a human that varies; 0 for the paper's agent).
        body = dict(zip(BODY_COLUMNS, (round(s.human.delay_s / design.dt) * design.dt, s.human.tau_nm,
                                       s.human.motor_sd)))
        truth.append({"subject": s.subject, "condition": s.condition, **trial, "run_index": s.run_index,
                      "q11": q11, "q22": q22, "R": R, "theta1": q11 / R, "theta2": q22 / R, **body})
    res = resolved(design)
    meta = {
        "seed": int(seed),
        "n_subjects": int(n_subjects),
        "run_seconds": float(seconds),
        "sample_time_s": design.dt,
        "encoder_counts_per_revolution": design.encoder_counts,
        "population": asdict(population),
        "assistant": res["conditions"]["assistant"],
        "human": {"name": human, **asdict(spec)},
        "sc_human": "plans with the assistant's feedback law (models.segment.Feedback), in closed loop",
        # The paper's assistant alone on the study reference (scioc assistant), for the paper's rig.
        "assistant_alone": (assistant_alone(seconds) if (design.dt, design.wheel, design.assistants)
                            == (STUDY.dt, STUDY.wheel, STUDY.assistants) else None),
        "analysis_window": window_note or "the experiment's",
        **sidecar(design, EXPERIMENT_FILE),
        "inputs": {"experiment": given},
        "versions": versions(),
    }
    names = {"study": "study.parquet", "experiment": EXPERIMENT_FILE, "truth": "truth.parquet",
             "truth_trajectories": "truth_trajectories.parquet", "meta": "simulation.json"}
    with staged_dir(out, force=force) as tmp:
        write_table_atomic(study, tmp / names["study"])
        write_experiment(design, tmp / names["experiment"])
        write_table_atomic(pd.DataFrame(truth), tmp / names["truth"])
        write_table_atomic(pd.concat(traj, ignore_index=True), tmp / names["truth_trajectories"])
        meta["outputs"] = outputs(tmp, [v for k, v in names.items() if k != "meta"])
        write_text_atomic(tmp / names["meta"], json.dumps(meta, indent=2) + "\n")
    return {k: str(out / v) for k, v in names.items()}

