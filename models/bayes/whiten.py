"""Per-subject whitening of a hierarchical model's unconstrained space: a fixed affine reparametrization for NUTS.

Why. In the ``delayed`` model each subject's baseline log R is tied to its log τ_nm and σ_m
(correlations -0.86 and 0.6, :mod:`scioc.models.bayes.delayed_model`, "Geometry"), one such
direction per subject. nutpie's diagonal mass matrix cannot hold those correlations, and its
low-rank one learns them only after more warm-up draws than the model has dimensions (README,
"Which part of the warm-up"). But the subjects are independent given the population: the
posterior's precision, on the sampler's unconstrained scale x, is block diagonal over the
subjects' coordinates, with a small dense block per subject, plus the population's few
coordinates. That structure is known before sampling.

What. With x̂ a point near the posterior's centre and H_i the Hessian of log p at x̂ in
subject i's coordinates x_i (k per subject), sample w where::

    x_i = x̂_i + L_i w_i,   L_i L_iᵀ = |H_i|⁻¹        (each subject's block)
    x_p = x̂_p + s_p w_p                              (every other coordinate)

|H_i| is -H_i with its eigenvalues replaced by their absolute values and floored at
``EIGEN_FLOOR`` times the largest, so L_i exists where x̂ is not a maximum (the SoftAbs
metric's idea, Betancourt 2013). The map is affine with a constant Jacobian, so the density
of w is p(x(w)) times a constant: the posterior is exactly the model's, only its coordinates
change. In w each subject's block is near the identity where the posterior is near Gaussian,
and the diagonal mass matrix then has little left to learn.

s_p is the population coordinate's own scale at x̂, |∂² log p / ∂x_p²|^(-1/2), capped at 1
(:func:`coordinate_scales`). Without it the chains' start, jittered by U(-1, 1) in w as PyMC
jitters its own, put the population's centres 8-22 posterior SDs from x̂ (β's SD is 0.036 on
the default study, μ_log θ1's 0.085), and the first 20 warm-up draws of the full-size ``delayed``
fit took trees of 127-1023 leapfrog steps to walk back (README, "Not yet").

Curved
------
An affine map cannot straighten a curved ridge. In the ``delayed`` model each subject's R trades
off against its motor noise σ_m along a parabola: the residual's variance at lag 0 is about the
policy noise's, which falls as R grows, plus σ_m²'s share, so the data hold log R ≈ c + k σ_m²
(on the full-size fit of the default study's max-ent human kept by ``scioc bench --parts
fit_delayed --keep``, measured ad hoc: the posterior's slope of log R on σ_m² 2.2-2.7 R on every
third subject; the correlation of baseline log R and σ_m per subject 0.21-0.90, median 0.80).
Where σ_m's coordinate is v (σ_m = |v|, the folded centred form), the mode is at v = 0 and that
parabola is symmetric about it: no linear map of v removes it, and each tree of NUTS has to turn
along it. So, given a ``pivot`` coordinate p in each block (σ_m's; ρ's where ρ = R^(-1/2) is signed, whose
ridge is an arch over it; with both signed, per subject the one whose fold the mode is nearest,
:func:`nearest_fold`, :func:`scioc.models.bayes.delayed_blocks.ridge_pivots`), the map is::

    x_i = x̂_i + L_i w_i + a_i δ_i²,   δ_i = (L_i w_i)_p,   a_ip = 0

with a_i the secant curvature of subject i's ridge (:func:`ridge_curvature`: the conditional
modes of the other coordinates with the pivot at x̂_p and ± one of its scales). The Jacobian of
w -> x is (I + 2 δ a eₚᵀ) L, whose determinant is det L (a_p = 0): constant, so the density of
w is still p(x(w)) times a constant. The map is one-to-one: δ is read off x_p, then w from
x - x̂ - a δ². On a banana whose ridge is exactly quadratic it is exact (the density of w is a
standard normal). Measured on the full-size study: README, "Speed".

x̂ and H are computed by :mod:`scioc.pipelines.fit.whiten` (the conditional mode with the
population's scales held, central differences of the exact gradient). H_i comes from one
difference per column of a block, for all subjects at once (:func:`block_hessian`): subject
j's gradient does not depend on subject i's coordinates, so 2k gradients give every block.

Measured against nutpie's low-rank and diagonal matrices on 12 subjects: README, "Not yet",
"On each subject's whitened coordinates" (less than half the gradients for the same ESS of the
population parameters; the subjects' baseline log R, whose posterior has a long tail towards
R -> ∞, mixes no better: a linear map cannot straighten a tail). Two variants, tried with ad
hoc patches on the same study (their numbers are in issue 13's note of 2026-12-05, not
reproducible from the repo), did not do better on these measures: whitening only the centred
coordinates (log R, log θ1's mean, log τ_nm, log σ_m), and a second stage whitened by the
covariance of 100 + 100 pilot draws. Neither is in the code.
"""

