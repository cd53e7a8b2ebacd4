"""``scioc identify``: per subject × condition maximum-likelihood θ, like the paper (Section IV-F).

For each segment: take the analysis window (default the paper's 15 s from 3:30; any
window or the whole run on request), reconstruct velocity and u_H from the angle where
the file lacks them (:mod:`models.reconstruct`, over the window plus a margin), and
maximize the max-ent likelihood (:mod:`models.identify`). The human's plan may look
``preview`` seconds past the window (default 2 s, the time a point of the reference
takes to cross the screen); ``--preview 0`` is the paper's horizon exactly.

In SC the human may model the assistant two ways (``--assistant-model``). ``feedback``
(default): the human knows the assistant's law (the paper's MPC, Section IV-D) and
plans on the wheel it closes, with its reference feedforward as the known input
(:class:`models.segment.Feedback`); the simulator's humans do this. ``exogenous`` is the
paper's Eq. 15-16: the recorded u_A is a known input sequence. In closed loop the
recorded u_A reacts to the human's own torque noise, which the exogenous model lets
the human anticipate; on the simulated study, from the true torques, it puts log θ1 in
SC about 0.55 too low (measured in the report's ground-truth section).

It also computes the model validation of Fig. 6: the trajectories that forward optimal
control generates with θ_MC and with θ_SC of the same subject, and the RMSE of angle
and torque when each condition's data are predicted with either.

Artifacts in ``--out DIR``: ``estimates.parquet`` (one row per subject × condition),
``trajectories.parquet`` (window samples: measured, reconstructed and predicted),
``validation.parquet`` (cross-prediction RMSE) and ``identify.json`` (settings, timings,
versions).
"""

from __future__ import annotations

import functools
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from models.adequacy import N_BOOT
from models.assistant import design_assistant, human_feedback
from models.design import WINDOW_SECONDS, WINDOW_START
from models.identify import PLAUSIBLE_THETA1, identify_segment
from models.maxent import forward_optimal_control
from models.plant import DT_HUMAN, discretize
from models.reconstruct import DEFAULT_RESOLUTION, FixedReconstruction, reconstruct
from models.segment import Segment, plan_inputs, prepare_batch
from pipelines.adequacy import assess_study, format_adequacy, not_checked
from pipelines.io import (Study, StudyFileError, SegmentData, load_study, refuse_inputs_inside, staged_dir,
                          write_table_atomic, write_text_atomic)
from pipelines.progress import progress
from pipelines.provenance import versions


@dataclass(frozen=True)
class IdentifySettings:
    """How to cut and treat each segment.

    Attributes
    ----------
    window_start : float or None
        Start of the analysis window, s on the file's time axis; None for the whole run.
    window_seconds : float or None
        Length of the window, s; None for the whole run.
    preview : float
        How far past the window the human plans, s (0: the paper's horizon).
    margin : float
        Extra seconds on each side of the window used by the reconstruction.
    reconstruct : str
        ``auto`` (only when velocity or u_H are missing) or ``always``.
    resolution : float
        Encoder increment, rad (sets the reconstruction's measurement noise).
    assistant_model : str
        ``feedback`` (the human plans with the assistant's law; default) or
        ``exogenous`` (the recorded u_A is a known input, the paper's Eq. 15-16).
    adequacy_boot : int
        Bootstrap data sets per segment for the model-adequacy checks
        (:mod:`pipelines.adequacy`; default 49; 0 skips them and the verdict reads
        "not checked").
    adequacy_seed : int
        Root seed of the adequacy bootstrap.
    """

    window_start: float | None = WINDOW_START
    window_seconds: float | None = WINDOW_SECONDS
    preview: float = 2.0
    margin: float = 1.0
    reconstruct: str = "auto"
    resolution: float = DEFAULT_RESOLUTION
    assistant_model: str = "feedback"
    adequacy_boot: int = N_BOOT
    adequacy_seed: int = 2018

    def __post_init__(self):
        if (self.window_start is None) != (self.window_seconds is None):
            raise ValueError("give both window start and length, or neither (whole run)")
        if self.window_seconds is not None and not self.window_seconds > 0:
            raise ValueError(f"window length must be > 0 s; got {self.window_seconds!r}")
        if not (self.preview >= 0 and self.margin >= 0):
            raise ValueError("preview and margin must be >= 0 s")
        if self.reconstruct not in ("auto", "always"):
            raise ValueError(f"reconstruct must be 'auto' or 'always'; got {self.reconstruct!r}")
        _check_assistant_model(self.assistant_model)
        if int(self.adequacy_boot) != self.adequacy_boot or self.adequacy_boot < 0:
            raise ValueError(f"adequacy bootstrap size must be an integer >= 0; got {self.adequacy_boot!r}")
        if int(self.adequacy_seed) != self.adequacy_seed or self.adequacy_seed < 0:
            raise ValueError(f"adequacy seed must be an integer >= 0; got {self.adequacy_seed!r}")


