"""Maximum-likelihood identification of the ``delayed`` human: θ, lag, motor noise, and the delay by profile.

The continuous parameters are searched, for each delay d of a grid, in::

    z = (log θ1, θ2 >= 0, w = R_0 / R > 0, τ_nm in [0, 1 s], σ_m >= 0)

(θ1 = q11/R and θ2 = q22/R as in :mod:`scioc.models.identify`; R_0 the max-ent estimate's R)
with L-BFGS-B and the exact gradient of :func:`scioc.models.delayed.likelihood.loglik_grad`,
whose τ_nm-derivative includes the arm torque at each window's start when it follows
from the torques before the window (:class:`scioc.models.delayed.lag.Warmup`). The delay is
discrete, so it is profiled: the log-likelihood maximized over z at every grid delay
(:data:`DELAY_GRID_S`, 0-300 ms in steps of 10 ms, rounded to whole samples:
:func:`delay_grid`), and the estimate is the grid delay of the largest one (the
smallest such delay on a tie, :data:`PROFILE_TIE`).

Choices
-------
* Starts. At every delay two searches: from the max-ent estimate
  (:func:`scioc.models.identify.identify_unit`) with τ_nm = :data:`START_TAU_NM` and
  σ_m = :data:`START_SIGMA_M`, and from the previous delay's optimum; the better one is
  kept. Either alone misses the maximum on some data (measured: the chained search
  stuck at σ_m = 0 on 8 SC trials with a 0.12-s delay, 16 nats below; the fresh one
  10 nats below past the true delay on another), and both together cost about twice
  one. Tested against searches from several starts at every delay.
* The policy noise's scale, w = R_0/R, not log R. The policy noise (variance
  ∝ 1/R) and the motor noise can both explain the torque's variability; where the motor
  noise explains all of it the likelihood is largest at R = ∞. In log R that is a
  plateau at infinite distance, where the gradient vanishes: a search that drifts onto
  it stays there at the next delays too (measured: a profile 10 nats too low past the
  true delay). In w it is the bound w = 0 (here :data:`scioc.models.delayed.search.R_SPAN`:
  R at most 1e6 R_0), reached with a finite slope and left when the slope turns.
* σ_m at d = 0. Without a delay the motor noise enters the residual as
  ``ε_k + m_k``, two white noises: the likelihood depends on 1/(2 S_k) + σ_m², which
  R alone can match except where S_k moves at the plan's end (not at all with a
  preview). σ_m is therefore held at 0 for d = 0 (the ``lag`` model); R absorbs it.
  At every d, σ_m = 0 gives the d = 0 likelihood (the delay is invisible without
  unknown noise), so the profile never falls below its d = 0 value. σ_m = 0 is a
  stationary point at every d; a search that ends there checks the slope beside it
  (:data:`scioc.models.delayed.search.SADDLE_PROBE`).
* τ_nm's upper bound :data:`scioc.models.delayed.search.TAU_NM_MAX` keeps the search where
  α = 1 - O(dt/τ_nm) is well away from 1.
* Scaling: the objective is the log-likelihood per torque sample, and τ_nm and σ_m
  enter the optimizer in units of :data:`scioc.models.delayed.search.Z_SCALE` (0.1 s and
  0.1 N·m), so every coordinate moves by O(1) over its plausible range.
* One thread (numba and BLAS) while it runs: units are independent, so parallel work
  belongs a level up.
* The whole grid, not a coarse grid refined: it costs about 1 s of one core per unit
  of the default study (15 s at 100 Hz), and the profile is not smooth in d (a few nats
  between neighbours), so a coarse grid can miss the maximum.

Standard errors at the chosen delay come from the observed information in z (central
differences of the exact gradient, as in :mod:`scioc.models.identify`), over the coordinates
not at a bound; a coordinate at its bound (θ2 = 0, τ_nm = 0, σ_m = 0, σ_m at d = 0,
and R at its upper bound) gets NaN; ``se_log_R = se_w / w``. They are conditional on
the delay.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import get_num_threads, set_num_threads
from threadpoolctl import threadpool_limits

from scioc.models.delayed.search import (
    LAG_NOISE_TOL,
    SearchUnit,
    at_bound,
    limits,
    loglik_grad_z,
    maximize,
    observed_information,
    projected,
    theta_from_z,
)
from scioc.models.design import WheelParameters
from scioc.models.identify import PLAUSIBLE_THETA1, identify_unit
from scioc.models.plant import DiscretePlant

#: The delays profiled, s: 0 to 300 ms in steps of 10 ms (rounded to whole samples by :func:`delay_grid`).
DELAY_GRID_S = tuple(round(0.01 * i, 2) for i in range(31))
#: τ_nm (s) and σ_m (N·m per sample) the search starts from at d = 0.
START_TAU_NM, START_SIGMA_M = 0.01, 0.05
#: Profile values within this many nats are a tie, resolved to the smallest delay (with
#: σ_m = 0 every delay has the d = 0 likelihood up to rounding).
PROFILE_TIE = 1e-6


def delay_grid(dt: float, grid_s=DELAY_GRID_S) -> np.ndarray:
    """The grid's delays in whole samples of ``dt``, rounded, duplicates removed.

    0..30 at 100 Hz, 0..60 in steps of 2 at 200 Hz, 0..15 at 50 Hz.
    """
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
        θ1 outside :data:`scioc.models.identify.PLAUSIBLE_THETA1`, or ``lag_at_bound``: the estimate
        is at the edge of the search, not a measurement.
    lag_at_bound : bool
        τ_nm on its upper bound :data:`scioc.models.delayed.search.TAU_NM_MAX`: the likelihood still
        rose with τ_nm there, as it does for a torque smoother than the human's (one
        reconstructed from encoder angles: a smoothed torque looks like a slow lag).
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
    lag_at_bound: bool


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
                          delays=None, tau0=None, maxiter: int = 300, angles=None,
                          sigma_y: float = 0.0) -> DelayedEstimate:
    """Maximize the ``delayed`` likelihood of one unit's segments over θ, τ_nm, σ_m and the delay (profile).

    Parameters
    ----------
    batches : sequence of SegmentBatch
        Every row of every batch is a trial of the same unit
        (:func:`scioc.models.segment.prepare_batch`); the log-likelihood is their sum.
    plant : DiscretePlant
        The wheel at the recording's sample time.
    params : WheelParameters
        The wheel ``plant`` was discretized from.
    delays : array_like of int, optional
        The delays to profile, samples (default :func:`delay_grid` of ``plant.dt``).
    tau0 : sequence, optional
        Per batch, a sequence with one :class:`scioc.models.delayed.lag.Warmup` (the torques
        before that window; τ_0 then follows the lag) or None (at rest, τ_0 = 0) per
        row. Default: every window starts at rest.
    maxiter : int
        L-BFGS-B iterations per delay.
    angles : sequence of AngleWindow, optional
        The unit's windows as recorded by the encoder (:class:`scioc.models.delayed.angles.AngleWindow`):
        the likelihood is then that of the angles (:func:`scioc.models.delayed.angles.window_loglik`,
        gradient by central differences), and ``batches`` (the reconstructed torques) only
        give the max-ent start and R_0. For recordings without a torque sensor.
    sigma_y : float
        The angle's noise SD with ``angles``, rad (an encoder step q: q / sqrt(12)).

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
    # One thread. BLAS: L-BFGS-B's small products otherwise wake OpenBLAS's pool, whose threads
    # then spin (measured: twice the CPU time for the same wall time). numba (its setting is
    # the calling thread's): a parallel region per evaluation of a unit of a few trials costs
    # more than the work on a busy machine (measured: 6 times the time of one thread).
    threads = get_num_threads()
    set_num_threads(1)
    angles = tuple(angles) if angles is not None else ()
    if angles and not (np.isfinite(sigma_y) and sigma_y >= 0):
        raise ValueError(f"sigma_y must be a finite number >= 0; got {sigma_y!r}")
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            return _identify(batches, warmups, grid, plant, params, maxiter, angles, float(sigma_y))
    finally:
        set_num_threads(threads)


