"""Hierarchical Bayesian model of the human cost parameters across condition levels (paper Eqs. 6, 8).

A *unit* is a subject i in a condition level c: the paper's MC (the baseline) and SC, or the L >= 2 levels of a
:class:`scioc.models.design.Design`, baseline first. θ = [q11, q22, R] enters the max-ent likelihood only through
θ1 = q11/R and θ2 = q22/R, which fix the policy (paper Section V-A), and R, which scales the torques' precision::

    log θ1[i, MC] = μ + a_i                      a_i ~ N(0, σ)        subject intercept
    log θ1[i, SC] = log θ1[i, MC] + β + b_i      b_i ~ N(0, σ_β)      SC change (β: the paper's question)
    log R[i, MC]  = μ_R + a^R_i                  a^R_i ~ N(0, σ_R)
    log R[i, SC]  = log R[i, MC] + β_R + b^R_i   b^R_i ~ N(0, σ_βR)
    θ2[i, c]      ~ HalfNormal(τ)
    u_H[segment] ~ max-ent(q11 = θ1 R, q22 = θ2 R, R | x0, angle_ref, u_A or the assistant's feedback law)

With L > 2 each non-baseline level has its own β, σ_β, β_R, σ_βR (dims ``contrast``); a unit's trials share its θ.
The pooled model (``condition_effects=False``) drops log θ1's changes alone, for the PSIS-LOO comparison.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.basic import Constant

from scioc.models.bayes.blocks import Parameterization, pooled_block, theta2_block, unit_block
from scioc.models.bayes.op import DATA_NAMES, MaxEntLoglikDataOp, MaxEntLoglikOp
from scioc.models.design import CONDITIONS, Design
from scioc.models.maxent import sample_maxent
from scioc.models.plant import DiscretePlant
from scioc.models.segment import as_batch, planning_plant
from scioc.models.units import index_study

#: The population parameters of the condition model; the pooled model has all but ``beta`` and ``sigma_beta``.
POPULATION_PARAMETERS = ("mu_log_theta1", "beta", "sigma_log_theta1", "sigma_beta", "mu_log_R", "beta_log_R",
                         "sigma_log_R", "sigma_beta_log_R", "tau_theta2")


@dataclass(frozen=True)
class Priors:
    """Hyperprior parameters at 100 Hz (docs/decisions/hierarchical-priors.md): (mean, SD) of the Normal priors on
    μ and μ_R, SDs of the N(0, ·) priors on β and β_R, scales of the half-normal priors on σ, σ_β, σ_R, σ_βR and τ.
    "SC" stands for every non-baseline level; :meth:`for_design` gives the priors at another sample time."""

    mu_log_theta1: tuple[float, float] = (3.0, 1.0)
    beta_sd: float = 1.0
    sigma_log_theta1: float = 0.5
    sigma_beta: float = 0.3
    mu_log_R: tuple[float, float] = (3.0, 1.0)
    beta_log_R_sd: float = 0.5
    sigma_log_R: float = 0.5
    sigma_beta_log_R: float = 0.3
    tau_theta2: float = 0.5

    @classmethod
    def for_design(cls, design: Design, **overrides) -> "Priors":
        """The priors at ``design``'s sample time: μ_R's centre + log(dt / 0.01), as R ∝ dt; the rest are rate-free."""
        base = cls(**overrides)
        centre, sd = base.mu_log_R
        return replace(base, mu_log_R=(centre + math.log(design.r_scale), sd))


def build_model(
    subjects: Sequence,
    conditions: Sequence,
    segments,
    plant: DiscretePlant,
    *,
    priors: Priors = Priors(),
    parameterization: Parameterization = Parameterization(),
    segment_ids: Sequence | None = None,
    data_containers: bool = False,
    condition_effects: bool = True,
    levels: Sequence = CONDITIONS,
) -> pm.Model:
    """The hierarchical max-ent model of a study (module docstring): coords ``subject``, ``condition``, ``segment``,
    ``step`` (``contrast`` with L > 2); observed ``u_H`` (segment, step), one log density per segment.

    Parameters
    ----------
    subjects, conditions, segments : sequences of length n, or a SegmentBatch
        Each segment's subject, level and demonstration (K observed torques, preview M; rad, rad/s, N·m).
    plant, priors : DiscretePlant, Priors
        At the recording's sample time (:meth:`Priors.for_design`).
    parameterization, segment_ids, levels
        The blocks' forms; labels of ``segment``; the condition levels, baseline first.
    data_containers : bool
        Data in ``pm.Data`` and the likelihood a potential, so one compiled model refits new data (no ``u_H``).
    condition_effects : bool
        False builds the pooled model.
    """
    levels = tuple(str(v) for v in levels)
    index = index_study(subjects, conditions, levels)
    batch = as_batch(segments, plant)
    n, K = batch.n, batch.K
    if n != index.subject_idx.shape[0]:
        raise ValueError(f"got {n} segments but {index.subject_idx.shape[0]} subject/condition labels")
    ids = list(range(n)) if segment_ids is None else list(segment_ids)
    if len(ids) != n:
        raise ValueError(f"segment_ids must have {n} entries; got {len(ids)}")
    coords = {"subject": index.subjects, "condition": levels, "segment": ids, "step": np.arange(K)}
    L = len(levels)
    effect = {} if L == 2 else {"dims": "contrast"}
    if L > 2:
        coords["contrast"] = levels[1:]
    s_idx, c_idx = index.subject_idx, index.condition_idx
    op = MaxEntLoglikOp(batch, plant)
    u_obs = op.u  # the Op's own read-only copy

    def logp(value, q11, q22, R, u_A):
        # The Op carries the observed data: refuse any other value rather than score the wrong torques.
        if not (isinstance(value, Constant) and np.array_equal(value.data, u_obs)):
            raise NotImplementedError("the max-ent likelihood of this model is bound to the observed torques")
        ll, _ = op(pt.stack([q11, q22, R]))
        return ll

    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    plans = [planning_plant(plant, gain) for gain in batch.fb]

    def random(q11, q22, R, u_A_window, rng=None, size=None):
        # Exact max-ent draws over all K + M steps, the K observed kept; the last batch axis is the segment.
        shape = tuple(size) if size is not None else np.broadcast_shapes(q11.shape, q22.shape, R.shape)
        th = [np.broadcast_to(p, shape) for p in (q11, q22, R)]
        out = np.empty(shape + (K,))
        for idx in np.ndindex(*shape):
            j = idx[-1]
            theta = [th[0][idx], th[1][idx], th[2][idx]]
            out[idx] = sample_maxent(theta, x0[j], batch.r[j], batch.a[j], plans[j], rng).u_H[:K]
        return out

    form = parameterization
    with pm.Model(coords=coords) as model:
        mu = pm.Normal("mu_log_theta1", *priors.mu_log_theta1)
        if condition_effects:
            beta = pm.Normal("beta", 0.0, priors.beta_sd, **effect)
        sigma = pm.HalfNormal("sigma_log_theta1", priors.sigma_log_theta1)
        if condition_effects:
            sigma_b = pm.HalfNormal("sigma_beta", priors.sigma_beta, **effect)
        mu_R = pm.Normal("mu_log_R", *priors.mu_log_R)
        beta_R = pm.Normal("beta_log_R", 0.0, priors.beta_log_R_sd, **effect)
        sigma_R = pm.HalfNormal("sigma_log_R", priors.sigma_log_R)
        sigma_bR = pm.HalfNormal("sigma_beta_log_R", priors.sigma_beta_log_R, **effect)
        tau = pm.HalfNormal("tau_theta2", priors.tau_theta2)

        if condition_effects:
            log_theta1 = unit_block("log_theta1", mu, beta, sigma, sigma_b, form.theta1_mc, form.theta1_sc, L)
        else:
            log_theta1 = pooled_block("log_theta1", mu, sigma, form.theta1_mc, L)
        log_R = unit_block("log_R", mu_R, beta_R, sigma_R, sigma_bR, form.R_mc, form.R_sc, L)
        theta2 = theta2_block(tau, form.theta2)
        pm.Deterministic("theta1", pt.exp(log_theta1), dims=("subject", "condition"))
        R = pm.Deterministic("R", pt.exp(log_R), dims=("subject", "condition"))

        lt1_s = log_theta1[s_idx, c_idx]
        lR_s = log_R[s_idx, c_idx]
        R_s = R[s_idx, c_idx]
        # θ as models.cost.from_log_normalized writes it, in the graph.
        q11 = pt.exp(lt1_s + lR_s)
        q22 = theta2[s_idx, c_idx] * R_s
        if data_containers:
            data = [pm.Data(name, getattr(batch, name)) for name in DATA_NAMES]
            ll, _ = MaxEntLoglikDataOp(plant)(pt.stack([q11, q22, R_s]), *data)
            pm.Potential("loglik", ll.sum())
            return model
        pm.CustomDist(
            "u_H",
            q11,
            q22,
            R_s,
            # u_A over the observed window gives the support its shape (K); the Op uses all of it, preview included.
            batch.a[:, :K],
            logp=logp,
            random=random,
            signature="(),(),(),(k)->(k)",
            observed=u_obs,
            dims=("segment", "step"),
        )
    return model


__all__ = [
    "Priors",
    "Parameterization",
    "build_model",
    "POPULATION_PARAMETERS",
]
