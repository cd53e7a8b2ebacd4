"""Maximum-likelihood identification of the ``delayed`` human: θ, lag, motor noise, and the delay by profile.

The continuous parameters are searched, for each delay d of a grid, in::

    z = (log θ1, θ2 >= 0, log R, τ_nm in [0, TAU_NM_MAX], σ_m >= 0)

(θ1 = q11/R and θ2 = q22/R as in :mod:`models.identify`) with L-BFGS-B and the exact
gradient of :func:`models.delayed.likelihood.loglik_grad`, whose τ_nm-derivative
includes the arm torque at each window's start when it follows from the torques before
the window (:class:`models.delayed.lag.Warmup`). The delay is discrete, so it is
profiled: the log-likelihood maximized over z at every grid delay
(:data:`DELAY_GRID_S`, 0-300 ms in steps of 10 ms, rounded to whole samples:
:func:`delay_grid`), and the estimate is the grid delay of the largest one (the
smallest such delay on a tie).

Choices
-------
* Start. The max-ent estimate (:func:`models.identify.identify_unit`) with
  τ_nm = :data:`START_TAU_NM` and σ_m = :data:`START_SIGMA_M`, at d = 0; each following
  delay starts from the previous one's optimum (the profile changes smoothly with d).
  A second start from the max-ent point at every delay changed no profile maximum on
  the recovery cases, so only the chained start is run (tested against fresh starts).
* σ_m at d = 0. Without a delay the motor noise enters the residual as
  ``ε_k + m_k``, two white noises: the likelihood depends on 1/(2 S_k) + σ_m², which
  R alone can match except where S_k moves at the plan's end (not at all with a
  preview). σ_m is therefore held at 0 for d = 0 (the ``lag`` model); R absorbs it.
  At every d, σ_m = 0 gives the d = 0 likelihood (the delay is invisible without
  unknown noise), so the profile never falls below its d = 0 value.
* τ_nm's upper bound :data:`TAU_NM_MAX` keeps the search where α = 1 - O(dt/τ_nm)
  is well away from 1.
* Scaling: the objective is the log-likelihood per torque sample, and τ_nm and σ_m
  enter the optimizer in units of :data:`Z_SCALE` (0.1 s and 0.1 N·m), so every
  coordinate moves by O(1) over its plausible range.

Standard errors at the chosen delay come from the observed information in z (central
differences of the exact gradient, as in :mod:`models.identify`), over the coordinates
not at a bound; a coordinate at its bound (θ2 = 0, τ_nm = 0, σ_m = 0, σ_m at d = 0,
and R at :data:`R_SPAN`) gets NaN. They are conditional on the delay.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import minimize
from threadpoolctl import threadpool_limits

from models.cost import from_normalized
from models.delayed.lag import lag_coefficients, window_tau0
from models.delayed.likelihood import loglik_grad
from models.design import WheelParameters
from models.identify import BOUND_TOL, PLAUSIBLE_THETA1, identify_unit
from models.plant import DiscretePlant

#: The delays profiled, s: 0 to 300 ms in steps of 10 ms (rounded to whole samples by :func:`delay_grid`).
DELAY_GRID_S = tuple(round(0.01 * i, 2) for i in range(31))
#: τ_nm (s) and σ_m (N·m per sample) the search starts from at d = 0.
START_TAU_NM, START_SIGMA_M = 0.01, 0.05
#: Largest τ_nm searched, s (McRuer & Jex: about 0.1 s; 10 times that is no longer a neuromuscular lag).
TAU_NM_MAX = 1.0
#: Units of z's last two coordinates in the optimizer: τ_nm in 0.1 s, σ_m in 0.1 N·m.
Z_SCALE = np.array([1.0, 1.0, 1.0, 0.1, 0.1])
#: τ_nm (s) or σ_m (N·m) below this counts as on its bound 0.
LAG_NOISE_TOL = 1e-6
#: R is searched up to this multiple of the max-ent estimate's R (the start). The max-ent fit
#: gives all the variability to the policy noise; where the motor noise explains all of it,
#: the likelihood keeps rising, ever more slowly, as R -> ∞ (policy noise -> 0), and R then
#: stops here, with a policy noise 1/1000 of the max-ent fit's SD: a bound like θ2 = 0.
R_SPAN = 1e6
#: A search counts as converged where the largest projected gradient component in the
#: optimizer's units, per torque sample, is at most this (L-BFGS-B's line search can stop
#: on rounding just short of its own tolerance).
CONVERGED_GTOL = 1e-6
#: σ_m (N·m) at which a search that ended at σ_m = 0 checks the slope (:func:`_maximize`).
SADDLE_PROBE = 1e-3


def delay_grid(dt: float, grid_s=DELAY_GRID_S) -> np.ndarray:
    """The grid delays in whole samples of ``dt`` (rounded, duplicates removed): 0..30 at 100 Hz, 0..60 step 2 at 200 Hz."""
    return np.unique(np.rint(np.asarray(grid_s, dtype=float) / float(dt)).astype(np.int64))


class DelayedEstimate(NamedTuple):
    """Maximum-likelihood estimate of the ``delayed`` human for one unit.

    Attributes
    ----------
    theta : ndarray, shape (3,)
        Raw [q11, q22, R] of the command cost.
    theta1, theta2 : float
        q11/R (1/rad²) and q22/R (1/(rad/s)²).
    delay : int
        Perceptual delay, samples (the profile's maximum).
    delay_s : float
        The same in s.
    tau_nm : float
        Neuromuscular time constant, s.
    sigma_m : float
        Motor-noise SD per sample, N·m.
    se_log_theta1, se_theta2, se_log_R, se_tau_nm, se_sigma_m : float
        Standard errors at the chosen delay (NaN at a bound or where the information
        is not positive definite).
    loglik : float
        Maximized log-likelihood, nats (summed over the unit's segments).
    delays : ndarray of int, shape (G,)
        The grid, samples.
    profile : ndarray, shape (G,)
        Log-likelihood maximized over the continuous parameters at each grid delay.
    profile_converged : ndarray of bool, shape (G,)
    converged : bool
        The optimizer converged at the chosen delay.
    iterations : int
        Optimizer iterations summed over the grid.
    grad_norm : float
        Norm of the projected gradient in z per torque sample at the solution.
    message : str
    implausible : bool
        θ1 outside :data:`models.identify.PLAUSIBLE_THETA1`.
    """

    theta: np.ndarray
    theta1: float
    theta2: float
    delay: int
    delay_s: float
    tau_nm: float
    sigma_m: float
    se_log_theta1: float
    se_theta2: float
    se_log_R: float
    se_tau_nm: float
    se_sigma_m: float
    loglik: float
    delays: np.ndarray
    profile: np.ndarray
    profile_converged: np.ndarray
    converged: bool
    iterations: int
    grad_norm: float
    message: str
    implausible: bool


class _Unit(NamedTuple):
    """One unit's data and the search's fixed settings."""

    batches: list
    warmups: list
    plant: DiscretePlant
    params: WheelParameters
    K: int
    log_r_max: float


def _theta_from_z(z) -> np.ndarray:
    return from_normalized(np.exp(z[0]), max(z[1], 0.0), np.exp(z[2]))


def _ll_grad(z, d: int, unit: _Unit):
    """Log-likelihood of the unit at delay d and z (unscaled) and its gradient in z."""
    th = _theta_from_z(z)
    tau, sig = max(z[3], 0.0), max(z[4], 0.0)
    lag = lag_coefficients(tau, unit.plant.dt, unit.params)
    ll = 0.0
    g = np.zeros(5)
    for batch, warm in zip(unit.batches, unit.warmups):
        t0, dt0 = window_tau0(warm, lag.a, lag.alpha)
        res = loglik_grad(th, batch, unit.plant, tau_nm=tau, sigma_m=sig, delay=d, tau0=t0, dtau0=dt0,
                          params=unit.params)
        ll += float(res.loglik.sum())
        g += res.grad.sum(axis=1)
    q11, q22, R = th
    gz = np.array([q11 * g[0], R * g[1], q11 * g[0] + q22 * g[1] + R * g[2], g[3], g[4]])
    return ll, gz


def _bounds(d: int, unit: _Unit) -> list:
    sig_hi = 0.0 if d == 0 else None  # σ_m is not identified without a delay (module docstring)
    return [(None, None), (0.0, None), (None, unit.log_r_max), (0.0, TAU_NM_MAX / Z_SCALE[3]), (0.0, sig_hi)]


def _at_bound(z, d: int, unit: _Unit) -> np.ndarray:
    return np.array([False, z[1] <= BOUND_TOL, z[2] >= unit.log_r_max - 1e-6, z[3] <= LAG_NOISE_TOL,
                     d == 0 or z[4] <= LAG_NOISE_TOL])


def _projected(g, z, d: int, unit: _Unit) -> np.ndarray:
    """The gradient without its components that push into an active bound (KKT)."""
    bound = _at_bound(z, d, unit)
    out = g.copy()
    lower = bound & (np.arange(5) != 2)
    out[lower & (g < 0)] = 0.0
    out[2] = 0.0 if bound[2] and g[2] > 0 else out[2]
    out[4] = 0.0 if d == 0 else out[4]
    return out


class _Fit(NamedTuple):
    z: np.ndarray
    loglik: float
    converged: bool
    iterations: int
    message: str


def _lbfgsb(z0, d: int, unit: _Unit, maxiter: int) -> _Fit:
    def fun(y):
        ll, g = _ll_grad(y * Z_SCALE, d, unit)
        return -ll / unit.K, -g * Z_SCALE / unit.K

    res = minimize(fun, z0 / Z_SCALE, jac=True, method="L-BFGS-B", bounds=_bounds(d, unit),
                   options={"maxiter": maxiter, "ftol": 1e-13, "gtol": 1e-8})
    z = np.array(res.x, dtype=float) * Z_SCALE
    # Converged: the optimizer says so, or it stopped (a line search that cannot improve on
    # rounding) where the projected gradient per sample is below CONVERGED_GTOL.
    g = -np.asarray(res.jac) / Z_SCALE * unit.K
    kkt = np.max(np.abs(_projected(g, z, d, unit) * Z_SCALE)) / unit.K <= CONVERGED_GTOL
    return _Fit(z, -float(res.fun) * unit.K, bool(res.success) or bool(kkt), int(res.nit), str(res.message))


def _maximize(z0, d: int, unit: _Unit, maxiter: int) -> _Fit:
    """The profile's inner maximization at delay d from z0 (unscaled).

    σ_m = 0 is a stationary point at every d (the likelihood depends on σ_m²); if the
    search ends there although the likelihood rises with σ_m² (the derivative at
    σ_m = :data:`SADDLE_PROBE`, divided by 2σ_m, is positive), it is restarted from that σ_m.
    """
    z0 = np.array(z0, dtype=float)
    if d == 0:
        z0[4] = 0.0
    fit = _lbfgsb(z0, d, unit, maxiter)
    if d > 0 and fit.z[4] <= LAG_NOISE_TOL:
        probe = fit.z.copy()
        probe[4] = SADDLE_PROBE
        if _ll_grad(probe, d, unit)[1][4] > 0:
            again = _lbfgsb(probe, d, unit, maxiter)
            if again.loglik > fit.loglik:
                fit = again._replace(iterations=again.iterations + fit.iterations)
    return fit


def _observed_information(z, d: int, unit: _Unit, free) -> np.ndarray:
    h = 1e-4
    idx = np.flatnonzero(free)
    H = np.empty((idx.size, idx.size))
    for a, j in enumerate(idx):
        step = h * (1.0 if j in (0, 2) else max(abs(z[j]), 1e-3 if j == 1 else 1e-2 * Z_SCALE[j]))
        if j == 3:
            step = min(step, 0.5 * z[3])  # stay inside τ_nm > 0, where the derivative is two-sided
        zp, zm = z.copy(), z.copy()
        zp[j] += step
        zm[j] -= step
        H[a] = -(_ll_grad(zp, d, unit)[1][idx] - _ll_grad(zm, d, unit)[1][idx]) / (2 * step)
    return 0.5 * (H + H.T)


def _check_warmups(tau0, batches) -> list:
    if tau0 is None:
        return [[None] * b.n for b in batches]
    tau0 = list(tau0)
    if len(tau0) != len(batches) or any(len(w) != b.n for w, b in zip(tau0, batches)):
        raise ValueError("tau0 needs one entry per batch, each with one Warmup (or None) per row of its batch")
    return [list(w) for w in tau0]


def _check_delays(delays, dt: float) -> np.ndarray:
    grid = delay_grid(dt) if delays is None else np.asarray(delays)
    if grid.ndim != 1 or grid.size < 1 or np.any(grid < 0) or np.any(grid != np.round(grid)):
        raise ValueError(f"delays must be a non-empty vector of whole numbers of samples >= 0; got {delays!r}")
    return grid.astype(np.int64)


def identify_unit_delayed(batches, plant: DiscretePlant, *, params: WheelParameters = WheelParameters(),
                          delays=None, tau0=None, maxiter: int = 300) -> DelayedEstimate:
    """Maximize the ``delayed`` likelihood of one unit's segments over θ, τ_nm, σ_m and the delay (profile).

    Parameters
    ----------
    batches : sequence of SegmentBatch
        Every row of every batch is a trial of the same unit
        (:func:`models.segment.prepare_batch`); the log-likelihood is their sum.
    plant : DiscretePlant
        The wheel at the recording's sample time.
    params : WheelParameters
        The wheel ``plant`` was discretized from.
    delays : array_like of int, optional
        The delays to profile, samples (default :func:`delay_grid` of ``plant.dt``).
    tau0 : sequence, optional
        Per batch, a sequence with one :class:`models.delayed.lag.Warmup` (the torques
        before that window; τ_0 then follows the lag) or None (at rest, τ_0 = 0) per
        row. Default: every window starts at rest.
    maxiter : int
        L-BFGS-B iterations per delay.

    Returns
    -------
    DelayedEstimate

    Examples
    --------
    >>> from models.delayed import sample_delayed
    >>> from models.plant import discretize
    >>> from models.segment import prepare_batch
    >>> plant = discretize(0.01)
    >>> ref = 0.3 * np.sin(np.linspace(0.0, 12.0, 1001))
    >>> draw = sample_delayed([400.0, 0.0, 20.0], [0.0, 0.0], ref, plant, np.random.default_rng(0), tau_nm=0.06,
    ...                       sigma_m=0.25, delay=12, n_obs=800)
    >>> est = identify_unit_delayed([prepare_batch(plant, draw.segments)], plant, delays=[0, 6, 12, 18])
    >>> int(est.delay), est.profile.shape
    (12, (4,))
    """
    batches = list(batches)
    if not batches or any(b.n < 1 for b in batches):
        raise ValueError("identify_unit_delayed needs at least one segment")
    warmups = _check_warmups(tau0, batches)
    grid = _check_delays(delays, plant.dt)
    # One BLAS thread: L-BFGS-B's small products otherwise wake OpenBLAS's pool, whose
    # threads then spin (measured: twice the CPU time for the same wall time).
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify(batches, warmups, grid, plant, params, maxiter)


def _identify(batches, warmups, grid, plant, params, maxiter) -> DelayedEstimate:
    start = identify_unit(batches, plant)
    zs = np.array([np.log(start.theta1), start.theta2, np.log(start.theta[2]), START_TAU_NM, START_SIGMA_M])
    unit = _Unit(batches, warmups, plant, params, sum(b.K * b.n for b in batches), zs[2] + np.log(R_SPAN))
    fits = []
    z = zs
    for d in grid:
        z_from = z.copy()
        if d > 0 and z_from[4] <= LAG_NOISE_TOL:
            z_from[4] = START_SIGMA_M  # from σ_m = 0 the gradient in σ_m is 0: start inside
        fits.append(_maximize(z_from, int(d), unit, maxiter))
        z = fits[-1].z
    profile = np.array([f.loglik for f in fits])
    best = int(np.argmax(profile))
    d, z = int(grid[best]), fits[best].z.copy()
    bound = _at_bound(z, d, unit)
    z[bound & (np.arange(5) != 2)] = 0.0  # on a bound 0: report exactly 0, not the optimizer's 1e-18
    z[2] = unit.log_r_max if bound[2] else z[2]
    ll, g = _ll_grad(z, d, unit)
    se = np.full(5, np.nan)
    try:
        cov = np.linalg.inv(_observed_information(z, d, unit, ~bound))
        if np.all(np.diag(cov) > 0):
            se[~bound] = np.sqrt(np.diag(cov))
    except np.linalg.LinAlgError:
        pass
    theta = _theta_from_z(z)
    theta1 = float(theta[0] / theta[2])
    return DelayedEstimate(
        theta=theta, theta1=theta1, theta2=float(theta[1] / theta[2]), delay=d, delay_s=d * float(plant.dt),
        tau_nm=float(z[3]), sigma_m=float(z[4]), se_log_theta1=float(se[0]), se_theta2=float(se[1]),
        se_log_R=float(se[2]), se_tau_nm=float(se[3]), se_sigma_m=float(se[4]), loglik=ll, delays=grid,
        profile=profile, profile_converged=np.array([f.converged for f in fits]),
        converged=fits[best].converged, iterations=sum(f.iterations for f in fits),
        grad_norm=float(np.linalg.norm(_projected(g, z, d, unit)) / unit.K), message=fits[best].message,
        implausible=not (PLAUSIBLE_THETA1[0] <= theta1 <= PLAUSIBLE_THETA1[1]),
    )


__all__ = ["DELAY_GRID_S", "DelayedEstimate", "START_SIGMA_M", "START_TAU_NM", "TAU_NM_MAX", "delay_grid",
           "identify_unit_delayed"]
