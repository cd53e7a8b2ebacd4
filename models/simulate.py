"""A simulator of the paper's experiment (Section IV) standing in for its unpublished data.

Each subject runs every level in random order as the max-ent LQ agent with its own θ per level
(:class:`Population`). In SC it plans with the assistant's law, so each SC run is an exact draw of the
max-ent model with :class:`scioc.models.segment.Feedback` (docs/decisions/assistant-as-state-feedback.md).
The lab's record is the encoder angle, reference and u_A; velocity, u_H and θ are ground truth.
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
from scioc.models.humans import HUMANS, PAPER_AGENT, HumanSpec, simulate_human
from scioc.models.lq import lq_policy
from scioc.models.maxent import maxent_noise
from scioc.models.plant import DT_HUMAN, DiscretePlant, discretize
from scioc.models.population import Population, draw_subjects
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Segment, planning_plant


class Run(NamedTuple):
    """One run, each (K + 1,): recorded ``angle`` (encoder, rad) and ``u_A`` (N·m; the last repeats the
    held torque); ground truth ``true_angle``, ``true_velocity`` (rad, rad/s) and ``u_H`` (N·m; last 0)."""

    angle: np.ndarray
    u_A: np.ndarray
    true_angle: np.ndarray
    true_velocity: np.ndarray
    u_H: np.ndarray


def quantize(angle, step: float = ENCODER_STEP) -> np.ndarray:
    """Encoder reading: the angle rounded to whole increments ``step``, rad (0: unchanged)."""
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
    """Simulate one run of one subject with true θ = [q11, q22, R]; ``MC`` is unassisted, another level
    assisted by ``assistant`` unless None. ``angle_ref`` (K + 1,) and ``encoder_step`` in rad, ``x0`` in
    rad, rad/s."""
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
    """One run of a human of :data:`scioc.models.humans.HUMANS`, recorded like :func:`simulate_run`
    (``maxent`` is that function). ``design`` gives the lagged humans' wheel; ``subject`` is this subject's
    draw of a human that varies between subjects."""
    spec = HUMANS.get(human)
    if spec is None:
        raise ValueError(f"unknown human {human!r}; choose one of {', '.join(HUMANS)}")
    if subject is not None:
        spec = subject
    if human == PAPER_AGENT:
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
    """Simulate the whole experiment: sample times ``t`` (K + 1,), s, and the runs in performed order.

    ``rng`` spawns a child per subject (its data do not depend on how many follow) and that one a child per
    run. ``human``: a name of :data:`scioc.models.humans.HUMANS`; ``seconds``: run length, s. The
    population's θ is scaled by ``design.r_scale``. ``trial`` is None with one trial per level.
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
        # Spawned after the runs' children, so the runs' streams are those of every other human.
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
    """Simulated windows with true x0 and u_H (SC segments with the assistant's Feedback), and true θ (3, n)."""

    subjects: list
    conditions: list
    segments: list
    theta: np.ndarray


def simulate_windows(n_subjects: int, rng: np.random.Generator, population: Population = Population(), *,
                     K: int = round(WINDOW_SECONDS / DT_HUMAN),
                     preview: int = round(PREVIEW_SECONDS / DT_HUMAN)) -> Windows:
    """Small studies for tests and calibration: each subject's MC and SC runs with true state and torque,
    simulated past what the likelihood sees and cut to K observed plus ``preview`` planning steps."""
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
