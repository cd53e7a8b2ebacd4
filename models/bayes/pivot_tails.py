"""The curved whitening's pivot with its tails drawn in: a smooth odd map that grows like a square root far out.

Where the pivot is ρ's signed coordinate ρ̃, the data hold ρ², so beyond the ridge's end the log density falls
like -(ρ̃² - c)² / 2v, a wall no affine map removes. With m the pivot's affine coordinate, its deviation is::

    δ = f_b(m) = m (1 + (m/b)²)^(-1/4),     f_b'(m) = (1 + t)^(-5/4) (1 + t/2),  t = (m/b)²

≈ m for |m| ≪ b and ≈ sign(m) √(b |m|) for |m| ≫ b, so a quartic wall in δ is quadratic in m (b = ∞: affine).
The sampled model adds log f_b'(m); b is fitted per subject to a pilot run's draws of δ (:func:`tail_scale`).
"""

from __future__ import annotations

import numpy as np

#: The candidate b in units of the draws' SD (inf: affine); below the SD the map would bend inside the bulk.
TAIL_GRID = (np.inf, 8.0, 4.0, 2.0, 1.0)


def tail_map(m, b):
    """δ = f_b(m) (module docstring), elementwise, on numpy arrays or pytensor tensors alike."""
    return m * (1.0 + (m / b) ** 2) ** -0.25


def tail_log_slope(m, b, xp=np):
    """log f_b'(m) = log1p(t/2) - (5/4) log1p(t), t = (m/b)², elementwise; ``xp``: numpy or ``pytensor.tensor``."""
    t = (m / b) ** 2
    return xp.log1p(0.5 * t) - 1.25 * xp.log1p(t)


def tail_inverse(delta, b) -> np.ndarray:
    """m with f_b(m) = δ: m = sign(δ) √y, y = δ² (δ²/(2b²) + √(1 + δ⁴/(4b⁴))), the positive root of
    y² - (δ⁴/b²) y - δ⁴ = 0, in a form exact for small δ and b = ∞."""
    delta = np.asarray(delta, dtype=float)
    b = np.asarray(b, dtype=float)
    r = delta**2 / (2.0 * b**2)
    return np.sign(delta) * np.abs(delta) * np.sqrt(r + np.sqrt(1.0 + r**2))


def tail_scale(delta: np.ndarray, grid=TAIL_GRID) -> tuple[float, dict]:
    """(b, log-likelihood by candidate): the b of ``grid`` (times the draws' SD about 0) that maximizes the
    likelihood of "m ~ N(0, s²), δ = f_b(m)" for the draws ``delta``, s² at its maximum; b = ∞ without spread."""
    delta = np.asarray(delta, dtype=float).ravel()
    sd = float(np.sqrt(np.mean(delta**2))) if delta.size else 0.0
    if not (np.isfinite(sd) and sd > 0.0):
        return np.inf, {}
    scores = {}
    for g in grid:
        b = g * sd
        m = tail_inverse(delta, b)
        s2 = float(np.mean(m**2))
        scores[float(g)] = float(-0.5 * delta.size * (np.log(2.0 * np.pi * s2) + 1.0) - np.sum(tail_log_slope(m, b)))
    best = max(scores, key=scores.get)
    return best * sd, scores


__all__ = ["TAIL_GRID", "tail_inverse", "tail_log_slope", "tail_map", "tail_scale"]
