"""Prior predictive checks of the hierarchical models (docs/decisions/hierarchical-priors.md).

Joint prior draws of every unit parameter, each segment of a study simulated exactly from the human the likelihood
assumes, and the RMS torque and tracking error per level beside the observed ones. The torque's lower end is the
deterministic torque that tracking needs, which no prior on the jitter can lower.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pymc as pm

from scioc.models.bayes.delayed_model import DelayedPriors, build_delayed_model
from scioc.models.bayes.delayed_op import pack_tau0, warmups_of
from scioc.models.bayes.hierarchical import Priors, build_model
from scioc.models.cost import from_normalized
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.design import CONDITIONS, WheelParameters
from scioc.models.maxent import sample_maxent
from scioc.models.plant import DiscretePlant
from scioc.models.segment import Feedback, as_batch, planning_plant
from scioc.models.units import index_study


class PriorPredictive(NamedTuple):
    """Quantiles (``quantiles``: 5, 25, 50, 75, 95 %) over draws × segments of the RMS human torque (``torque_rms``,
    N·m) and RMS tracking error (``error_rms``, rad), dicts by level, and the same over the observed segments."""

    quantiles: np.ndarray
    torque_rms: dict
    error_rms: dict
    observed_torque_rms: dict
    observed_error_rms: dict


def prior_predictive_summary(
    subjects: Sequence,
    conditions: Sequence,
    segments,
    plant: DiscretePlant,
    rng: np.random.Generator,
    *,
    draws: int = 200,
    priors: Priors = Priors(),
    levels: Sequence = CONDITIONS,
) -> PriorPredictive:
    """Simulate the study's segments under ``draws`` joint prior draws of
    :func:`scioc.models.bayes.hierarchical.build_model` (same arguments, at the recording's sample time) with
    :func:`scioc.models.maxent.sample_maxent`, and summarize their K observed steps."""
    batch = as_batch(segments, plant)
    levels = tuple(str(v) for v in levels)
    index = index_study(subjects, conditions, levels)
    model = build_model(subjects, conditions, batch, plant, priors=priors, levels=levels)
    seed = int(rng.integers(2**63))
    lt1, lR, t2 = pm.draw([model["log_theta1"], model["log_R"], model["theta2"]], draws=draws, random_seed=seed)
    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    K = batch.K
    tq = np.empty((draws, batch.n))
    er = np.empty((draws, batch.n))
    s, c = index.subject_idx, index.condition_idx
    for d in range(draws):
        R = np.exp(lR[d, s, c])
        th1 = np.exp(lt1[d, s, c])
        theta = from_normalized(th1, t2[d, s, c], R)
        for j in range(batch.n):
            demo = sample_maxent(theta[:, j], x0[j], batch.r[j], batch.a[j], planning_plant(plant, batch.fb[j]), rng)
            # Over the observed window only (the plan may look M steps further).
            tq[d, j] = np.sqrt(np.mean(demo.u_H[:K] ** 2))
            er[d, j] = np.sqrt(np.mean((demo.x[1 : K + 1, 0] - batch.r[j, 1 : K + 1]) ** 2))
    return _summarize(tq, er, batch, c, levels)


def _summarize(tq, er, batch, c, levels) -> PriorPredictive:
    """Quantiles of the simulated and observed RMS torque and error per level."""
    K = batch.K
    probs = np.array([0.05, 0.25, 0.5, 0.75, 0.95])
    obs_tq = np.sqrt(np.mean(batch.u**2, axis=1))
    obs_er = np.sqrt(np.mean((batch.x1[:, 1:] - batch.r[:, 1 : K + 1]) ** 2, axis=1))
    out = {k: {} for k in ("tq", "er", "otq", "oer")}
    for ci, cname in enumerate(levels):
        m = c == ci
        out["tq"][cname] = np.quantile(tq[:, m], probs)
        out["er"][cname] = np.quantile(er[:, m], probs)
        out["otq"][cname] = np.quantile(obs_tq[m], probs)
        out["oer"][cname] = np.quantile(obs_er[m], probs)
    return PriorPredictive(probs, out["tq"], out["er"], out["otq"], out["oer"])




class DelayedPriorPredictive(NamedTuple):
    """:class:`PriorPredictive` of the ``delayed`` model (``summary``) and the prior quantiles over draws × subjects
    of τ_nm (s) and σ_m (N·m)."""

    summary: PriorPredictive
    tau_nm: np.ndarray
    sigma_m: np.ndarray


def delayed_prior_predictive_summary(subjects: Sequence, conditions: Sequence, segments, plant: DiscretePlant,
                                     rng: np.random.Generator, *, delay, tau0=0.0, draws: int = 200,
                                     priors: Priors = Priors(), delayed_priors: DelayedPriors = DelayedPriors(),
                                     levels: Sequence = CONDITIONS,
                                     params: WheelParameters = WheelParameters()) -> DelayedPriorPredictive:
    """:func:`prior_predictive_summary` for :func:`scioc.models.bayes.delayed_model.build_delayed_model`: each segment
    from the ``delayed`` human (:func:`scioc.models.delayed.sample_delayed`) at its plug-in ``delay`` (samples) and
    arm torque ``tau0`` at its start (:func:`scioc.models.bayes.delayed_op.pack_tau0`, at the drawn τ_nm)."""
    batch = as_batch(segments, plant)
    levels = tuple(str(v) for v in levels)
    index = index_study(subjects, conditions, levels)
    model = build_delayed_model(subjects, conditions, batch, plant, delay=delay, tau0=tau0, priors=priors,
                                delayed_priors=delayed_priors, levels=levels, params=params)
    seed = int(rng.integers(2**63))
    names = ["log_theta1", "log_R", "theta2", "tau_nm", "sigma_m"]
    lt1, lR, t2, tau, sig = pm.draw([model[v] for v in names], draws=draws, random_seed=seed)
    d_seg = np.broadcast_to(np.asarray(delay, dtype=np.int64), (batch.n,))
    warm = warmups_of(tau0, batch.n)
    fixed = None if warm is not None else pack_tau0(tau0, batch.n)[2]
    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    K = batch.K
    tq = np.empty((draws, batch.n))
    er = np.empty((draws, batch.n))
    s, c = index.subject_idx, index.condition_idx
    for d in range(draws):
        theta = from_normalized(np.exp(lt1[d, s, c]), t2[d, s, c], np.exp(lR[d, s, c]))
        for j in range(batch.n):
            t = float(tau[d, s[j]])
            if warm is None:
                t0 = float(fixed[j])
            else:
                lag = lag_coefficients(t, plant.dt, params)
                t0 = float(window_tau0([warm[j]], lag.a, lag.alpha)[0][0])
            fb = Feedback(batch.fb[j], batch.a[j]) if np.any(batch.fb[j] != 0) else None
            demo = sample_delayed(theta[:, j], x0[j], batch.r[j], plant, rng, u_A=None if fb else batch.a[j],
                                  feedback=fb, tau_nm=t, sigma_m=float(sig[d, s[j]]), delay=int(d_seg[j]), tau0=t0,
                                  n_obs=K, params=params)
            tq[d, j] = np.sqrt(np.mean(demo.u_H[:K] ** 2))
            er[d, j] = np.sqrt(np.mean((demo.x[1 : K + 1, 0] - batch.r[j, 1 : K + 1]) ** 2))
    summary = _summarize(tq, er, batch, c, levels)
    return DelayedPriorPredictive(summary, np.quantile(tau, summary.quantiles), np.quantile(sig, summary.quantiles))


__all__ = ["DelayedPriorPredictive", "PriorPredictive", "delayed_prior_predictive_summary", "prior_predictive_summary"]
