"""Population blocks of the ``delayed`` model: its hyperpriors, the forms of its blocks, and the blocks.

The max-ent cost blocks (:func:`cost_blocks`) with the subjects' baseline R log-normal, half-normal in ρ = R^(-1/2)
or unpooled (docs/decisions/delayed-R-population.md), and the per-subject lag and motor noise (:func:`motor_blocks`;
docs/decisions/delayed-half-normal-populations.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymc as pm
import pytensor.tensor as pt

from scioc.models.bayes.blocks import Parameterization, theta2_block, unit_block
from scioc.models.bayes.hierarchical import Priors

#: Population parameters of the lag and motor-noise blocks (and of ρ, with ``R_population="policy_scale"``).
DELAYED_POPULATION_PARAMETERS = ("tau_nm_scale", "sigma_m_scale", "rho_scale")
#: The populations of the subjects' baseline R (:class:`DelayedPriors`).
R_POPULATIONS = ("lognormal", "policy_scale", "unpooled")
#: The forms of τ_nm, σ_m and ρ (:class:`DelayedForm`).
MOTOR_FORMS = ("centred", "noncentred", "folded", "folded_centred")


@dataclass(frozen=True)
class DelayedPriors:
    """Hyperpriors of the lag and motor-noise blocks and the population of R (τ_nm in s, σ_m in N·m per sample).

    ``tau_nm_scale``: scale of s_τ's half-normal prior. s_m² ~ InverseGamma(``sigma_m_variance_inverse_gamma``:
    shape, scale; docs/decisions/motor-noise-scale-prior.md). ``R_population``: log R ~ N(μ_R, σ_R), σ_R
    half-normal; ρ = R^(-1/2) ~ HalfNormal(s_ρ), s_ρ ~ HalfNormal(``rho_scale_factor`` e^(-μ_R/2)); or each subject's
    own N(m, s) (:meth:`unpooled_log_R_prior`).
    """

    tau_nm_scale: float = 0.1
    sigma_m_variance_inverse_gamma: tuple[float, float] = (1.0, 0.03)
    R_population: str = "lognormal"
    rho_scale_factor: float = 2.0

    def __post_init__(self):
        g = self.sigma_m_variance_inverse_gamma
        if g is None or not (len(g) == 2 and all(np.isfinite(v) and v > 0 for v in g)):
            raise ValueError(f"sigma_m_variance_inverse_gamma must be (shape, scale), both > 0; got {g!r}")
        if self.R_population not in R_POPULATIONS:
            raise ValueError(f"R_population must be one of {R_POPULATIONS}; got {self.R_population!r}")
        if not (np.isfinite(self.rho_scale_factor) and self.rho_scale_factor > 0):
            raise ValueError(f"rho_scale_factor must be > 0; got {self.rho_scale_factor!r}")

    def rho_prior_scale(self, priors: Priors) -> float:
        """Scale of the half-normal prior on s_ρ: ``rho_scale_factor`` × exp(-μ/2), μ the centre of ``mu_log_R``."""
        return float(self.rho_scale_factor * np.exp(-0.5 * priors.mu_log_R[0]))

    @staticmethod
    def unpooled_log_R_prior(priors: Priors) -> tuple[float, float]:
        """(m, s) of ``unpooled``: the lognormal population's marginal prior of one subject (s² = sd² + E[σ_R²])."""
        centre, sd = priors.mu_log_R
        return float(centre), float(np.hypot(sd, priors.sigma_log_R))


@dataclass(frozen=True)
class DelayedForm:
    """The forms of the lag, motor-noise and ρ blocks: each the same half-normal law in other coordinates.

    ``centred`` samples the value; ``noncentred`` z ~ HalfNormal(1), value s z; ``folded`` z ~ N(0, 1), value s |z|;
    ``folded_centred`` v ~ N(0, s), value |v|.
    """

    tau_nm: str = "centred"
    sigma_m: str = "centred"
    rho: str = "folded"

    def __post_init__(self):
        for name in ("tau_nm", "sigma_m", "rho"):
            if getattr(self, name) not in MOTOR_FORMS:
                raise ValueError(f"DelayedForm.{name} must be one of {MOTOR_FORMS}; got {getattr(self, name)!r}")


