"""The forms of the ``delayed`` model's blocks for the data at hand (``scioc fit --human-model delayed``).

Centred suits a block whose values the data fix more tightly than the population spreads them, non-centred one the
data leave loose (Papaspiliopoulos, Roberts & Sköld 2007): the same posterior, another geometry. The fit measures the
data by their ML estimates as z = estimate / SE per unit and records each choice and its reason in the sidecar. The
rules: docs/decisions/delayed-lag-and-noise-forms.md, delayed-log-R-form.md, delayed-rho-form.md and
delayed-R-population.md.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scioc.models.bayes.delayed_blocks import DelayedForm

#: The ML estimate / SE from which the data pin a value: a block is centred where the median unit reaches it
#: (ρ's: where every subject does, :func:`rho_pinned`).
CENTRED_Z = 3.0
#: The forms of τ_nm's and σ_m's blocks where the data do not pin them
#: (docs/decisions/delayed-lag-and-noise-forms.md).
LOOSE_FORM = {"tau_nm": "noncentred", "sigma_m": "folded_centred"}
#: The forms the baseline log R blocks may take (``log_R_form`` in ``scioc fit --sampler-config``; default: :func:`log_R_form`).
LOG_R_FORMS = ("centred", "noncentred")
#: θ2's form in the delayed fit (:func:`scioc.models.bayes.blocks.theta2_block`): where the torque barely constrains
#: θ2, its posterior is about its prior, a standard normal in this form (docs/decisions/delayed-target-accept.md).
THETA2_FORM = "quantile"


def choose_delayed_form(estimates: pd.DataFrame | None, subjects=None) -> tuple[DelayedForm, str]:
    """The forms of the lag, motor-noise and policy-scale blocks for these data, and why (for the sidecar).

    Per block, z = ML estimate / SE per unit (0 at the bound 0 or without an SE): centred if the median z is at least
    :data:`CENTRED_Z`, else :data:`LOOSE_FORM`. ρ = R^(-1/2) likewise with z = 2 / SE(log R̂), else folded centred;
    given ``subjects`` (the model's order), centred only where :func:`rho_pinned` flags every subject. Without
    estimates: τ_nm and σ_m non-centred, ρ folded.
    """
    if estimates is None or not {"tau_nm", "se_tau_nm", "sigma_m", "se_sigma_m"} <= set(estimates.columns):
        return DelayedForm("noncentred", "noncentred"), "non-centred (no delayed estimates to measure the data by)"
    forms, why = {}, []
    for name in ("tau_nm", "sigma_m"):
        v = pd.to_numeric(estimates[name], errors="coerce").to_numpy(dtype=float)
        se = pd.to_numeric(estimates[f"se_{name}"], errors="coerce").to_numpy(dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):  # an SE of 0 or NaN: not valid, z unused there
            z = v / se
        forms[name], reason = _form_by_z(name, z, se > 0)
        why.append(reason)
    if "se_log_R" in estimates.columns:
        if subjects is not None and "subject" in estimates.columns:
            forms["rho"], reason = _rho_by_subject(estimates, subjects)
        else:
            se = pd.to_numeric(estimates["se_log_R"], errors="coerce").to_numpy(dtype=float)
            with np.errstate(divide="ignore"):
                z = 2.0 / se
            forms["rho"], reason = _form_by_z("rho", z, se > 0, loose="folded_centred")
        why.append(reason + " (with R_population = \"policy_scale\")")
    return DelayedForm(**forms), "; ".join(why)


def rho_pinned(estimates: pd.DataFrame, subjects) -> tuple[bool, ...]:
    """Per subject of ``subjects``: do its estimates fix ρ = R^(-1/2)? Its units' z = 2/SE(log R̂) (0 without an SE)
    combined as sqrt(Σ z²), the z of their inverse-variance mean, at least :data:`CENTRED_Z`."""
    se = pd.to_numeric(estimates["se_log_R"], errors="coerce").to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(np.isfinite(2.0 / se) & (se > 0), 2.0 / se, 0.0)
    by_subject = np.sqrt((pd.Series(z) ** 2).groupby(estimates["subject"].astype(str).to_numpy()).sum())
    return tuple(bool(by_subject.get(str(s), 0.0) >= CENTRED_Z) for s in subjects)


def _rho_by_subject(estimates: pd.DataFrame, subjects) -> tuple[str, str]:
    """(ρ's form, reason): centred if :func:`rho_pinned` flags every subject, else folded centred."""
    pinned = rho_pinned(estimates, subjects)
    form = "centred" if all(pinned) else "folded_centred"
    return form, (f"rho {form} ({sum(pinned)} of {len(pinned)} subjects with their units' estimate/SE "
                  f"combined at least the threshold {CENTRED_Z:g})")


def choose_R_population(estimates: pd.DataFrame | None, subjects) -> tuple[str, str]:
    """The population of the subjects' baseline R (``DelayedPriors.R_population``) for these data, and why:
    ``lognormal`` where :func:`rho_pinned` flags at least half the subjects (or without SEs of log R), else
    ``policy_scale`` (docs/decisions/delayed-R-population.md)."""
    if estimates is None or not {"se_log_R", "subject"} <= set(estimates.columns):
        return "lognormal", "lognormal: no estimates of R with SEs to measure the data by"
    pinned = rho_pinned(estimates, subjects)
    n, fixed = len(pinned), sum(pinned)
    if 2 * fixed >= n:
        return "lognormal", (f"lognormal: the estimates fix the R of {fixed} of {n} subjects (their units' "
                             f"2/SE(log R) combined at least {CENTRED_Z:g}), at least half")
    return "policy_scale", (f"policy_scale: the estimates leave the R of {n - fixed} of {n} subjects loose (their "
                            f"units' 2/SE(log R) combined below {CENTRED_Z:g}; R may be infinite, no policy noise), "
                            "more than half, so R^(-1/2) has a half-normal population")


def _form_by_z(name: str, z: np.ndarray, valid: np.ndarray, loose: str | None = None) -> tuple[str, str]:
    """Centred if the median of ``z`` (0 where not ``valid`` or not finite) is at least :data:`CENTRED_Z`, else
    ``loose`` (default ``LOOSE_FORM[name]``); and the reason."""
    z = np.where(np.isfinite(z) & valid, z, 0.0)
    med = float(np.median(z))
    form = "centred" if med >= CENTRED_Z else (LOOSE_FORM[name] if loose is None else loose)
    return form, f"{name} {form} (median estimate/SE {med:.3g}, threshold {CENTRED_Z:g})"


def log_R_form(delayed_form: DelayedForm) -> tuple[str, str]:
    """The form of the baseline log R blocks (both levels) and why: centred where σ_m's block is not centred (no
    motor noise found), else non-centred (docs/decisions/delayed-log-R-form.md)."""
    if delayed_form.sigma_m != "centred":
        return "centred", (f"log R centred: σ_m's block is {delayed_form.sigma_m} (no motor noise found), so the "
                           "policy noise alone fixes each unit's R")
    return "noncentred", ("log R non-centred: σ_m's block is centred (motor noise found), which the policy noise "
                          "trades off against, leaving R loose per unit")


__all__ = ["CENTRED_Z", "LOG_R_FORMS", "LOOSE_FORM", "THETA2_FORM", "choose_R_population", "choose_delayed_form",
           "log_R_form", "rho_pinned"]
