"""Per-subject whitening of a hierarchical model's unconstrained space: a fixed affine reparametrization for NUTS.

Why. In the ``delayed`` model each subject's baseline log R is tied to its log τ_nm and σ_m
(correlations -0.86 and 0.6, :mod:`models.bayes.delayed_model`, "Geometry"), one such
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

x̂ and H are computed by :mod:`pipelines.fit.whiten` (the conditional mode with the
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

#: Eigenvalues of |H_i| below this fraction of its largest are raised to it (a direction the data and
#: prior leave flat at x̂ gets a finite scale; its own diagonal mass-matrix entry adapts it).
EIGEN_FLOOR = 1e-6
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


def block_hessian(grad, x: np.ndarray, blocks: np.ndarray, step: float) -> np.ndarray:
    """Hessian blocks (n, k, k) of log p in each subject's coordinates, by central differences of ``grad``.

    Column c of every block comes from one pair of gradients with coordinate c of *every*
    subject moved by ±``step`` (module docstring: the blocks do not interact). Symmetrized.
    """
    n, k = blocks.shape
    H = np.empty((n, k, k))
    for c in range(k):
        e = np.zeros_like(x)
        e[blocks[:, c]] = step
        H[:, :, c] = (np.asarray(grad(x + e))[blocks] - np.asarray(grad(x - e))[blocks]) / (2.0 * step)
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


def to_unconstrained(w: np.ndarray, x_hat: np.ndarray, groups) -> np.ndarray:
    """x of the module docstring from w (..., D): the inverse of the reparametrization, on draws.

    ``groups``: (blocks (n, k), L (n, k, k)) pairs on disjoint coordinates; every other coordinate is x̂ + w.
    """
    w = np.asarray(w, dtype=float)
    x = w + x_hat
    for blocks, L in groups:
        x[..., blocks] = x_hat[blocks] + np.einsum("ijk,...ik->...ij", L, w[..., blocks])
    return x


def whitened_model(logp, flat, x_hat: np.ndarray, groups) -> pm.Model:
    """A model in w alone whose log density is ``logp`` at x(w) (module docstring; ``groups`` as
    :func:`to_unconstrained`'s).

    ``logp``: the original model's log density (with its transforms' Jacobians) as a graph of
    ``flat``, its unconstrained coordinates joined into one vector
    (:func:`pymc.pytensorf.join_nonshared_inputs`). w is a ``Flat`` of that size, so the
    model's initial point, w = 0, is x̂.
    """
    with pm.Model() as model:
        w = pm.Flat(WHITE, shape=x_hat.shape[0])
        x = pt.as_tensor(x_hat) + w
        for blocks, L in groups:
            wb = w[blocks]
            moved = pt.as_tensor(x_hat[blocks]) + pt.sum(pt.as_tensor(L) * wb[:, None, :], axis=-1)
            x = pt.set_subtensor(x[blocks], moved)
        pm.Potential("logp", graph_replace(logp, {flat: x}, strict=False))
    return model


__all__ = ["EIGEN_FLOOR", "WHITE", "block_hessian", "coordinate_scales", "subject_blocks", "to_unconstrained",
           "whitened_model", "whitening_factors"]
