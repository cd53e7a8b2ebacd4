"""Maximum-likelihood identification of the ``delayed`` human: θ, lag, motor noise, and the delay by profile.

At a grid delay (:func:`delay_grid`) L-BFGS-B maximizes the exact likelihood in z (:mod:`.search`)
from the max-ent start and from the optimum at the nearest delay searched before, keeping the
better; σ_m is held at 0 for d = 0. The estimate is the grid delay with the largest maximum, the
smallest on a tie. :func:`profile_argmax` finds it from a coarse pass refined around each peak
it shows, and searches every delay where the profile is too ragged for that. Standard errors
come from the observed information in z over the coordinates not at a bound and are
conditional on the delay. See docs/decisions/delayed-profile-search.md.
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

#: The delays profiled, s: 0 to 300 ms in steps of 10 ms (:func:`delay_grid` rounds them to samples).
DELAY_GRID_S = tuple(round(0.01 * i, 2) for i in range(31))
#: τ_nm (s) and σ_m (N·m per sample) of the fresh start at every delay.
START_TAU_NM, START_SIGMA_M = 0.01, 0.05
#: Profile values within this many nats are a tie (σ_m = 0 gives every delay the d = 0 likelihood).
PROFILE_TIE = 1e-6
#: The searches of the delay's profile: ``"bracket"`` (:func:`profile_argmax`) or ``"grid"`` (every delay).
DELAY_SEARCHES = ("bracket", "grid")
#: :func:`profile_argmax`'s coarse pass searches every this many grid delays (40 ms on the default grid) and the last.
COARSE_STRIDE = 4


#: More peaks than this among the delays searched, and :func:`profile_argmax` searches every delay: refining each
#: costs about as much (9 coarse delays and up to 4 per peak of 31), and so ragged a profile is not one a coarse
#: pass stands for.
MAX_PEAKS = 3


def _peaks(values, tie: float) -> np.ndarray:
    """Positions in ``values`` above both neighbours (one at an end) by more than ``tie``."""
    v = np.concatenate([[-np.inf], values, [-np.inf]])
    return np.flatnonzero((v[1:-1] > v[:-2] + tie) & (v[1:-1] > v[2:] + tie))


def profile_argmax(n: int, value, *, stride: int = COARSE_STRIDE, tie: float = PROFILE_TIE) -> tuple[int, np.ndarray]:
    """The index of the largest of ``value(0)``..``value(n - 1)``, the first within ``tie`` of it, with few calls.

    ``value(i)`` is called at most once per index, in this order: every ``stride``-th index and the
    last; then, while the values found have peaks (above both neighbours found by more than
    ``tie``) with a gap beside them, the gaps' midpoints. A peak's gaps close to single steps, so a
    unimodal profile's argmax is found; so is every peak the coarse pass shows, each refined apart.
    Where the values found show no peak (a flat profile: ties alone) or more than
    :data:`MAX_PEAKS`, every index is evaluated. A peak narrower than ``stride`` on a stretch the
    coarse pass sees as monotone goes unseen.

    Parameters
    ----------
    n : int
        The grid's size.
    value : callable
        ``value(i)``, the profile at index i (nats).
    stride, tie : int, float
        The coarse pass's step (default :data:`COARSE_STRIDE`) and the tie (default :data:`PROFILE_TIE`, nats).

    Returns
    -------
    tuple
        (index, values (n,), NaN where not evaluated).

    Examples
    --------
    >>> p = -np.abs(np.arange(31) - 12.3)
    >>> best, vals = profile_argmax(31, lambda i: p[i])
    >>> best, int(np.isfinite(vals).sum())
    (12, 13)
    """
    vals = np.full(n, np.nan)

    def at(i):
        if np.isnan(vals[i]):
            vals[i] = value(int(i))

    for i in sorted(set(range(0, n, max(int(stride), 1))) | {n - 1}):
        at(i)
    while True:
        idx = np.flatnonzero(~np.isnan(vals))
        peaks = _peaks(vals[idx], tie)
        if peaks.size == 0 or peaks.size > MAX_PEAKS:
            for i in range(n):
                at(i)
            break
        mids = sorted({(idx[k + j - 1] + idx[k + j]) // 2 for k in peaks for j in (0, 1)
                       if 0 < k + j < idx.size and idx[k + j] - idx[k + j - 1] > 1})
        if not mids:
            break
        for i in mids:
            at(i)
    return int(np.flatnonzero(vals >= np.nanmax(vals) - tie)[0]), vals


def delay_grid(dt: float, grid_s=DELAY_GRID_S) -> np.ndarray:
    """The grid's delays in whole samples of ``dt``, duplicates removed (0..30 at 100 Hz)."""
    return np.unique(np.rint(np.asarray(grid_s, dtype=float) / float(dt)).astype(np.int64))


