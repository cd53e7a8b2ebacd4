"""The search at one delay of :mod:`.identify`: log-likelihood in z, bounds, L-BFGS-B, information.

z = (log θ1, θ2, w = R_0 / R, τ_nm, σ_m) within :func:`limits`, R_0 the max-ent estimate's R.
L-BFGS-B minimizes minus the log-likelihood per scored sample, in the units of :data:`Z_SCALE`,
with the exact gradient of :func:`.likelihood.loglik_grad`, or of :func:`.angles.window_loglik_grad`
for angle-only units. See docs/decisions/delayed-profile-search.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize

from scioc.models.cost import from_normalized
from scioc.models.delayed.angles import window_loglik_grad
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.delayed.likelihood import loglik_grad
from scioc.models.design import WheelParameters
from scioc.models.identify import BOUND_TOL, PLAUSIBLE_THETA1
from scioc.models.plant import DiscretePlant

#: Largest τ_nm searched, s: ten times McRuer & Jex's neuromuscular lag of about 0.1 s.
TAU_NM_MAX = 1.0
#: Units of z in the optimizer: τ_nm in 0.1 s, σ_m in 0.1 N·m, the others as they are.
Z_SCALE = np.array([1.0, 1.0, 1.0, 0.1, 0.1])
#: τ_nm (s) or σ_m (N·m) below this counts as on its bound 0.
LAG_NOISE_TOL = 1e-6
#: R is searched within this factor of R_0; at R = R_SPAN R_0 the policy noise is negligible.
R_SPAN = 1e6
#: log θ1 is searched within a decade beyond :data:`scioc.models.identify.PLAUSIBLE_THETA1`: a likelihood
#: rising without end (a torque smoother than any lag explains) would drive θ1 to overflow.
LOG_THETA1_RANGE = (float(np.log(PLAUSIBLE_THETA1[0] / 10.0)), float(np.log(PLAUSIBLE_THETA1[1] * 10.0)))
#: Converged: the largest projected gradient component per sample, in the optimizer's units, is below this.
CONVERGED_GTOL = 1e-6
#: σ_m (N·m) at which a search that ended at σ_m = 0 checks the slope (:func:`maximize`).
SADDLE_PROBE = 1e-3


class SearchUnit(NamedTuple):
    """One unit's data: per batch one :class:`.lag.Warmup` or None per row; ``K`` scored samples; ``R0``, w's
    scale. With ``angles`` (noise SD ``sigma_y``, rad) the angles' likelihood replaces the torques'."""

    batches: list
    warmups: list
    plant: DiscretePlant
    params: WheelParameters
    K: int
    R0: float
    angles: tuple = ()
    sigma_y: float = 0.0


def theta_from_z(z, R0: float) -> np.ndarray:
    """[q11, q22, R] of z: θ1 = exp(z0), θ2 = z1, R = R0 / z2."""
    return from_normalized(np.exp(z[0]), max(z[1], 0.0), R0 / z[2])


#: Smallest |z| the finite-difference steps of :func:`observed_information` scale with.
STEP_FLOOR = np.array([1.0, 1e-3, 1.0, 1e-2 * Z_SCALE[3], 1e-2 * Z_SCALE[4]])


def _to_z(g, th, w: float) -> np.ndarray:
    """The gradient in (q11, q22, R, τ_nm, σ_m) carried to z; θ = (θ1 R, θ2 R, R), R = R0 / w."""
    q11, q22, R = th
    return np.array([q11 * g[0], R * g[1], -(q11 * g[0] + q22 * g[1] + R * g[2]) / w, g[3], g[4]])


def loglik_grad_z(z, d: int, unit: SearchUnit):
    """Log-likelihood of the unit at delay d and z (unscaled) and its gradient in z."""
    th = theta_from_z(z, unit.R0)
    tau, sig = max(z[3], 0.0), max(z[4], 0.0)
    ll = 0.0
    g = np.zeros(5)
    if unit.angles:
        for w in unit.angles:
            res = window_loglik_grad(th, tau, sig, d, w, unit.plant, sigma_y=unit.sigma_y, params=unit.params)
            ll += res.loglik
            g += res.grad
        return ll, _to_z(g, th, z[2])
    lag = lag_coefficients(tau, unit.plant.dt, unit.params)
    for batch, warm in zip(unit.batches, unit.warmups):
        t0, dt0 = window_tau0(warm, lag.a, lag.alpha)
        res = loglik_grad(th, batch, unit.plant, tau_nm=tau, sigma_m=sig, delay=d, tau0=t0, dtau0=dt0,
                          params=unit.params)
        ll += float(res.loglik.sum())
        g += res.grad.sum(axis=1)
    return ll, _to_z(g, th, z[2])


def limits(d: int) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of z (unscaled); σ_m is held at 0 for d = 0 (module docstring)."""
    lo = np.array([LOG_THETA1_RANGE[0], 0.0, 1.0 / R_SPAN, 0.0, 0.0])
    hi = np.array([LOG_THETA1_RANGE[1], np.inf, R_SPAN, TAU_NM_MAX, 0.0 if d == 0 else np.inf])
    return lo, hi


