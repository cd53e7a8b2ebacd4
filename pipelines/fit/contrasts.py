"""The paper's question on the posterior: β, exp(β), P(β < 0) and the per-subject MC→SC contrasts."""

from __future__ import annotations

import arviz as az
import numpy as np

from models.design import MANUAL, SHARED

#: Probability of every highest-density interval reported.
HDI_PROB = 0.94


def hdi(x, prob: float = HDI_PROB) -> list:
    """Highest-density interval of the draws ``x`` (flattened over chains and draws): ``[low, high]``.

    ArviZ's ``hdi`` (method "nearest"): the shortest interval between two draws that holds
    ``floor(prob · n) + 1`` of the n draws. Until scioc 0.1 the fit used its own interval of
    ``ceil(prob · n)`` draws; the two agree unless ``prob · n`` is an integer (4000 draws at
    94 %: then ArviZ's holds one draw more; ``tests/pipelines/fit/test_contrasts.py``).
    """
    low, high = az.hdi(np.ravel(np.asarray(x, dtype=float)), prob=prob)
    return [float(low), float(high)]


def summary(x: np.ndarray) -> dict:
    """Mean, SD, median and HDI of the draws ``x``."""
    x = np.ravel(x)
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)), "median": float(np.median(x)), "hdi": hdi(x)}


def condition_change(posterior, name: str = "log_theta1"):
    """Per-subject draws of ``name``[SC] − ``name``[MC], dims (chain, draw, subject)."""
    v = posterior[name]
    return (v.sel(condition=SHARED) - v.sel(condition=MANUAL)).transpose("chain", "draw", "subject")


def contrasts(idata) -> dict:
    """β, exp(β), P(β < 0) and the per-subject MC→SC contrasts of log θ1.

    Returns
    -------
    dict
        ``beta`` (mean, sd, median, 94 % HDI, ``p_negative``), ``ratio`` (exp β: the
        factor by which SC multiplies the population median θ1; median, mean, HDI of the
        exp-transformed draws), ``beta_log_R`` and ``sigma_beta`` summaries, and
        ``subjects``: per subject log θ1[SC] − log θ1[MC] (mean, sd, HDI, P(< 0)).
    """
    post = idata["posterior"]
    beta = post["beta"].values
    ratio = np.exp(beta)
    change = condition_change(post)
    subjects = []
    for j, s in enumerate(change["subject"].values):
        d = change.values[:, :, j]
        subjects.append({"subject": str(s), **summary(d), "p_negative": float((d < 0).mean())})
    return {
        "hdi_prob": HDI_PROB,
        "beta": {**summary(beta), "p_negative": float((beta < 0).mean())},
        "ratio": {"median": float(np.median(ratio)), "mean": float(ratio.mean()), "hdi": hdi(ratio)},
        "sigma_beta": summary(post["sigma_beta"].values),
        "beta_log_R": summary(post["beta_log_R"].values),
        "subjects": subjects,
        "subjects_with_hdi_below_zero": int(sum(s["hdi"][1] < 0 for s in subjects)),
    }
