"""The unit-parameter blocks of the hierarchical model: baseline value plus condition changes, in a chosen form.

A block is one log-parameter (log θ1 or log R) of every unit, dims (subject, condition),
written as the subject's baseline value and its change in each non-baseline level::

    x[i, 0] = baseline value of subject i          x[i, 0] ~ N(μ, σ)
    x[i, c] = x[i, 0] + d[i, c]                    d[i, c] ~ N(β_c, σ_β,c),  c = 1..L-1

(the changes of one subject independent across levels). :class:`Parameterization` says
how each part is sampled; :func:`unit_block` declares it inside a ``pm.Model``.

With two levels (the paper's MC and SC) the variables are named as they always were
(``log_theta1_MC``, ``z_log_theta1_SC``, ...; "MC" names the baseline and "SC" the other
level whatever the labels), scalars β, σ_β and changes with dims ``subject``: the model,
and so its draws for a seed, is exactly the two-level model of earlier versions. With
L > 2 levels β and σ_β have dims ``contrast`` (the non-baseline levels), the changes dims
(subject, contrast), and the names say ``baseline`` and ``contrast`` instead.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import pymc as pm
import pytensor.tensor as pt

Form = Literal["centred", "noncentred", "mean", "given", "quantile"]

#: Dims of a block's unit values.
UNIT_DIMS = ("subject", "condition")


@dataclass(frozen=True)
class Parameterization:
    """Centred or non-centred form of each block of unit parameters.

    For log θ1 and log R there are two blocks: the baseline value of each subject (the
    subject intercept; ``*_mc``, named after the paper's manual control) and its changes
    in the other levels (``*_sc``). ``centred`` samples the unit values themselves
    (log θ1[i, MC] ~ N(μ, σ); log θ1[i, SC] ~ N(log θ1[i, MC] + β, σ_β));
    ``noncentred`` samples standard-normal z and sets ``μ + σ z`` (intercept) or
    ``log θ1[i, MC] + β + σ_β z`` (change). ``mean`` (intercept only) samples the
    subject mean over the L levels, m_i = (1/L) Σ_c log θ1[i, c] ~ N(μ + Σ_c d_ic / L, σ)
    centred, after the changes d_ic (in the form ``theta1_sc`` says, as d_ic ~ N(β_c, σ_β,c)
    when centred): the same model, with the data acting on nearly orthogonal
    coordinates (for two levels m_i = (log θ1[i, MC] + log θ1[i, SC]) / 2 and the shift
    is d_i / 2). For θ2, ``centred`` samples θ2 ~ HalfNormal(τ), ``noncentred``
    samples z ~ HalfNormal(1) with θ2 = τ z, and ``quantile`` samples n ~ N(0, 1) with θ2 = τ h(n),
    h the half-normal's quantile of n's normal probability (:func:`half_normal_quantile`, :func:`theta2_block`).

    Attributes
    ----------
    theta1_mc, R_mc : {"centred", "noncentred", "mean"}
    theta1_sc, R_sc : {"centred", "noncentred"}
    theta2 : {"centred", "noncentred", "quantile"}
    """

    theta1_mc: Form = "mean"
    theta1_sc: Form = "noncentred"
    R_mc: Form = "centred"
    R_sc: Form = "centred"
    theta2: Form = "noncentred"

    def __post_init__(self):
        for name in ("theta1_mc", "theta1_sc", "R_mc", "R_sc", "theta2"):
            allowed = {"theta1_mc": ("centred", "noncentred", "mean"), "R_mc": ("centred", "noncentred", "mean"),
                       "theta2": ("centred", "noncentred", "quantile")}.get(name, ("centred", "noncentred"))
            if getattr(self, name) not in allowed:
                raise ValueError(f"Parameterization.{name} must be one of {allowed}; got {getattr(self, name)!r}")


def half_normal_quantile(n):
    """h(n) = F⁻¹(Φ(n)), F the half-normal(1)'s distribution function and Φ the normal's: n ~ N(0, 1) makes
    h(n) ~ HalfNormal(1), a smooth increasing map of the real line onto (0, ∞). F(h) = erf(h/√2), so h =
    √2 erfinv(Φ(n)) = √2 erfcinv(1 - Φ(n)); the first is evaluated where n < 0 and the second where n >= 0, each
    in the form that keeps its argument's relative precision (Φ(n) = erfc(-n/√2)/2), and each on n clipped to its
    own side so that the other branch's gradient is finite (0, not 0·∞)."""
    root2 = float(np.sqrt(2.0))
    below, above = pt.minimum(n, 0.0), pt.maximum(n, 0.0)
    return pt.switch(n < 0, root2 * pt.erfinv(pt.erfc(-below / root2) / 2),
                     root2 * pt.erfcinv(pt.erfc(above / root2) / 2))


def theta2_block(tau, form: Form, dims=UNIT_DIMS):
    """θ2 of every unit, HalfNormal(τ), declared in ``form`` (:class:`Parameterization`).

    Why ``quantile``. θ2 is the cost's weight on the rate error, which the recorded torque often barely
    constrains: on the twelve ``kbl`` subjects of :mod:`scioc.pipelines.fit.warmup` (the delayed fit at a target
    acceptance of 0.8, seed 1, ad hoc) each unit's posterior of log z (``noncentred``, z = θ2/τ on PyMC's log scale)
    had about the prior's quantiles (2.5 %, 50 %, 97.5 %: -4.2 to -2.5, -0.7 to 0.0, 0.65 to 0.92 over the 24 units,
    against the prior's -3.5, -0.4, 0.8). Under that law log z has an exponential tail towards 0 (log density ≈
    log z) and a wall above it (-z²/2, whose curvature grows as z²): the whitened coordinates of θ2 had excess
    kurtosis 1-10. In n, whose prior is N(0, 1), the same law is a standard normal. Measured
    (:mod:`scioc.pipelines.fit.warmup`, "The pivot's tails"): 10-12 % fewer gradients on those subjects.
    """
    if form == "centred":
        return pm.HalfNormal("theta2", tau, dims=dims)
    if form == "quantile":
        z = half_normal_quantile(pm.Normal("n_theta2", 0.0, 1.0, dims=dims))
    else:
        z = pm.HalfNormal("z_theta2", 1.0, dims=dims)
    return pm.Deterministic("theta2", tau * z, dims=dims)


def pooled_block(name: str, mu, sigma, form_mc: Form, n_levels: int):
    """log-parameter of every unit without condition changes: one value per subject for all levels.

    The subject value is its own mean, so "mean" is the centred form.
    """
    if form_mc == "noncentred":
        m = mu + sigma * pm.Normal(f"z_{name}_mean", 0.0, 1.0, dims="subject")
    else:
        m = pm.Normal(f"{name}_mean", mu, sigma, dims="subject")
    return pm.Deterministic(name, pt.stack([m] * n_levels, axis=1), dims=UNIT_DIMS)


def unit_block(name: str, mu, beta, sigma, sigma_beta, form_mc: Form, form_sc: Form, n_levels: int = 2):
    """log-parameter of every unit, (subject, condition), as baseline intercept + changes.

    Parameters
    ----------
    name : str
        The deterministic's name (``log_theta1``, ``log_R``); the free variables are named after it.
    mu, sigma : scalar tensors
        Population mean and SD of the baseline value.
    beta, sigma_beta : tensors
        Mean and SD of the changes: scalars for two levels, dims ``contrast`` for more.
    form_mc, form_sc : str
        The forms of the intercept and of the changes (:class:`Parameterization`);
        ``form_mc="given"``: ``mu`` (dims ``subject``) is the baseline value itself, declared
        by the caller in another form (``sigma`` unused), and only the changes are declared here.
    n_levels : int
        L >= 2, the baseline included.
    """
    if n_levels == 2:
        return _two_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc)
    return _many_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc, n_levels)