#: How the human in SC may model the assistant (see the module docstring).
ASSISTANT_MODELS = ("feedback", "exogenous")


def _check_assistant_model(name: str) -> None:
    if name not in ASSISTANT_MODELS:
        raise ValueError(f"assistant model must be one of {ASSISTANT_MODELS}; got {name!r}")


@functools.lru_cache(maxsize=1)
def paper_assistant():
    """The study's assistant (the paper's MPC, :func:`models.assistant.design_assistant`), built once."""
    return design_assistant()


def with_assistant_model(segment: Segment, condition: str, angle_ref_run, start: int, assistant_model: str) -> Segment:
    """``segment`` (rows ``start``.. of its run) with the human's model of the assistant.

    ``feedback`` in SC: the paper's MPC law, its feedforward from the run's whole reference
    ``angle_ref_run`` (the assistant previews 1 s past the segment). Otherwise unchanged
    (the recorded u_A as a known input).
    """
    _check_assistant_model(assistant_model)
    if assistant_model != "feedback" or condition != "SC":
        return segment
    full = human_feedback(paper_assistant(), angle_ref_run)
    return segment._replace(feedback=full.window(start, segment.u_A.shape[0]))


@dataclass(frozen=True)
class PreparedSegment:
    """A segment cut to its window, with the arrays the likelihood needs."""

    data: SegmentData
    rows: slice  # window rows within the segment, k = 0..K
    segment: Segment  # x0, reference and u_A with preview, u_H over the window
    velocity: np.ndarray  # (K + 1,) used for x0 (recorded or reconstructed), rad/s
    u_H: np.ndarray  # (K + 1,) recorded or reconstructed, N·m
    angle_used: np.ndarray  # (K + 1,) angle the states start from (smoothed if reconstructed), rad
    reconstructed: bool
    sigma_eps: float
    q: float
    span: slice  # rows of the segment the reconstruction saw (the window rows without reconstruction)
    span_state0: np.ndarray  # (2,) angle (rad) and velocity (rad/s) used at the span's first row
    smoother: FixedReconstruction | None  # the reconstruction's linear smoother over the span (None: measured)


def _window_rows(seg: SegmentData, settings: IdentifySettings, path) -> slice:
    n = seg.t.shape[0]
    if settings.window_start is None:
        return slice(0, n)
    i0 = int(np.searchsorted(seg.t, settings.window_start - 0.5 * DT_HUMAN))
    K = int(round(settings.window_seconds / DT_HUMAN))
    if i0 + K >= n or abs(seg.t[min(i0, n - 1)] - settings.window_start) > 0.5 * DT_HUMAN:
        raise StudyFileError(
            path,
            f"segment ({seg.subject}, {seg.condition}) covers t = {seg.t[0]:g}..{seg.t[-1]:g} s, which does not "
            f"contain the window {settings.window_start:g}..{settings.window_start + settings.window_seconds:g} s; "
            "choose another --window or use --whole-run",
            column="t",
            row=seg.first_row,
        )
    return slice(i0, i0 + K + 1)


def prepare_segment(seg: SegmentData, settings: IdentifySettings, plant, path="<table>") -> PreparedSegment:
    """Cut one recorded segment to its window, reconstructing velocity and u_H if needed."""
    rows = _window_rows(seg, settings, path)
    n = seg.t.shape[0]
    i0, i1 = rows.start, rows.stop - 1  # window rows k = 0..K
    K = i1 - i0
    M = min(int(round(settings.preview / DT_HUMAN)), n - 1 - i1)
    need = seg.velocity is None or seg.u_H is None or settings.reconstruct == "always"
    if need:
        m = int(round(settings.margin / DT_HUMAN))
        j0, j1 = max(0, i0 - m), min(n, i1 + 1 + m)
        rec = reconstruct(seg.angle[j0:j1], seg.u_A[j0:j1], plant, resolution=settings.resolution)
        cut = slice(i0 - j0, i1 + 1 - j0)
        angle, velocity, u_H = rec.angle[cut], rec.velocity[cut], rec.u_H[cut]
        sigma_eps, q = rec.sigma_eps, rec.q
        span, state0, smoother = slice(j0, j1), np.array([rec.angle[0], rec.velocity[0]]), rec.smoother
    else:
        angle, velocity, u_H = seg.angle[rows], seg.velocity[rows], seg.u_H[rows]
        sigma_eps = q = float("nan")
        span, state0, smoother = rows, np.array([angle[0], velocity[0]]), None
    segment = Segment(
        x0=np.array([angle[0], velocity[0]]),
        angle_ref=seg.angle_ref[i0 : i1 + M + 1],
        u_H=u_H[:K],
        u_A=seg.u_A[i0 : i1 + M],
    )
    segment = with_assistant_model(segment, seg.condition, seg.angle_ref, i0, settings.assistant_model)
    return PreparedSegment(seg, rows, segment, velocity, u_H, angle, need, sigma_eps, q, span, state0, smoother)


