"""Hierarchical Bayesian model of the ``delayed`` human: the max-ent cost blocks plus lag and motor noise.

The cost part is :mod:`scioc.models.bayes.hierarchical`'s, block for block (log θ1 and log R per
subject × level with condition effects, θ2 >= 0 with a learned half-normal scale; the same
:class:`scioc.models.bayes.hierarchical.Priors` and :class:`scioc.models.bayes.blocks.Parameterization`);
θ = [q11, q22, R] is now the cost of the *commands* (:mod:`scioc.models.delayed.likelihood`).
Added, per subject i (kept in every level: the lag and the motor noise are the person's,
as the simulated ``kbl`` human's are)::

    τ_nm[i] ~ HalfNormal(s_τ)      neuromuscular lag, s              s_τ ~ HalfN(0.1)
    σ_m[i]  ~ HalfNormal(s_m)      motor-noise SD, N·m per sample    s_m² ~ InvGamma(1, 0.03)
    u_H[segment] ~ delayed(θ, τ_nm[i], σ_m[i], d[segment] | x0, angle_ref, assistant, τ_0)

(:class:`DelayedPriors`, where s_m's prior is explained; each block centred, non-centred
or folded, :class:`DelayedForm`). Half-normal
populations, not log-normal ones, because the model must contain the paper's human: on
data without lag or motor noise the ML τ_nm is 0 (<= 0.7 ms in every unit of the max-ent
human with a torque sensor, README "Human models") and σ_m near it, which a log-normal
population can reach only by sending its mean to -∞ (its prior then fights the data; a
trial fit with log τ_nm ~ N(μ_τ, σ_τ), μ_τ ~ N(log 0.06, 0.9), on 12 such subjects had not
finished its 600 draws per chain after 30 min where the delayed human's took 20).
A half-normal puts mass at 0 and, with the data of a delayed human (SE of τ_nm about
0.006 s at 0.06 s, of σ_m 0.02-0.03 N·m at 0.25), shrinks its values negligibly.

Prior predictive check (:func:`scioc.models.bayes.prior_predictive.delayed_prior_predictive_summary`,
as the max-ent model's: the default study's 84 segments (:func:`scioc.pipelines.bench.common.default_study_segments`,
2-s preview), every one with delay 12 samples and its warm-up, 200 joint prior draws,
``default_rng(1)``), with the default priors (s_m² ~ InvGamma(1, 0.03), since the last change of
2026-12-05)::

                        5 %    25 %   50 %   75 %   95 %
    MC torque (N·m)    0.223  0.262  0.279  0.308  0.474    observed 0.271-0.318
    SC torque (N·m)    0.059  0.102  0.128  0.184  0.395    observed 0.118-0.193
    MC error (rad)     0.008  0.018  0.028  0.043  0.087    observed 0.009-0.035
    SC error (rad)     0.006  0.013  0.022  0.034  0.054    observed 0.011-0.032
    τ_nm (s)           0.002  0.012  0.036  0.084  0.217
    σ_m (N·m)          0.012  0.064  0.145  0.288  0.782

The observations sit in the central part of every distribution, as for the max-ent model;
τ_nm covers no lag to twice McRuer & Jex's 0.1 s, σ_m near 0 to 3 times KBL's 0.25 N·m. With
s_m ~ HalfNormal(0.3), the prior before 2026-12-05, the same draws gave the table of before
(torque MC 0.221 0.261 0.277 0.296 0.422, SC 0.056 0.099 0.123 0.163 0.339; error MC 0.007 0.015
0.025 0.040 0.080, SC 0.005 0.011 0.020 0.033 0.050; σ_m 0.006 0.035 0.102 0.234 0.617 N·m): the
inverse gamma widens the upper quarter of σ_m and of the torques a little and moves σ_m's 5 %
from 0.006 to 0.012 N·m. (The Gamma(2, rate 8) between them gave σ_m almost the half-normal's
law: 0.008 0.048 0.122 0.265 0.651 N·m in 2·10⁶ Monte Carlo draws.)

The delay d is *data*: fixed per subject at the maximum of its profile likelihood
(:func:`build_delayed_model` takes a delay per segment; ``scioc fit`` chooses it,
:func:`scioc.pipelines.fit.delayed.unit_delays`). Why, and what else was measured:

The delay: a plug-in, one per subject
-------------------------------------
How sharply do the data fix the delay? ``scioc bench --parts fit_delayed``
(:func:`scioc.pipelines.bench.fit_delayed.bench_delay_profile`): 6 subjects × MC, SC drawn from
the delayed model (:func:`scioc.models.bayes.delayed_windows.delayed_windows`; K = 1500 with
2-s preview, delay 12 samples, τ_nm 0.06 s, σ_m 0.25 N·m, θ of the default population),
each unit's ML profile over 0-300 ms (:func:`scioc.models.delayed.identify.identify_unit_delayed`);
drop of the profile log-likelihood from its maximum::

                ±1 sample: median (range)     ±2 samples: median (range)    argmax - truth
    MC          -1.6 (-5.3 to -0.1) nats      -3.9 (-7.9 to -1.3) nats      0, 1, 0, 0, 1, 0
    SC          -0.3 (-2.1 to -0.0) nats      -0.5 (-2.3 to -0.2) nats      -6, 2, 13, 3, 13, 0

So the profile does *not* drop by tens of nats: in MC the delay is known to about ±1
sample (neighbours carry e^-1.6 ≈ 0.2 of the maximum's weight), and in SC, where the
assistant's feedback makes the human's own gains small and so the MA coefficients of the
motor noise, the profile is nearly flat and its maximum lands anywhere from -60 to +130
ms. Marginalizing over the delay would therefore change something, and a delay per unit
would be noise in SC. Hence one delay per subject (the person's, kept across levels like
τ_nm and σ_m), at the maximum of the sum of its units' profiles: the MC data fix it. What
a plug-in costs: along a joint (MC + SC, shared τ_nm and σ_m) profile of three such
subjects, the conditional ML estimates moved, per sample of delay, by <= 0.06 in log θ1
(MC), <= 0.03 (SC), <= 0.03 in log τ_nm and <= 0.02 N·m in σ_m, against posterior SDs of
about 0.2, 0.08 and 0.02-0.03 per subject (below): marginalizing over ±1-2 samples would
widen log θ1 by a few per cent of its variance. log R moved by up to 0.9 (it is barely
identified apart from σ_m, below). Marginalizing exactly would mean one kernel call per
grid delay and segment at every evaluation (each about as costly as the plug-in's: the
plan, 60 % of the cost at d = 12, does not depend on d but the kernel recomputes it), 5×
the cost for ±2 samples, outside the speed goal (below).

Geometry
--------
What the data fix, per subject (MC + SC windows of a ``kbl``-like subject, K = 1500, true
torques; observed information at the ML point in (log θ1, log R per level, log τ_nm,
σ_m), two subjects): SD of log θ1 0.20-0.22 per unit (the max-ent model's: 0.06), of
log R 0.40-0.47, of log τ_nm 0.08-0.09, of σ_m 0.02-0.03 N·m; correlations log R_MC-log R_SC
0.96-0.97, log R-log τ_nm -0.86, log R-σ_m 0.57-0.69. The policy noise (variance 1/(2S),
S ∝ R) and the motor noise explain the same torque variability except through the
motor noise's moving average, and a slightly shorter lag lets R run to infinity (profile:
log R 3.4 at the ML lag, 7.7 or 15 at a lag 20 % shorter, for 2.6 and 3.9 nats). So log R
per unit is barely identified and strongly tied to the subject's lag and noise, while
τ_nm and σ_m are well identified.

Measured (12 subjects × MC, SC of :func:`scioc.models.bayes.delayed_windows.delayed_windows`, true
torques and delays, 2 chains × 300 draws after 300 tuning, nutpie, sampler seed 1, on a
machine shared with other jobs; minimum over the population parameters of the bulk ESS,
and the parameter)::

    τ_nm, σ_m                        log R MC / SC   mass matrix       steps/draw  div  worst ESS
    log-normal NC, half-normal NC    C / C           diagonal          86          0    16 (s_m)
    log-normal C, half-normal C      C / C           low rank          38          1    19 (σ_R)
    log-normal C, half-normal C      NC / NC         diagonal          41          3    16 (μ_R)
    log-normal C, half-normal C      NC / NC         low rank          29          4    25 (σ_R)   <- default
    log-normal C, half-normal C      NC / NC         low rank, cut 3   35          1    28 (σ_R)

(C centred, NC non-centred; "low rank": nutpie's ``adaptation="low_rank"`` with its
eigenvalue cutoff, 2 (``nutpie._lib.PyNutsSettings.LowRank(0).as_dict()``; nutpie's
docstring says 100, which is not what its settings hold), or 3; log-normal C with log R
C / C and a diagonal mass matrix had not finished after 40 min.) The non-centred population
scale of strongly identified values (first row) forms the ridge; centred τ_nm and σ_m remove
it (ESS of their population parameters 500-1300). log R is best non-centred here, unlike in the max-ent model, because
its per-unit SD (0.4) exceeds the population's (about 0.3); the low-rank mass matrix
takes the within-subject correlations (steps 41 -> 29). σ_R, the between-subject SD of
log R, stays slow in every form (ESS 15-28 of 600): R is the nuisance the data cannot
separate from the motor noise, and β, θ1, τ_nm and σ_m mix well (ESS 500-1300). The
population of τ_nm is now half-normal (above), with the same forms; on data without lag
or motor noise they are non-centred (:func:`scioc.pipelines.fit.delayed_forms.choose_delayed_form`),
and so is log R centred there (:func:`scioc.pipelines.fit.delayed_forms.log_R_form`: without motor noise
the policy noise alone fixes each unit's R, measured in that module).

At full size (42 subjects of the ``kbl`` human, 4 chains × 1000 draws; README "Human
models", "The hierarchical fit") the same holds and is worse: σ_R reached R-hat 1.09-1.12
with a bulk ESS of 24-54 (one chain sat near σ_R = 0.03 for about 400 draws) while β
mixed well (R-hat <= 1.006, bulk ESS >= 3906), and the sampler needed 32.5 leapfrog steps
per draw (102-152 minutes with other jobs on the machine, against the 15-minute goal).

Other populations of R (a Gamma prior on σ_R; the policy-noise scale ρ in place of log R) are
measured in :mod:`scioc.models.bayes.delayed_blocks`.

Whitened
--------
Given the population, the subjects are independent, so what a diagonal or low-rank mass matrix
cannot hold (each subject's log R tied to its τ_nm and σ_m, above) is block diagonal: eight
coordinates per subject. ``scioc fit`` therefore samples, by default (:data:`ADAPTATIONS`), on each
subject's whitened coordinates (:mod:`scioc.models.bayes.whiten`, :mod:`scioc.pipelines.fit.whiten`: the mode with
the population scales held, each subject's Hessian block there, x_i = x̂_i + L_i w_i), with nutpie's
diagonal mass matrix on w. On 12 subjects (README "On each subject's whitened coordinates", two seeds
each) it needed 40-46 k gradients against the low-rank matrix's 99-100 k and the diagonal one's 79-82
k, for about the same ESS of the population parameters; with the lognormal population σ_R mixed
better (ESS 99 against 35). At full size (42 subjects of the ``kbl`` human with a change of cost,
unpooled R, 4 × (1000 + 1000) draws) it sampled in 2349 s at 31.2 leapfrog steps per kept draw,
every population parameter at R-hat <= 1.007 and ESS >= 601, with one divergent transition (in one
subject's tail of σ_m towards 0). The affine map cannot straighten the subjects' tails in log R
and σ_m; they set the trees' depth.

Since 2026-12-05 the default (:data:`CURVED`) also bends each subject's coordinates along its ridge in σ_m
(:mod:`scioc.models.bayes.whiten`, "Curved"): with σ_m's block folded centred, σ_m = |v| and log R grows with v², a
parabola through the mode v = 0 that no affine map straightens. Measured: README, "Speed". With a signed
ρ = R^(-1/2) (``R_population="policy_scale"``, ρ folded or folded centred) it bends along ρ's coordinate
instead, the ridge there being an arch over it, or with σ_m's signed too, per subject along the one whose fold
its mode is nearest (:func:`scioc.models.bayes.delayed_blocks.ridge_pivots`).

Its target acceptance rate is 0.9 (:data:`WHITENED_TARGET_ACCEPT`), not nutpie's 0.8: the
convergence verdict fails on a single divergent transition, and the smaller steps left fewer. With the pilot run
and a signed ρ it is 0.8 again (:data:`PILOT_ADAPTATION_TARGET_ACCEPT`).
Measured on 12 subjects of each human (those of :mod:`scioc.pipelines.fit.delayed_forms`' table, the same
command without ``--log-R-form``, the kernel with its reverse-mode plan, alone on the machine; the
rate set by patching ``nutpie_options`` in a wrapper script, as ``scioc fit`` has no option for it)::

    human   rate, seed   steps (warm-up, kept)   div   population: smallest ESS; largest R-hat
    maxent  0.8, 1       43.0  26.1               5    σ_log θ1 26; σ_log θ1 1.051
    maxent  0.8, 2       47.5  29.1               0    s_m 36; s_m 1.079
    maxent  0.9, 1       54.4  40.0               1    s_m 52; s_m 1.020
    maxent  0.9, 2       52.5  31.8               0    s_m 77; σ_β 1.029
    kbl     0.8, 1       58.4  48.3               1    σ_R 24; σ_R 1.091
    kbl     0.8, 2       58.5  43.6               2    μ_R 50; σ_R 1.053
    kbl     0.9, 1       70.0  50.0               0    σ_R 39; σ_R 1.028
    kbl     0.9, 2       71.2  52.9               0    μ_R 39; μ_R 1.088

One divergent transition in four runs against eight, for 10-30 % more leapfrog steps; the
population's mixing is no worse (two seeds of 600 draws each: noisy). At full size: README,
"The same delayed fit with the forms the data choose".

Pilot
-----
The Hessian at the mode describes some subjects' posteriors badly (the ``kbl`` human's log σ_m, whose tail
towards 0 it does not see): on the twelve that sample worst, the curved fit's draws had SDs of 0.75 to 28 in
w and, within subjects, correlations that nutpie's diagonal mass matrix cannot take
(:mod:`scioc.models.bayes.whiten_draws`). Since 2026-12-06 the default (:data:`PILOT`) therefore measures the same
coordinates again on the draws of a pilot run (:mod:`scioc.pipelines.fit.warmup`: 100 + 100 draws per chain) and
starts the kept run at the pilot's last draw. On those twelve (2 chains × (300 + 300) draws, seed 1, policy-scale
R, ρ folded centred; the pilot 100 + 100): 26.8 leapfrog steps per kept draw against the curved fit's 58.0
(:mod:`scioc.pipelines.fit.delayed_forms`' table), 29.0 per warm-up draw, the pilot 37.9 per draw; the smallest ESS
of a population parameter 204 (σ_β) against 84. At full size: README, "Speed". The pilot runs on 2 chains (at
most the fit's; :data:`scioc.pipelines.fit.warmup.PILOT_CHAINS` says what that saved).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.basic import Constant

from scioc.models.bayes.blocks import Parameterization
from scioc.models.bayes.delay_step import DelayMetropolis
from scioc.models.bayes.delayed_blocks import (
    DELAYED_POPULATION_PARAMETERS,
    R_POPULATIONS,
    DelayedForm,
    DelayedPriors,
    cost_blocks,
    motor_blocks,
)
from scioc.models.bayes.delayed_op import DelayedLoglikOp, pack_tau0, warmups_of
from scioc.models.bayes.delayed_value import DelayedLoglikValueOp  # noqa: F401 (registers its rewrite)
from scioc.models.bayes.hierarchical import Priors
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.design import CONDITIONS, WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.segment import Feedback, as_batch
from scioc.models.units import index_study

#: Name of the sampled delays' grid indices (dims ``subject``) in a model built with ``delay=None``.
DELAY_INDEX = "delay_index"
#: The cost blocks' forms for the delayed human (module docstring, "Geometry"): log R non-centred,
#: the rest as the max-ent model's default (``scioc fit`` chooses log R's by the data:
#: :func:`scioc.pipelines.fit.delayed_forms.log_R_form`).
DELAYED_PARAMETERIZATION = Parameterization(R_mc="noncentred", R_sc="noncentred")
#: nutpie's own mass matrices for this model (module docstring, "Geometry"): low rank and diagonal.
NUTPIE_ADAPTATIONS = ("low_rank", "diag")
#: nutpie's options for this model on its own coordinates (``scioc bench-fit``, which has no ML start to whiten
#: at): the low-rank mass matrix.
DELAYED_NUTS = {"adaptation": NUTPIE_ADAPTATIONS[0]}
#: The name in :data:`ADAPTATIONS` of the whitened sampling.
WHITENED = "whitened"
#: The name in :data:`ADAPTATIONS` of the whitened sampling with each subject's ridge along σ_m (or a signed ρ)
#: curved (module docstring, "Curved").
CURVED = "curved"
#: The name in :data:`ADAPTATIONS` of the curved whitened sampling with nutpie's low-rank mass matrix on top.
CURVED_LOW_RANK = "curved_low_rank"
#: The name in :data:`ADAPTATIONS` of the curved whitening measured again on a pilot run's draws
#: (:mod:`scioc.models.bayes.whiten_draws`; module docstring, "Pilot").
PILOT = "pilot"
#: The mass matrices a delayed fit with profile delays may use (``scioc fit --adaptation``), the default first:
#: nutpie's diagonal one on each subject's whitened coordinates curved along its ridge, measured on a pilot run's
#: draws, then measured at the Hessian alone, then on the affine whitened ones (:mod:`scioc.models.bayes.whiten`; module
#: docstring, "Whitened", "Curved"), then nutpie's own, then its low-rank one on the curved coordinates
#: (:data:`CURVED_LOW_RANK`).
ADAPTATIONS = (PILOT, CURVED, WHITENED, *NUTPIE_ADAPTATIONS, CURVED_LOW_RANK)
#: The entries of :data:`ADAPTATIONS` sampled on each subject's whitened coordinates, and those of them curved.
WHITENED_ADAPTATIONS = (PILOT, CURVED, WHITENED, CURVED_LOW_RANK)
CURVED_ADAPTATIONS = (PILOT, CURVED, CURVED_LOW_RANK)


#: nutpie's target acceptance rate on the whitened coordinates (module docstring, "Whitened"; nutpie's default 0.8).
WHITENED_TARGET_ACCEPT = 0.9
#: With a pilot run (:data:`PILOT`) and ρ signed: the pilot gives each pivot a tail map (models/bayes/pivot_tails.py),
#: which removed the divergences at ρ̃'s wall that kept 0.9; not with lognormal R (0.8 failed, R-hat 1.011, there).
#: Measured: :mod:`scioc.pipelines.fit.warmup`, "The pivot's tails", and README, "Speed".
PILOT_ADAPTATION_TARGET_ACCEPT = 0.8


def nutpie_options(adaptation: str, rho_signed: bool = False) -> dict:
    """nutpie's options for a delayed fit with this :data:`ADAPTATIONS` entry (whitened, curved or not: its diagonal
    mass matrix, or the low-rank one with :data:`CURVED_LOW_RANK`, and :data:`WHITENED_TARGET_ACCEPT`, or
    :data:`PILOT_ADAPTATION_TARGET_ACCEPT` with the pilot run where ρ's coordinate is signed, ``rho_signed``)."""
    if adaptation not in ADAPTATIONS:
        raise ValueError(f"adaptation must be one of {', '.join(ADAPTATIONS)}; got {adaptation!r}")
    if adaptation in WHITENED_ADAPTATIONS:
        return {"adaptation": "low_rank" if adaptation == CURVED_LOW_RANK else "diag",
                "target_accept": PILOT_ADAPTATION_TARGET_ACCEPT if adaptation == PILOT and rho_signed
                else WHITENED_TARGET_ACCEPT}
    return {"adaptation": adaptation}




