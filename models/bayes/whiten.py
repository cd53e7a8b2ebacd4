"""Per-subject whitening of a hierarchical model's unconstrained space: a fixed reparametrization for NUTS.

Given the population the subjects are independent, so on the sampler's unconstrained scale x the posterior's
precision is block diagonal over the subjects plus the population's few coordinates
(docs/decisions/delayed-whitening.md). With x̂ near the posterior's centre and H_i the Hessian of log p at x̂ in
subject i's coordinates, NUTS samples w where::

    x_i = x̂_i + L_i w_i + a_i δ_i²,   L_i L_iᵀ = |H_i|⁻¹,   δ_i = (L_i w_i)_p,   a_ip = 0
    x_q = x̂_q + s_q w_q,   s_q = min(1, |∂² log p / ∂x_q²|^(-1/2))       (every other coordinate)

|H_i| is -H_i with its eigenvalues made absolute and floored (SoftAbs, Betancourt 2013). a_i = 0 is the affine
map; a curved one bends along a pivot coordinate p (:func:`scioc.models.bayes.delayed_blocks.ridge_pivots`) with
the secant curvature of the subject's ridge (:func:`ridge_curvature`). The Jacobian (I + 2 δ a eₚᵀ) L has the
constant determinant det L, and the map is one-to-one (δ is read off x_p), so the posterior is exactly the
model's; a pivot's tail map (:mod:`scioc.models.bayes.pivot_tails`) adds its log Jacobian.
"""

from __future__ import annotations

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.replace import graph_replace

from scioc.models.bayes.pivot_tails import tail_log_slope, tail_map

#: Eigenvalues of |H_i| below this fraction of its largest are raised to it: a flat direction gets a finite scale.
EIGEN_FLOOR = 1e-6
#: Most Newton iterations of each conditional mode of :func:`ridge_curvature`.
RIDGE_MAX_ITER = 50
#: How often :func:`ridge_curvature` halves a span without a ridge maximum.
RIDGE_HALVINGS = 2
#: :func:`ridge_curvature` has settled when every step is below this fraction of its coordinate's scale.
RIDGE_TOL = 1e-6
#: Name of the whitened coordinates w in the sampled model.
WHITE = "w"


def subject_blocks(point_map_info, dims: list, n_subjects: int) -> np.ndarray:
    """Flat indices (n_subjects, k) of every coordinate with a leading ``subject`` dim, row i subject i's;
    ``point_map_info``: :class:`pymc.blocking.RaveledVars`'s per value variable, ``dims`` their dims."""
    cols, start = [], 0
    for (name, shape, size, _), d in zip(point_map_info, dims):
        d = tuple(d or ())
        if d and d[0] == "subject":
            if shape[0] != n_subjects:
                raise ValueError(f"{name}: {shape[0]} entries along 'subject', expected {n_subjects}")
            cols.append(np.arange(start, start + size).reshape(n_subjects, -1))
        elif "subject" in d:
            raise ValueError(f"{name}: 'subject' must be its first dim to be whitened; dims {d}")
        start += size
    if not cols:
        raise ValueError("no variable has a 'subject' dim: nothing to whiten")
    return np.concatenate(cols, axis=1)


def block_column(point_map_info, dims: list, n_subjects: int, name: str) -> int:
    """The column of value variable ``name`` in :func:`subject_blocks`' rows (one coordinate per subject)."""
    col = 0
    for (var, shape, size, _), d in zip(point_map_info, dims):
        d = tuple(d or ())
        if var == name:
            if not d or d[0] != "subject" or size != n_subjects:
                raise ValueError(f"{name}: needs exactly one coordinate per subject to be a block's pivot; dims {d}")
            return col
        if d and d[0] == "subject":
            col += size // n_subjects
    raise ValueError(f"{name} is not a value variable of the model")


def block_hessian(grad, x: np.ndarray, blocks: np.ndarray, step) -> np.ndarray:
    """Hessian blocks (n, k, k) of log p in each subject's coordinates by central differences, symmetrized:
    column c from one pair of gradients with coordinate c of every subject moved by ±``step`` (scalar or (n, k))."""
    n, k = blocks.shape
    steps = np.broadcast_to(np.asarray(step, dtype=float), (n, k))
    H = np.empty((n, k, k))
    for c in range(k):
        e = np.zeros_like(x)
        e[blocks[:, c]] = steps[:, c]
        H[:, :, c] = (np.asarray(grad(x + e))[blocks] - np.asarray(grad(x - e))[blocks]) / (2.0 * steps[:, c, None])
    return 0.5 * (H + np.swapaxes(H, 1, 2))


def coordinate_scales(grad, x: np.ndarray, coords: np.ndarray, step: float) -> np.ndarray:
    """Scales (m, 1, 1) of the single coordinates ``coords``: |∂² log p / ∂x_c²|^(-1/2) at x, capped at 1."""
    S = np.ones((len(coords), 1, 1))
    for j, c in enumerate(np.asarray(coords, dtype=int)):
        e = np.zeros_like(x)
        e[c] = step
        h = (np.asarray(grad(x + e))[c] - np.asarray(grad(x - e))[c]) / (2.0 * step)
        if not np.isfinite(h):
            raise ValueError(f"coordinate {c}: the second derivative is not finite")
        if abs(h) > 1.0:
            S[j, 0, 0] = abs(h) ** -0.5
    return S


