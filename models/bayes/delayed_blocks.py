"""Population blocks of the ``delayed`` model: its hyperpriors, the forms of its blocks, and the blocks.

:mod:`scioc.models.bayes.delayed_model` builds the model from these: the max-ent cost blocks
(:func:`cost_blocks`, :mod:`scioc.models.bayes.blocks`), with the subjects' baseline R either
log-normal, as the max-ent model's, or through its policy-noise scale ρ = R^(-1/2)
(:class:`DelayedPriors`), and the per-subject lag and motor noise (:func:`motor_blocks`).
Why these forms: :mod:`scioc.models.bayes.delayed_model`, "Geometry"; the measurements of the
population of R follow.

σ_R's prior (measured 2026-12-02 with the half-normal τ_nm population, as
``pipelines.bench.fit_delayed.bench_fit_delayed(n_subjects=12, chains=2, draws=300,
tune=300, seed=1, ...)``, a calibration run on the machine's two cores beside it)::

    σ_R prior          log R MC / SC   steps/draw  div  σ_R R-hat, ESS   ESS of unit log R, σ_m (min)
    HalfNormal(0.5)    NC / NC         31.8        0    1.107, 12        37, 78       <- default
    Gamma(2, rate 4)   NC / NC         27.9        0    1.021, 42        76, 213
    Gamma(2, rate 4)   C / C           27.5        12   1.054, 41        28, 39
    Gamma(2, rate 4)   NC / NC         27.1        1    1.159, 11        23, 108
      and σ_βR ~ Gamma(2, rate 10)

A Gamma prior of shape 2 (``DelayedPriors(sigma_log_R_gamma=(2, 4))``: density 0 at
σ_R = 0, mean 0.5 like the half-normal's scale) removes the region near 0 where a chain
sat. Its one run helped every slow quantity, but the last row (the same prior on σ_R, and
a Gamma on σ_βR as well; an experiment, not an option) fell back to ESS 11: with one seed
of 600 draws per row the prior's effect is not established, and σ_R does not mix in any
form tried. Not the default.

The policy-noise scale instead of log R (measured 2026-12-02 beside a calibration run, as
``scioc bench-fit --human-model delayed --subjects 12 --chains 2 --draws 300 --tune 300
--seed 1 --R-population policy_scale --rho-form F --adaptation A``; the first row is the
σ_R table's default). ``DelayedPriors(R_population="policy_scale")`` replaces each subject's
baseline log R ~ N(μ_R, σ_R) by ρ = R^(-1/2) ~ HalfNormal(s_ρ): the direction the data
leave open (R -> ∞ at a slightly shorter lag) becomes ρ -> 0, a finite interval, and
a human without policy noise is in the population::

    baseline R           form, mass matrix   steps/draw  div  worst population (R-hat, ESS)   unit log R (R-hat, ESS)
    log R ~ N(μ_R, σ_R)  NC, low rank        31.8        0    σ_R 1.107, 12                   -, 37
    ρ ~ HalfN(s_ρ)       centred, low rank   41.4        0    σ_β 1.036, 85                   1.451, 4
    ρ ~ HalfN(s_ρ)       folded, low rank    86.3        0    s_ρ 1.032, 100                  1.022, 99
    ρ ~ HalfN(s_ρ)       folded, diagonal    81.6        0    s_ρ 1.017, 101                  1.016, 133
    ρ ~ HalfN(s_ρ)       folded centred, lr  56.2        0    σ_βR 1.013, 121                 1.042, 50
    log R ~ N(m, s) own  unpooled, low rank  34.4        0    σ_β 1.015, 110                  1.038, 69

(``folded``: z ~ N(0, 1), ρ = s_ρ |z|, :class:`DelayedForm`; these two rows ran before z's
initial point was set to 1, from nutpie's jittered start. ``folded centred``: ρ̃ ~ N(0, s_ρ),
ρ = |ρ̃|, measured 2026-12-02 beside a two-worker calibration run, ``--rho-form
folded_centred``; its slowest quantities were σ_β and σ_βR, ESS 121 each (the smaller of bulk
and tail), and
τ_nm's truth was inside its HDI for 10 of 12 subjects, σ_m's for 11, β's yes.) Centring the
folded form cut the steps per draw by a third but halved the worst unit log R's ESS: per
gradient it is about as good as ``folded`` on the population and worse on the units, in one
run each. Centred (the second row), PyMC's log transform
stretches ρ -> 0 into an infinite tail of log ρ and the units stall (one subject's ρ at
ESS 4). Folded, every block mixes (R-hat <= 1.032, every unit ESS >= 99; β's truth, τ_nm's
for 11 of 12 and σ_m's for 12 of 12 inside their 94 % HDIs): per gradient about three times
the ESS of the lognormal population's worst parameter, but at 2.6 times the leapfrog steps
per draw, which puts a full-size fit at about an hour on this machine. Not the default yet:
it has not been run at full size, and the step count is the next thing to understand.

Without a population (``DelayedPriors(R_population="unpooled")``, the last row, measured
2026-12-03 beside a full-size delayed fit, ``--R-population unpooled``): each subject's
baseline log R has its own N(m, s) prior, with the lognormal population's marginal centre
and variance (:meth:`DelayedPriors.unpooled_log_R_prior`), so there is no σ_R. Every population
parameter mixed (worst σ_β: R-hat 1.015, ESS 110 of 600 draws; μ_log θ1's R-hat 1.015),
at 34.4 leapfrog steps per draw, about the lognormal population's 31.8 and 40 % of
the folded ρ's; β's truth inside its HDI (−0.62, [−0.82, −0.42], truth −0.7), τ_nm's and
σ_m's for 11 of 12 subjects each. The price: the subjects' R are not shrunk towards each
other (R is the nuisance the data barely fix; the cost ratio θ1 = q11/R keeps its
population). One run, one seed. At full size (the README's ``kbl0`` fit) it converged too and
passes the adequacy check at a posterior draw (it failed the innovation variance at the posterior
means, a fault of that rule: README, "At the posterior"); not the default until the study with a
change of cost has been fitted with it at full size.

The motor-noise scale. s_m² ~ InverseGamma(1, 0.03) by default (``DelayedPriors.
sigma_m_variance_inverse_gamma``, since the last change of 2026-12-05; s_m's median 0.21 N·m).
Before it, s_m ~ Gamma(2, rate 8) (``sigma_m_scale_gamma``; before that, HalfNormal(0.3), whose
mean 0.24 N·m the Gamma's 0.25 keeps). On a human without motor noise the data bound each σ_m
from above only, and below that bound s_m's posterior is its prior: the half-normal's density is
flat at 0, an exponential tail in log s_m that the sampler crossed slowly (the convergence
verdict's slowest quantity on the max-ent human at full size); the Gamma's vanishes at 0 like
s_m, which halved that tail's length in log s_m and about doubled s_m's ESS, still short of the
verdict's 400 at full size. The inverse gamma's density vanishes at 0 faster than any power, so
s_m stays where the subjects' σ_m put it, and with σ_m's block then centred (folded centred,
:func:`half_normal_block`) s_m mixes freely: ESS 1110 and 1667 of 600 draws on 12 subjects
against 30 and 37 with the Gamma, at the same leapfrog steps (table and reasons in
:mod:`scioc.pipelines.fit.delayed_forms`, "The motor-noise scale's prior"). Where the data find
motor noise (the ``kbl`` human, σ_m about 0.25 N·m) s_m is fixed by the data under any of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymc as pm
import pytensor.tensor as pt

from scioc.models.bayes.blocks import Parameterization, theta2_block, unit_block
from scioc.models.bayes.hierarchical import Priors
from scioc.models.bayes.noise_blocks import (
    NOISE_A,
    NOISE_B,
    mixed_half_normal_block,
    polar_noise_block,
    squared_half_normal_block,
)

#: Population parameters of the lag and motor-noise blocks (and of ρ, with ``R_population="policy_scale"``).
DELAYED_POPULATION_PARAMETERS = ("tau_nm_scale", "sigma_m_scale", "rho_scale")
#: The populations of the subjects' baseline R (:class:`DelayedPriors`).
R_POPULATIONS = ("lognormal", "policy_scale", "unpooled")
#: The forms of τ_nm and σ_m (:class:`DelayedForm`); ρ's add ``mixed`` (:func:`mixed_half_normal_block`).
MOTOR_FORMS = ("centred", "noncentred", "folded", "folded_centred")
RHO_FORMS = MOTOR_FORMS + ("mixed", "polar", "squared")


@dataclass(frozen=True)
class DelayedPriors:
    """Hyperpriors of the lag and motor-noise blocks (rate-free: τ_nm in s, σ_m in N·m per sample).

    Attributes
    ----------
    tau_nm_scale : float
        Scale of the HalfNormal prior on s_τ, the population scale of τ_nm, s.
    sigma_m_scale : float
        Scale of the HalfNormal prior on s_m, the population scale of σ_m, N·m, when
        ``sigma_m_variance_inverse_gamma`` and ``sigma_m_scale_gamma`` are None.
    sigma_m_variance_inverse_gamma : (float, float) or None
        Shape α and scale β of the inverse-gamma prior on s_m², the variance of the σ_m
        population (default (1, 0.03): s_m's median 0.21 N·m, the Gamma's, and 90 % of its mass
        on 0.10-0.77 N·m, against the Gamma's 0.04-0.59; its density vanishes at 0 faster than any
        power). Sampled as ``sigma_m_scale_sq``, with s_m the deterministic ``sigma_m_scale``.
        Set to None for the Gamma (or the half-normal). The module docstring, "The motor-noise
        scale", says why.
    sigma_m_scale_gamma : (float, float) or None
        Shape and rate of a Gamma prior on s_m ((2, 8): mean 0.25 N·m, about the half-normal's
        0.24, and density 0 at s_m = 0; the default from 2026-12-05 until the inverse gamma),
        used where ``sigma_m_variance_inverse_gamma`` is None; both None give
        HalfNormal(``sigma_m_scale``).
    sigma_log_R_gamma : (float, float) or None
        Shape and rate of a Gamma prior on σ_R, the between-subject SD of log R, in place
        of the cost blocks' HalfNormal(``Priors.sigma_log_R``); None (default) keeps the
        half-normal. A Gamma of shape 2 has density 0 at σ_R = 0 (a boundary-avoiding
        prior, Chung et al. 2013), meant to remove the neck near 0 where the sampler stalled;
        its help is not established (module docstring).
    R_population : {"lognormal", "policy_scale"}
        The population of each subject's baseline R. ``lognormal`` (the max-ent model's):
        log R[i, baseline] ~ N(μ_R, σ_R). ``policy_scale``: ρ[i] = R[i, baseline]^(-1/2),
        the scale of the subject's max-ent (policy) noise at given gains, ρ[i] ~
        HalfNormal(s_ρ) (``rho``, ``rho_scale``), so that a human without policy noise
        (ρ = 0, R = ∞, as KBL's) is inside the population and the direction the data do not
        fix (policy against motor noise, :mod:`scioc.models.bayes.delayed_model` "Geometry") is bounded.
        ``unpooled``: no population, each subject's baseline log R ~ N(m, s) on its own, with
        the lognormal population's marginal centre and spread (:meth:`unpooled_log_R_prior`),
        so that no between-subject SD of log R (σ_R, the quantity that did not mix) exists;
        the subjects' R are then not shrunk towards each other. The changes of log R across
        levels are the same in all three.
    rho_scale_factor : float
        s_ρ ~ HalfNormal(``rho_scale_factor`` × exp(-μ/2)), μ the centre of ``Priors.mu_log_R``
        (:meth:`rho_prior_scale`; so it follows :meth:`Priors.for_design`'s sample time).
    """

    tau_nm_scale: float = 0.1
    sigma_m_scale: float = 0.3
    sigma_m_variance_inverse_gamma: tuple[float, float] | None = (1.0, 0.03)
    sigma_m_scale_gamma: tuple[float, float] | None = None
    sigma_log_R_gamma: tuple[float, float] | None = None
    R_population: str = "lognormal"
    rho_scale_factor: float = 2.0

    def __post_init__(self):
        for name in ("sigma_log_R_gamma", "sigma_m_scale_gamma", "sigma_m_variance_inverse_gamma"):
            g = getattr(self, name)
            if g is not None and not (len(g) == 2 and all(np.isfinite(v) and v > 0 for v in g)):
                what = "(shape, scale)" if name == "sigma_m_variance_inverse_gamma" else "(shape, rate)"
                raise ValueError(f"{name} must be {what}, both > 0; got {g!r}")
        if self.sigma_m_variance_inverse_gamma is not None and self.sigma_m_scale_gamma is not None:
            raise ValueError("s_m has one prior: give sigma_m_variance_inverse_gamma or sigma_m_scale_gamma, not both "
                             "(sigma_m_variance_inverse_gamma=None for the Gamma)")
        g = self.sigma_log_R_gamma
        if self.R_population not in R_POPULATIONS:
            raise ValueError(f"R_population must be one of {R_POPULATIONS}; got {self.R_population!r}")
        if self.R_population != "lognormal" and g is not None:
            raise ValueError("sigma_log_R_gamma is a prior of the lognormal R population; "
                             f"R_population={self.R_population!r} has no σ_R")
        if not (np.isfinite(self.rho_scale_factor) and self.rho_scale_factor > 0):
            raise ValueError(f"rho_scale_factor must be > 0; got {self.rho_scale_factor!r}")

    def rho_prior_scale(self, priors: Priors) -> float:
        """Scale of the HalfNormal prior on s_ρ: ``rho_scale_factor`` × exp(-μ/2), μ the centre of ``priors.mu_log_R``."""
        return float(self.rho_scale_factor * np.exp(-0.5 * priors.mu_log_R[0]))

    @staticmethod
    def unpooled_log_R_prior(priors: Priors) -> tuple[float, float]:
        """(m, s) of ``R_population="unpooled"``: log R[i, baseline] ~ N(m, s), each subject on its own.

        m is the centre of ``priors.mu_log_R`` and s = sqrt(sd² + σ²), sd its SD and σ the
        scale of σ_R's half-normal prior: the lognormal population's marginal prior of one
        subject has this centre and (as E[σ_R²] = σ²) this variance.
        """
        centre, sd = priors.mu_log_R
        return float(centre), float(np.hypot(sd, priors.sigma_log_R))


@dataclass(frozen=True)
class DelayedForm:
    """Centred, non-centred or folded form of the lag and motor-noise blocks.

    ``centred`` samples the subject's value, τ_nm[i] ~ HalfNormal(s_τ) (σ_m[i] ~
    HalfNormal(s_m)); ``noncentred`` samples z[i] ~ HalfNormal(1) and sets s_τ z[i] (s_m z[i]);
    ``folded`` samples z[i] ~ N(0, 1), unconstrained, and sets s_τ |z[i]| (s_m |z[i]|): the same
    law; ``folded_centred`` samples v[i] ~ N(0, s_τ) (N(0, s_m)), unconstrained, and sets |v[i]|:
    the same law again, centred, chosen for σ_m where the data find no motor noise
    (:mod:`scioc.pipelines.fit.delayed_forms`, "Motor noise" and "The motor-noise scale's prior").
    ``rho`` is the form of ρ = R^(-1/2) with ``DelayedPriors(R_population="policy_scale")``
    (unused otherwise): ``centred``, ``noncentred``, ``folded`` (default), z[i] ~ N(0, 1) and
    ρ[i] = s_ρ |z[i]| (the same half-normal law, with z unconstrained where the log transform of
    a half-normal stretches ρ -> 0 to an infinite tail), or ``folded_centred``, ρ̃[i] ~ N(0, s_ρ)
    and ρ[i] = |ρ̃[i]| (the same law again, centred: for subjects whose data fix ρ, where
    ``folded`` ties z to s_ρ); measured in the module docstring. ``mixed``: centred for the
    subjects of ``rho_pinned`` (one flag per subject, in the model's order), folded centred for
    the others (:func:`mixed_half_normal_block`; :func:`scioc.pipelines.fit.delayed_forms.choose_delayed_form`
    flags the subjects whose estimates fix ρ). ``polar``: ρ and σ_m of each subject with a k in ``polar_k`` (one
    per subject, NaN for none) in polar coordinates, the others folded centred (:mod:`scioc.models.bayes.noise_blocks`;
    ``sigma_m``'s form then does not apply; :func:`scioc.pipelines.fit.noise_arcs.noise_arcs` chooses k). ``squared``:
    ρ = u², u unconstrained and signed (:func:`scioc.models.bayes.noise_blocks.squared_half_normal_block`).
    """

    tau_nm: str = "centred"
    sigma_m: str = "centred"
    rho: str = "folded"
    rho_pinned: tuple = ()
    polar_k: tuple = ()

    def __post_init__(self):
        for name, allowed in (("tau_nm", MOTOR_FORMS), ("sigma_m", MOTOR_FORMS), ("rho", RHO_FORMS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f"DelayedForm.{name} must be one of {allowed}; got {getattr(self, name)!r}")
        if not all(isinstance(v, (bool, np.bool_)) for v in self.rho_pinned):
            raise ValueError(f"DelayedForm.rho_pinned must hold one bool per subject; got {self.rho_pinned!r}")
        if self.rho == "mixed" and not self.rho_pinned:
            raise ValueError("DelayedForm.rho='mixed' needs rho_pinned, one flag per subject (from ML estimates)")
        if self.rho == "polar" and not self.polar_k:
            raise ValueError("DelayedForm.rho='polar' needs polar_k, one k (or NaN) per subject (from ML estimates)")


def baseline_log_R(priors: Priors, delayed_priors: DelayedPriors, form: DelayedForm):
    """The subjects' baseline log R as -2 log ρ, ρ = R^(-1/2) ~ HalfNormal(s_ρ) (``R_population="policy_scale"``).

    Folded: ρ -> 0 is a finite step, not log ρ -> -∞, and z = 1 is not R = ∞; folded centred starts at
    ρ = exp(-μ/2), R at the prior's centre."""
    scale = pm.HalfNormal("rho_scale", delayed_priors.rho_prior_scale(priors))
    start = float(np.exp(-0.5 * priors.mu_log_R[0]))
    if form.rho == "mixed":
        rho = mixed_half_normal_block("rho", scale, np.asarray(form.rho_pinned, dtype=bool), start=start)
    elif form.rho == "squared":
        rho = squared_half_normal_block("rho", scale, start=start)
    elif form.rho == "polar":
        rho, _ = polar_noise_block(scale, motor_noise_scale(delayed_priors), form.polar_k, start_rho=start,
                                   start_sigma=FOLDED_CENTRED_START["sigma_m"])
    else:
        rho = half_normal_block("rho", scale, form.rho, start=start)
    return -2.0 * pt.log(rho)


def cost_blocks(priors: Priors, form: Parameterization, n_levels: int, effect: dict, delayed_priors: DelayedPriors,
                delayed_form: DelayedForm):
    """The population parameters and unit blocks of θ, as :func:`scioc.models.bayes.hierarchical.build_model` has them
    (σ_R Gamma(shape, rate) instead of half-normal with ``sigma_log_R_gamma``; the baseline log R from a
    half-normal ρ = R^(-1/2) with ``R_population="policy_scale"``, or each subject's own normal prior with
    ``R_population="unpooled"``: :class:`DelayedPriors`)."""
    sigma_R_gamma = delayed_priors.sigma_log_R_gamma
    mu = pm.Normal("mu_log_theta1", *priors.mu_log_theta1)
    beta = pm.Normal("beta", 0.0, priors.beta_sd, **effect)
    sigma = pm.HalfNormal("sigma_log_theta1", priors.sigma_log_theta1)
    sigma_b = pm.HalfNormal("sigma_beta", priors.sigma_beta, **effect)
    beta_R = pm.Normal("beta_log_R", 0.0, priors.beta_log_R_sd, **effect)
    sigma_bR = pm.HalfNormal("sigma_beta_log_R", priors.sigma_beta_log_R, **effect)
    if delayed_priors.R_population == "policy_scale":
        mu_R, sigma_R, form_R = baseline_log_R(priors, delayed_priors, delayed_form), None, "given"
    elif delayed_priors.R_population == "unpooled":
        m, sd = delayed_priors.unpooled_log_R_prior(priors)
        mu_R, sigma_R, form_R = pm.Normal("log_R_base", m, sd, dims="subject"), None, "given"
    else:
        mu_R = pm.Normal("mu_log_R", *priors.mu_log_R)
        sigma_R = (pm.HalfNormal("sigma_log_R", priors.sigma_log_R) if sigma_R_gamma is None
                   else pm.Gamma("sigma_log_R", alpha=sigma_R_gamma[0], beta=sigma_R_gamma[1]))
        form_R = form.R_mc
    tau = pm.HalfNormal("tau_theta2", priors.tau_theta2)
    log_theta1 = unit_block("log_theta1", mu, beta, sigma, sigma_b, form.theta1_mc, form.theta1_sc, n_levels)
    log_R = unit_block("log_R", mu_R, beta_R, sigma_R, sigma_bR, form_R, form.R_sc, n_levels)
    theta2 = theta2_block(tau, form.theta2)
    pm.Deterministic("theta1", pt.exp(log_theta1), dims=("subject", "condition"))
    R = pm.Deterministic("R", pt.exp(log_R), dims=("subject", "condition"))
    return log_theta1, log_R, theta2, R


#: Where a ``folded_centred`` block's signed values start without ML estimates (off the symmetric point 0):
#: τ_nm 0.05 s, σ_m 0.05 N·m, a modest lag and motor noise.
FOLDED_CENTRED_START = {"tau_nm": 0.05, "sigma_m": 0.05}


def motor_noise_scale(priors: DelayedPriors):
    """s_m, the population scale of σ_m: s_m² inverse gamma by default, else Gamma or half-normal (:class:`DelayedPriors`)."""
    if priors.sigma_m_variance_inverse_gamma is not None:
        a, b = priors.sigma_m_variance_inverse_gamma
        return pm.Deterministic("sigma_m_scale", pt.sqrt(pm.InverseGamma("sigma_m_scale_sq", alpha=a, beta=b)))
    if priors.sigma_m_scale_gamma is not None:
        return pm.Gamma("sigma_m_scale", alpha=priors.sigma_m_scale_gamma[0], beta=priors.sigma_m_scale_gamma[1])
    return pm.HalfNormal("sigma_m_scale", priors.sigma_m_scale)


def motor_blocks(priors: DelayedPriors, form: DelayedForm):
    """τ_nm and σ_m per subject, each from a half-normal population, in the forms of ``form``; s_τ half-normal,
    s_m (:func:`motor_noise_scale`). σ_m already in the model (``rho="polar"``: made with ρ) is taken as it is."""
    s_tau = pm.HalfNormal("tau_nm_scale", priors.tau_nm_scale)
    model = pm.modelcontext(None)
    made = "sigma_m" in model.named_vars
    s_m = None if made else motor_noise_scale(priors)
    tau_nm = half_normal_block("tau_nm", s_tau, form.tau_nm)
    return tau_nm, model["sigma_m"] if made else half_normal_block("sigma_m", s_m, form.sigma_m)


def motor_coordinate(name: str, form: str) -> str:
    """The free variable that holds each subject's ``name`` in ``form`` of :data:`MOTOR_FORMS` (as
    :func:`half_normal_block` names it): the coordinate a whitened fit curves each subject's ridge along
    (:func:`scioc.models.bayes.whiten.ridge_curvature`)."""
    if form not in MOTOR_FORMS:
        raise ValueError(f"unknown form {form!r}; one of {MOTOR_FORMS}")
    return {"centred": name, "noncentred": f"z_{name}", "folded": f"z_{name}", "folded_centred": f"{name}_signed"}[form]


#: The forms in which a half-normal block's coordinate is signed: its law symmetric about the coordinate's 0.
SIGNED_FORMS = ("folded", "folded_centred")


def ridge_pivots(priors: DelayedPriors, form: DelayedForm, n_subjects: int) -> tuple[tuple[str, np.ndarray], ...]:
    """The free variables a curved whitening may bend each subject's block along (:func:`scioc.models.bayes.whiten.
    ridge_curvature`), each with the subjects (n_subjects,) in which its coordinate is signed; per subject the
    signed one whose fold its mode is nearest, else the last (:func:`scioc.models.bayes.whiten.nearest_fold`). ρ's
    coordinate comes first where ρ = R^(-1/2) has one (``R_population="policy_scale"``; signed in
    :data:`SIGNED_FORMS`, and for ``mixed`` in the subjects not ``rho_pinned``); σ_m's (:func:`motor_coordinate`)
    always, last.

    Why. The policy noise (variance ∝ ρ²) and the motor noise (∝ σ_m²) share the torque's variability, so each
    subject's posterior follows a ridge ρ² + k σ_m² ≈ c. Along σ_m's coordinate that ridge is log R ≈ c' + k' σ_m²,
    the parabola :mod:`scioc.models.bayes.whiten` ("Curved") bends along. With ρ's coordinate signed (ρ = |ρ̃|) the ridge
    is an arch over it: σ_m largest where ρ̃ = 0 and falling as |ρ̃| grows, on both sides, which a subject whose
    data leave ρ near 0 crosses (ρ̃ changes sign). ρ̃ as a function of σ_m has two branches, which no bend along σ_m
    follows; σ_m as a function of ρ̃ is one symmetric curve, a parabola at its top, so the bend is along ρ̃. Where
    the data leave σ_m near 0 instead (no motor noise), the arch tops in σ_m, and so the bend is along the signed
    coordinate whose fold the subject's mode is nearest. Measured: :mod:`scioc.pipelines.fit.delayed_forms`, "The
    ridge's pivot with a signed ρ" and "The form of ρ". With ``rho="polar"`` the candidates are the polar block's
    a (signed where a subject is not in polar coordinates: a = ρ̃) and b (φ, or σ̃): a subject in polar coordinates
    bends along φ, what is left of its arc where k is not its ellipse's. With ``rho="squared"`` ρ's candidate is its
    root u (signed).
    """
    sigma_m = (motor_coordinate("sigma_m", form.sigma_m), np.full(n_subjects, form.sigma_m in SIGNED_FORMS))
    if priors.R_population != "policy_scale":
        return (sigma_m,)
    if form.rho == "polar":
        polar = np.isfinite(np.asarray(form.polar_k, dtype=float))
        if polar.shape != (n_subjects,):
            raise ValueError(f"polar_k has {polar.size} values for {n_subjects} subjects")
        return (NOISE_A, ~polar), (NOISE_B, np.full(n_subjects, True))
    if form.rho == "squared":
        return ("rho_root", np.full(n_subjects, True)), sigma_m
    if form.rho == "mixed":
        pinned = np.asarray(form.rho_pinned, dtype=bool)
        if pinned.shape != (n_subjects,):
            raise ValueError(f"rho_pinned has {pinned.size} flags for {n_subjects} subjects")
        return ("rho_free", ~pinned), sigma_m
    return (motor_coordinate("rho", form.rho), np.full(n_subjects, form.rho in SIGNED_FORMS)), sigma_m


def half_normal_block(name: str, scale, form: str, *, start: float | None = None):
    """Per subject, ``name`` ~ HalfNormal(``scale``) in one of :data:`MOTOR_FORMS`: centred; non-centred
    (scale · z, z ~ HalfNormal(1), named ``z_<name>``); folded (scale · |z|, z ~ N(0, 1) unconstrained,
    starting at z = 1, off the symmetric point z = 0); folded centred (|v|, v ~ N(0, scale) unconstrained,
    named ``<name>_signed``, starting at ``start``, default :data:`FOLDED_CENTRED_START`: the same law, centred)."""
    if form == "centred":
        return pm.HalfNormal(name, scale, dims="subject")
    if form == "noncentred":
        return pm.Deterministic(name, scale * pm.HalfNormal(f"z_{name}", 1.0, dims="subject"), dims="subject")
    n = len(pm.modelcontext(None).coords["subject"])
    if form == "folded_centred":
        signed = pm.Normal(f"{name}_signed", 0.0, scale, dims="subject",
                           initval=np.full(n, FOLDED_CENTRED_START[name] if start is None else start))
        return pm.Deterministic(name, pt.abs(signed), dims="subject")
    z = pm.Normal(f"z_{name}", 0.0, 1.0, dims="subject", initval=np.ones(n))
    return pm.Deterministic(name, scale * pt.abs(z), dims="subject")


__all__ = ["DELAYED_POPULATION_PARAMETERS", "FOLDED_CENTRED_START", "DelayedForm", "DelayedPriors", "MOTOR_FORMS",
           "RHO_FORMS", "R_POPULATIONS", "SIGNED_FORMS", "baseline_log_R", "cost_blocks", "half_normal_block",
           "motor_blocks", "motor_coordinate", "motor_noise_scale", "ridge_pivots"]
