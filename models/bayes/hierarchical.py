"""Hierarchical Bayesian model of the human cost parameters across condition levels.

One *unit* is a subject i in a condition level c: by default the paper's MC (manual
control, the baseline) and SC (shared control); an experiment may have L >= 2 levels, the
baseline first (:class:`scioc.models.design.Design`). Its cost θ = [q11, q22, R] (paper Eq. 6)
enters the max-ent likelihood (paper Eq. 8) only through

* θ1 = q11 / R and θ2 = q22 / R, which fix the optimal policy (scaling J keeps the
  optimum, paper Section V-A), and
* R, which scales the precision of the torques around it: given the state, the torque of
  step k is Gaussian with variance 1 / (2 S_k) and S_k ∝ R at fixed θ1, θ2.

so the model is written in (θ1, θ2, R)::

    log θ1[i, MC] = μ + a_i                      a_i ~ N(0, σ)        subject intercept
    log θ1[i, SC] = log θ1[i, MC] + β + b_i      b_i ~ N(0, σ_β)      SC change (β: the paper's question)
    log R[i, MC]  = μ_R + a^R_i                  a^R_i ~ N(0, σ_R)
    log R[i, SC]  = log R[i, MC] + β_R + b^R_i   b^R_i ~ N(0, σ_βR)
    θ2[i, c]      ~ HalfNormal(τ)                (θ2 >= 0; τ -> 0 says "θ2 = 0 for everyone")
    u_H[segment] ~ max-ent(q11 = θ1 R, q22 = θ2 R, R | x0, angle_ref, u_A)

(on an assisted level the max-ent human plans with the assistant's feedback law when the
segment carries :class:`scioc.models.segment.Feedback`, as ``scioc fit`` does by default, or with
the recorded u_A as a known input, the paper's model).

More levels. With levels 0 (the baseline), 1, ..., L-1 every non-baseline level c gets
its own change of each subject against the baseline, b_ic ~ N(0, σ_β,c) with its own mean
β_c, and likewise for log R (β_R,c, σ_βR,c); a subject's changes are independent across
levels. β, σ_β, β_R and σ_βR then have dims ``contrast`` (the non-baseline levels), and
with L = 2 the model is exactly the one above (scalar β; the names of
:mod:`scioc.models.bayes.blocks`). Each level's own σ_β rather than one shared: the
between-subject spread of the response to a weak and to a strong assistant need not be
alike, and a shared σ_β would pull the smaller spread up and the larger one down,
widening or narrowing the per-subject contrasts of both. The marginal model of the
baseline and any one level is then the two-level model. The price is one scale per
level, each learnt from that level's changes alone; their changes are non-centred by
default (see below), so a small σ_β,c does not form a funnel.

Several segments may belong to one unit (trials: they share its θ); every subject needs
at least one segment in each level.

Priors (:class:`Priors`; units: θ1, θ2 in rad⁻² and (rad/s)⁻² per (N·m)⁻², R in (N·m)⁻²)::

    μ   ~ N(3, 1)          β   ~ N(0, 1)      σ   ~ HalfN(0.5)   σ_β  ~ HalfN(0.3)
    μ_R ~ N(3, 1)          β_R ~ N(0, 0.5)    σ_R ~ HalfN(0.5)   σ_βR ~ HalfN(0.3)
    τ   ~ HalfN(0.5)

(each β_c, σ_β,c, β_R,c, σ_βR,c with the prior of β, σ_β, β_R, σ_βR above).

R is a per-sample precision and scales with the sample time (:mod:`scioc.models.design`), θ1 and
θ2 do not: μ_R's prior is stated at the paper's 100 Hz and :meth:`Priors.for_design`
shifts its centre by log(dt / 0.01) (``Design.r_scale``), so that the prior says the same
about the human at any rate; at 100 Hz it is exactly :class:`Priors` ``()``.

The centres say what the parameters mean physically. θ1 = e³ ≈ 20 rad⁻² weighs a 0.2-rad
error (the RMS of the reference) like a 0.9 N·m torque. R sets the human's torque jitter:
given the state the torque of one 10-ms step has SD 1 / √(2 S_k), and S_k = 1.08 R at
θ1 = 20, θ2 = 0 (``models.lq.lq_policy`` on the study window), so log R = 3 ± 2 is a jitter
of 0.06-0.41 N·m per sample around 0.15 N·m.

The priors pass a prior predictive check on the default study; :mod:`scioc.models.bayes.prior_predictive`
holds the check, its numbers and why the first priors were replaced.

Pooled model (``build_model(..., condition_effects=False)``), the alternative for the
PSIS-LOO comparison: log θ1[i, c] = m_i ~ N(μ, σ) in every level (β = σ_β = 0), with the
log R and θ2 blocks unchanged, so that the two models differ only in the paper's question.

Parameterization (:class:`Parameterization`), chosen by measurement. Per unit at K = 1500
the data pin log R down to about ±0.04 (prior spread σ_R ≈ 0.3: centred suits it) and
log θ1 to about ±0.05-0.09, comparable with σ_β ≈ 0.2. Measured with
``scioc bench-fit`` (the default simulated study of ``scioc run``, 42 × 2
segments reconstructed from the angle, 2-s preview; 4 chains × 1000 draws after 500
tuning draws, nutpie on 2 cores, sampler seed 2018; ``--study-seed``, ``--window-seconds``
and the form options as in the rows); minimum over the nine population parameters of
bulk/tail ESS, and the largest R-hat::

    log θ1 MC/SC   log R MC/SC  θ2   study           div   steps/draw  min ESS (parameter)  max R-hat
    mean / NC      C / C        NC   2018            0     15.0        855 (β)              1.006 (σ_β)   <- default
    mean / NC      C / C        NC   2019            0     15.0        511 (β)              1.008 (β)
    mean / NC      C / C        NC   2018, 3-s win.  0     15.0        713 (σ_β)            1.003 (σ_β)
    C / NC         C / C        NC   2018            0     15.0        489 (β)              1.011 (β)
    C / C          C / C        NC   2018            0     15.0        2170 (τ)             1.001 (σ_R)
    C / C          C / C        NC   2019            0     15.0        1709 (τ)             1.003 (μ)
    C / C          C / C        NC   2018, 3-s win.  1000  17.2        4 (σ_β)              1.532 (σ_β)
    mean / NC      C / C        C    2018            0     15.0        47 (τ)               1.038 (τ)
    mean / NC      NC / NC      NC   2018            0     21.2        97 (μ_R)             1.028 (σ_R)

(C centred, NC non-centred, mean: subject mean centred after a non-centred change; every
run put the true β in its 94 % HDI.) θ2 must be non-centred: with θ2 = 0 for everyone the
centred τ forms a funnel (ESS 47). log R must be centred: non-centred it needs 40 % more
leapfrog steps and μ_R gets ESS 97. The SC change of log θ1 is the delicate block. Centred
(C / C) it mixes best on the 15-s windows, whose data outweigh σ_β, but with less data per
unit (3-s windows) every transition of every chain diverged in the σ_β funnel. The
default keeps the change non-centred, which passes on all three data sets, at about half
the ESS of C / C where that works; ``scioc fit`` passes ``Parameterization(theta1_mc="centred",
theta1_sc="centred")`` when the data pin each unit's log θ1 down tightly enough
(``pipelines.fit.stage.CENTRED_SE_LOG_THETA1``, where later measurements are). (Session 1 measured the same
pattern on an earlier stand-in simulator, no longer in the repository.) The table is the
two-level study's; with more levels every change gets the form ``theta1_sc`` / ``R_sc``
says, a choice carried over from it, not measured again.

The pointwise log-likelihood of each segment is the element-wise log density of the
observed variable ``u_H`` (dims segment × step, one value per segment), so
``pm.compute_log_likelihood(idata, model=model)`` gives a ``log_likelihood`` group with
dims (chain, draw, segment) for ``arviz.loo``. With one segment per unit, leaving a segment
out removes all data on that unit's θ, so expect large Pareto k: compare models with
``loo`` only alongside its k diagnostics (or with K-fold by subject). Trials are separate
segments, so with several trials per unit leaving one out keeps the unit's other data.
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

#: The population parameters of the condition model, as the model names them. The pooled
#: model (``condition_effects=False``) has all but ``beta`` and ``sigma_beta``.
POPULATION_PARAMETERS = ("mu_log_theta1", "beta", "sigma_log_theta1", "sigma_beta", "mu_log_R", "beta_log_R",
                         "sigma_log_R", "sigma_beta_log_R", "tau_theta2")


@dataclass(frozen=True)
class Priors:
    """Hyperprior parameters (see the module docstring for the model), stated at 100 Hz.

    "MC" below is the baseline and "SC" every other level (each its own β, σ_β, β_R, σ_βR
    with these priors). Use :meth:`for_design` for another sample time.

    Attributes
    ----------
    mu_log_theta1 : (float, float)
        Mean and SD of the Normal prior on μ, the MC population mean of log θ1.
    beta_sd : float
        SD of the Normal(0, ·) prior on β, the mean SC change of log θ1.
    sigma_log_theta1 : float
        Scale of the HalfNormal prior on σ (between-subject SD of log θ1 in MC).
    sigma_beta : float
        Scale of the HalfNormal prior on σ_β (between-subject SD of the SC change).
    mu_log_R : (float, float)
        Mean and SD of the Normal prior on μ_R, at 100 Hz (:meth:`for_design` shifts the mean).
    beta_log_R_sd : float
        SD of the Normal(0, ·) prior on β_R.
    sigma_log_R : float
        Scale of the HalfNormal prior on σ_R.
    sigma_beta_log_R : float
        Scale of the HalfNormal prior on σ_βR.
    tau_theta2 : float
        Scale of the HalfNormal prior on τ, the population scale of θ2.
    """

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
        """The priors at ``design``'s sample time: μ_R's centre + log(dt / 0.01), the rest as stated.

        R ∝ dt (:mod:`scioc.models.design`), so the prior centre of log R at 100 Hz moves by
        ``log(design.r_scale)``; its SD and every other prior are rate-free. At 100 Hz
        ``log(1.0) = 0.0`` and the priors are exactly ``Priors()``.

        Examples
        --------
        >>> Priors.for_design(Design()) == Priors()
        True
        >>> round(Priors.for_design(Design(dt=0.001)).mu_log_R[0], 4)
        0.6974
        """
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
    """The hierarchical max-ent model of a study (see the module docstring).

    Parameters
    ----------
    subjects : sequence, length n
        Subject label of each segment.
    conditions : sequence of str, length n
        Condition level of each segment (one of ``levels``).
    segments : SegmentBatch or sequence of Segment
        The n demonstrations, all with K observed torques and the same preview M >= 0
        (x0 in rad, rad/s; angle_ref (K + M + 1,) in rad; u_H (K,), u_A (K + M,) in N·m).
    plant : DiscretePlant
        The wheel discretized at the recording's sample time.
    priors : Priors
        At the recording's rate: :meth:`Priors.for_design` (``Priors()`` is 100 Hz).
    parameterization : Parameterization
    segment_ids : sequence, length n, optional
        Labels of the ``segment`` coordinate (default 0..n-1).
    data_containers : bool
        Put the data in ``pm.Data`` containers ``x1, x2, r, u, a`` (a
        :class:`scioc.models.segment.SegmentBatch`'s arrays) and the likelihood in a potential
        (:class:`scioc.models.bayes.op.MaxEntLoglikDataOp`), so that one compiled
        model refits new data of the same shape (``with_data``); used by
        simulation-based calibration. No observed variable then, hence no pointwise
        log-likelihood and no predictive draws.
    condition_effects : bool
        False builds the *pooled* model for the PSIS-LOO comparison: log θ1 of a subject
        is the same in every level (β = 0, σ_β = 0; no ``beta``, ``sigma_beta`` or change
        variables), sampled as ``log_theta1_mean`` ~ N(μ, σ) (centred unless
        ``parameterization.theta1_mc`` is ``noncentred``). The log R block and θ2 keep
        their condition effects, so the comparison is about θ1 alone, the paper's
        question. The design check (every subject in every level) is the same.
    levels : sequence of str
        The condition levels, baseline first (default MC, SC; ``Design.ordered_levels``).

    Returns
    -------
    pymc.Model
        Coordinates ``subject``, ``condition`` (``levels``), ``segment`` and ``step``
        (0..K-1); with more than two levels also ``contrast`` (the non-baseline levels),
        the dims of ``beta``, ``sigma_beta``, ``beta_log_R`` and ``sigma_beta_log_R``
        (scalars with two levels). Free variables: the population parameters ``mu_log_theta1``,
        ``beta``, ``sigma_log_theta1``, ``sigma_beta``, ``mu_log_R``, ``beta_log_R``,
        ``sigma_log_R``, ``sigma_beta_log_R``, ``tau_theta2`` and the unit parameters
        in the chosen form (by default ``log_theta1_mean``, ``z_log_theta1_SC``,
        ``log_R_MC``, ``log_R_SC``, ``z_theta2``; with more levels ``log_theta1_mean``,
        ``z_log_theta1_contrast``, ``log_R_baseline``, ``log_R_contrast``, ``z_theta2``:
        :mod:`scioc.models.bayes.blocks`). Deterministics ``log_theta1``, ``log_R``, ``theta1``,
        ``R``, ``theta2`` (subject, condition). Observed ``u_H`` (segment, step),
        whose element-wise log density is one log-likelihood per segment.

    Raises
    ------
    ValueError
        See :func:`scioc.models.units.index_study`; also if the number of segments does not match the
        labels.

    Examples
    --------
    >>> import numpy as np
    >>> from models.segment import Segment
    >>> from models.plant import discretize
    >>> seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10))
    >>> m = build_model(["a", "a"], ["MC", "SC"], [seg, seg], discretize(0.01))
    >>> m.coords["condition"]
    ('MC', 'SC')
    >>> m3 = build_model(["a"] * 3, ["none", "weak", "strong"], [seg] * 3, discretize(0.01),
    ...                  levels=("none", "weak", "strong"))
    >>> m3.coords["contrast"], m3.named_vars_to_dims["beta"]
    (('weak', 'strong'), ('contrast',))
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
    # Two levels: scalar condition effects, the graph of every earlier version (models.bayes.blocks).
    effect = {} if L == 2 else {"dims": "contrast"}
    if L > 2:
        coords["contrast"] = levels[1:]
    s_idx, c_idx = index.subject_idx, index.condition_idx
    op = MaxEntLoglikOp(batch, plant)
    u_obs = op.u  # the Op's own read-only copy

    def logp(value, q11, q22, R, u_A):
        # The Op carries the observed data; refuse any other value rather than return
        # the likelihood of the wrong torques.
        if not (isinstance(value, Constant) and np.array_equal(value.data, u_obs)):
            raise NotImplementedError("the max-ent likelihood of this model is bound to the observed torques")
        ll, _ = op(pt.stack([q11, q22, R]))
        return ll

    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    plans = [planning_plant(plant, gain) for gain in batch.fb]

    def random(q11, q22, R, u_A_window, rng=None, size=None):
        # Exact max-ent draws of the human the likelihood assumes (planning with the known
        # u_A, or with the assistant's feedback law on the closed wheel):
        # plan over the whole K + M steps, keep the K observed ones (the later torques
        # integrate out of the sequential factorization). The last batch axis is the segment.
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
            # u_A over the observed window: it gives the support its shape (K); the Op and
            # `random` use the whole recorded u_A, preview included.
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