class Identification(NamedTuple):
    """What :func:`identify_study` returns.

    Attributes
    ----------
    estimates : DataFrame
        One row per subject × condition, with the per-segment adequacy columns.
    trajectories : DataFrame
        Window samples with measured, used and predicted angle, velocity and torque.
    validation : DataFrame
        RMSE of angle and u_H when each condition is predicted with θ_MC and θ_SC.
    timing : dict
        Seconds spent reconstructing, optimizing and checking adequacy.
    adequacy : dict
        The model-adequacy verdict (:func:`pipelines.adequacy.assess_study`).
    """

    estimates: pd.DataFrame
    trajectories: pd.DataFrame
    validation: pd.DataFrame
    timing: dict
    adequacy: dict


def identify_study(study: Study, settings: IdentifySettings = IdentifySettings(), *,
                   show_progress: bool = True) -> Identification:
    """Identify θ for every segment of a study, check the model's adequacy, cross-predict the conditions."""
    plant = discretize(DT_HUMAN)
    prepared, t_rec = [], 0.0
    for seg in progress(study.segments, desc="reconstruct", enabled=show_progress):
        t0 = time.perf_counter()
        prepared.append(prepare_segment(seg, settings, plant, study.path))
        t_rec += time.perf_counter() - t0
    t0 = time.perf_counter()
    estimates = [identify_segment(prepare_batch(plant, [p.segment]), plant) for p in prepared]
    t_opt = time.perf_counter() - t0

    rows = []
    for p, e in zip(prepared, estimates):
        rows.append({
            "subject": p.data.subject,
            "condition": p.data.condition,
            "window_start": float(p.data.t[p.rows.start]),
            "K": p.segment.K,
            "preview": p.segment.preview,
            "q11": e.theta[0],
            "q22": e.theta[1],
            "R": e.theta[2],
            "theta1": e.theta1,
            "theta2": e.theta2,
            "se_log_theta1": e.se_log_theta1,
            "se_theta2": e.se_theta2,
            "se_log_R": e.se_log_R,
            "loglik": e.loglik,
            "converged": e.converged,
            "implausible": e.implausible,
            "iterations": e.iterations,
            "grad_norm": e.grad_norm,
            "message": e.message,
            "reconstructed": p.reconstructed,
            "recon_sigma_eps": p.sigma_eps,
            "recon_q": p.q,
        })
    est = pd.DataFrame(rows)
    t0 = time.perf_counter()
    if settings.adequacy_boot > 0:
        cols, adequacy = assess_study(prepared, [e.theta for e in estimates], plant,
                                      assistant_model=settings.assistant_model, resolution=settings.resolution,
                                      n_boot=settings.adequacy_boot, seed=settings.adequacy_seed,
                                      assistant=paper_assistant())
        est = pd.concat([est, cols], axis=1)
    else:
        adequacy = not_checked("switched off (adequacy bootstrap size 0)")
    t_adq = time.perf_counter() - t0
    traj, val = _cross_predict(prepared, est, plant)
    timing = {"reconstruct_s": t_rec, "optimize_s": t_opt, "adequacy_s": t_adq, "segments": len(prepared)}
    return Identification(est, traj, val, timing, adequacy)


