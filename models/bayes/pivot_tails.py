"""The curved whitening's pivot with its tails drawn in: a smooth odd map that grows like a square root far out.

Why. In the curved whitening (:mod:`scioc.models.bayes.whiten`, "Curved") each subject's pivot p is an affine coordinate.
Where p is ρ's signed coordinate ρ̃ (ρ = R^(-1/2), the policy noise's scale), the data hold the policy noise's
variance, ρ², so beyond the ridge's end the log density falls about like -(ρ̃² - c)² / 2v: a wall whose
curvature grows as ρ̃², which no affine map removes. On the twelve ``kbl`` subjects of :mod:`scioc.pipelines.fit.warmup`
at nutpie's target acceptance 0.8, four of five divergent trajectories ended on one subject's pivot beyond the
largest |ρ̃| of its draws (read ad hoc with nutpie's ``store_divergences``, 2026-12-07; measured: module
:mod:`scioc.pipelines.fit.warmup`, "The pivot's tails"), and the trajectory's last step moved ρ̃ by a third of its draws'
range or more, with energy errors of 10³-10¹⁰.

What. With m the pivot's affine coordinate (the p-th of L_i w_i) the pivot's deviation from its centre is::

    δ = f_b(m) = m (1 + (m/b)²)^(-1/4),     f_b'(m) = (1 + t)^(-5/4) (1 + t/2),  t = (m/b)²

odd, increasing, f_b(m) ≈ m for |m| ≪ b and ≈ sign(m) √(b |m|) for |m| ≫ b, so that a quartic wall in δ is a
quadratic one in m; b = ∞ is the identity (the affine pivot). The map w -> x then has the Jacobian determinant
det L_i f_b'(m_i) per subject, whose log the sampled model adds (:func:`scioc.models.bayes.whiten.whitened_model`): the
posterior is still exactly the model's. b is chosen per subject from posterior draws of δ (a pilot run's,
:func:`scioc.models.bayes.whiten_draws.draws_factors`), by maximum likelihood of the law "m normal, δ = f_b(m)" over the
grid :data:`TAIL_GRID` (in units of δ's SD): the map that makes the pivot's draws most normal, the identity among
them. The grid stops at δ's SD: with b down to a quarter of it (where the likelihood went for every subject, as
ρ̃'s draws have two modes), the map's bend lay inside the bulk, and the kept trees were as deep as without the map
at 0.9 (:mod:`scioc.pipelines.fit.warmup`, "The pivot's tails").
"""

from __future__ import annotations

import numpy as np

#: The candidate b, in units of the pivot's SD in the draws (np.inf: the identity, the affine pivot).
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
    y² - (δ⁴/b²) y - δ⁴ = 0 (m⁴ = δ⁴ (1 + m²/b²)), in a form exact for small δ and b = ∞."""
    delta = np.asarray(delta, dtype=float)
    b = np.asarray(b, dtype=float)
    r = delta**2 / (2.0 * b**2)
    return np.sign(delta) * np.abs(delta) * np.sqrt(r + np.sqrt(1.0 + r**2))


def tail_scale(delta: np.ndarray, grid=TAIL_GRID) -> tuple[float, dict]:
    """(b, log-likelihood by candidate): the b of :data:`TAIL_GRID` (times the SD of the draws ``delta`` about 0)
    that maximizes Σ_j log N(m_j; 0, s²) - log f_b'(m_j), m_j = f_b⁻¹(δ_j), s² = mean m² (its maximum for that b):
    the likelihood of the law "m ~ N(0, s²), δ = f_b(m)" for δ's draws. Draws without spread keep b = ∞."""
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
