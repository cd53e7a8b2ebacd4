"""The preparation step shared by ``scioc identify``, ``scioc fit`` and ``scioc loglik``.

For each recorded segment: take the analysis window (default the paper's 15 s from 3:30;
any window or the whole run on request), reconstruct velocity and u_H from the angle
where the file lacks them (:mod:`models.reconstruct`, over the window plus a margin), and
cut the arrays the max-ent likelihood needs (:class:`models.segment.Segment`), with the
``preview`` seconds the human's plan looks past the window (default 2 s, the time a
point of the reference takes to cross the screen; 0 is the paper's horizon).

In SC the human may model the assistant two ways (``assistant_model``). ``feedback``
(default): the human knows the assistant's law (the paper's MPC, Section IV-D) and plans
on the wheel it closes, with its reference feedforward as the known input
(:class:`models.segment.Feedback`); the simulator's humans do this. ``exogenous`` is the
paper's Eq. 15-16: the recorded u_A is a known input sequence. In closed loop the
recorded u_A reacts to the human's own torque noise, which the exogenous model lets the
human anticipate; on the simulated study, from the true torques, it puts log θ1 in SC
about 0.55 too low (measured in the report's ground-truth section).

:func:`prepare_study` does this once per study; ``scioc run`` passes its result to both
the identification and the Bayesian fit.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from models.adequacy import N_BOOT
from models.assistant import design_assistant, human_feedback
from models.design import PREVIEW_SECONDS, SHARED, WINDOW_SECONDS, WINDOW_START
from models.plant import DT_HUMAN, discretize
from models.reconstruct import DEFAULT_RESOLUTION, FixedReconstruction, reconstruct
from models.segment import Segment
from models.units import index_study
from pipelines.io import InputDataError, SegmentData, Study, StudyFileError
from pipelines.progress import progress

#: How the human in SC may model the assistant (see the module docstring).
ASSISTANT_MODELS = ("feedback", "exogenous")


def check_assistant_model(name: str) -> None:
    """Raise ValueError unless ``name`` is one of :data:`ASSISTANT_MODELS`."""
    if name not in ASSISTANT_MODELS:
        raise ValueError(f"assistant model must be one of {ASSISTANT_MODELS}; got {name!r}")


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
    preview: float = PREVIEW_SECONDS
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
        check_assistant_model(self.assistant_model)
        if int(self.adequacy_boot) != self.adequacy_boot or self.adequacy_boot < 0:
            raise ValueError(f"adequacy bootstrap size must be an integer >= 0; got {self.adequacy_boot!r}")
        if int(self.adequacy_seed) != self.adequacy_seed or self.adequacy_seed < 0:
            raise ValueError(f"adequacy seed must be an integer >= 0; got {self.adequacy_seed!r}")


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
    check_assistant_model(assistant_model)
    if assistant_model != "feedback" or condition != SHARED:
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


@dataclass(frozen=True)
class PreparedStudy:
    """A study file cut and reconstructed for the likelihood, one entry per segment (file order).

    Attributes
    ----------
    path : str
        The study file (named in error messages).
    settings : IdentifySettings
        The settings the segments were prepared with.
    segments : tuple of PreparedSegment
    seconds : float
        Wall time of the preparation (mostly the reconstruction), s.
    """

    path: str
    settings: IdentifySettings
    segments: tuple
    seconds: float

    @property
    def subjects(self) -> list:
        return [p.data.subject for p in self.segments]

    @property
    def conditions(self) -> list:
        return [p.data.condition for p in self.segments]

    @property
    def labels(self) -> list:
        return [f"{s}/{c}" for s, c in zip(self.subjects, self.conditions)]


def check_design(path, subjects, conditions) -> None:
    """Raise :class:`pipelines.io.InputDataError` unless every subject has both conditions.

    The message is that of :func:`models.units.index_study` (a subject without one of the
    conditions, or no SC (MC) segment at all), prefixed with the file ``path``.
    """
    try:
        index_study(list(subjects), list(conditions))
    except ValueError as exc:  # the data do not have the design the model needs: bad input (exit 3)
        raise InputDataError(f"{path}: {exc}") from None


def prepare_study(study: Study, settings: IdentifySettings = IdentifySettings(), *,
                  show_progress: bool = False) -> PreparedStudy:
    """Cut and, where needed, reconstruct every segment of a validated study.

    Raises
    ------
    pipelines.io.StudyFileError
        If a segment does not contain the analysis window.
    """
    plant = discretize(DT_HUMAN)
    t0 = time.perf_counter()
    segments = tuple(prepare_segment(s, settings, plant, study.path)
                     for s in progress(study.segments, desc="reconstruct", enabled=show_progress))
    return PreparedStudy(study.path, settings, segments, time.perf_counter() - t0)
