"""Maximum-likelihood identification of θ for one unit (paper Eq. 17, Section IV-F).

SLSQP (as in the paper) with the exact gradient, in ``z = (log θ1, θ2, log R)``, θ1 = q11/R, θ2 = q22/R
(Section V-A): the policy depends on θ1, θ2 only, the logs condition the Hessian, θ2 >= 0 is a bound.
The start is the best θ1 of a grid with θ2 = 0, where R has the closed form ``R̂ = K / (2 Σ S̃_k v_k²)``
(the log-likelihood is ``-R Σ S̃_k v_k² + (K/2) log R + const``, S̃ = S/R). Standard errors come from the
observed information (central differences of the gradient); at the bound θ2 = 0 that of θ2 is NaN.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize

from scioc.models.cost import from_normalized
from scioc.models.maxent import loglik_grad
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Grid of θ1 = q11/R (1/rad²) for the starting point.
START_GRID = np.geomspace(0.3, 3e4, 21)
#: θ2 below this counts as on the bound (1/(rad/s)²).
BOUND_TOL = 1e-8
#: θ1 beyond a decade outside the start grid (1/rad²) is the edge of the search, not a measurement
#: (an angle in degrees, or a segment without information).
PLAUSIBLE_THETA1 = (float(START_GRID[0]) / 10.0, float(START_GRID[-1]) * 10.0)


class Estimate(NamedTuple):
    """Maximum-likelihood θ: ``theta`` [q11, q22, R], ``theta1`` (1/rad²), ``theta2`` (1/(rad/s)²), their
    standard errors (NaN where undefined), ``loglik`` in nats, SLSQP's ``converged``, ``iterations`` and
    ``message``, ``grad_norm`` (projected gradient in z per sample), and ``implausible``: θ1 outside
    :data:`PLAUSIBLE_THETA1` (``scioc compare`` leaves it out)."""

    theta: np.ndarray
    theta1: float
    theta2: float
    se_log_theta1: float
    se_theta2: float
    se_log_R: float
    loglik: float
    converged: bool
    iterations: int
    grad_norm: float
    message: str
    implausible: bool = False


def _theta_from_z(z) -> np.ndarray:
    return from_normalized(np.exp(z[0]), max(z[1], 0.0), np.exp(z[2]))


def _ll_grad_z(z, batches, plant: DiscretePlant):
    """Log-likelihood summed over every segment of ``batches`` (one unit's trials) and its gradient in z."""
    th = _theta_from_z(z)
    ll = 0.0
    g = np.zeros(3)
    for batch in batches:
        res = loglik_grad(th, batch, plant)
        ll += float(res.loglik.sum())
        g += res.grad.sum(axis=1)
    q11, q22, R = th
    gz = np.array([q11 * g[0], R * g[1], q11 * g[0] + q22 * g[1] + R * g[2]])
    return ll, gz


def _start(batches, plant: DiscretePlant) -> np.ndarray:
    n = START_GRID.shape[0]
    theta = np.vstack([START_GRID, np.zeros(n), np.ones(n)])
    K = 0
    quad = np.zeros(n)
    rest = np.zeros(n)
    for batch in batches:
        for j in range(batch.n):
            res = loglik_grad(theta, batch.repeat(j, n), plant)
            # At R = 1, Σ S̃ v² = -quad, quad = g_R + θ1 g_q11 - K/2 (Euler; models.maxent._finish).
            q = res.grad[2] + START_GRID * res.grad[0] - 0.5 * batch.K
            quad += q
            rest += res.loglik - q
            K += batch.K
    R_hat = K / np.maximum(-2.0 * quad, 1e-300)
    profiled = -R_hat * (-quad) + 0.5 * K * np.log(R_hat) + rest
    i = int(np.argmax(profiled))
    return np.array([np.log(START_GRID[i]), 0.0, np.log(R_hat[i])])


def _observed_information(z, batches, plant, free) -> np.ndarray:
    h = 1e-4
    idx = np.flatnonzero(free)
    H = np.empty((idx.size, idx.size))
    for a, j in enumerate(idx):
        zp, zm = z.copy(), z.copy()
        step = h if j != 1 else h * max(abs(z[1]), 1e-3)
        zp[j] += step
        zm[j] -= step
        gp = _ll_grad_z(zp, batches, plant)[1]
        gm = _ll_grad_z(zm, batches, plant)[1]
        H[a] = -(gp[idx] - gm[idx]) / (2 * step)
    return 0.5 * (H + H.T)


def identify_segment(batch: SegmentBatch, plant: DiscretePlant, *, maxiter: int = 200) -> Estimate:
    """Maximize the max-ent likelihood of one segment over θ (:func:`identify_unit` of one batch of one row)."""
    if batch.n != 1:
        raise ValueError(f"identify_segment takes a batch of one segment; got {batch.n}")
    return identify_unit([batch], plant, maxiter=maxiter)


def identify_unit(batches, plant: DiscretePlant, *, maxiter: int = 200) -> Estimate:
    """Maximize the summed max-ent likelihood of one unit's trials over one θ: Eq. 17 with d ≥ 1.

    ``batches``: sequence of :class:`scioc.models.segment.SegmentBatch`, every row a trial of the unit.
    """
    batches = list(batches)
    if not batches or any(b.n < 1 for b in batches):
        raise ValueError("identify_unit needs at least one segment")
    K = sum(b.K * b.n for b in batches)
    z0 = _start(batches, plant)
    scale = 1.0 / K  # per-sample log-likelihood: O(1) numbers for SLSQP's tolerances

    def fun(z):
        ll, g = _ll_grad_z(z, batches, plant)
        return -ll * scale, -g * scale

    res = minimize(
        fun,
        z0,
        jac=True,
        method="SLSQP",
        bounds=[(None, None), (0.0, None), (None, None)],
        options={"maxiter": maxiter, "ftol": 1e-12},
    )
    z = np.array(res.x, dtype=float)
    if z[1] <= BOUND_TOL:
        z[1] = 0.0  # on the bound: report θ2 = 0 exactly, not the optimizer's 1e-18
    ll, g = _ll_grad_z(z, batches, plant)
    at_bound = z[1] <= BOUND_TOL
    proj = g.copy()
    if at_bound and proj[1] < 0:
        proj[1] = 0.0  # KKT: a negative slope into the bound is allowed
    free = np.array([True, not at_bound, True])
    se = np.full(3, np.nan)
    try:
        H = _observed_information(z, batches, plant, free)
        cov = np.linalg.inv(H)
        if np.all(np.diag(cov) > 0):
            se[free] = np.sqrt(np.diag(cov))
    except np.linalg.LinAlgError:
        pass
    theta = _theta_from_z(z)
    return Estimate(
        theta=theta,
        theta1=float(theta[0] / theta[2]),
        theta2=float(theta[1] / theta[2]),
        se_log_theta1=float(se[0]),
        se_theta2=float(se[1]),
        se_log_R=float(se[2]),
        loglik=ll,
        converged=bool(res.success),
        iterations=int(res.nit),
        grad_norm=float(np.linalg.norm(proj) / K),
        message=str(res.message),
        implausible=not (PLAUSIBLE_THETA1[0] <= theta[0] / theta[2] <= PLAUSIBLE_THETA1[1]),
    )
