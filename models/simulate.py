"""A faithful simulator of the paper's experiment (Section IV) standing in for its unpublished data.

Each subject performs two 4-minute runs at 100 Hz, manual control (MC) and shared control
(SC), in random order, tracking the same reference (:mod:`scioc.models.reference`). The
simulated human is the max-ent LQ agent of :mod:`scioc.models.maxent` with its own θ per
subject and condition, drawn from :class:`Population`.

Shared control closes two loops. The assistant re-solves its MPC every sample, so it
acts as a fixed state feedback plus a feedforward from the reference
(:func:`scioc.models.assistant.human_feedback`). The simulated human knows it, as a
practised subject feels the assistant's pull as part of the wheel: it plans its
optimal torque on the wheel closed by the assistant's feedback, with the feedforward
as a known input. The run samples the human's max-ent variability from the
linear-Gaussian policy of that plan (``u_H,k = -L_k x_k + f_k + ε_k``,
``ε_k ~ N(0, 1 / 2 S_k)``) while the assistant reacts to the actual state, so every
SC torque sequence is an exact draw of the max-ent model with
:class:`scioc.models.segment.Feedback`. The paper's model, in which the human takes the
recorded u_A as a known sequence, is then misspecified in SC: the recorded u_A
reacts to the human's own variability. The recorded angle is quantized by the
encoder (40000 increments per revolution).

Only what a lab records goes into the study table: angle, reference and u_A. Velocity,
u_H and θ are kept apart as ground truth.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.assistant import MPCAssistant, build_assistant, design_assistant, human_feedback, simulate_closed_loop
from scioc.models.design import (
    ENCODER_STEP,
    MANUAL,
    PREVIEW_SECONDS,
    RUN_SECONDS,
    SHARED,
    STUDY,
    WINDOW_SECONDS,
    Design,
)
from scioc.models.humans import HUMANS, HumanSpec, simulate_human
from scioc.models.lq import lq_policy
from scioc.models.maxent import maxent_noise
from scioc.models.plant import DT_HUMAN, DiscretePlant, discretize
from scioc.models.population import Population, draw_subjects
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Segment, planning_plant


class Run(NamedTuple):
    """One simulated run with what the lab records and what only the simulator knows.

    Attributes
    ----------
    angle : ndarray, shape (K + 1,)
        Encoder angle (quantized), rad.
    u_A : ndarray, shape (K + 1,)
        Assistant torque (0 in MC), N·m; the last entry repeats the held torque.
    true_angle, true_velocity : ndarray, shape (K + 1,)
        rad, rad/s.
    u_H : ndarray, shape (K + 1,)
        Human torque, N·m; the last entry is unused (0).
    """

    angle: np.ndarray
    u_A: np.ndarray
    true_angle: np.ndarray
    true_velocity: np.ndarray
    u_H: np.ndarray


def quantize(angle, step: float = ENCODER_STEP) -> np.ndarray:
    """Encoder reading: the angle rounded to whole increments, rad (error uniform within ±step/2); step 0: unchanged."""
    a = np.asarray(angle, dtype=float)
    return np.round(a / step) * step if step > 0 else a.copy()


def _assisted(condition: str, assistant: MPCAssistant | None) -> MPCAssistant | None:
    """The assistant acting in ``condition``: none in MC, the given one otherwise (None: an unassisted level)."""
    if condition == MANUAL:
        return None
    if condition == SHARED and assistant is None:
        raise ValueError("shared control (SC) needs the assistant")
    return assistant


def simulate_run(
    theta,
    condition: str,
    angle_ref,
    plant: DiscretePlant,
    assistant: MPCAssistant | None,
    rng: np.random.Generator,
    x0=(0.0, 0.0),
    *,
    encoder_step: float = ENCODER_STEP,
) -> Run:
    """Simulate one run of one subject.

    Parameters
    ----------
    theta : array_like, shape (3,)
        True [q11, q22, R].
    condition : str
        The level: ``MC`` is unassisted whatever ``assistant`` is; any other level is
        assisted by ``assistant`` unless it is None.
    angle_ref : array_like, shape (K + 1,)
    plant : DiscretePlant
        The wheel at the recording's sample time.
    assistant : MPCAssistant or None
        The level's assistant; it must re-solve every sample (``hold == 1``).
    rng : numpy.random.Generator
    x0 : array_like, shape (2,)
        Initial state (the wheel at rest by default).
    encoder_step : float
        Encoder increment, rad (0: the angle is not quantized).

    Returns
    -------
    Run
    """
    ref = np.asarray(angle_ref, dtype=float)
    K = ref.shape[0] - 1
    x0 = np.asarray(x0, dtype=float)
    asst = _assisted(condition, assistant)
    if asst is None:
        pol = lq_policy(plant, theta, ref, np.zeros(K))
    else:
        fb = human_feedback(asst, ref)
        pol = lq_policy(planning_plant(plant, fb.gain), theta, ref, fb.feedforward)
    run = simulate_closed_loop(plant, asst, x0, ref, pol.L, pol.f, maxent_noise(pol, rng))
    u_A = np.append(run.u_A, run.u_A[-1] if K > 0 else 0.0)
    return Run(
        angle=quantize(run.x[:, 0], encoder_step),
        u_A=u_A,
        true_angle=run.x[:, 0],
        true_velocity=run.x[:, 1],
        u_H=np.append(run.u_H, 0.0),
    )


class SimulatedSegment(NamedTuple):
    """One subject × condition run (one trial) of the simulated study."""

    subject: str
    condition: str
    run_index: int
    theta: np.ndarray
    run: Run
    trial: int | None = None
    human: HumanSpec | None = None


def simulate_human_run(human: str, theta, condition: str, angle_ref, plant: DiscretePlant,
                       assistant: MPCAssistant | None, rng: np.random.Generator, *,
                       encoder_step: float = ENCODER_STEP, design: Design = STUDY,
                       subject: HumanSpec | None = None) -> Run:
    """One run of the named human of :data:`scioc.models.humans.HUMANS`, recorded like :func:`simulate_run`.

    ``maxent`` is :func:`simulate_run` itself (the paper's agent, bit for bit); every other
    name is a human the max-ent likelihood does not describe (negative controls).
    ``design`` gives the wheel of the lagged humans. ``subject`` is the subject's own draw
    of a human that varies between subjects (:meth:`scioc.models.humans.HumanSpec.for_subject`).
    """
    spec = HUMANS.get(human)
    if spec is None:
        raise ValueError(f"unknown human {human!r}; choose one of {', '.join(HUMANS)}")
    if subject is not None:
        spec = subject
    if human == "maxent":
        return simulate_run(theta, condition, angle_ref, plant, assistant, rng, encoder_step=encoder_step)
    run = simulate_human(spec, theta, condition, angle_ref, plant, _assisted(condition, assistant), rng,
                         params=design.wheel)
    K = run.u_H.shape[0]
    return Run(angle=quantize(run.x[:, 0], encoder_step), u_A=np.append(run.u_A, run.u_A[-1] if K > 0 else 0.0),
               true_angle=run.x[:, 0], true_velocity=run.x[:, 1], u_H=np.append(run.u_H, 0.0))


def simulate_study(
    n_subjects: int,
    rng: np.random.Generator,
    population: Population = Population(),
    seconds: float = RUN_SECONDS,
    human: str = "maxent",
    design: Design = STUDY,
) -> tuple[np.ndarray, list[SimulatedSegment]]:
    """Simulate the whole experiment.

    Parameters
    ----------
    n_subjects : int
    rng : numpy.random.Generator
        Every subject gets an independent child generator spawned from it, so a subject's
        data do not depend on how many subjects follow; each of its runs (level × trial)
        gets a child of that.
    population : Population
    seconds : float
        Length of each run, s (240: 4 minutes).
    human : str
        Which simulated human (:data:`scioc.models.humans.HUMANS`); ``maxent`` is the paper's
        agent, the others are negative controls the likelihood does not describe.
    design : Design
        The experiment: sample time, wheel, encoder, levels with their assistants, and
        ``trials`` runs per subject × level (the paper's study by default). The
        population's θ (stated at 100 Hz) is scaled by ``design.r_scale``, so that the
        same subjects recorded at another rate have the same θ1, θ2 and R at 100 Hz.

    Returns
    -------
    t : ndarray, shape (K + 1,)
        Sample times, s.
    segments : list of SimulatedSegment
        Subject by subject, in the order the runs were performed (a level's trials one
        after another); ``trial`` is None with one trial per level.
    """
    if human not in HUMANS:
        raise ValueError(f"unknown human {human!r}; choose one of {', '.join(HUMANS)}")
    plant = discretize(design.dt, design.wheel)
    levels = design.ordered_levels
    laws = [None if design.assistant(v) is None else build_assistant(design.assistant(v), design) for v in levels]
    ref = reference_trajectory(seconds, design.dt)
    subjects = draw_subjects(population, n_subjects, rng, len(levels))
    children = rng.spawn(len(subjects))
    width = max(2, len(str(len(subjects))))
    T = design.trials
    scale = design.r_scale  # the population's θ is per 10-ms sample (models.design: θ ∝ dt); 1.0 at 100 Hz
    out = []
    for i, (sub, child) in enumerate(zip(subjects, children)):
        if scale != 1.0:
            sub = sub._replace(thetas=tuple(th * scale for th in sub.thetas))
        name = f"S{i + 1:0{width}d}"
        runs = child.spawn(len(levels) * T)  # level-major: level j, trial t is runs[j * T + t]
        # A human that varies between subjects draws this subject's delay and lag from the next child
        # (spawned after the runs', so the runs' streams are those of every other human).
        spec = HUMANS[human].for_subject(child.spawn(1)[0]) if HUMANS[human].varies else None
        n = 0
        for j in sub.order:
            for t in range(T):
                run = simulate_human_run(human, sub.thetas[j], levels[j], ref.angle, plant, laws[j],
                                         runs[j * T + t], encoder_step=design.encoder_step, design=design,
                                         subject=spec)
                out.append(SimulatedSegment(name, levels[j], n, sub.thetas[j], run, t + 1 if T > 1 else None,
                                            spec or HUMANS[human]))
                n += 1
    return ref.t, out


class Windows(NamedTuple):
    """Simulated analysis windows with the true torques, ready for the likelihood.

    Attributes
    ----------
    subjects, conditions : list of str
    segments : list of Segment
        True x0, u_H and recorded u_A; SC segments carry the assistant's Feedback.
    theta : ndarray, shape (3, n)
        True [q11, q22, R] per segment.
    """

    subjects: list
    conditions: list
    segments: list
    theta: np.ndarray


def simulate_windows(n_subjects: int, rng: np.random.Generator, population: Population = Population(), *,
                     K: int = round(WINDOW_SECONDS / DT_HUMAN),
                     preview: int = round(PREVIEW_SECONDS / DT_HUMAN)) -> Windows:
    """Small studies straight from the simulator: each subject's MC and SC runs, first K steps.

    Each run is simulated over K + preview + 200 samples of the study reference (so the
    simulated human plans past what the likelihood sees, as in a real run) and cut to
    its first K observed steps plus ``preview`` planning steps (by default the design's
    15-s window and 2-s preview). No encoder, no reconstruction: the true state and
    torque, for tests and calibration.
    """
    plant = discretize(DT_HUMAN)
    assistant = design_assistant()
    ref = reference_trajectory(DT_HUMAN * (K + preview + 200)).angle
    fb = human_feedback(assistant, ref)
    subjects, conditions, segments, thetas = [], [], [], []
    width = max(2, len(str(int(n_subjects))))
    for i, sub in enumerate(draw_subjects(population, n_subjects, rng)):
        for cond, theta in ((MANUAL, sub.mc), (SHARED, sub.sc)):  # the paper's two levels
            run = simulate_run(theta, cond, ref, plant, assistant, rng)
            x0 = np.array([run.true_angle[0], run.true_velocity[0]])
            feedback = fb.window(0, K + preview) if cond == SHARED else None
            segments.append(Segment(x0, ref[: K + preview + 1], run.u_H[:K], run.u_A[: K + preview], feedback))
            subjects.append(f"S{i + 1:0{width}d}")
            conditions.append(cond)
            thetas.append(theta)
    return Windows(subjects, conditions, segments, np.column_stack(thetas))
