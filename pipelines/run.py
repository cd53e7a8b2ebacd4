"""``scioc run``: the whole workflow on the built-in simulated study, ending with the report.

Stages (each writes its own artifacts, each also a command of its own):
simulate → identify (from angles, like a lab) → identify from the true torques (what the
reconstruction costs; and with the paper's exogenous-u_A likelihood, what that costs in
SC) → compare → fit → report.
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import pandas as pd

from models.design import STUDY, Design
from models.simulate import Population
from pipelines.compare import compare_to_file
from pipelines.identify import format_identify, identify_study, identify_to_dir
from pipelines.io import load_study, validate_table
from pipelines.prepare import IdentifySettings, prepare_study
from pipelines.report import build_report
from pipelines.simulate import DEFAULT_SEED, simulate_to_dir
from pipelines.storage import staged_dir, write_table_atomic, write_text_atomic

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
    write_text_atomic(out / "identify.json", json.dumps({"timing_s": timing, "source": "true velocity and u_H", "adequacy": adequacy}) + "\n")
    return {"estimates": str(out / "estimates.parquet")}


def run_all(out="reports", *, name: str = DEFAULT_NAME, n_subjects: int | None = None,
            seed: int = DEFAULT_SEED, settings: IdentifySettings | None = None, fit: bool = True,
            human: str = "maxent", population: Population | None = None, design: Design | None = None) -> Path:
    """Run every stage on the simulated study; returns the report's path.

    ``fit=False`` skips the hierarchical Bayesian fit (minutes) for quick looks. ``human``
    and ``population`` choose the simulated study (:func:`pipelines.simulate.simulate_to_dir`):
    a negative-control human shows what the report says when the model does not fit.
    ``design`` is the experiment simulated and analysed (the paper's study by default;
    ``data/experiment.toml`` holds it); ``settings`` default to its ``[analysis]``. The study is
    reconstructed once (:func:`pipelines.prepare.prepare_study`) and shared by the
    identification and the fit.
    """
    design = STUDY if design is None else design
    settings = IdentifySettings.for_design(design) if settings is None else settings
    if settings.design != design:
        raise ValueError("the settings were made for another experiment than the one simulated")
    n_subjects = design.subjects if n_subjects is None else n_subjects
    root = Path(out) / name
    steps = 6 if fit else 5
    levels = "/".join(design.levels)
    trials = f" × {design.trials} trials" if design.trials > 1 else ""
    t0 = time.perf_counter()
    # Every stage writes into one fresh folder that replaces ``root`` as a whole at the end:
    # an interrupted run leaves the previous results as they were, never a mix of two runs.
    with staged_dir(root, force=True) as tmp:
        log(f"[1/{steps}] simulating {n_subjects} subjects × {len(design.levels)} conditions ({levels}){trials} × "
            f"{design.run_seconds:g} s at {design.rate_hz:g} Hz (seed {seed}, human {human}) -> {root / 'data'}")
        sim = simulate_to_dir(tmp / "data", n_subjects=n_subjects, seed=seed, human=human, population=population,
                              design=design)
        source = str(Path(sim["experiment"]).relative_to(tmp).as_posix())
        log(f"[2/{steps}] identifying every subject × condition from the recorded "
            f"{'angle and torque' if design.torque_sensor else 'encoder angle'}")
        prepared = prepare_study(load_study(sim["study"], design), settings, show_progress=True)
        identify_to_dir(sim["study"], tmp / "identify", settings, prepared=prepared, experiment_file=source)
        log(format_identify(tmp / "identify"))
        log(f"[3/{steps}] identifying again from the true torques (the cost of reconstruction)")
        identify_with_truth(sim["study"], sim["truth_trajectories"], tmp / "identify_true_torque", settings)
        # The paper's likelihood (recorded u_A as a known input) on the same torques: its SC bias.
        identify_with_truth(sim["study"], sim["truth_trajectories"], tmp / "identify_true_torque_exogenous",
                            replace(settings, assistant_model="exogenous"))
        log(f"[4/{steps}] Wilcoxon matched-pairs tests against {design.baseline}")
        compare_to_file(tmp / "identify" / "estimates.parquet", tmp / "compare.json")
        if fit:
            from pipelines.fit import fit_to_dir  # imports PyMC (seconds): not for --skip-fit

            log(f"[5/{steps}] hierarchical Bayesian fit (nutpie, 4 chains; the condition model and the pooled one)")
            fit_to_dir(sim["study"], tmp / "fit", seed=seed, settings=settings, truth_dir=tmp / "data",
                       estimates_path=tmp / "identify" / "estimates.parquet", show_progress=True, prepared=prepared,
                       experiment_file=source)
        log(f"[{steps}/{steps}] writing the report")
        build_report(tmp, title=name)
    report = root / "index.html"
    log(f"done in {time.perf_counter() - t0:.0f} s")
    log(f"report: {report}")
    return report


__all__ = ["run_all", "identify_with_truth"]
