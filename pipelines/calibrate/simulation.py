"""What both SBC levels share: the fitted wheel, the window, the exact demonstration per level, a per-worker cache.

Runs inside Dask workers, which cache compiled models keyed by everything that changes them
(:func:`cached`): compiling takes longer than a unit fit. Everything follows the calibrated experiment
(the paper's study by default): sample time, wheel, levels, assistants and analysis window. The negative
controls fit the same draws wrongly: ``inertia`` with the wheel inertia :data:`INERTIA_ERROR` too high,
``ignore-uA`` with the assistant's torque given to the human.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from scioc.models.assistant import human_feedback
from scioc.models.bayes.op import DATA_NAMES
from scioc.models.design import STUDY, Design
from scioc.models.maxent import sample_maxent
from scioc.models.plant import discretize
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Segment, planning_plant, prepare_batch
from scioc.pipelines.prepare import assistant_law

#: Relative error of the inertia in the ``inertia`` negative control.
INERTIA_ERROR = 0.10

_CACHE: dict = {}


def cached(key, build: Callable[[], object]):
    """The value cached under ``key`` in this worker process, built by ``build()`` the first time."""
    if key not in _CACHE:
        _CACHE[key] = build()
    return _CACHE[key]


def fit_plant(negative_control, design: Design = STUDY):
    """The wheel the fit assumes: the experiment's, or 10 % too heavy for the ``inertia`` negative control."""
    wheel = design.wheel
    if negative_control == "inertia":
        wheel = wheel._replace(inertia=wheel.inertia * (1 + INERTIA_ERROR))
    return discretize(design.dt, wheel)


def window_start(design: Design = STUDY) -> float:
    """Where the calibrated windows start on the study reference, s: the analysis window, or 0 for whole trials."""
    return 0.0 if design.whole else design.window_start


def window_inputs(K: int, design: Design = STUDY):
    """``(ref, {level: Feedback or None})``: the window's reference (K + 1,) and each level's assistant feedback."""

    def build():
        dt = design.dt
        i0 = int(round(window_start(design) / dt))
        ref = reference_trajectory(window_start(design) + K * dt + 2.0, dt).angle  # the MPC previews 1 s
        laws = {}
        for level in design.ordered_levels:
            law = assistant_law(design, level)
            laws[level] = None if law is None else human_feedback(law, ref).window(i0, K)
        return np.ascontiguousarray(ref[i0 : i0 + K + 1]), laws

    return cached(("ref", K, design), build)


def rest_segment(K: int, design: Design = STUDY) -> Segment:
    """A placeholder segment of the window (zero torques) that gives a model its shapes before the data."""
    ref = window_inputs(K, design)[0]
    return Segment(np.array([ref[0], 0.0]), ref, np.zeros(K), np.zeros(K))


def simulate_unit(theta, condition: str, K: int, negative_control, rng: np.random.Generator,
                  design: Design = STUDY) -> Segment:
    """One exact max-ent demonstration over the analysis window, as the fit will see it.

    On an assisted level the human plans on the wheel the assistant's law closes, and the recorded
    u_A is ``-gain @ x_k + feedforward_k`` along the draw; ``ignore-uA`` adds it to u_H instead.
    """
    ref, laws = window_inputs(K, design)
    fb = laws[condition]
    plant = discretize(design.dt, design.wheel)
    x0 = np.array([ref[0], 0.0])
    if fb is None:
        demo = sample_maxent(theta, x0, ref, np.zeros(K), plant, rng)
        u_A, feedback = np.zeros(K), None
    else:
        demo = sample_maxent(theta, x0, ref, fb.feedforward, planning_plant(plant, fb.gain), rng)
        u_A, feedback = fb.feedforward - demo.x[:K] @ fb.gain, fb
    if negative_control == "ignore-uA":
        return Segment(x0, ref, demo.u_H + u_A, np.zeros(K))
    return Segment(x0, ref, demo.u_H, u_A, feedback)


def fitted_batch(segments, negative_control, design: Design = STUDY):
    """The segments as the (possibly wrong) fit sees them, and the data by the names of the models' containers."""
    batch = prepare_batch(fit_plant(negative_control, design), list(segments))
    return batch, {name: getattr(batch, name) for name in DATA_NAMES}


def config_design(config) -> Design:
    """The experiment a calibration configuration calibrates (its ``experiment``; the paper's study without one)."""
    if config.experiment is None:
        return STUDY
    from scioc.pipelines.experiment import parse_experiment

    return parse_experiment(config.experiment, "<calibration experiment>")