from __future__ import annotations

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.replace import graph_replace

from scioc.models.bayes.pivot_tails import tail_log_slope, tail_map

#: Eigenvalues of |H_i| below this fraction of its largest are raised to it (a direction the data and
#: prior leave flat at x̂ gets a finite scale; its own diagonal mass-matrix entry adapts it).
EIGEN_FLOOR = 1e-6
#: Most Newton iterations of each conditional mode of :func:`ridge_curvature`.
RIDGE_MAX_ITER = 50
#: How often :func:`ridge_curvature` halves a subject's span where its ridge has no maximum there.
RIDGE_HALVINGS = 2
#: :func:`ridge_curvature`'s iteration has settled when every step is below this fraction of its coordinate's scale.
RIDGE_TOL = 1e-6
#: Name of the whitened coordinates w in the sampled model.
WHITE = "w"


def subject_blocks(point_map_info, dims: list, n_subjects: int) -> np.ndarray:
    """Flat indices (n_subjects, k) of every coordinate with a leading ``subject`` dim.

    ``point_map_info``: :class:`pymc.blocking.RaveledVars`'s (name, shape, size, dtype) per value
    variable, in the flat vector's order; ``dims``: each value variable's dims (None or a tuple).
    Row i holds subject i's coordinates, in the same order for every subject.
    """
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
    """Hessian blocks (n, k, k) of log p in each subject's coordinates, by central differences of ``grad``.

    Column c of every block comes from one pair of gradients with coordinate c of *every*
    subject moved by ±``step`` (module docstring: the blocks do not interact). Symmetrized.
    ``step``: one for every coordinate, or (n, k), one per subject and coordinate.
    """
    n, k = blocks.shape
    steps = np.broadcast_to(np.asarray(step, dtype=float), (n, k))
    H = np.empty((n, k, k))
    for c in range(k):
        e = np.zeros_like(x)
        e[blocks[:, c]] = steps[:, c]
        H[:, :, c] = (np.asarray(grad(x + e))[blocks] - np.asarray(grad(x - e))[blocks]) / (2.0 * steps[:, c, None])
    return 0.5 * (H + np.swapaxes(H, 1, 2))


def coordinate_scales(grad, x: np.ndarray, coords: np.ndarray, step: float) -> np.ndarray:
    """Scales (m, 1, 1) of the single coordinates ``coords`` (m,): each |∂² log p / ∂x_c²|^(-1/2) at x, by
    central differences of ``grad`` (one pair of gradients per coordinate: these coordinates may interact), and
    never above 1.

    For the coordinates outside the subjects' blocks (the population's), as one-coordinate blocks of
    :func:`to_unconstrained`'s ``groups``. Capped at 1, so that a flat direction (or a held scale with
    little curvature at x̂) keeps the unit scale it would have without them.
    """
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
    """(L, n_negative): L[i] L[i]ᵀ = |H[i]|⁻¹ (module docstring), and each block's count of non-negative-definite
    directions of -H[i] (where x̂ is not a maximum)."""
    L = np.empty_like(H)
    n_neg = np.zeros(H.shape[0], dtype=int)
    for i, Hi in enumerate(H):
        lam, V = np.linalg.eigh(-Hi)
        if not np.all(np.isfinite(lam)):
            raise ValueError(f"subject block {i}: the Hessian is not finite")
        n_neg[i] = int(np.sum(lam <= 0))
        lam = np.maximum(np.abs(lam), floor * np.max(np.abs(lam)))
        # L = V diag(lam^-1/2) is a square root of V diag(1/lam) Vᵀ; the Cholesky factor of it is the
        # triangular one, which keeps each subject's first coordinate on its own axis.
        L[i] = np.linalg.cholesky((V / lam) @ V.T)
    return L, n_neg


