"""Small studies of the ``delayed`` human from its generative model: the truth fits are checked against.

Per subject θ per level from a :class:`scioc.models.population.Population`, one delay, lag and motor noise in all
levels, and exact windows (:func:`scioc.models.delayed.sample_delayed`; true torques, the arm at rest at the start).
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
    """Windows of the ``delayed`` human with their truth, one per subject × level (MC, SC): ``segments`` (true x0
    and u_H; SC ones carry the assistant's Feedback), ``theta`` (3, n) the command cost, ``delay`` (n,) samples,
    ``tau_nm`` (n,) s, ``sigma_m`` (n,) N·m per sample, ``tau0`` (n,) N·m (0)."""

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

    ``rng`` draws every subject's θ first, then per subject its delay, lag and motor noise and its windows;
    ``delay``, ``tau_nm``, ``sigma_m`` are uniform ranges (whole samples, s, N·m; default the ``kbl`` human's); ``K``
    observed steps and ``preview`` planning steps past them.
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
