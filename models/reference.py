"""The reference trajectory of the simulated study (paper Section IV-B, IV-F, Fig. 4).

One smooth curve for every subject and condition over a whole run: a sum of sines between 0.05 and
0.5 Hz with amplitudes ∝ 1/f and fixed phases, scaled to :data:`RMS_ANGLE` and faded in over 2 s. The
paper does not publish its own; why this one: docs/decisions/reference-trajectory.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.design import DT_HUMAN, RUN_SECONDS, WINDOW_SECONDS, WINDOW_START

#: Target RMS of the reference angle, rad.
RMS_ANGLE = 0.2
#: Frequencies of the components, Hz (incommensurate, 0.05 .. 0.5).
FREQUENCIES = np.array([0.05, 0.083, 0.121, 0.157, 0.199, 0.241, 0.293, 0.347, 0.411, 0.5])
#: Seed of the fixed phases: the trajectory is part of the study design, not of a replication.
PHASE_SEED = 2018


class Reference(NamedTuple):
    """A reference angle ``angle`` (N,), rad, at times ``t`` (N,), s from 0."""

    t: np.ndarray
    angle: np.ndarray


def reference_trajectory(seconds: float = RUN_SECONDS, dt: float = DT_HUMAN, rms: float = RMS_ANGLE) -> Reference:
    """The study's reference: ``round(seconds / dt) + 1`` samples (``seconds``, ``dt`` in s), RMS ``rms`` rad
    over a whole 4-minute run."""
    n = int(round(seconds / dt)) + 1
    t = np.arange(n) * dt
    phases = np.random.default_rng(PHASE_SEED).uniform(0.0, 2.0 * np.pi, FREQUENCIES.shape[0])
    amps = 1.0 / FREQUENCIES
    # Scale on the full 4-minute grid so that a shorter or longer call gives the same curve.
    t_full = np.arange(int(round(RUN_SECONDS / dt)) + 1) * dt
    raw_full = np.sin(2 * np.pi * FREQUENCIES[:, None] * t_full[None, :] + phases[:, None]).T @ amps
    scale = rms / np.sqrt(np.mean(raw_full**2))
    raw = np.sin(2 * np.pi * FREQUENCIES[:, None] * t[None, :] + phases[:, None]).T @ amps
    fade = np.clip(t / 2.0, 0.0, 1.0)
    fade = fade * fade * (3.0 - 2.0 * fade)  # smoothstep: zero slope at both ends
    return Reference(t=t, angle=scale * raw * fade)


def window_slice(start: float = WINDOW_START, seconds: float = WINDOW_SECONDS, dt: float = DT_HUMAN) -> slice:
    """Sample indices k = 0..K of the analysis window (K = seconds / dt, so K + 1 rows)."""
    i0 = int(round(start / dt))
    return slice(i0, i0 + int(round(seconds / dt)) + 1)