def nearest_fold(x: np.ndarray, blocks: np.ndarray, L: np.ndarray, pivots, signed) -> np.ndarray:
    """Each subject's pivot (n,), an index into ``pivots`` (columns of a block): among the pivots whose coordinate
    is signed in that subject (``signed`` (n, len(pivots)) bool: its law symmetric about 0, the fold), the one
    whose value at ``x`` is nearest 0 in its own scale, |x_p| / sqrt((L_i L_iᵀ)_pp), the first on a tie; the last
    pivot where none is signed. The ridge a signed pair shares is an arch that tops where one of them is 0
    (:func:`scioc.models.bayes.delayed_blocks.ridge_pivots`), and the subject's mode lies near that top."""
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
    """(a (n, k), record): each subject's ridge's curvature along its coordinate ``pivot`` (module docstring,
    "Curved"), a[:, pivot] = 0; zero for a subject whose conditional modes are not found.

    With P_i = (L_i L_iᵀ)⁻¹ (the SoftAbs precision), r the block's other coordinates and h_i = ``span`` ·
    sqrt((L_i L_iᵀ)_pp) the pivot's scale: y_i(t), the maximum of log p over r with the pivot at x_p + t
    (:func:`conditional_modes`), for t = 0 and ±h; then a_r = (y(h) + y(-h) - 2 y(0)) / (2 h²), the secant of
    the ridge. Where the ridge has no maximum at ±h (R -> ∞ once the motor noise alone exceeds a subject's
    residual), h is halved, at most ``halvings`` times; a subject whose modes are still not found keeps
    the affine map.
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
    """(y (n, k-1), settled (n), iterations): each subject's maximum of log p over its block's coordinates but
    ``pivot``, with the pivot held at x_p + t_i; from x_r + slope_i t_i, by Newton's iteration
    (:func:`newton_steps`; every subject at once: the blocks do not interact) until every step is below ``tol``
    of its coordinate's ``scale`` (n, k-1). Each step is at most one scale, and halved in length for a subject
    whenever it grew (where log p is not near quadratic, e.g. log τ_nm's tail towards 0: a chord iteration with
    the Hessian at x̂ jumped by a hundred scales or cycled on the full-size study). Not settled: no step below
    ``tol`` within ``max_iter``, or not finite."""
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
    """Each block's Newton step (n, k) towards the maximum of log p over its coordinates, at x: |H_i|⁻¹ ∇_i log p
    with |H_i| as in :func:`whitening_factors` (H by :func:`block_hessian`, step 1e-4 of each coordinate's
    ``scale`` (n, k)); NaN for a block whose Hessian or gradient is not finite."""
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
    """(pivot, a (n, k), b (n,) or None) of a curved group's third entry, (pivot, a) or (pivot, a, b) with b the
    pivot's tail scales (:mod:`scioc.models.bayes.pivot_tails`; None or absent: the affine pivot)."""
    pivot, a, *rest = curve
    b = rest[0] if rest else None
    return int(pivot), a, (None if b is None else np.asarray(b, dtype=float))


def to_unconstrained(w: np.ndarray, x_hat: np.ndarray, groups) -> np.ndarray:
    """x of the module docstring from w (..., D): the inverse of the reparametrization, on draws.

    ``groups``: (blocks (n, k), L (n, k, k)) pairs on disjoint coordinates, or (blocks, L, (pivot, a (n, k)[, b
    (n,)])) with each subject's ridge curvature (:func:`ridge_curvature`) and its pivot's tail scale
    (:mod:`scioc.models.bayes.pivot_tails`: δ = f_b(m_p)); every other coordinate is x̂ + w.
    """
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
    """A model in w alone whose log density is ``logp`` at x(w), plus the log Jacobian of a pivot's tail map where a
    group has one (module docstring; ``groups`` as :func:`to_unconstrained`'s).

    ``logp``: the original model's log density (with its transforms' Jacobians) as a graph of
    ``flat``, its unconstrained coordinates joined into one vector
    (:func:`pymc.pytensorf.join_nonshared_inputs`). w is a ``Flat`` of that size, so the
    model's initial point, w = 0, is x̂.
    """
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