def _two_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc):
    # The two-level graph exactly as scioc has always built it (names, dims, operations).
    if form_sc == "centred":
        change = None if form_mc != "mean" else pm.Normal(f"{name}_change", beta, sigma_beta, dims="subject")
    else:
        change = beta + sigma_beta * pm.Normal(f"z_{name}_SC", 0.0, 1.0, dims="subject")
    if form_mc == "mean":
        # log θ[i, MC] ~ N(μ, σ) and change d_i independent  <=>  d_i, then the subject
        # mean m_i = log θ[i, MC] + d_i / 2 ~ N(μ + d_i / 2, σ). The MC and SC data inform
        # m_i - d_i / 2 and m_i + d_i / 2, so (m_i, d_i) are nearly uncorrelated a posteriori.
        m = pm.Normal(f"{name}_mean", mu + 0.5 * change, sigma, dims="subject")
        mc, sc = m - 0.5 * change, m + 0.5 * change
    else:
        if form_mc == "given":
            mc = mu
        elif form_mc == "centred":
            mc = pm.Normal(f"{name}_MC", mu, sigma, dims="subject")
        else:
            mc = mu + sigma * pm.Normal(f"z_{name}_MC", 0.0, 1.0, dims="subject")
        if form_sc == "centred":
            sc = pm.Normal(f"{name}_SC", mc + beta, sigma_beta, dims="subject")
        else:
            sc = mc + change
    return pm.Deterministic(name, pt.stack([mc, sc], axis=1), dims=UNIT_DIMS)


def _many_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc, n_levels):
    changes = ("subject", "contrast")
    if form_sc == "centred":
        change = None if form_mc != "mean" else pm.Normal(f"{name}_change", beta, sigma_beta, dims=changes)
    else:
        change = beta + sigma_beta * pm.Normal(f"z_{name}_contrast", 0.0, 1.0, dims=changes)
    if form_mc == "mean":
        # The subject mean over all L levels (the baseline's change is 0): the baseline
        # value is m_i - Σ_c d_ic / L, and the level values follow from it.
        shift = change.sum(axis=1) / n_levels
        m = pm.Normal(f"{name}_mean", mu + shift, sigma, dims="subject")
        base = m - shift
        others = base[:, None] + change
    else:
        if form_mc == "given":
            base = mu
        elif form_mc == "centred":
            base = pm.Normal(f"{name}_baseline", mu, sigma, dims="subject")
        else:
            base = mu + sigma * pm.Normal(f"z_{name}_baseline", 0.0, 1.0, dims="subject")
        if form_sc == "centred":
            others = pm.Normal(f"{name}_contrast", base[:, None] + beta, sigma_beta, dims=changes)
        else:
            others = base[:, None] + change
    return pm.Deterministic(name, pt.concatenate([base[:, None], others], axis=1), dims=UNIT_DIMS)


__all__ = ["Form", "Parameterization", "UNIT_DIMS", "half_normal_quantile", "pooled_block", "theta2_block", "unit_block"]
