"""A faithful simulator of the paper's experiment (Section IV) standing in for its unpublished data.

Each subject performs two 4-minute runs at 100 Hz, manual control (MC) and shared control
(SC), in random order, tracking the same reference (:mod:`models.reference`). The
simulated human is the max-ent LQ agent of :mod:`models.maxent` with its own θ per
subject and condition, drawn from :class:`Population`.

Shared control closes two loops. The assistant re-solves its MPC every sample, so it
acts as a fixed state feedback plus a feedforward from the reference
(:func:`models.assistant.human_feedback`). The simulated human knows it, as a
practised subject feels the assistant's pull as part of the wheel: it plans its
optimal torque on the wheel closed by the assistant's feedback, with the feedforward
as a known input. The run samples the human's max-ent variability from the
linear-Gaussian policy of that plan (``u_H,k = -L_k x_k + f_k + ε_k``,
``ε_k ~ N(0, 1 / 2 S_k)``) while the assistant reacts to the actual state, so every
SC torque sequence is an exact draw of the max-ent model with
:class:`models.segment.Feedback`. The paper's model, in which the human takes the
recorded u_A as a known sequence, is then misspecified in SC: the recorded u_A
reacts to the human's own variability. The recorded angle is quantized by the
encoder (40000 increments per revolution).

Only what a lab records goes into the study table: angle, reference and u_A. Velocity,
u_H and θ are kept apart as ground truth.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np

from models.assistant import MPCAssistant, design_assistant, human_feedback, simulate_closed_loop
from models.cost import from_log_normalized
from models.design import ENCODER_STEP, MANUAL, PREVIEW_SECONDS, RUN_SECONDS, SHARED, WINDOW_SECONDS
from models.humans import HUMANS, simulate_human
from models.lq import lq_policy
from models.maxent import maxent_noise
from models.plant import DT_HUMAN, DiscretePlant, discretize
from models.reference import reference_trajectory
from models.segment import Segment, planning_plant


@dataclass(frozen=True)
class Population:
    """The population θ per subject and condition is drawn from (all logs natural).

    For subject i::

        log θ1[i, MC] ~ N(log_theta1_mc, sd_log_theta1)          θ1 = q11 / R, 1/rad²
        log θ1[i, SC] = log θ1[i, MC] + beta + N(0, sd_change)
        log R[i, MC]  ~ N(log_R, sd_log_R)                      R, 1/(N·m)²
        log R[i, SC]  = log R[i, MC] + gamma + N(0, sd_R_change)
        θ2[i, c] = q22 / R = theta2                             (the paper found 0)

    The defaults make the paper's qualitative findings appear: q22 = 0; in SC the
    normalized angle weight drops to about half (β = -0.7) for nearly every subject,
    with between-subject spread. With R around 20 the max-ent torque variability is about
    0.16 N·m per 10-ms sample, and the tracking error RMS about 0.02-0.05 rad for the
    0.2-rad RMS reference.

    Attributes
    ----------
    log_theta1_mc : float
        Mean of log θ1 in MC (default log 20).
    sd_log_theta1 : float
        Between-subject SD of log θ1 (default 0.5).
    beta : float
        Mean SC shift of log θ1 (default -0.7).
    sd_change : float
        Between-subject SD of the SC shift (default 0.2).
    log_R : float
        Mean of log R in MC (default log 20).
    sd_log_R : float
        Between-subject SD of log R (default 0.3).
    gamma : float
        Mean SC shift of log R (default 0).
    sd_R_change : float
        Between-subject SD of the SC shift of log R (default 0.1).
    theta2 : float
        q22 / R for everyone (default 0).
    """

    log_theta1_mc: float = float(np.log(20.0))
    sd_log_theta1: float = 0.5
    beta: float = -0.7
    sd_change: float = 0.2
    log_R: float = float(np.log(20.0))
    sd_log_R: float = 0.3
    gamma: float = 0.0
    sd_R_change: float = 0.1
    theta2: float = 0.0

    def __post_init__(self):
        for name, value in asdict(self).items():
            if not np.isfinite(value):
                raise ValueError(f"population parameter {name} must be finite; got {value!r}")
            if name.startswith("sd") and value < 0:
                raise ValueError(f"population parameter {name} must be >= 0; got {value!r}")
        if self.theta2 < 0:
            raise ValueError(f"population parameter theta2 must be >= 0; got {self.theta2!r}")


class SubjectTheta(NamedTuple):
    """True cost parameters of one subject: θ = [q11, q22, R] per condition, and run order."""

    mc: np.ndarray
    sc: np.ndarray
    sc_first: bool


def draw_subjects(population: Population, n_subjects: int, rng: np.random.Generator) -> list[SubjectTheta]:
    """Draw θ_MC, θ_SC and the run order for each subject.

    Parameters
    ----------
    population : Population
    n_subjects : int
    rng : numpy.random.Generator

    Returns
    -------
    list of SubjectTheta
    """
    if int(n_subjects) != n_subjects or n_subjects < 1:
        raise ValueError(f"n_subjects must be a positive integer; got {n_subjects!r}")
    p = population
    out = []
    for _ in range(int(n_subjects)):
        z = rng.standard_normal(4)
        lt1_mc = p.log_theta1_mc + p.sd_log_theta1 * z[0]
        lt1_sc = lt1_mc + p.beta + p.sd_change * z[1]
        lr_mc = p.log_R + p.sd_log_R * z[2]
        lr_sc = lr_mc + p.gamma + p.sd_R_change * z[3]
        sc_first = bool(rng.integers(0, 2))
        out.append(SubjectTheta(from_log_normalized(lt1_mc, p.theta2, lr_mc),
                                from_log_normalized(lt1_sc, p.theta2, lr_sc), sc_first))
    return out


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
    """Encoder reading: the angle rounded to whole increments, rad (error uniform within ±step/2)."""
    return np.round(np.asarray(angle, dtype=float) / step) * step


def simulate_run(
    theta,
    condition: str,
    angle_ref,
    plant: DiscretePlant,
    assistant: MPCAssistant,
    rng: np.random.Generator,
    x0=(0.0, 0.0),
) -> Run:
    """Simulate one run of one subject.

    Parameters
    ----------
    theta : array_like, shape (3,)
        True [q11, q22, R].
    condition : {"MC", "SC"}
    angle_ref : array_like, shape (K + 1,)
    plant : DiscretePlant
        0.01-s wheel.
    assistant : MPCAssistant
        Used in SC only; it must re-solve every sample (``hold == 1``).
    rng : numpy.random.Generator
    x0 : array_like, shape (2,)
        Initial state (the wheel at rest by default).

    Returns
    -------
    Run
    """
    ref = np.asarray(angle_ref, dtype=float)
    K = ref.shape[0] - 1
    x0 = np.asarray(x0, dtype=float)
    if condition == MANUAL:
        pol, asst = lq_policy(plant, theta, ref, np.zeros(K)), None
    elif condition == SHARED:
        fb = human_feedback(assistant, ref)
        pol, asst = lq_policy(planning_plant(plant, fb.gain), theta, ref, fb.feedforward), assistant
    else:
        raise ValueError(f"condition must be {MANUAL!r} or {SHARED!r}; got {condition!r}")
    run = simulate_closed_loop(plant, asst, x0, ref, pol.L, pol.f, maxent_noise(pol, rng))
    u_A = np.append(run.u_A, run.u_A[-1] if K > 0 else 0.0)
    return Run(
        angle=quantize(run.x[:, 0]),
        u_A=u_A,
        true_angle=run.x[:, 0],
        true_velocity=run.x[:, 1],
        u_H=np.append(run.u_H, 0.0),
    )


class SimulatedSegment(NamedTuple):
    """One subject × condition run of the simulated study."""

    subject: str
    condition: str
    run_index: int
    theta: np.ndarray
    run: Run


def simulate_human_run(human: str, theta, condition: str, angle_ref, plant: DiscretePlant, assistant: MPCAssistant,
                       rng: np.random.Generator) -> Run:
    """One run of the named human of :data:`models.humans.HUMANS`, recorded like :func:`simulate_run`.

    ``maxent`` is :func:`simulate_run` itself (the paper's agent, bit for bit); every other
    name is a human the max-ent likelihood does not describe (negative controls).
    """
    spec = HUMANS.get(human)
    if spec is None:
        raise ValueError(f"unknown human {human!r}; choose one of {', '.join(HUMANS)}")
    if human == "maxent":
        return simulate_run(theta, condition, angle_ref, plant, assistant, rng)
    run = simulate_human(spec, theta, condition, angle_ref, plant, assistant if condition == SHARED else None, rng)
    K = run.u_H.shape[0]
    return Run(angle=quantize(run.x[:, 0]), u_A=np.append(run.u_A, run.u_A[-1] if K > 0 else 0.0),
               true_angle=run.x[:, 0], true_velocity=run.x[:, 1], u_H=np.append(run.u_H, 0.0))


def simulate_study(
    n_subjects: int,
    rng: np.random.Generator,
    population: Population = Population(),
    seconds: float = RUN_SECONDS,
    human: str = "maxent",
) -> tuple[np.ndarray, list[SimulatedSegment]]:
    """Simulate the whole experiment.

    Parameters
    ----------
    n_subjects : int
    rng : numpy.random.Generator
        Every subject gets an independent child generator spawned from it, so a subject's
        data do not depend on how many subjects follow.
    population : Population
    seconds : float
        Length of each run, s (240: 4 minutes).
    human : str
        Which simulated human (:data:`models.humans.HUMANS`); ``maxent`` is the paper's
        agent, the others are negative controls the likelihood does not describe.

    Returns
    -------
    t : ndarray, shape (K + 1,)
        Sample times, s.
    segments : list of SimulatedSegment
        Subject by subject, in the order the runs were performed.
    """
    plant = discretize(DT_HUMAN)
    assistant = design_assistant()
    ref = reference_trajectory(seconds)
    subjects = draw_subjects(population, n_subjects, rng)
    children = rng.spawn(len(subjects))
    width = max(2, len(str(len(subjects))))
    out = []
    for i, (sub, child) in enumerate(zip(subjects, children)):
        name = f"S{i + 1:0{width}d}"
        order = (SHARED, MANUAL) if sub.sc_first else (MANUAL, SHARED)
        runs = dict(zip((MANUAL, SHARED), child.spawn(2)))
        for j, cond in enumerate(order):
            theta = sub.mc if cond == MANUAL else sub.sc
            run = simulate_human_run(human, theta, cond, ref.angle, plant, assistant, runs[cond])
            out.append(SimulatedSegment(name, cond, j, theta, run))
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
        for cond, theta in ((MANUAL, sub.mc), (SHARED, sub.sc)):
            run = simulate_run(theta, cond, ref, plant, assistant, rng)
            x0 = np.array([run.true_angle[0], run.true_velocity[0]])
            feedback = fb.window(0, K + preview) if cond == SHARED else None
            segments.append(Segment(x0, ref[: K + preview + 1], run.u_H[:K], run.u_A[: K + preview], feedback))
            subjects.append(f"S{i + 1:0{width}d}")
            conditions.append(cond)
            thetas.append(theta)
    return Windows(subjects, conditions, segments, np.column_stack(thetas))
