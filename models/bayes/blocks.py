"""The unit-parameter blocks of the hierarchical model: baseline value plus condition changes, in a chosen form.

A block is one log-parameter (log θ1 or log R) of every unit, dims (subject, condition)::

    x[i, 0] = baseline value of subject i          x[i, 0] ~ N(μ, σ)
    x[i, c] = x[i, 0] + d[i, c]                    d[i, c] ~ N(β_c, σ_β,c),  c = 1..L-1

Two levels keep the paper's names (``log_theta1_MC``, ``z_log_theta1_SC``) and scalar β, σ_β; more have dims
``contrast`` and names with ``baseline``, ``contrast``.
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
    """The form of each block: the same model in other coordinates (docs/decisions/maxent-parameterization.md).

    ``*_mc`` is the subject's baseline, ``*_sc`` its changes. ``centred`` samples the values; ``noncentred`` z ~ N(0, 1)
    with value μ + σ z (changes: baseline + β + σ_β z); ``mean`` (baseline only) the subject mean over the L levels,
    ~ N(μ + Σ_c d_ic / L, σ), after the changes d_ic. θ2: HalfNormal(τ) itself, τ z with z ~ HalfNormal(1), or
    τ h(n) with n ~ N(0, 1) (``quantile``, :func:`half_normal_quantile`).
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
    """h(n) = F⁻¹(Φ(n)), F the HalfNormal(1)'s distribution function: n ~ N(0, 1) makes h(n) ~ HalfNormal(1).
    Each branch keeps its argument's relative precision, on n clipped to its own side (finite gradients)."""
    root2 = float(np.sqrt(2.0))
    below, above = pt.minimum(n, 0.0), pt.maximum(n, 0.0)
    return pt.switch(n < 0, root2 * pt.erfinv(pt.erfc(-below / root2) / 2),
                     root2 * pt.erfcinv(pt.erfc(above / root2) / 2))


def theta2_block(tau, form: Form, dims=UNIT_DIMS):
    """θ2 of every unit, HalfNormal(τ), declared in ``form`` (:class:`Parameterization`)."""
    if form == "centred":
        return pm.HalfNormal("theta2", tau, dims=dims)
    if form == "quantile":
        z = half_normal_quantile(pm.Normal("n_theta2", 0.0, 1.0, dims=dims))
    else:
        z = pm.HalfNormal("z_theta2", 1.0, dims=dims)
    return pm.Deterministic("theta2", tau * z, dims=dims)


def pooled_block(name: str, mu, sigma, form_mc: Form, n_levels: int):
    """log-parameter of every unit without condition changes ("mean" is the centred form: one value per subject)."""
    if form_mc == "noncentred":
        m = mu + sigma * pm.Normal(f"z_{name}_mean", 0.0, 1.0, dims="subject")
    else:
        m = pm.Normal(f"{name}_mean", mu, sigma, dims="subject")
    return pm.Deterministic(name, pt.stack([m] * n_levels, axis=1), dims=UNIT_DIMS)


def unit_block(name: str, mu, beta, sigma, sigma_beta, form_mc: Form, form_sc: Form, n_levels: int = 2):
    """log-parameter ``name`` of every unit, (subject, condition), as baseline intercept + changes.

    ``mu``, ``sigma``: population mean and SD of the baseline; ``beta``, ``sigma_beta``: of the changes (scalars for
    two levels, dims ``contrast`` for more); ``form_mc``, ``form_sc``: :class:`Parameterization`'s, or
    ``form_mc="given"``: ``mu`` (dims ``subject``) is the baseline itself. Free variables are named after ``name``.
    """
    if n_levels == 2:
        return _two_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc)
    return _many_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc, n_levels)


def _two_levels(name, mu, beta, sigma, sigma_beta, form_mc, form_sc):
    # The paper's two levels: scalar changes, variables named MC and SC.
    if form_sc == "centred":
        change = None if form_mc != "mean" else pm.Normal(f"{name}_change", beta, sigma_beta, dims="subject")
    else:
        change = beta + sigma_beta * pm.Normal(f"z_{name}_SC", 0.0, 1.0, dims="subject")
    if form_mc == "mean":
        # log θ[i, MC] ~ N(μ, σ) independent of d_i  <=>  m_i = log θ[i, MC] + d_i / 2 ~ N(μ + d_i / 2, σ);
        # the MC and SC data inform m_i ∓ d_i / 2, so (m_i, d_i) are nearly uncorrelated a posteriori.
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
        # The subject mean over all L levels (the baseline's change is 0): the baseline is m_i - Σ_c d_ic / L.
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
