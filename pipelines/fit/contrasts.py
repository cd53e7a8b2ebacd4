"""The paper's question on the posterior: β, exp(β), P(β < 0) and the per-subject contrasts against the baseline."""

from __future__ import annotations

import arviz as az
import numpy as np

#: Probability of every highest-density interval reported.
HDI_PROB = 0.94


def hdi(x, prob: float = HDI_PROB) -> list:
    """Highest-density interval ``[low, high]`` of the draws ``x`` (flattened): ArviZ's ``hdi`` (method "nearest"),
    the shortest interval between two draws that holds ``floor(prob · n) + 1`` of the n draws."""
    low, high = az.hdi(np.ravel(np.asarray(x, dtype=float)), prob=prob)
    return [float(low), float(high)]


def summary(x: np.ndarray) -> dict:
    """Mean, SD, median and HDI of the draws ``x``."""
    x = np.ravel(x)
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)), "median": float(np.median(x)), "hdi": hdi(x)}


def levels_of(posterior) -> tuple[str, ...]:
    """The condition levels of a fit, baseline first (the model's ``condition`` coordinate)."""
    return tuple(str(v) for v in posterior["log_theta1"].coords["condition"].values)


def condition_change(posterior, name: str = "log_theta1", level: str | None = None):
    """Per-subject draws of ``name``[level] − ``name``[baseline], dims (chain, draw, subject); ``level`` defaults
    to the first non-baseline level (SC in the paper's study)."""
    v = posterior[name]
    conds = [str(c) for c in v.coords["condition"].values]
    level = conds[1] if level is None else level
    return (v.sel(condition=level) - v.sel(condition=conds[0])).transpose("chain", "draw", "subject")


def effect_draws(posterior, name: str, level: str) -> np.ndarray:
    """Draws (chain, draw) of a condition effect (``beta``, ``sigma_beta``, ...) of one non-baseline level."""
    v = posterior[name]
    return (v.sel(contrast=level) if "contrast" in v.dims else v).values


def level_contrast(posterior, level: str) -> dict:
    """β, exp(β), σ_β, β_R and the per-subject changes of log θ1 of a non-baseline ``level``."""
    beta = effect_draws(posterior, "beta", level)
    ratio = np.exp(beta)
    change = condition_change(posterior, level=level)
    subjects = []
    for j, s in enumerate(change["subject"].values):
        d = change.values[:, :, j]
        subjects.append({"subject": str(s), **summary(d), "p_negative": float((d < 0).mean())})
    return {
        "beta": {**summary(beta), "p_negative": float((beta < 0).mean())},
        "ratio": {"median": float(np.median(ratio)), "mean": float(ratio.mean()), "hdi": hdi(ratio)},
        "sigma_beta": summary(effect_draws(posterior, "sigma_beta", level)),
        "beta_log_R": summary(effect_draws(posterior, "beta_log_R", level)),
        "subjects": subjects,
        "subjects_with_hdi_below_zero": int(sum(s["hdi"][1] < 0 for s in subjects)),
    }


def contrasts(idata) -> dict:
    """β, exp(β), P(β < 0) and the per-subject contrasts of log θ1 against the baseline.

    Returns
    -------
    dict
        Two levels: ``hdi_prob`` and :func:`level_contrast`'s keys: ``beta`` (with ``p_negative``), ``ratio``
        (exp β: the factor by which SC multiplies the population median θ1), ``sigma_beta``, ``beta_log_R``,
        ``subjects`` (per subject log θ1[SC] − log θ1[MC]) and ``subjects_with_hdi_below_zero``. More levels:
        ``hdi_prob``, ``baseline``, ``levels`` and ``contrasts``, one such block per non-baseline level.
    """
    post = idata["posterior"]
    levels = levels_of(post)
    if len(levels) == 2:
        return {"hdi_prob": HDI_PROB, **level_contrast(post, levels[1])}
    return {"hdi_prob": HDI_PROB, "baseline": levels[0], "levels": list(levels),
            "contrasts": {c: level_contrast(post, c) for c in levels[1:]}}


__all__ = ["HDI_PROB", "hdi", "summary", "levels_of", "condition_change", "effect_draws", "level_contrast",
           "contrasts"]
