"""The preparation step shared by ``scioc identify``, ``scioc fit`` and ``scioc loglik``.

Each recorded segment is cut to the analysis window (by default the paper's 15 s from 3:30) plus
``preview`` seconds of reference the human's plan looks past it (default 2 s; 0 is the paper's
horizon; docs/decisions/plan-preview.md). Where the file lacks u_H, velocity and u_H are reconstructed
from the angle over the window plus a margin (:mod:`scioc.models.reconstruct`); a measured u_H without
velocity gets its initial state fitted to the angles (:func:`scioc.models.reconstruct.initial_state`).

On an assisted level the human models the assistant as ``feedback`` (default: it plans on the
wheel the level's law closes, :class:`scioc.models.segment.Feedback`, and the recorded u_A must
follow that law, :func:`check_assistant_law`) or ``exogenous`` (the paper's Eq. 15-16: the
recorded u_A is a known input). See docs/decisions/assistant-as-state-feedback.md.

For the ``delayed`` human each segment keeps the torques before its window, which set the arm
torque at its start (:func:`_warmup`). ``scioc run`` shares one :func:`prepare_study` result
between the identification and the fit.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from scioc.models.adequacy import N_BOOT
from scioc.models.assistant import MPCAssistant, build_assistant, human_feedback
from scioc.models.delayed.angles import AngleWindow
from scioc.models.delayed.lag import Warmup
from scioc.models.design import (
    CONDITIONS,
    MAX_PREVIEW,
    PREVIEW_SECONDS,
    STUDY,
    WINDOW_SECONDS,
    WINDOW_START,
    Design,
)
from scioc.models.plant import discretize, propagate
from scioc.models.reconstruct import DEFAULT_RESOLUTION, FixedReconstruction, initial_state, reconstruct
from scioc.models.segment import Segment
from scioc.models.units import index_study
from scioc.pipelines.io import InputDataError, SegmentData, Study, StudyFileError
from scioc.pipelines.progress import progress

#: How the human on an assisted level may model the assistant (see the module docstring).
ASSISTANT_MODELS = ("feedback", "exogenous")
#: Measurement resolution the reconstruction assumes for an angle that is not quantized
#: (``encoder.counts_per_rev = 0``), rad: a sensor's noise floor, far below any encoder's step.
UNQUANTIZED_RESOLUTION = 1e-6
#: :func:`check_assistant_law`: RMS(u_A − law) over the window <= LAW_RTOL · RMS(u_A) + :data:`LAW_ATOL`.
LAW_RTOL = 0.1
#: Absolute part of the law check's tolerance, N·m.
LAW_ATOL = 0.01


def check_assistant_model(name: str) -> None:
    """Raise ValueError unless ``name`` is one of :data:`ASSISTANT_MODELS`."""
    if name not in ASSISTANT_MODELS:
        raise ValueError(f"assistant model must be one of {ASSISTANT_MODELS}; got {name!r}")


@dataclass(frozen=True)
class IdentifySettings:
    """How to cut and treat each segment (times in s, on the file's time axis)."""

    window_start: float | None = WINDOW_START  # None, with window_seconds None: the whole run
    window_seconds: float | None = WINDOW_SECONDS
    preview: float = PREVIEW_SECONDS  # how far past the window the human plans (0: the paper's horizon)
    margin: float = 1.0  # extra seconds on each side of the window that the reconstruction sees
    reconstruct: str = "auto"  # "auto" (only where u_H is missing) or "always"
    resolution: float = DEFAULT_RESOLUTION  # encoder increment, rad: the reconstruction's measurement noise
    assistant_model: str = "feedback"  # or "exogenous" (:data:`ASSISTANT_MODELS`)
    adequacy_boot: int = N_BOOT  # bootstrap data sets per segment (pipelines.adequacy); 0: "not checked"
    adequacy_seed: int = 2018  # root seed of the adequacy bootstrap
    human_model: str = "maxent"  # a registered human model (scioc.pipelines.human_model)
    design: Design = STUDY  # the experiment; :meth:`for_design` also takes window, preview, resolution from it

    @classmethod
    def for_design(cls, design: Design, **overrides) -> "IdentifySettings":
        """The settings of ``design``'s ``[analysis]`` and encoder, with ``overrides`` on top."""
        base = {
            "window_start": None if design.whole else design.window_start,
            "window_seconds": None if design.whole else design.window_seconds,
            "preview": design.preview,
            "resolution": design.encoder_step or UNQUANTIZED_RESOLUTION,
            "design": design,
        }
        base.update(overrides)
        return cls(**base)

    def as_dict(self) -> dict:
        """The settings as JSON-ready values (the design goes to the sidecar's ``experiment``)."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "design"}

    def __post_init__(self):
        if (self.window_start is None) != (self.window_seconds is None):
            raise ValueError("give both window start and length, or neither (whole run)")
        if self.window_seconds is not None and not self.window_seconds > 0:
            raise ValueError(f"window length must be > 0 s; got {self.window_seconds!r}")
        if not (self.preview >= 0 and self.margin >= 0):
            raise ValueError("preview and margin must be >= 0 s")
        if not self.preview <= MAX_PREVIEW:
            raise ValueError(f"preview must be at most {MAX_PREVIEW:g} s (the plan past the window); got "
                             f"{self.preview:g} s")
        if self.reconstruct not in ("auto", "always"):
            raise ValueError(f"reconstruct must be 'auto' or 'always'; got {self.reconstruct!r}")
        check_assistant_model(self.assistant_model)
        if not isinstance(self.human_model, str) or not self.human_model:
            raise ValueError(f"human model must be a registered model's name; got {self.human_model!r}")
        if int(self.adequacy_boot) != self.adequacy_boot or self.adequacy_boot < 0:
            raise ValueError(f"adequacy bootstrap size must be an integer >= 0; got {self.adequacy_boot!r}")
        if int(self.adequacy_seed) != self.adequacy_seed or self.adequacy_seed < 0:
            raise ValueError(f"adequacy seed must be an integer >= 0; got {self.adequacy_seed!r}")


@functools.lru_cache(maxsize=16)
def assistant_law(design: Design, level: str) -> MPCAssistant | None:
    """The assistant of ``level`` in ``design`` (:func:`scioc.models.assistant.build_assistant`), built once; None if unassisted."""
    spec = design.assistant(level)
    return None if spec is None else build_assistant(spec, design)


def with_assistant_model(segment: Segment, condition: str, angle_ref_run, start: int, assistant_model: str,
                         design: Design = STUDY) -> Segment:
    """``segment`` (rows ``start``.. of its run) with the human's model of the assistant.

    ``feedback`` on an assisted level attaches the level's law, its feedforward from the whole run's
    reference (the MPC previews past the segment); otherwise ``segment`` is returned unchanged.
    Raises ValueError for an assistant that holds its torque over several samples (``period_s`` >
    the sample time): that is no state feedback to plan with; use ``exogenous``.
    """
    check_assistant_model(assistant_model)
    law = assistant_law(design, condition)
    if assistant_model != "feedback" or law is None:
        return segment
    try:
        full = human_feedback(law, angle_ref_run)
    except ValueError as exc:
        raise ValueError(f"level {condition}: {exc}; analyse it with --assistant-model exogenous") from None
    return segment._replace(feedback=full.window(start, segment.u_A.shape[0]))


def check_assistant_law(seg: SegmentData, segment: Segment, angle, velocity, path) -> None:
    """Raise :class:`scioc.pipelines.io.StudyFileError` unless the recorded u_A follows the law the human plans with.

    Compared over the window on the recorded (or reconstructed) states: the RMS of
    ``u_A - (-gain @ x + feedforward)`` must be at most ``LAW_RTOL · RMS(u_A) + LAW_ATOL``.
    """
    fb = segment.feedback
    if fb is None:
        return
    K = segment.K
    law = -(fb.gain[0] * angle[:K] + fb.gain[1] * velocity[:K]) + fb.feedforward[:K]
    rec = segment.u_A[:K]
    rms = float(np.sqrt(np.mean((rec - law) ** 2)))
    tol = LAW_RTOL * float(np.sqrt(np.mean(rec**2))) + LAW_ATOL
    if not rms <= tol:
        raise StudyFileError(
            path,
            f"segment {seg.label}: the recorded u_A does not follow the assistant law the experiment declares for "
            f"level {seg.condition} (RMS difference {rms:.3g} N·m over the window, tolerance {tol:.3g} N·m); "
            "check [conditions.assistant] in the experiment file, or analyse with --assistant-model exogenous "
            "(the recorded u_A as a known input)",
            column="u_A",
            row=seg.first_row,
        )


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
    warmup: Warmup | None = None  # the torques before the window, for the lagged human's arm torque (_warmup)


def _window_rows(seg: SegmentData, settings: IdentifySettings, path) -> slice:
    n = seg.t.shape[0]
    if settings.window_start is None:
        return slice(0, n)
    dt = settings.design.dt
    i0 = int(np.searchsorted(seg.t, settings.window_start - 0.5 * dt))
    K = int(round(settings.window_seconds / dt))
    if i0 + K >= n or abs(seg.t[min(i0, n - 1)] - settings.window_start) > 0.5 * dt:
        raise StudyFileError(
            path,
            f"segment {seg.label} covers t = {seg.t[0]:g}..{seg.t[-1]:g} s, which does not "
            f"contain the window {settings.window_start:g}..{settings.window_start + settings.window_seconds:g} s; "
            "choose another --window or use --whole-run (experiment file: [analysis] window_start_s, window_s, "
            "whole)",
            column="t",
            row=seg.first_row,
        )
    return slice(i0, i0 + K + 1)


def prepare_segment(seg: SegmentData, settings: IdentifySettings, plant, path="<table>") -> PreparedSegment:
    """Cut one recorded segment to its window, reconstructing velocity and u_H if needed."""
    rows = _window_rows(seg, settings, path)
    n = seg.t.shape[0]
    dt = settings.design.dt
    i0, i1 = rows.start, rows.stop - 1  # window rows k = 0..K
    K = i1 - i0
    M = min(int(round(settings.preview / dt)), n - 1 - i1)
    need = seg.u_H is None or settings.reconstruct == "always"
    if need:
        m = int(round(settings.margin / dt))
        j0, j1 = max(0, i0 - m), min(n, i1 + 1 + m)
        rec = reconstruct(seg.angle[j0:j1], seg.u_A[j0:j1], plant, resolution=settings.resolution)
        cut = slice(i0 - j0, i1 + 1 - j0)
        angle, velocity, u_H = rec.angle[cut], rec.velocity[cut], rec.u_H[cut]
        sigma_eps, q = rec.sigma_eps, rec.q
        span, state0, smoother = slice(j0, j1), np.array([rec.angle[0], rec.velocity[0]]), rec.smoother
    elif seg.velocity is None:  # measured torque, no velocity: the state follows from the plant
        u_H = seg.u_H[rows]
        total = u_H[:K] + seg.u_A[i0:i1]
        x = propagate(plant, initial_state(seg.angle[rows], total, plant), total)
        angle, velocity = x[:, 0], x[:, 1]
        sigma_eps = q = float("nan")
        span, state0, smoother = rows, x[0].copy(), None
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
    try:
        segment = with_assistant_model(segment, seg.condition, seg.angle_ref, i0, settings.assistant_model,
                                       settings.design)
    except ValueError as exc:
        raise StudyFileError(path, f"segment {seg.label}: {exc}", column="u_A", row=seg.first_row) from None
    check_assistant_law(seg, segment, angle, velocity, path)
    before = rec.u_H[: i0 - j0] if need else seg.u_H[:i0]
    return PreparedSegment(seg, rows, segment, velocity, u_H, angle, need, sigma_eps, q, span, state0, smoother,
                           _warmup(before, from_start=not need or j0 == 0))


def _warmup(before, from_start: bool) -> Warmup | None:
    """The torques before a window, from which the ``delayed`` human's arm torque at its start follows.

    None for a window at its recording's start (at rest, τ_0 = 0); measured torques start at rest.
    A reconstructed torque covers only the margin: the arm torque at its start is taken as that
    first torque (a held torque passes the lag unchanged), and the error decays by |p| per sample
    (:mod:`scioc.models.delayed.lag`; below 3e-3 after the 1-s margin for τ_nm <= 0.1 s).
    """
    if before is None or before.shape[0] == 0:
        return None
    return Warmup(np.ascontiguousarray(before, dtype=float), 0.0 if from_start else float(before[0]))


@dataclass(frozen=True)
class PreparedStudy:
    """A study file cut and reconstructed for the likelihood, one entry per segment (file order)."""

    path: str  # the study file, named in error messages
    settings: IdentifySettings  # what the segments were prepared with
    segments: tuple  # of PreparedSegment
    seconds: float  # wall time of the preparation (mostly the reconstruction), s

    @property
    def subjects(self) -> list:
        return [p.data.subject for p in self.segments]

    @property
    def conditions(self) -> list:
        return [p.data.condition for p in self.segments]

    @property
    def units(self) -> dict:
        """``{(subject, condition): [positions of its segments]}``: each unit's trials, in file order."""
        out: dict = {}
        for i, p in enumerate(self.segments):
            out.setdefault((p.data.subject, p.data.condition), []).append(i)
        return out

    @property
    def labels(self) -> list:
        """``subject/condition`` per segment, with ``/trial`` when the file has trials."""
        return [f"{p.data.subject}/{p.data.condition}" + (f"/{p.data.trial}" if p.data.trial is not None else "")
                for p in self.segments]


def check_design(path, subjects, conditions, levels=CONDITIONS) -> None:
    """Raise :class:`scioc.pipelines.io.InputDataError` (:func:`scioc.models.units.index_study`'s message
    after ``path``) unless every subject has every level (``levels``: baseline first)."""
    try:
        index_study(list(subjects), list(conditions), levels)
    except ValueError as exc:  # the data do not have the design the model needs: bad input (exit 3)
        raise InputDataError(f"{path}: {exc}") from None


def prepare_study(study: Study, settings: IdentifySettings = IdentifySettings(), *,
                  show_progress: bool = False) -> PreparedStudy:
    """Cut and, where needed, reconstruct every segment; StudyFileError if a segment lacks the window."""
    if study.design != settings.design:
        raise ValueError("the study file was validated against another experiment than these settings'")
    plant = discretize(settings.design.dt, settings.design.wheel)
    t0 = time.perf_counter()
    segments = tuple(prepare_segment(s, settings, plant, study.path)
                     for s in progress(study.segments, desc="reconstruct", enabled=show_progress))
    return PreparedStudy(study.path, settings, segments, time.perf_counter() - t0)


def from_angles(prepared, idx) -> bool:
    """The unit is identified from its recorded angles: its torques are reconstructed."""
    return any(prepared[i].reconstructed for i in idx)


def angle_windows(prepared, idx) -> list[AngleWindow]:
    """The unit's windows as the encoder recorded them, for the angle likelihood (:mod:`scioc.models.delayed.angles`)."""
    out = []
    for i in idx:
        p = prepared[i]
        s = p.segment
        out.append(AngleWindow(np.ascontiguousarray(p.data.angle[p.rows], dtype=float), s.angle_ref,
                               None if s.feedback is not None else s.u_A, s.feedback, float(p.velocity[0]), p.warmup))
    return out