def _tau0_at(spec, n: int, dt: float, params: WheelParameters):
    """A function (segment j, τ_nm) -> τ_0, N·m: the fixed value, or the warm-up's arm torque at that lag."""
    warmups = warmups_of(spec, n)
    if warmups is not None:
        def from_warmup(j, tau_nm):
            lag = lag_coefficients(tau_nm, dt, params)
            return float(window_tau0([warmups[j]], lag.a, lag.alpha)[0][0])

        return from_warmup
    fixed = pack_tau0(spec, n)[2]
    return lambda j, tau_nm: float(fixed[j])


def build_delayed_model(subjects: Sequence, conditions: Sequence, segments, plant: DiscretePlant, *, delay,
                        tau0=0.0, priors: Priors = Priors(), delayed_priors: DelayedPriors = DelayedPriors(),
                        parameterization: Parameterization = DELAYED_PARAMETERIZATION,
                        delayed_form: DelayedForm = DelayedForm(), segment_ids: Sequence | None = None,
                        levels: Sequence = CONDITIONS, params: WheelParameters = WheelParameters(),
                        delay_grid=None) -> pm.Model:
    """The hierarchical ``delayed`` model of a study (see the module docstring).

    Parameters
    ----------
    subjects, conditions, segments, plant, priors, parameterization, segment_ids, levels
        As :func:`scioc.models.bayes.hierarchical.build_model` (condition effects always on).
    delay : int, array_like of int (n,), or None
        Perceptual delay of each segment, samples: data, not a parameter. None samples it:
        one delay per subject, ``delay_index`` (dims ``subject``) uniform over
        ``delay_grid``, updated by :class:`scioc.models.bayes.delay_step.DelayMetropolis`
        (:func:`delay_step`); the continuous draws are then delay-marginal.
    delay_grid : array_like of int, optional
        The grid of a sampled delay, samples (required with ``delay=None``).
    tau0 : float, array_like (n,), or sequence of Warmup or None (n)
        The arm torque at each window's start (:func:`scioc.models.bayes.delayed_op.pack_tau0`).
    delayed_priors : DelayedPriors
    delayed_form : DelayedForm
    params : WheelParameters
        The wheel ``plant`` was discretized from.

    Returns
    -------
    pymc.Model
        The variables of :func:`scioc.models.bayes.hierarchical.build_model`'s condition model, plus
        ``tau_nm_scale``, ``sigma_m_scale``, the per-subject ``tau_nm``, ``sigma_m`` (dims
        ``subject``; ``z_tau_nm``, ``z_sigma_m`` when non-centred or folded). Observed ``u_H`` (segment, step),
        one log-likelihood per segment.
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
    sampled = delay is None
    if sampled:
        if delay_grid is None:
            raise ValueError("a sampled delay (delay=None) needs its delay_grid")
        grid = np.asarray(delay_grid, dtype=np.int64)
        if grid.ndim != 1 or grid.shape[0] < 2 or np.any(grid < 0) or np.any(np.diff(grid) <= 0):
            raise ValueError(f"delay_grid must be increasing whole samples >= 0, two or more; got {delay_grid!r}")
        delay = 0
    op = DelayedLoglikOp(batch, plant, delay=delay, tau0=tau0, params=params)
    u_obs = op.bound[3]
    d_seg = op.delay

    def logp(value, q11, q22, R, tau_nm, sigma_m, d, u_A):
        if not (isinstance(value, Constant) and np.array_equal(value.data, u_obs)):
            raise NotImplementedError("the delayed likelihood of this model is bound to the observed torques")
        ll, _ = op(pt.stack([q11, q22, R]), tau_nm, sigma_m, d if sampled else None)
        return ll

    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    tau0_at = _tau0_at(tau0, n, plant.dt, params)

    def random(q11, q22, R, tau_nm, sigma_m, d, u_A_window, rng=None, size=None):
        # Exact draws of the delayed human (models.delayed.sample_delayed); the last batch axis is the segment.
        shape = tuple(size) if size is not None else np.broadcast_shapes(q11.shape, tau_nm.shape)
        ps = [np.broadcast_to(p, shape) for p in (q11, q22, R, tau_nm, sigma_m, d)]
        out = np.empty(shape + (K,))
        for idx in np.ndindex(*shape):
            j = idx[-1]
            fb = Feedback(batch.fb[j], batch.a[j]) if np.any(batch.fb[j] != 0) else None
            tau = float(ps[3][idx])
            out[idx] = sample_delayed([ps[0][idx], ps[1][idx], ps[2][idx]], x0[j], batch.r[j], plant, rng,
                                      u_A=None if fb is not None else batch.a[j], feedback=fb, tau_nm=tau,
                                      sigma_m=float(ps[4][idx]), delay=int(ps[5][idx]),
                                      tau0=tau0_at(j, tau), n_obs=K, params=params).u_H
        return out

    with pm.Model(coords=coords) as model:
        _, log_R, theta2, R = cost_blocks(priors, parameterization, L, effect, delayed_priors, delayed_form)
        tau_nm, sigma_m = motor_blocks(delayed_priors, delayed_form)
        log_theta1 = model["log_theta1"]
        R_s = R[s_idx, c_idx]
        q11 = pt.exp(log_theta1[s_idx, c_idx] + log_R[s_idx, c_idx])
        q22 = theta2[s_idx, c_idx] * R_s
        if sampled:
            index_var = pm.DiscreteUniform(DELAY_INDEX, 0, grid.shape[0] - 1, dims="subject")
            d = pt.as_tensor(grid)[index_var][s_idx]
        else:
            d = pt.as_tensor(np.asarray(d_seg, dtype=np.int64))
        pm.CustomDist("u_H", q11, q22, R_s, tau_nm[s_idx], sigma_m[s_idx], d, batch.a[:, :K], logp=logp, random=random,
                      signature="(),(),(),(),(),(),(k)->(k)", observed=u_obs, dims=("segment", "step"))
        if sampled:
            # Each subject's log-likelihood, for the delay's Metropolis step (delay_step).
            ll_seg, _ = op(pt.stack([q11, q22, R_s]), tau_nm[s_idx], sigma_m[s_idx], d)
            member = np.zeros((len(index.subjects), n))
            member[s_idx, np.arange(n)] = 1.0
            model.delay_group_loglik = pt.dot(pt.as_tensor(member), ll_seg)
            model.delay_grid = grid
    return model


def delay_step(model: pm.Model, **kwargs) -> DelayMetropolis:
    """The Metropolis step of a sampled-delay model's ``delay_index`` (:func:`build_delayed_model` with delay=None)."""
    if not hasattr(model, "delay_group_loglik"):
        raise ValueError("this model's delays are fixed (built with a delay): there is no delay to sample")
    return DelayMetropolis([model[DELAY_INDEX]], model.delay_group_loglik, model.delay_grid.shape[0], model=model,
                           **kwargs)


__all__ = ["ADAPTATIONS", "CURVED", "CURVED_ADAPTATIONS", "CURVED_LOW_RANK", "DELAY_INDEX", "DELAYED_NUTS",
           "DELAYED_PARAMETERIZATION", "DELAYED_POPULATION_PARAMETERS", "DelayedForm", "DelayedPriors",
           "NUTPIE_ADAPTATIONS", "PILOT", "PILOT_ADAPTATION_TARGET_ACCEPT", "R_POPULATIONS", "WHITENED",
           "WHITENED_ADAPTATIONS", "WHITENED_TARGET_ACCEPT", "build_delayed_model", "delay_step", "nutpie_options"]
