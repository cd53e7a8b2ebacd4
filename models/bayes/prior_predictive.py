"""Prior predictive check of the hierarchical model (:mod:`scioc.models.bayes.hierarchical`).

:func:`prior_predictive_summary` draws all unit parameters jointly from the model's prior,
simulates every segment of a study exactly from the max-ent human the likelihood
assumes, and summarizes the RMS torque and RMS tracking error against the observed ones,
per condition level. It works for any design: pass the levels (baseline first), the wheel
discretized at the recording's sample time and the priors at that rate
(:meth:`scioc.models.bayes.hierarchical.Priors.for_design`).

Prior predictive check: :func:`prior_predictive_summary` on the default study of ``scioc run``
(``reports/default-study/data/study.parquet``, seed 2018, 42 subjects; every segment through
``pipelines.prepare.prepare_segment`` with the default ``IdentifySettings()``: the 15-s
window, velocity and u_H reconstructed from the angle, 2-s preview), 200 joint prior
draws, ``rng = default_rng(1)``; quantiles 5/25/50/75/95 % over draws × segments of the
per-segment RMS human torque and RMS tracking error, and the same quantiles over the 42
observed segments per condition (``observed_*``)::

                        5 %    25 %   50 %   75 %   95 %
    MC torque (N·m)    0.246  0.281  0.304  0.339  0.447    observed 0.271-0.318
    SC torque (N·m)    0.097  0.138  0.180  0.250  0.445    observed 0.118-0.193
    MC error (rad)     0.005  0.010  0.018  0.033  0.073    observed 0.009-0.035
    SC error (rad)     0.003  0.008  0.015  0.027  0.044    observed 0.011-0.032

The priors thus allow anything from very tight (0.1°) to loose (4°) tracking with
torques from about a tenth to half a N·m, and the observations sit inside the central
part of each distribution. The torque's lower end is the deterministic torque that
tracking the reference needs, which no prior on the jitter can lower. Vague priors (same
centres; μ, μ_R, β, β_R with SD 3, σ's HalfN(2), τ HalfN(10)), through the same call,
put 5 % of the segments above 2.4 N·m (MC) and 8.5 N·m (SC) RMS torque and above 0.25
rad (MC) and 0.20 rad (SC) RMS error, i.e. as bad as or worse than not steering at all
(the reference itself has an RMS of 0.2 rad): those priors are rejected by the check.

The first priors, μ ~ N(log 50, 1) and μ_R ~ N(0, 1), were chosen for an earlier
stand-in simulator whose R was about 1; on the simulated study of :mod:`scioc.models.simulate`,
R about 20, the observed RMS torque lies at or below the 5 % quantile of their prior
predictive, through the same call: 5-95 % 0.37-1.70 N·m in MC against 0.27-0.32
observed, 0.25-1.94 in SC against 0.12-0.19. Hence the priors of
:class:`scioc.models.bayes.hierarchical.Priors`.
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
    """Prior predictive torques and tracking errors, per condition level.

    Attributes
    ----------
    quantiles : ndarray, shape (5,)
        The probabilities of the columns below: 0.05, 0.25, 0.5, 0.75, 0.95.
    torque_rms : dict of str -> ndarray, shape (5,)
        Quantiles over draws × segments of the RMS human torque of a segment, N·m.
    error_rms : dict of str -> ndarray, shape (5,)
        Quantiles of the RMS tracking error angle - angle_ref of a segment, rad.
    observed_torque_rms, observed_error_rms : dict of str -> ndarray, shape (5,)
        The same quantiles over the observed segments, for comparison.
    """

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
    """Simulate the study's segments under prior draws and summarize torques and errors.

    Each draw takes all unit parameters jointly from the prior
    (:func:`scioc.models.bayes.hierarchical.build_model`) and simulates every segment exactly
    from the max-ent model with :func:`scioc.models.maxent.sample_maxent`
    (x0, angle_ref and the segment's known input and plan, preview included); states follow
    from the drawn torques, and both are summarized over the K observed steps.

    Parameters
    ----------
    subjects, conditions, segments, plant
        As for :func:`scioc.models.bayes.hierarchical.build_model` (``plant`` at the
        recording's sample time).
    rng : numpy.random.Generator
    draws : int
        Number of prior draws.
    priors : Priors
        At the recording's rate (``Priors.for_design(design)``; ``Priors()`` is 100 Hz).
    levels : sequence of str
        The condition levels, baseline first (default MC, SC): the keys of the summaries.

    Returns
    -------
    PriorPredictive
    """
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
    """:class:`PriorPredictive` of the ``delayed`` model, with the prior quantiles of its new parameters.

    Attributes
    ----------
    summary : PriorPredictive
        Torques and tracking errors per level, as for the max-ent model.
    tau_nm, sigma_m : ndarray, shape (5,)
        Quantiles (``summary.quantiles``) over draws × subjects of τ_nm (s) and σ_m (N·m).
    """

    summary: PriorPredictive
    tau_nm: np.ndarray
    sigma_m: np.ndarray


def delayed_prior_predictive_summary(subjects: Sequence, conditions: Sequence, segments, plant: DiscretePlant,
                                     rng: np.random.Generator, *, delay, tau0=0.0, draws: int = 200,
                                     priors: Priors = Priors(), delayed_priors: DelayedPriors = DelayedPriors(),
                                     levels: Sequence = CONDITIONS,
                                     params: WheelParameters = WheelParameters()) -> DelayedPriorPredictive:
    """:func:`prior_predictive_summary` for :func:`scioc.models.bayes.delayed_model.build_delayed_model`.

    Each draw takes all unit parameters (θ per unit, τ_nm and σ_m per subject) jointly from
    the model's prior and simulates every segment from the ``delayed`` human
    (:func:`scioc.models.delayed.sample_delayed`, the physical arm) at the segment's plug-in
    ``delay`` (samples) and arm torque ``tau0`` at its start (a number per segment, or
    warm-ups: :func:`scioc.models.bayes.delayed_op.pack_tau0`, evaluated at the drawn τ_nm).
    Also the prior quantiles of τ_nm and σ_m themselves.
    """
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
