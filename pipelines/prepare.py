"""The preparation step shared by ``scioc identify``, ``scioc fit`` and ``scioc loglik``.

For each recorded segment: take the analysis window (the experiment's, by default the
paper's 15 s from 3:30; any window or the whole trial on request), reconstruct velocity
and u_H from the angle where the file lacks the torque (:mod:`scioc.models.reconstruct`, over
the window plus a margin), and cut the arrays the max-ent likelihood needs
(:class:`scioc.models.segment.Segment`), with the ``preview`` seconds the human's plan looks
past the window (default 2 s, the time a point of the reference takes to cross the
screen; 0 is the paper's horizon). A measured u_H is used as measured; where the file
has no velocity beside it, the initial state is fitted to the angles with the measured
torques (:func:`scioc.models.reconstruct.initial_state`) and the velocity follows from the plant.

On an assisted level the human may model the assistant two ways (``assistant_model``).
``feedback`` (default): the human knows the assistant's law (the experiment's
``[conditions.assistant]`` entry; the paper's MPC, Section IV-D, by default) and plans on
the wheel it closes, with its reference feedforward as the known input
(:class:`scioc.models.segment.Feedback`); the simulator's humans do this. The recorded u_A must
then follow that law (:func:`check_assistant_law`). ``exogenous`` is the paper's
Eq. 15-16: the recorded u_A is a known input sequence. In closed loop the recorded u_A
reacts to the human's own torque noise, which the exogenous model lets the human
anticipate; on the simulated study, from the true torques, it puts log θ1 in SC about
0.55 too low (measured in the report's ground-truth section).

The ``delayed`` human (``human_model``, :mod:`scioc.models.delayed`) has an arm torque that
lags its commands; at a window's start it follows from the torques before the window, so
each prepared segment keeps them (:class:`scioc.models.delayed.lag.Warmup`; see
:func:`_warmup` for which segments have them and from where).

:func:`prepare_study` does this once per study; ``scioc run`` passes its result to both
the identification and the Bayesian fit.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from scioc.models.adequacy import N_BOOT
from scioc.models.assistant import MPCAssistant, build_assistant, human_feedback
from scioc.models.delayed.lag import Warmup
from scioc.models.design import CONDITIONS, PREVIEW_SECONDS, STUDY, WINDOW_SECONDS, WINDOW_START, Design
from scioc.models.plant import discretize, propagate
from scioc.models.reconstruct import DEFAULT_RESOLUTION, FixedReconstruction, initial_state, reconstruct
from scioc.models.segment import Segment
from scioc.models.units import index_study
from scioc.pipelines.io import InputDataError, SegmentData, Study, StudyFileError
from scioc.pipelines.progress import progress

#: How the human on an assisted level may model the assistant (see the module docstring).
ASSISTANT_MODELS = ("feedback", "exogenous")
#: The human models (README "The model"): the paper's max-ent agent, and the ``delayed``
#: human with perceptual delay, neuromuscular lag and motor noise (:mod:`scioc.models.delayed`).
HUMAN_MODELS = ("maxent", "delayed")
#: Measurement resolution the reconstruction assumes for an angle that is not quantized
#: (``encoder.counts_per_rev = 0``), rad: a sensor's noise floor, far below any encoder's step.
UNQUANTIZED_RESOLUTION = 1e-6
#: The recorded u_A follows the declared law if the RMS of their difference over the
#: window is at most this fraction of the recorded u_A's RMS plus :data:`LAW_ATOL`
#: (measured on the simulated study from the reconstructed states: about 0.01).
LAW_RTOL = 0.1
#: Absolute part of the law check's tolerance, N·m.
LAW_ATOL = 0.01


def check_assistant_model(name: str) -> None:
    """Raise ValueError unless ``name`` is one of :data:`ASSISTANT_MODELS`."""
    if name not in ASSISTANT_MODELS:
        raise ValueError(f"assistant model must be one of {ASSISTANT_MODELS}; got {name!r}")


def check_human_model(name: str) -> None:
    """Raise ValueError unless ``name`` is one of :data:`HUMAN_MODELS`."""
    if name not in HUMAN_MODELS:
        raise ValueError(f"human model must be one of {HUMAN_MODELS}; got {name!r}")


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
        ``auto`` (only when u_H is missing) or ``always``.
    resolution : float
        Encoder increment, rad (sets the reconstruction's measurement noise).
    assistant_model : str
        ``feedback`` (the human plans with the assistant's law; default) or
        ``exogenous`` (the recorded u_A is a known input, the paper's Eq. 15-16).
    adequacy_boot : int
        Bootstrap data sets per segment for the model-adequacy checks
        (:mod:`scioc.pipelines.adequacy`; default 49; 0 skips them and the verdict reads
        "not checked").
    adequacy_seed : int
        Root seed of the adequacy bootstrap.
    human_model : str
        ``maxent`` (the paper's human; default) or ``delayed`` (perceptual delay,
        neuromuscular lag and motor noise; :data:`HUMAN_MODELS`).
    design : Design
        The experiment: sample time, wheel, levels and their assistants
        (:data:`scioc.models.design.STUDY` without an experiment file). :meth:`for_design`
        takes the window, preview and encoder resolution from it too.
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
    human_model: str = "maxent"
    design: Design = STUDY

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
        if self.reconstruct not in ("auto", "always"):
            raise ValueError(f"reconstruct must be 'auto' or 'always'; got {self.reconstruct!r}")
        check_assistant_model(self.assistant_model)
        check_human_model(self.human_model)
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

    ``feedback`` on an assisted level: the level's law, its feedforward from the run's
    whole reference ``angle_ref_run`` (the MPC previews past the segment). Otherwise
    unchanged (the recorded u_A as a known input).

    Raises
    ------
    ValueError
        If the level's assistant holds its torque over several samples (an MPC with
        ``period_s`` > the sample time): it is then not a state feedback the human can
        plan with; use ``exogenous``.
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

    A window at the start of its recording (whole trials) starts at rest: None (τ_0 = 0).
    Measured torques run from the recording's start, where the arm is at rest (τ = 0). A
    reconstructed torque exists only over the reconstruction's margin before the window;
    the arm torque at the margin's start is then taken as that first torque (a held
    torque passes the lag unchanged), and its error decays through the arm-torque
    recursion by |p| per sample (:mod:`scioc.models.delayed.lag`: below 3e-3 after the default
    1-s margin for τ_nm <= 0.1 s, and the residual ``u - τ`` it starts from is itself
    small where the lag is slow).
    """
    if before is None or before.shape[0] == 0:
        return None
    return Warmup(np.ascontiguousarray(before, dtype=float), 0.0 if from_start else float(before[0]))


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
    """Raise :class:`scioc.pipelines.io.InputDataError` unless every subject has every level.

    ``levels``: baseline first (default MC, SC). The message is that of
    :func:`scioc.models.units.index_study` (a subject without one of the levels, or a level
    with no segment at all), prefixed with the file ``path``.
    """
    try:
        index_study(list(subjects), list(conditions), levels)
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
    if study.design != settings.design:
        raise ValueError("the study file was validated against another experiment than these settings'")
    plant = discretize(settings.design.dt, settings.design.wheel)
    t0 = time.perf_counter()
    segments = tuple(prepare_segment(s, settings, plant, study.path)
                     for s in progress(study.segments, desc="reconstruct", enabled=show_progress))
    return PreparedStudy(study.path, settings, segments, time.perf_counter() - t0)
