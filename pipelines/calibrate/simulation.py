"""What both SBC levels share: the fitted wheel, the study window, the exact SC/MC demonstration, a per-worker cache.

Runs inside Dask workers. Compiled models and other slow-to-build objects are cached per
worker process (compiling takes seconds, a unit fit a fraction of one), keyed by
everything that changes them (:func:`cached`).

Negative controls (same draws, same sizes, a wrong fit): ``inertia`` fits with the wheel
inertia 10 % too high (0.044 instead of 0.04 kg·m²), ``ignore-uA`` attributes the
assistant's torque to the human.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from models.assistant import design_assistant, human_feedback
from models.bayes.op import DATA_NAMES
from models.design import MANUAL, STUDY, WINDOW_START
from models.maxent import sample_maxent
from models.plant import DT_HUMAN, WheelParameters, discretize
from models.reference import reference_trajectory
from models.segment import Segment, planning_plant, prepare_batch

#: Relative error of the inertia in the ``inertia`` negative control.
INERTIA_ERROR = 0.10

_CACHE: dict = {}


def cached(key, build: Callable[[], object]):
    """The value cached under ``key`` in this worker process, built by ``build()`` the first time."""
    if key not in _CACHE:
        _CACHE[key] = build()
    return _CACHE[key]


def fit_plant(negative_control):
    """The wheel the fit assumes: the study's, or 10 % too heavy for the ``inertia`` negative control."""
    if negative_control == "inertia":
        return discretize(DT_HUMAN, WheelParameters(inertia=STUDY.wheel.inertia * (1 + INERTIA_ERROR)))
    return discretize(DT_HUMAN)


def window_inputs(K: int):
    """The window's reference (K + 1,) and the assistant's feedback over it (gain, feedforward (K,))."""

    def build():
        i0 = int(round(WINDOW_START / DT_HUMAN))
        ref = reference_trajectory(WINDOW_START + K * DT_HUMAN + 2.0).angle  # the assistant previews 1 s
        fb = human_feedback(design_assistant(), ref)
        return np.ascontiguousarray(ref[i0 : i0 + K + 1]), fb.window(i0, K)

    return cached(("ref", K), build)


def rest_segment(K: int) -> Segment:
    """A placeholder segment of the window (zero torques) that gives a model its shapes before the data."""
    ref = window_inputs(K)[0]
    return Segment(np.array([ref[0], 0.0]), ref, np.zeros(K), np.zeros(K))


def simulate_unit(theta, condition: str, K: int, negative_control, rng: np.random.Generator) -> Segment:
    """One exact max-ent demonstration over the analysis window, as the fit will see it.

    MC: u_A = 0. SC: the human plans with the assistant's law on the closed wheel (the
    simulator's human), the assistant's recorded torque is ``-gain @ x_k + feedforward_k``
    along the sampled trajectory. The returned segment carries the Feedback the
    likelihood plans with, except for ``ignore-uA``, which attributes the assistant's
    torque to the human and plans without it.
    """
    ref, fb = window_inputs(K)
    plant = discretize(DT_HUMAN)
    x0 = np.array([ref[0], 0.0])
    if condition == MANUAL:
        demo = sample_maxent(theta, x0, ref, np.zeros(K), plant, rng)
        u_A, feedback = np.zeros(K), None
    else:
        demo = sample_maxent(theta, x0, ref, fb.feedforward, planning_plant(plant, fb.gain), rng)
        u_A, feedback = fb.feedforward - demo.x[:K] @ fb.gain, fb
    if negative_control == "ignore-uA":
        return Segment(x0, ref, demo.u_H + u_A, np.zeros(K))
    return Segment(x0, ref, demo.u_H, u_A, feedback)


def fitted_batch(segments, negative_control):
    """The segments as the (possibly wrong) fit sees them, and the data by the names of the models' containers."""
    batch = prepare_batch(fit_plant(negative_control), list(segments))
    return batch, {name: getattr(batch, name) for name in DATA_NAMES}