def whitening_factors(H: np.ndarray, floor: float = EIGEN_FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """(L, n_negative): L[i] L[i]ᵀ = |H[i]|⁻¹, and each block's count of directions in which x̂ is not a maximum."""
    L = np.empty_like(H)
    n_neg = np.zeros(H.shape[0], dtype=int)
    for i, Hi in enumerate(H):
        lam, V = np.linalg.eigh(-Hi)
        if not np.all(np.isfinite(lam)):
            raise ValueError(f"subject block {i}: the Hessian is not finite")
        n_neg[i] = int(np.sum(lam <= 0))
        lam = np.maximum(np.abs(lam), floor * np.max(np.abs(lam)))
        # The Cholesky factor, not V diag(lam^-1/2): it keeps each subject's first coordinate on its own axis.
        L[i] = np.linalg.cholesky((V / lam) @ V.T)
    return L, n_neg


def nearest_fold(x: np.ndarray, blocks: np.ndarray, L: np.ndarray, pivots, signed) -> np.ndarray:
    """Each subject's pivot (n,), an index into ``pivots``: among those ``signed`` in the subject, the one nearest
    0 at ``x`` in its own scale (where the arch of a signed pair tops); the last where none is."""
    pivots = np.asarray(pivots, dtype=int)
    n, k = blocks.shape
    if pivots.ndim != 1 or pivots.size == 0 or np.any((pivots < 0) | (pivots >= k)):
        raise ValueError(f"pivots {pivots.tolist()} must be columns of a block's {k} coordinates")
    signed = np.broadcast_to(np.asarray(signed, dtype=bool), (n, pivots.size))
    sd = np.sqrt(np.einsum("ijk,ijk->ij", L, L))[:, pivots]
    distance = np.where(signed, np.abs(x[blocks[:, pivots]]) / sd, np.inf)
    return np.where(signed.any(axis=1), np.argmin(distance, axis=1), pivots.size - 1)


def ridge_curvature(grad, x: np.ndarray, blocks: np.ndarray, L: np.ndarray, pivot: int, span: float = 1.0,
                    max_iter: int = RIDGE_MAX_ITER, tol: float = RIDGE_TOL,
                    halvings: int = RIDGE_HALVINGS) -> tuple[np.ndarray, dict]:
    """(a (n, k), record): each subject's ridge curvature along ``pivot``, a[:, pivot] = 0.

    a = (y(h) + y(-h) - 2 y(0)) / (2 h²), y(t) the block's :func:`conditional_modes` with the pivot at x_p + t and
    h = ``span`` × its SD under L; halved up to ``halvings`` times where the ridge has no maximum at ±h (R -> ∞
    once the motor noise alone exceeds the residual); a subject still without keeps the affine map.
    """
    n, k = blocks.shape
    if not 0 <= pivot < k:
        raise ValueError(f"pivot {pivot} is not one of a block's {k} coordinates")
    rest = np.array([c for c in range(k) if c != pivot], dtype=int)
    cov = L @ np.swapaxes(L, 1, 2)
    P = np.linalg.inv(cov)
    b = -np.linalg.solve(P[:, rest][:, :, rest], P[:, rest, pivot][:, :, None])[:, :, 0]
    sd = np.sqrt(np.einsum("ijj->ij", cov))[:, rest]

    def modes(t):
        return conditional_modes(grad, x, blocks, pivot, t, b, sd, max_iter=max_iter, tol=tol)

    y0, settled, it0 = modes(np.zeros(n))
    h = span * np.sqrt(cov[:, pivot, pivot])
    a = np.zeros((n, k))
    found = np.zeros(n, dtype=bool)
    iterations = [it0]
    for _ in range(halvings + 1):
        (lo, ok_lo, i_lo), (hi, ok_hi, i_hi) = modes(-h), modes(h)
        iterations += [i_lo, i_hi]
        new = ~found & settled & ok_lo & ok_hi
        a[np.ix_(new, rest)] = (lo[new] + hi[new] - 2.0 * y0[new]) / (2.0 * h[new, None] ** 2)
        found |= new
        if found[settled].all():
            break
        h = np.where(found, h, 0.5 * h)
    return a, {"pivot_scale_range": [float(h.min()), float(h.max())],
               "subjects_without_curvature": int(np.sum(~found)), "ridge_iterations": iterations,
               "largest_shift_in_scales": float(np.max(np.abs(a[:, rest]) * h[:, None] ** 2 / sd))}


def conditional_modes(grad, x: np.ndarray, blocks: np.ndarray, pivot: int, t: np.ndarray, slope: np.ndarray,
                      scale: np.ndarray, *, max_iter: int = RIDGE_MAX_ITER, tol: float = RIDGE_TOL):
    """(y (n, k-1), settled (n), iterations): each block's maximum of log p over all but ``pivot``, held at
    x_p + t_i, by Newton's iteration from x_r + slope_i t_i; steps at most one ``scale`` and halved whenever they grew
    (log p is not near quadratic everywhere)."""
    n, k = blocks.shape
    cols = blocks[:, [c for c in range(k) if c != pivot]]
    y = np.array(x, dtype=float)
    y[blocks[:, pivot]] += t
    y[cols] += slope * t[:, None]
    done, broken = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    length, last = np.ones(n), np.full(n, np.inf)
    for it in range(max_iter):
        with np.errstate(invalid="ignore", over="ignore"):
            step = newton_steps(grad, y, cols, scale)
        broken |= ~np.all(np.isfinite(step), axis=1)
        step[done | broken] = 0.0
        size = np.max(np.abs(step) / scale, axis=1)  # the Newton step, in the coordinates' scales
        done |= ~broken & (size < tol)
        length = np.where(size > last, 0.5 * length, length)  # not contracting: shorter steps
        last = size
        with np.errstate(divide="ignore"):
            y[cols] += step * np.minimum(length, 1.0 / size)[:, None]  # and at most one scale at a time
        if np.all(done | broken):
            break
    return y[cols], done & ~broken, it + 1


def newton_steps(grad, x: np.ndarray, blocks: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Each block's Newton step (n, k) at x, |H_i|⁻¹ ∇_i log p; NaN where H or the gradient is not finite."""
    n, k = blocks.shape
    g = np.asarray(grad(x), dtype=float)[blocks]
    H = block_hessian(grad, x, blocks, 1e-4 * scale)
    step = np.full((n, k), np.nan)
    for i in range(n):
        if np.all(np.isfinite(H[i])) and np.all(np.isfinite(g[i])):
            lam, V = np.linalg.eigh(-H[i])
            lam = np.maximum(np.abs(lam), EIGEN_FLOOR * np.max(np.abs(lam)))
            step[i] = V @ ((V.T @ g[i]) / lam)
    return step


def pivot_curve(curve):
    """(pivot, a (n, k), b (n,) or None) of a curved group's third entry; b the pivot's tail scales (None: affine)."""
    pivot, a, *rest = curve
    b = rest[0] if rest else None
    return int(pivot), a, (None if b is None else np.asarray(b, dtype=float))


def to_unconstrained(w: np.ndarray, x_hat: np.ndarray, groups) -> np.ndarray:
    """x from w (..., D). ``groups``: (blocks (n, k), L (n, k, k)[, (pivot, a[, b])]) on disjoint coordinates."""
    w = np.asarray(w, dtype=float)
    x = w + x_hat
    for blocks, L, *curve in groups:
        moved = np.einsum("ijk,...ik->...ij", L, w[..., blocks])
        if curve:
            pivot, a, b = pivot_curve(curve[0])
            if b is not None:
                moved[..., pivot] = tail_map(moved[..., pivot], b)
            moved = moved + a * moved[..., pivot:pivot + 1] ** 2
        x[..., blocks] = x_hat[blocks] + moved
    return x


def whitened_model(logp, flat, x_hat: np.ndarray, groups) -> pm.Model:
    """A model in w alone (``Flat``: w = 0 is x̂) with log density ``logp`` at x(w) plus the tail maps' log
    Jacobians; ``logp`` is a graph of ``flat``, the unconstrained coordinates as one vector."""
    with pm.Model() as model:
        w = pm.Flat(WHITE, shape=x_hat.shape[0])
        x = pt.as_tensor(x_hat) + w
        log_jacobian = pt.as_tensor(0.0)
        for blocks, L, *curve in groups:
            wb = w[blocks]
            moved = pt.sum(pt.as_tensor(L) * wb[:, None, :], axis=-1)
            if curve:
                pivot, a, b = pivot_curve(curve[0])
                if b is not None:
                    m = moved[:, pivot]
                    log_jacobian = log_jacobian + pt.sum(tail_log_slope(m, pt.as_tensor(b), pt))
                    moved = pt.set_subtensor(moved[:, pivot], tail_map(m, pt.as_tensor(b)))
                moved = moved + pt.as_tensor(a) * moved[:, pivot:pivot + 1] ** 2
            x = pt.set_subtensor(x[blocks], pt.as_tensor(x_hat[blocks]) + moved)
        pm.Potential("logp", graph_replace(logp, {flat: x}, strict=False) + log_jacobian)
    return model


__all__ = ["EIGEN_FLOOR", "RIDGE_HALVINGS", "RIDGE_MAX_ITER", "RIDGE_TOL", "WHITE", "block_column", "block_hessian",
           "conditional_modes", "coordinate_scales", "nearest_fold", "newton_steps", "pivot_curve", "ridge_curvature",
           "subject_blocks", "to_unconstrained", "whitened_model", "whitening_factors"]
