"""The per-subject whitening of :mod:`scioc.models.bayes.whiten` measured on posterior draws instead of a Hessian.

The Hessian at the mode misses what lies away from it (log σ_m's tail towards 0); a pilot run's draws see it
(docs/decisions/delayed-pilot-run.md). :func:`draws_factors` gives an affine block its draws' mean and the
Cholesky factor of their covariance; a curved block (pivot p) the pivot's centre (0 where it is signed, its draws
then counted twice, as drawn and reflected), the other coordinates' centres and curvatures a by regression on
(1, δ, δ²), δ = x_p - centre, and the pivot's tail scale b. The draws choose coordinates, not the law.
"""

from __future__ import annotations

import numpy as np

from scioc.models.bayes.pivot_tails import tail_inverse, tail_scale
from scioc.models.bayes.whiten import EIGEN_FLOOR, pivot_curve


def covariance_factor(cov: np.ndarray, floor: float = EIGEN_FLOOR) -> np.ndarray | None:
    """The Cholesky factor of ``cov`` (k, k) with its eigenvalues floored at ``floor`` times the largest, or None
    where it has no positive finite eigenvalue (a coordinate that did not move)."""
    cov = np.atleast_2d(np.asarray(cov, dtype=float))
    if not np.all(np.isfinite(cov)):
        return None
    lam, V = np.linalg.eigh(0.5 * (cov + cov.T))
    if lam[-1] <= 0.0:
        return None
    lam = np.maximum(lam, floor * lam[-1])
    return np.linalg.cholesky((V * lam) @ V.T)


def draws_factors(x: np.ndarray, x_hat: np.ndarray, groups, folds, tails: bool = True
                  ) -> tuple[np.ndarray, list, int]:
    """(x̂, groups, kept): ``groups`` (as :func:`scioc.models.bayes.whiten.to_unconstrained` takes them) measured
    again on the draws ``x`` (..., D); ``folds``: per group None or (n,) bool, each subject's pivot signed; ``kept``
    counts the blocks whose draws did not move, which keep their centre and factor."""
    x_hat = np.asarray(x_hat, dtype=float)
    X = np.asarray(x, dtype=float).reshape(-1, x_hat.shape[0])
    if X.shape[0] < 2 or not np.all(np.isfinite(X)):
        raise ValueError(f"draws_factors needs at least 2 finite draws; got {X.shape[0]} draws")
    if len(folds) != len(groups):
        raise ValueError(f"folds needs one entry per group ({len(groups)}); got {len(folds)}")
    centre = x_hat.copy()
    out, kept = [], 0
    for (blocks, L, *curve), fold in zip(groups, folds):
        L = np.array(L, dtype=float)
        if curve:
            pivot, a, b = pivot_curve(curve[0])
            a = np.array(a, dtype=float)
            b = np.full(blocks.shape[0], np.inf) if b is None else np.array(b, dtype=float)
        for i, cols in enumerate(blocks):
            xi = X[:, cols]
            c = xi.mean(axis=0)
            if curve:
                if fold is not None and fold[i]:
                    mirror = xi.copy()
                    mirror[:, pivot] = -mirror[:, pivot]
                    xi = np.concatenate([xi, mirror])
                    c_p = 0.0
                else:
                    c_p = c[pivot]
                delta = xi[:, pivot] - c_p
                coef = np.linalg.lstsq(np.column_stack([np.ones_like(delta), delta, delta**2]), xi, rcond=None)[0]
                c, ai = coef[0].copy(), coef[2].copy()
                c[pivot], ai[pivot] = c_p, 0.0
                bi = tail_scale(delta)[0] if tails else np.inf
                xi = xi - np.outer(delta**2, ai)
                xi[:, pivot] = c_p + tail_inverse(delta, bi)  # the pivot's affine coordinate m
            factor = covariance_factor(np.cov(xi, rowvar=False))
            if factor is None:
                kept += 1
                continue
            L[i] = factor
            centre[cols] = c
            if curve:
                a[i], b[i] = ai, bi
        out.append((blocks, L, (pivot, a, b)) if curve else (blocks, L))
    return centre, out, kept


def to_white(x: np.ndarray, x_hat: np.ndarray, groups) -> np.ndarray:
    """w from x (..., D): the inverse of :func:`scioc.models.bayes.whiten.to_unconstrained`."""
    x = np.asarray(x, dtype=float)
    w = x - x_hat
    for blocks, L, *curve in groups:
        dx = x[..., blocks] - x_hat[blocks]
        if curve:
            pivot, a, b = pivot_curve(curve[0])
            delta = dx[..., pivot:pivot + 1]
            dx = dx - a * delta ** 2
            if b is not None:
                dx[..., pivot] = tail_inverse(delta[..., 0], b)
        w[..., blocks] = np.linalg.solve(L, dx[..., None])[..., 0]
    return w


__all__ = ["covariance_factor", "draws_factors", "to_white"]