def _identify(batches, warmups, grid, plant, params, maxiter, angles=(), sigma_y=0.0) -> DelayedEstimate:
    start = identify_unit(batches, plant)
    zs = np.array([np.log(start.theta1), start.theta2, 1.0, START_TAU_NM, START_SIGMA_M])
    K = sum(w.angles.shape[0] - 1 for w in angles) if angles else sum(b.K * b.n for b in batches)
    unit = SearchUnit(batches, warmups, plant, params, K, float(start.theta[2]), angles, sigma_y)
    fits = []
    z = zs
    for d in grid:
        fit = maximize(zs, int(d), unit, maxiter)
        if d > grid[0]:
            z_from = z.copy()
            if z_from[4] <= LAG_NOISE_TOL:
                z_from[4] = START_SIGMA_M  # from σ_m = 0 the gradient in σ_m is 0: start inside
            chained = maximize(z_from, int(d), unit, maxiter)
            its = fit.iterations + chained.iterations
            fit = (chained if chained.loglik > fit.loglik else fit)._replace(iterations=its)
        fits.append(fit)
        z = fit.z
    profile = np.array([f.loglik for f in fits])
    best = int(np.flatnonzero(profile >= profile.max() - PROFILE_TIE)[0])
    d, z = int(grid[best]), fits[best].z.copy()
    low, high = at_bound(z, d)
    lo, hi = limits(d)
    z = np.where(low, lo, np.where(high, hi, z))  # on a bound: exactly there, not the optimizer's 1e-18 beside it
    bound = low | high
    ll, g = loglik_grad_z(z, d, unit)
    se = np.full(5, np.nan)
    try:
        cov = np.linalg.inv(observed_information(z, d, unit, ~bound))
        if np.all(np.diag(cov) > 0):
            se[~bound] = np.sqrt(np.diag(cov))
    except np.linalg.LinAlgError:
        pass
    se[2] /= z[2]  # se of log R = se of log w
    theta = theta_from_z(z, unit.R0)
    theta1 = float(theta[0] / theta[2])
    return DelayedEstimate(
        theta=theta, theta1=theta1, theta2=float(theta[1] / theta[2]), delay=d, delay_s=d * float(plant.dt),
        tau_nm=float(z[3]), sigma_m=float(z[4]), se_log_theta1=float(se[0]), se_theta2=float(se[1]),
        se_log_R=float(se[2]), se_tau_nm=float(se[3]), se_sigma_m=float(se[4]), loglik=ll, delays=grid,
        profile=profile, profile_converged=np.array([f.converged for f in fits]),
        converged=fits[best].converged, iterations=sum(f.iterations for f in fits),
        grad_norm=float(np.linalg.norm(projected(g, z, d)) / unit.K), message=fits[best].message,
        implausible=bool(high[3]) or not (PLAUSIBLE_THETA1[0] <= theta1 <= PLAUSIBLE_THETA1[1]),
        lag_at_bound=bool(high[3]),
    )


__all__ = ["DELAY_GRID_S", "DelayedEstimate", "PROFILE_TIE", "START_SIGMA_M", "START_TAU_NM", "delay_grid",
           "identify_unit_delayed"]
