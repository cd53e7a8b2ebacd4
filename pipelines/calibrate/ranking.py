"""The one SBC replication loop after the data: sample, thin, rank, randomize the PIT, keep the thinned draws.

Each level simulates its data and calls :func:`sample_and_rank` with its targets (the draws of one
scalar and its true value). Ranks follow simuk (draws strictly below the truth,
:func:`scioc.models.sbc.rank`) among L draws thinned by ArviZ's ESS factor (:func:`thin`); the PIT
``(rank + U) / (L + 1)`` takes U from the replication's generator, one per target in order. Besides
the parameters every replication ranks the log-likelihood of its data at each draw and at the truth
(:func:`loglik_draws`), a test quantity that depends on the data (Modrák et al. 2023).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from arviz_stats.base import array_stats

from scioc.models.maxent import loglik_grad
from scioc.models.sbc import rank

#: Name of the log-likelihood test quantity among the ranked targets.
LOGLIK = "loglik"


class Target(NamedTuple):
    """One ranked quantity: its label, its draws (chains, draws) and its true value."""

    label: str
    draws: np.ndarray
    truth: float


def thin(draws: np.ndarray, L: int) -> tuple[np.ndarray, float]:
    """L of the (chains, draws) ``draws``: each chain thinned by ArviZ's ``ceil(N / min(bulk, tail ESS))``,
    then L evenly spaced (from all draws if fewer than L remain).

    Returns the kept draws, shape (L,), and min(bulk ESS, tail ESS); below L the kept draws are still
    autocorrelated and the summary counts the replication (``low_ess``).
    """
    x = np.atleast_2d(np.asarray(draws, dtype=float))
    ess = float(min(array_stats.ess(x, method="bulk", chain_axis=0, draw_axis=1),
                    array_stats.ess(x, method="tail", prob=0.95, chain_axis=0, draw_axis=1)))
    factor = array_stats.thin_factor(x, chain_axis=0, draw_axis=1) if np.isfinite(ess) and ess > 0 else 1
    pool = array_stats.thin(x, factor=int(factor), chain_axis=0, draw_axis=1).reshape(-1)
    if pool.shape[0] < L:
        pool = x.reshape(-1)
    return pool[np.round(np.linspace(0, pool.shape[0] - 1, L)).astype(int)], ess


def loglik_draws(thetas, batch, plant) -> np.ndarray:
    """Log-likelihood (nats) of a batch's data, summed over its n segments, at each θ of ``thetas``.

    ``thetas``: shape (..., 3, n), [q11, q22, R] per segment; ``plant``: the one the fit assumes.
    Returns shape (...).
    """
    thetas = np.asarray(thetas, dtype=float)
    flat = thetas.reshape((-1,) + thetas.shape[-2:])
    out = np.array([loglik_grad(th, batch, plant).loglik.sum() for th in flat])
    return out.reshape(thetas.shape[:-2])


def sample_and_rank(compiled, config, rng: np.random.Generator, targets, prior_var: dict, *, sample=None) -> dict:
    """Sample a compiled model with nutpie and rank every target's truth among its thinned draws.

    Parameters
    ----------
    compiled : nutpie compiled model with the replication's data (None with ``sample``)
    config : CalibrationConfig
    rng : numpy.random.Generator
        The replication's generator: the sampler's seed, then one U per target.
    targets : callable
        ``targets(posterior) -> list of Target``.
    prior_var : dict
        Prior variance per target label, for the contraction.
    sample : callable, optional
        ``sample(seed) -> DataTree`` with ``posterior`` and ``sample_stats.diverging``, in place of nutpie.

    Returns
    -------
    dict
        Per target label ``truth``, ``ranks``, ``pit_u``, ``ess``, ``contraction`` and ``thinned``; ``divergences``.
    """
    seed = int(rng.integers(2**62))
    if sample is not None:
        trace = sample(seed)
    else:
        import nutpie  # lazy: nutpie imports numba-compiled PyMC machinery (seconds)

        trace = nutpie.sample(compiled, chains=config.chains, tune=config.tune, draws=config.draws, seed=seed,
                              cores=1, progress_bar=False)
    out = {"truth": {}, "ranks": {}, "pit_u": {}, "ess": {}, "contraction": {}, "thinned": {}}
    for t in targets(trace["posterior"]):
        draws = np.asarray(t.draws, dtype=float)
        kept, ess = thin(draws, config.L)
        out["truth"][t.label] = float(t.truth)
        out["ranks"][t.label] = rank(kept, t.truth)
        out["pit_u"][t.label] = float(rng.uniform())
        out["ess"][t.label] = ess
        if t.label in prior_var:
            out["contraction"][t.label] = float(1.0 - draws.var() / prior_var[t.label])
        out["thinned"][t.label] = [float(v) for v in kept]
    out["divergences"] = int(np.asarray(trace["sample_stats"]["diverging"].values).sum())
    return out
