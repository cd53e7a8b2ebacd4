"""``scioc identify``: per subject × condition maximum-likelihood θ, like the paper (Section IV-F).

Each segment is prepared (:mod:`scioc.pipelines.prepare`), the likelihood maximized
(:mod:`scioc.models.identify`) and the model's adequacy checked (:mod:`scioc.pipelines.adequacy`).
The trials of one unit share θ, so their log-likelihoods add (Eq. 17 with d > 1). The model
validation of Fig. 6 predicts every segment with each level's θ of its subject (forward optimal
control) and records the RMSE of angle and torque.

The human model (:mod:`scioc.pipelines.human_model`) identifies each unit, adds its own columns, draws the
adequacy bootstrap and gives the mean behaviour of the cross-prediction.

Artifacts in ``--out DIR``: ``estimates.parquet`` (one row per unit), ``trajectories.parquet``
(window samples: measured, used, predicted), ``validation.parquet`` (cross-prediction RMSE) and
``identify.json`` (settings, timings, adequacy, experiment, the SHA-256 of its inputs and outputs, versions).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from scioc.models.identify import PLAUSIBLE_THETA1
from scioc.models.plant import discretize
from scioc.models.runtime import configure
from scioc.pipelines.adequacy import assess_study, format_adequacy, not_checked
from scioc.pipelines.experiment import parse_experiment, sidecar
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.io import InputDataError, Study, load_study
from scioc.pipelines.lineage import experiment_entry, outputs, study_entry
from scioc.pipelines.prepare import IdentifySettings, PreparedStudy, prepare_study
from scioc.pipelines.progress import progress
from scioc.pipelines.provenance import versions
from scioc.pipelines.storage import (
    check_output_dir,
    refuse_inputs_inside,
    staged_dir,
    write_table_atomic,
    write_text_atomic,
)


class Identification(NamedTuple):
    """What :func:`identify_study` returns."""

    estimates: pd.DataFrame  # one row per subject × condition, with the adequacy columns
    trajectories: pd.DataFrame  # window samples: measured, used and predicted angle, velocity and torque
    validation: pd.DataFrame  # RMSE of angle and u_H when each level is predicted with each level's θ
    timing: dict  # seconds reconstructing, optimizing and checking adequacy
    adequacy: dict  # the verdict of :func:`scioc.pipelines.adequacy.assess_study`


def identify_study(study: Study, settings: IdentifySettings = IdentifySettings(), *,
                   show_progress: bool = True) -> Identification:
    """Prepare a study, identify θ per unit, check adequacy and cross-predict (:func:`identify_prepared`)."""
    return identify_prepared(prepare_study(study, settings, show_progress=show_progress), show_progress=show_progress)


def identify_prepared(study: PreparedStudy, *, show_progress: bool = False) -> Identification:
    """:func:`identify_study` on a study already prepared (with ``study.settings``); a progress bar over the units
    of a human model whose units take long to identify with ``show_progress``."""
    settings, prepared = study.settings, study.segments
    model = get(settings.human_model)
    plant = discretize(settings.design.dt, settings.design.wheel)
    units = study.units
    trials = any(p.data.trial is not None for p in prepared)
    t0 = time.perf_counter()
    estimates = {u: model.identify_unit(prepared, units[u], plant, settings)
                 for u in progress(units, desc="identify", enabled=show_progress and model.slow_identification)}
    t_opt = time.perf_counter() - t0

    rows = []
    for (subject, condition), idx in units.items():
        e = estimates[(subject, condition)]
        first = prepared[idx[0]]
        rows.append({
            "subject": subject,
            "condition": condition,
            **({"trials": len(idx)} if trials else {}),
            "window_start": float(first.data.t[first.rows.start]),
            "K": sum(prepared[i].segment.K for i in idx),
            "preview": first.segment.preview,
            "q11": e.theta[0],
            "q22": e.theta[1],
            "R": e.theta[2],
            "theta1": e.theta1,
            "theta2": e.theta2,
            "se_log_theta1": e.se_log_theta1,
            "se_theta2": e.se_theta2,
            "se_log_R": e.se_log_R,
            **model.estimate_columns(e, prepared, idx),
            "human_model": settings.human_model,
            "loglik": e.loglik,
            "converged": e.converged,
            "implausible": e.implausible,
            "iterations": e.iterations,
            "grad_norm": e.grad_norm,
            "message": e.message,
            "reconstructed": any(prepared[i].reconstructed for i in idx),
            "recon_sigma_eps": float(np.mean([prepared[i].sigma_eps for i in idx])),
            "recon_q": float(np.mean([prepared[i].q for i in idx])),
        })
    est = pd.DataFrame(rows)
    t0 = time.perf_counter()
    if settings.adequacy_boot > 0:
        fitted = [estimates[(p.data.subject, p.data.condition)] for p in prepared]
        extra = model.adequacy_parameters(prepared, fitted, plant, settings)
        cols, adequacy = assess_study(prepared, [e.theta for e in fitted], plant, settings, delayed=extra)
        est = pd.concat([est, cols], axis=1)
    else:
        adequacy = not_checked("switched off (adequacy bootstrap size 0)")
    t_adq = time.perf_counter() - t0
    traj, val = _cross_predict(prepared, est, plant, model, settings)
    timing = {"reconstruct_s": study.seconds, "optimize_s": t_opt, "adequacy_s": t_adq, "segments": len(prepared)}
    return Identification(est, traj, val, timing, adequacy)


def _cross_predict(prepared, est: pd.DataFrame, plant, model, settings):
    """Each segment's measured trajectories beside the mean behaviour of each level's estimates, and their RMSEs."""
    levels = settings.design.levels
    theta = {(r.subject, r.condition): model.cross_prediction_parameters(r) for r in est.itertuples()}
    frames, val = [], []
    for p in prepared:
        K = p.segment.K
        d = p.data
        frame = {
            "subject": np.full(K + 1, d.subject, dtype=object),
            "condition": np.full(K + 1, d.condition, dtype=object),
            **({"trial": np.full(K + 1, d.trial, dtype=object)} if d.trial is not None else {}),
            "t": d.t[p.rows],
            "angle": d.angle[p.rows],
            "angle_ref": d.angle_ref[p.rows],
            "u_A": d.u_A[p.rows],
            "velocity": p.velocity,
            "u_H": p.u_H,
        }
        rmse = {"subject": d.subject, "condition": d.condition, **({"trial": d.trial} if d.trial is not None else {})}
        for c in levels:
            th = theta.get((d.subject, c))
            key = c.lower()
            if th is None:
                for q in ("angle", "velocity", "u_H"):
                    frame[f"pred_{key}_{q}"] = np.full(K + 1, np.nan)
                rmse[f"rmse_angle_theta_{key}"] = rmse[f"rmse_uH_theta_{key}"] = np.nan
                continue
            demo = model.mean_behaviour(p, th, plant, settings)
            frame[f"pred_{key}_angle"] = demo.x[: K + 1, 0]
            frame[f"pred_{key}_velocity"] = demo.x[: K + 1, 1]
            frame[f"pred_{key}_u_H"] = np.append(demo.u_H[:K], np.nan)
            rmse[f"rmse_angle_theta_{key}"] = float(np.sqrt(np.mean((demo.x[1 : K + 1, 0] - d.angle[p.rows][1:]) ** 2)))
            rmse[f"rmse_uH_theta_{key}"] = float(np.sqrt(np.mean((demo.u_H[:K] - p.u_H[:K]) ** 2)))
        frames.append(pd.DataFrame(frame))
        val.append(rmse)
    return pd.concat(frames, ignore_index=True), pd.DataFrame(val)


def identify_to_dir(study_path, out, settings: IdentifySettings = IdentifySettings(), *, show_progress=True,
                    force: bool = False, prepared: PreparedStudy | None = None,
                    experiment_file: str | None = None) -> dict:
    """Run :func:`identify_study` on a file and replace ``out`` as a whole (:func:`scioc.pipelines.storage.staged_dir`).

    A non-empty ``out`` is replaced only with ``force``. ``prepared``: the study already prepared with
    ``settings`` (``scioc run`` shares it with the fit). ``experiment_file``: where ``settings.design``
    came from, recorded in ``identify.json``.
    """
    configure()
    refuse_inputs_inside(out, study_path)
    check_output_dir(out, force=force)  # before the work, not after
    if prepared is None:
        prepared = prepare_study(load_study(study_path, settings.design), settings, show_progress=show_progress)
    elif prepared.settings != settings:
        raise ValueError("the prepared study was cut with other settings than these")
    study_record = study_entry(study_path)
    est, traj, val, timing, adequacy = identify_prepared(prepared, show_progress=show_progress)
    model = get(settings.human_model)
    out = Path(out)
    meta = {
        "study": str(study_path),
        # Relative to this folder: still right after the run folder holding both is renamed.
        "study_relative": os.path.relpath(Path(study_path).resolve(), out.resolve()),
        "settings": settings.as_dict(),
        "timing_s": timing,
        "converged": int(est["converged"].sum()),
        "segments": int(len(est)),
        "not_converged": [{"subject": r.subject, "condition": r.condition, "message": r.message}
                          for r in est.itertuples() if not r.converged],
        "implausible": [{"subject": r.subject, "condition": r.condition, "theta1": r.theta1,
                         **model.implausible_fields(r)} for r in est.itertuples() if r.implausible],
        "adequacy": adequacy,
        "human_model": settings.human_model,
        "reconstructed_units": int(est["reconstructed"].sum()),
        "delay_grid": None,
        **model.identify_sidecar(est, settings),
        **sidecar(settings.design, experiment_file),
        "inputs": {"study": study_record, "experiment": experiment_entry(settings.design, experiment_file)},
        "versions": versions(),
    }
    names = {"estimates": "estimates.parquet", "trajectories": "trajectories.parquet",
             "validation": "validation.parquet", "meta": "identify.json"}
    with staged_dir(out, force=force) as tmp:
        write_table_atomic(est, tmp / names["estimates"])
        write_table_atomic(traj, tmp / names["trajectories"])
        write_table_atomic(val, tmp / names["validation"])
        meta["outputs"] = outputs(tmp, [names[k] for k in ("estimates", "trajectories", "validation")])
        write_text_atomic(tmp / names["meta"], json.dumps(meta, indent=2) + "\n")
    return {k: str(out / v) for k, v in names.items()}


def identification_settings(estimates_path) -> tuple[IdentifySettings, str | None] | None:
    """The settings and experiment file an identification used, from ``identify.json`` beside ``estimates_path``;
    None where there is none. InputDataError where it is malformed."""
    meta_path = Path(estimates_path).parent / "identify.json"
    if not meta_path.is_file():
        return None
    try:
        meta = json.loads(meta_path.read_text())
        design = parse_experiment(meta["experiment"], f"{meta_path} (experiment)")
        return IdentifySettings(**meta["settings"], design=design), meta.get("experiment_file")
    except (ValueError, KeyError, TypeError) as exc:
        raise InputDataError(f"{meta_path}: not the sidecar of scioc identify ({exc})") from None


def format_identify(out) -> str:
    """The console summary of an identify folder: convergence, the segments that did not converge, adequacy."""
    meta = json.loads((Path(out) / "identify.json").read_text())
    model = get(meta.get("human_model", "maxent"))
    lines = [f"identified {meta['segments']} segments; {meta['converged']} converged (human model: {model.name})"]
    lines += model.identify_notes(meta)
    for r in meta.get("not_converged", []):
        lines.append(f"  NOT CONVERGED: {r['subject']} {r['condition']}: {r['message']}")
    for r in meta.get("implausible", []):
        if r.get("lag_at_bound"):
            lines.append(f"  AT THE EDGE OF THE SEARCH: {r['subject']} {r['condition']}: tau_nm = {r['tau_nm']:g} s, its "
                         "bound (a torque smoother than any lag explains: reconstructed from encoder angles?)")
            continue
        lines.append(f"  AT THE EDGE OF THE SEARCH: {r['subject']} {r['condition']}: theta1 = {r['theta1']:.3g} 1/rad² "
                     f"(outside {PLAUSIBLE_THETA1[0]:g}..{PLAUSIBLE_THETA1[1]:g}: angles in degrees? no information?)")
    lines.append(format_adequacy(meta["adequacy"]))
    return "\n".join(lines)