def _cross_predict(prepared, est: pd.DataFrame, plant):
    theta = {(r.subject, r.condition): np.array([r.q11, r.q22, r.R]) for r in est.itertuples()}
    frames, val = [], []
    for p in prepared:
        s, K = p.segment, p.segment.K
        d = p.data
        frame = {
            "subject": np.full(K + 1, d.subject, dtype=object),
            "condition": np.full(K + 1, d.condition, dtype=object),
            "t": d.t[p.rows],
            "angle": d.angle[p.rows],
            "angle_ref": d.angle_ref[p.rows],
            "u_A": d.u_A[p.rows],
            "velocity": p.velocity,
            "u_H": p.u_H,
        }
        rmse = {"subject": d.subject, "condition": d.condition}
        for c in ("MC", "SC"):
            th = theta.get((d.subject, c))
            key = c.lower()
            if th is None:
                for q in ("angle", "velocity", "u_H"):
                    frame[f"pred_{key}_{q}"] = np.full(K + 1, np.nan)
                rmse[f"rmse_angle_theta_{key}"] = rmse[f"rmse_uH_theta_{key}"] = np.nan
                continue
            # θ's plan against this segment's assistant (in closed loop under Feedback).
            plan_plant, known = plan_inputs(s, plant)
            demo = forward_optimal_control(th, s.x0, s.angle_ref, known, plan_plant)
            frame[f"pred_{key}_angle"] = demo.x[: K + 1, 0]
            frame[f"pred_{key}_velocity"] = demo.x[: K + 1, 1]
            frame[f"pred_{key}_u_H"] = np.append(demo.u_H[:K], np.nan)
            rmse[f"rmse_angle_theta_{key}"] = float(np.sqrt(np.mean((demo.x[1 : K + 1, 0] - d.angle[p.rows][1:]) ** 2)))
            rmse[f"rmse_uH_theta_{key}"] = float(np.sqrt(np.mean((demo.u_H[:K] - p.u_H[:K]) ** 2)))
        frames.append(pd.DataFrame(frame))
        val.append(rmse)
    return pd.concat(frames, ignore_index=True), pd.DataFrame(val)


def identify_to_dir(study_path, out, settings: IdentifySettings = IdentifySettings(), *, show_progress=True,
                    force: bool = False) -> dict:
    """Run :func:`identify_study` on a file and write its artifacts into ``out`` as a whole.

    ``out`` is written through :func:`pipelines.io.staged_dir`: it holds this run's
    artifacts and nothing else, or, if the run fails or is interrupted, what it held
    before. An existing non-empty ``out`` is replaced only with ``force``.
    """
    refuse_inputs_inside(out, study_path)
    study = load_study(study_path)
    est, traj, val, timing, adequacy = identify_study(study, settings, show_progress=show_progress)
    out = Path(out)
    meta = {
        "study": str(study_path),
        # Relative to this folder: still right after the run folder holding both is renamed.
        "study_relative": os.path.relpath(Path(study_path).resolve(), out.resolve()),
        "settings": {k: getattr(settings, k) for k in settings.__dataclass_fields__},
        "timing_s": timing,
        "converged": int(est["converged"].sum()),
        "segments": int(len(est)),
        "not_converged": [{"subject": r.subject, "condition": r.condition, "message": r.message}
                          for r in est.itertuples() if not r.converged],
        "implausible": [{"subject": r.subject, "condition": r.condition, "theta1": r.theta1}
                        for r in est.itertuples() if r.implausible],
        "adequacy": adequacy,
        "versions": versions(),
    }
    with staged_dir(out, force=force) as tmp:
        write_table_atomic(est, tmp / "estimates.parquet")
        write_table_atomic(traj, tmp / "trajectories.parquet")
        write_table_atomic(val, tmp / "validation.parquet")
        write_text_atomic(tmp / "identify.json", json.dumps(meta, indent=2) + "\n")
    names = {"estimates": "estimates.parquet", "trajectories": "trajectories.parquet",
             "validation": "validation.parquet", "meta": "identify.json"}
    return {k: str(out / v) for k, v in names.items()}


def format_identify(out) -> str:
    """The console summary of an identify folder: convergence, the segments that did not converge, adequacy."""
    meta = json.loads((Path(out) / "identify.json").read_text())
    lines = [f"identified {meta['segments']} segments; {meta['converged']} converged"]
    for r in meta.get("not_converged", []):
        lines.append(f"  NOT CONVERGED: {r['subject']} {r['condition']}: {r['message']}")
    for r in meta.get("implausible", []):
        lines.append(f"  AT THE EDGE OF THE SEARCH: {r['subject']} {r['condition']}: theta1 = {r['theta1']:.3g} 1/rad² "
                     f"(outside {PLAUSIBLE_THETA1[0]:g}..{PLAUSIBLE_THETA1[1]:g}: angles in degrees? no information?)")
    lines.append(format_adequacy(meta["adequacy"]))
    return "\n".join(lines)