def at_bound(z, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Which coordinates sit on their lower and on their upper bound."""
    lo, hi = limits(d)
    tol = np.array([1e-9, BOUND_TOL, 1e-6 / R_SPAN, LAG_NOISE_TOL, LAG_NOISE_TOL])
    finite = np.isfinite(hi)
    top = np.where(finite, hi, 0.0)
    return z <= lo + tol, finite & (z >= top - np.maximum(tol, 1e-9 * np.abs(top)))


def projected(g, z, d: int) -> np.ndarray:
    """The gradient without its components that push into an active bound (KKT)."""
    low, high = at_bound(z, d)
    out = g.copy()
    out[(low & (g < 0)) | (high & (g > 0)) | (low & high)] = 0.0
    return out


class SearchResult(NamedTuple):
    """One search: z (unscaled), its log-likelihood, whether it converged, iterations, the optimizer's message."""

    z: np.ndarray
    loglik: float
    converged: bool
    iterations: int
    message: str


def _lbfgsb(z0, d: int, unit: SearchUnit, maxiter: int) -> SearchResult:
    def fun(y):
        ll, g = loglik_grad_z(y * Z_SCALE, d, unit)
        return -ll / unit.K, -g * Z_SCALE / unit.K

    lo, hi = limits(d)
    bounds = [(None if not np.isfinite(a) else a / c, None if not np.isfinite(b) else b / c)
              for a, b, c in zip(lo, hi, Z_SCALE)]
    res = minimize(fun, z0 / Z_SCALE, jac=True, method="L-BFGS-B", bounds=bounds,
                   options={"maxiter": maxiter, "ftol": 1e-13, "gtol": 1e-8})
    z = np.array(res.x, dtype=float) * Z_SCALE
    g = -np.asarray(res.jac) / Z_SCALE * unit.K
    kkt = np.max(np.abs(projected(g, z, d) * Z_SCALE)) / unit.K <= CONVERGED_GTOL
    return SearchResult(z, -float(res.fun) * unit.K, bool(res.success) or bool(kkt), int(res.nit), str(res.message))


def maximize(z0, d: int, unit: SearchUnit, maxiter: int) -> SearchResult:
    """The profile's inner maximization at delay d from z0 (unscaled).

    σ_m = 0 is stationary at every d; a search ending there while the likelihood rises at
    σ_m = :data:`SADDLE_PROBE` restarts from it.
    """
    z0 = np.array(z0, dtype=float)
    if d == 0:
        z0[4] = 0.0
    fit = _lbfgsb(z0, d, unit, maxiter)
    if d > 0 and fit.z[4] <= LAG_NOISE_TOL:
        probe = fit.z.copy()
        probe[4] = SADDLE_PROBE
        if loglik_grad_z(probe, d, unit)[1][4] > 0:
            again = _lbfgsb(probe, d, unit, maxiter)
            if again.loglik > fit.loglik:
                fit = again._replace(iterations=again.iterations + fit.iterations)
    return fit


def observed_information(z, d: int, unit: SearchUnit, free) -> np.ndarray:
    """Minus the Hessian of the log-likelihood in z over the ``free`` coordinates (central differences)."""
    h = 1e-4
    idx = np.flatnonzero(free)
    H = np.empty((idx.size, idx.size))
    for a, j in enumerate(idx):
        step = h * (1.0 if j == 0 else max(abs(z[j]), STEP_FLOOR[j]))
        if j > 0:
            step = min(step, 0.5 * z[j])  # stay inside θ2, w, τ_nm, σ_m > 0 (τ_nm's derivative is two-sided there)
        zp, zm = z.copy(), z.copy()
        zp[j] += step
        zm[j] -= step
        H[a] = -(loglik_grad_z(zp, d, unit)[1][idx] - loglik_grad_z(zm, d, unit)[1][idx]) / (2 * step)
    return 0.5 * (H + H.T)


__all__ = [
    "CONVERGED_GTOL",
    "LAG_NOISE_TOL",
    "LOG_THETA1_RANGE",
    "R_SPAN",
    "SADDLE_PROBE",
    "STEP_FLOOR",
    "TAU_NM_MAX",
    "Z_SCALE",
    "SearchResult",
    "SearchUnit",
    "at_bound",
    "limits",
    "loglik_grad_z",
    "maximize",
    "observed_information",
    "projected",
    "theta_from_z",
]
