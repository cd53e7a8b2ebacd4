"""Small studies of the ``delayed`` human straight from its generative model, for tests and benchmarks.

:func:`delayed_windows` draws each subject's θ per level from :class:`scioc.models.population.Population`
(as :func:`scioc.models.simulate.simulate_windows` does for the max-ent human), gives every
subject one perceptual delay, neuromuscular lag and motor-noise SD (kept in every level:
the human does not change between conditions, as the simulated ``kbl`` human of
:mod:`scioc.models.humans`), and draws each window exactly from the model the likelihood
assumes (:func:`scioc.models.delayed.sample_delayed`): MC on the open wheel, SC with the
assistant's law, the true torques (no encoder, no reconstruction), the arm torque at
rest at the window's start (τ_0 = 0, known). The window runs from the start of the
study reference, like :func:`scioc.models.simulate.simulate_windows`. Nothing here is fitted:
it is the truth the fits are checked against.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.delayed import sample_delayed
from scioc.models.design import DT_HUMAN, MANUAL, PREVIEW_SECONDS, SHARED, WINDOW_SECONDS
from scioc.models.plant import discretize
from scioc.models.population import Population, draw_subjects
from scioc.models.reference import reference_trajectory


class DelayedWindows(NamedTuple):
    """Windows of the ``delayed`` human with their truth, one per subject × level (MC, SC).

    Attributes
    ----------
    subjects, conditions : list of str
    segments : list of Segment
        True x0 and u_H; SC segments carry the assistant's Feedback.
    theta : ndarray, shape (3, n)
        True [q11, q22, R] (command cost) per segment.
    delay : ndarray of int, shape (n,)
        Perceptual delay, samples.
    tau_nm, sigma_m : ndarray, shape (n,)
        Lag time constant (s) and motor-noise SD (N·m per sample).
    tau0 : ndarray, shape (n,)
        Arm torque at each window's start, N·m (0).
    """

    subjects: list
    conditions: list
    segments: list
    theta: np.ndarray
    delay: np.ndarray
    tau_nm: np.ndarray
    sigma_m: np.ndarray
    tau0: np.ndarray


def delayed_windows(n_subjects: int, rng: np.random.Generator, population: Population = Population(), *,
                    delay=(10, 20), tau_nm=(0.05, 0.10), sigma_m=(0.25, 0.25),
                    K: int = round(WINDOW_SECONDS / DT_HUMAN),
                    preview: int = round(PREVIEW_SECONDS / DT_HUMAN)) -> DelayedWindows:
    """Draw a study of ``n_subjects`` × (MC, SC) windows of the ``delayed`` human.

    Parameters
    ----------
    n_subjects : int
    rng : numpy.random.Generator
        θ of every subject first (:func:`scioc.models.population.draw_subjects`), then per
        subject its delay, lag and motor noise, then its two windows in order MC, SC.
    population : Population
        θ per subject and level (R at 100 Hz).
    delay : (int, int)
        Range of the subjects' delays, samples: uniform on ``delay[0] .. delay[1]``
        inclusive (default 0.10-0.20 s, the ``kbl`` human's and issue 13's range).
    tau_nm, sigma_m : (float, float)
        Ranges of the subjects' lag (s) and motor-noise SD (N·m): uniform (default: the
        ``kbl`` human's 0.05-0.10 s and 0.25 N·m).
    K, preview : int
        Observed steps and planning steps past them (default: the 15-s window, 2 s).

    Returns
    -------
    DelayedWindows
    """
    plant = discretize(DT_HUMAN)
    ref = reference_trajectory(DT_HUMAN * (K + preview)).angle
    fb = human_feedback(design_assistant(), ref)
    width = max(2, len(str(int(n_subjects))))
    out = {k: [] for k in DelayedWindows._fields}
    for i, sub in enumerate(draw_subjects(population, n_subjects, rng)):
        d = int(rng.integers(delay[0], delay[1] + 1))
        tau = float(rng.uniform(*tau_nm))
        sig = float(rng.uniform(*sigma_m))
        x0 = np.array([ref[0], 0.0])
        for cond, theta in ((MANUAL, sub.mc), (SHARED, sub.sc)):
            feedback = fb.window(0, K + preview) if cond == SHARED else None
            draw = sample_delayed(theta, x0, ref, plant, rng, feedback=feedback, tau_nm=tau, sigma_m=sig, delay=d,
                                  n_obs=K)
            seg = draw.segments[0]
            out["segments"].append(seg._replace(u_H=seg.u_H[:K]))
            out["subjects"].append(f"S{i + 1:0{width}d}")
            out["conditions"].append(cond)
            out["theta"].append(np.asarray(theta, dtype=float))
            out["delay"].append(d)
            out["tau_nm"].append(tau)
            out["sigma_m"].append(sig)
            out["tau0"].append(0.0)
    return DelayedWindows(out["subjects"], out["conditions"], out["segments"], np.column_stack(out["theta"]),
                          np.array(out["delay"], dtype=np.int64), np.array(out["tau_nm"]), np.array(out["sigma_m"]),
                          np.array(out["tau0"]))


__all__ = ["DelayedWindows", "delayed_windows"]