class DelayedEstimate(NamedTuple):
    """Maximum-likelihood estimate of the ``delayed`` human for one unit.

    ``theta``: raw [q11, q22, R]; ``theta1``, ``theta2``: q11/R (1/rad²), q22/R (1/(rad/s)²);
    ``delay`` (samples), ``delay_s``, ``tau_nm`` (s), ``sigma_m`` (N·m per sample); ``se_*``: standard
    errors at the chosen delay (NaN at a bound or without positive information); ``loglik``: summed
    over the unit's segments, nats; ``delays``, ``profile``, ``profile_converged`` (G,): the grid and
    the maximum and convergence at each delay searched (NaN and False at the others);
    ``converged``, ``message``, ``grad_norm`` (projected, per sample) at the chosen delay;
    ``iterations`` over the delays searched. ``lag_at_bound``: τ_nm on :data:`.search.TAU_NM_MAX`, as
    for a torque smoother than the human's (reconstructed); ``implausible``: that, or θ1 outside
    :data:`scioc.models.identify.PLAUSIBLE_THETA1`.
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
                          delays=None, tau0=None, maxiter: int = 300, angles=None, sigma_y: float = 0.0,
                          delay_search: str = "bracket") -> DelayedEstimate:
    """Maximize the ``delayed`` likelihood of one unit over θ, τ_nm, σ_m and (by profile) the delay.

    ``batches``: :class:`SegmentBatch` objects whose rows are the unit's trials, on ``plant``
    (discretized from ``params``); the log-likelihood is their sum. ``delays``: samples to profile (default
    :func:`delay_grid`). ``tau0``: per batch, one :class:`.lag.Warmup` or None (at rest) per row.
    ``maxiter``: L-BFGS-B iterations per search. ``angles``: for a unit without a torque sensor,
    its :class:`.angles.AngleWindow` windows, whose likelihood (noise SD ``sigma_y``, rad) then replaces
    the torques'; ``batches`` give only the start. ``delay_search``: ``"bracket"``
    (:func:`profile_argmax`) or ``"grid"`` (every delay, the whole profile). Returns a :class:`DelayedEstimate`.
    """
    batches = list(batches)
    if not batches or any(b.n < 1 for b in batches):
        raise ValueError("identify_unit_delayed needs at least one segment")
    if delay_search not in DELAY_SEARCHES:
        raise ValueError(f"delay_search must be one of {DELAY_SEARCHES}; got {delay_search!r}")
    warmups = _check_warmups(tau0, batches)
    grid = _check_delays(delays, plant.dt)
    # One thread: parallel work belongs a level up (docs/decisions/delayed-profile-search.md).
    threads = get_num_threads()
    set_num_threads(1)
    angles = tuple(angles) if angles is not None else ()
    if angles and not (np.isfinite(sigma_y) and sigma_y >= 0):
        raise ValueError(f"sigma_y must be a finite number >= 0; got {sigma_y!r}")
    try:
        with threadpool_limits(limits=1, user_api="blas"):
            return _identify(batches, warmups, grid, plant, params, maxiter, angles, float(sigma_y), delay_search)
    finally:
        set_num_threads(threads)


def _identify(batches, warmups, grid, plant, params, maxiter, angles=(), sigma_y=0.0,
              delay_search="bracket") -> DelayedEstimate:
    start = identify_unit(batches, plant)
    zs = np.array([np.log(start.theta1), start.theta2, 1.0, START_TAU_NM, START_SIGMA_M])
    K = sum(w.angles.shape[0] - 1 for w in angles) if angles else sum(b.K * b.n for b in batches)
    unit = SearchUnit(batches, warmups, plant, params, K, float(start.theta[2]), angles, sigma_y)
    fits = [None] * grid.size

    def search(i: int) -> float:
        fit = maximize(zs, int(grid[i]), unit, maxiter)
        done = [j for j in range(grid.size) if fits[j] is not None]
        if done:  # chained from the optimum at the nearest delay searched, the earlier one on a tie
            z_from = fits[min(done, key=lambda j: (abs(j - i), j))].z.copy()
            if z_from[4] <= LAG_NOISE_TOL:
                z_from[4] = START_SIGMA_M  # from σ_m = 0 the gradient in σ_m is 0: start inside
            chained = maximize(z_from, int(grid[i]), unit, maxiter)
            its = fit.iterations + chained.iterations
            fit = (chained if chained.loglik > fit.loglik else fit)._replace(iterations=its)
        fits[i] = fit
        return fit.loglik

    best, profile = profile_argmax(grid.size, search, stride=1 if delay_search == "grid" else COARSE_STRIDE)
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
        profile=profile, profile_converged=np.array([f is not None and f.converged for f in fits]),
        converged=fits[best].converged, iterations=sum(f.iterations for f in fits if f is not None),
        grad_norm=float(np.linalg.norm(projected(g, z, d)) / unit.K), message=fits[best].message,
        implausible=bool(high[3]) or not (PLAUSIBLE_THETA1[0] <= theta1 <= PLAUSIBLE_THETA1[1]),
        lag_at_bound=bool(high[3]),
    )


__all__ = ["COARSE_STRIDE", "DELAY_GRID_S", "DELAY_SEARCHES", "MAX_PEAKS", "PROFILE_TIE", "START_SIGMA_M",
           "START_TAU_NM", "DelayedEstimate", "delay_grid", "identify_unit_delayed", "profile_argmax"]