def baseline_log_R(priors: Priors, delayed_priors: DelayedPriors, form: DelayedForm):
    """The subjects' baseline log R = -2 log ρ, ρ ~ HalfNormal(s_ρ) in ``form.rho``, starting at R = e^μ."""
    scale = pm.HalfNormal("rho_scale", delayed_priors.rho_prior_scale(priors))
    rho = half_normal_block("rho", scale, form.rho, start=float(np.exp(-0.5 * priors.mu_log_R[0])))
    return -2.0 * pt.log(rho)


def cost_blocks(priors: Priors, form: Parameterization, n_levels: int, effect: dict, delayed_priors: DelayedPriors,
                delayed_form: DelayedForm):
    """The population parameters and unit blocks of θ, as in the max-ent model but for the population of R."""
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
        sigma_R = pm.HalfNormal("sigma_log_R", priors.sigma_log_R)
        form_R = form.R_mc
    tau = pm.HalfNormal("tau_theta2", priors.tau_theta2)
    log_theta1 = unit_block("log_theta1", mu, beta, sigma, sigma_b, form.theta1_mc, form.theta1_sc, n_levels)
    log_R = unit_block("log_R", mu_R, beta_R, sigma_R, sigma_bR, form_R, form.R_sc, n_levels)
    theta2 = theta2_block(tau, form.theta2)
    pm.Deterministic("theta1", pt.exp(log_theta1), dims=("subject", "condition"))
    R = pm.Deterministic("R", pt.exp(log_R), dims=("subject", "condition"))
    return log_theta1, log_R, theta2, R


#: Where a ``folded_centred`` block starts without ML estimates, off 0: a modest lag (s) and motor noise (N·m).
FOLDED_CENTRED_START = {"tau_nm": 0.05, "sigma_m": 0.05}


def motor_noise_scale(priors: DelayedPriors):
    """s_m, the population scale of σ_m: s_m² inverse gamma (:class:`DelayedPriors`)."""
    a, b = priors.sigma_m_variance_inverse_gamma
    return pm.Deterministic("sigma_m_scale", pt.sqrt(pm.InverseGamma("sigma_m_scale_sq", alpha=a, beta=b)))


def motor_blocks(priors: DelayedPriors, form: DelayedForm):
    """τ_nm and σ_m per subject from half-normal populations, in ``form``."""
    s_tau = pm.HalfNormal("tau_nm_scale", priors.tau_nm_scale)
    s_m = motor_noise_scale(priors)
    tau_nm = half_normal_block("tau_nm", s_tau, form.tau_nm)
    return tau_nm, half_normal_block("sigma_m", s_m, form.sigma_m)


def motor_coordinate(name: str, form: str) -> str:
    """The free variable that holds each subject's ``name`` in ``form`` (as :func:`half_normal_block` names it)."""
    if form not in MOTOR_FORMS:
        raise ValueError(f"unknown form {form!r}; one of {MOTOR_FORMS}")
    return {"centred": name, "noncentred": f"z_{name}", "folded": f"z_{name}", "folded_centred": f"{name}_signed"}[form]


#: The forms in which a half-normal block's coordinate is signed: its law symmetric about the coordinate's 0.
SIGNED_FORMS = ("folded", "folded_centred")


def ridge_pivots(priors: DelayedPriors, form: DelayedForm, n_subjects: int) -> tuple[tuple[str, np.ndarray], ...]:
    """The free variables a curved whitening may bend each subject's block along, each with the subjects (n,) in
    which it is signed: ρ's first where it has one, σ_m's last. The ridge ρ² + k σ_m² ≈ c is a parabola along σ_m
    and an arch over a signed ρ̃ (:func:`scioc.models.bayes.whiten.nearest_fold` picks per subject)."""
    sigma_m = (motor_coordinate("sigma_m", form.sigma_m), np.full(n_subjects, form.sigma_m in SIGNED_FORMS))
    if priors.R_population != "policy_scale":
        return (sigma_m,)
    return (motor_coordinate("rho", form.rho), np.full(n_subjects, form.rho in SIGNED_FORMS)), sigma_m


def half_normal_block(name: str, scale, form: str, *, start: float | None = None):
    """Per subject ``name`` ~ HalfNormal(``scale``) in a :data:`MOTOR_FORMS` form; signed coordinates start off 0."""
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
           "R_POPULATIONS", "SIGNED_FORMS", "baseline_log_R", "cost_blocks", "half_normal_block",
           "motor_blocks", "motor_coordinate", "motor_noise_scale", "ridge_pivots"]
