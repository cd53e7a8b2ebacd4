"""``scioc simulate``: write the simulated study in the data convention, with its ground truth apart.

Artifacts in ``--out DIR``:

* ``study.parquet`` — what a lab records: subject, condition, t, angle (encoder), angle_ref, u_A.
* ``truth.parquet`` — one row per subject × condition: run order, true q11, q22, R, θ1, θ2.
* ``truth_trajectories.parquet`` — true angle, velocity and u_H per sample.
* ``simulation.json`` — seed, population, design and package versions.
"""

from __future__ import annotations

import json
from dataclasses import asdict

import numpy as np
import pandas as pd

from models.design import ASSISTANT_HORIZON, DT_ASSISTANT, DT_HUMAN, ENCODER_COUNTS, THETA_ASSISTANT
from models.humans import HUMANS
from models.reference import reference_trajectory
from models.simulate import Population, simulate_study
from pipelines.assistant_check import assistant_alone
from pipelines.provenance import versions
from pipelines.storage import check_output_dir, staged_dir, write_table_atomic, write_text_atomic

DEFAULT_SEED = 2018
DEFAULT_SUBJECTS = 42


def study_table(t, segs) -> pd.DataFrame:
    """The lab's view of simulated runs: subject, condition, t, angle (encoder), angle_ref, u_A."""
    ref = reference_trajectory(float(t[-1])).angle
    n = t.shape[0]
    return pd.concat(
        [pd.DataFrame({"subject": np.full(n, s.subject, dtype=object), "condition": np.full(n, s.condition, dtype=object),
                       "t": t, "angle": s.run.angle, "angle_ref": ref, "u_A": s.run.u_A}) for s in segs],
        ignore_index=True,
    )


def simulate_to_dir(
    out, *, n_subjects: int = DEFAULT_SUBJECTS, seed: int = DEFAULT_SEED, population: Population = Population(),
    seconds: float = 240.0, human: str = "maxent", force: bool = False,
) -> dict:
    """Simulate the experiment and write its artifacts.

    Parameters
    ----------
    out : str or Path
        Output folder (created).
    n_subjects : int
    seed : int
        Root seed; subject i uses the i-th child of ``SeedSequence(seed)``.
    population : Population
    seconds : float
        Length of each run, s.
    human : str
        The simulated human (:data:`models.humans.HUMANS`): ``maxent`` is the paper's
        agent; the others are negative controls the likelihood does not describe. The
        crossover operator has no cost θ: its truth rows carry NaN.
    force : bool
        Replace an existing non-empty ``out`` as a whole (:func:`pipelines.storage.staged_dir`);
        without it such a folder is refused.

    Returns
    -------
    dict
        Paths of the written files.
    """
    if int(n_subjects) != n_subjects or n_subjects < 1:
        raise ValueError(f"--subjects must be a positive integer; got {n_subjects!r}")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"--seed must be a non-negative integer; got {seed!r}")
    out = check_output_dir(out, force=force)
    rng = np.random.default_rng(np.random.SeedSequence(int(seed)))
    t, segs = simulate_study(int(n_subjects), rng, population, seconds, human=human)
    spec = HUMANS[human]
    study = study_table(t, segs)
    truth, traj = [], []
    for s in segs:
        n = t.shape[0]
        common = {"subject": np.full(n, s.subject, dtype=object), "condition": np.full(n, s.condition, dtype=object)}
        traj.append(pd.DataFrame({**common, "t": t, "angle": s.run.true_angle, "velocity": s.run.true_velocity,
                                  "u_H": s.run.u_H}))
        q11, q22, R = s.theta if spec.kind == "lq" else (np.nan, np.nan, np.nan)
        truth.append({"subject": s.subject, "condition": s.condition, "run_index": s.run_index,
                      "q11": q11, "q22": q22, "R": R, "theta1": q11 / R, "theta2": q22 / R})
    meta = {
        "seed": int(seed),
        "n_subjects": int(n_subjects),
        "run_seconds": float(seconds),
        "sample_time_s": DT_HUMAN,
        "encoder_counts_per_revolution": ENCODER_COUNTS,
        "population": asdict(population),
        "assistant": {"theta_A": list(THETA_ASSISTANT), "horizon_steps": ASSISTANT_HORIZON,
                      "prediction_step_s": DT_ASSISTANT, "resolved_every_s": DT_HUMAN},
        "human": {"name": human, **asdict(spec)},
        "sc_human": "plans with the assistant's feedback law (models.segment.Feedback), in closed loop",
        "assistant_alone": assistant_alone(seconds),
        "versions": versions(),
    }
    with staged_dir(out, force=force) as tmp:
        write_table_atomic(study, tmp / "study.parquet")
        write_table_atomic(pd.DataFrame(truth), tmp / "truth.parquet")
        write_table_atomic(pd.concat(traj, ignore_index=True), tmp / "truth_trajectories.parquet")
        write_text_atomic(tmp / "simulation.json", json.dumps(meta, indent=2) + "\n")
    names = {"study": "study.parquet", "truth": "truth.parquet", "truth_trajectories": "truth_trajectories.parquet",
             "meta": "simulation.json"}
    return {k: str(out / v) for k, v in names.items()}

