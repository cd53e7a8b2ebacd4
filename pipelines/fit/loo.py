"""Model comparison of the fit: PSIS-LOO over segments and leave-one-subject-out, condition effects vs pooled."""

from __future__ import annotations

import warnings

import arviz as az
import numpy as np
import xarray as xr

from scioc.models.bayes.subject_loo import subject_loglik
from scioc.models.design import CONDITIONS
from scioc.models.units import index_study


def psis_summary(data, var_name: str, dim: str) -> tuple[dict, np.ndarray]:
    """PSIS-LOO of one model: ELPD, SE, p_loo and the Pareto k summary (per left-out ``dim`` under ``by_<dim>``; a
    NaN k counts as above the threshold); and the pointwise ELPD."""
    reff = relative_ess(data)
    log_weights, pareto_k = psis_weights(data["log_likelihood"][var_name], dim, reff)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the k warning is reported with numbers instead
        res = az.loo(data, pointwise=True, var_name=var_name, reff=reff, log_weights=log_weights, pareto_k=pareto_k)
    k = np.asarray(res.pareto_k, dtype=float).ravel()
    good = float(res.good_k)
    finite = np.isfinite(k).any()
    summary = {
        "elpd_loo": float(res.elpd), "se": float(res.se), "p_loo": float(res.p),
        "pareto_k": {"threshold": good, "max": float(np.nanmax(k)) if finite else float("nan"),
                     "median": float(np.nanmedian(k)) if finite else float("nan"),
                     "n_le_0.5": int((k <= 0.5).sum()), "n_gt_threshold": int((~(k <= good)).sum()),
                     "n_gt_1": int((k > 1).sum()), "n_nan": int(np.isnan(k).sum()), "n": int(k.size),
                     f"by_{dim}": {str(u): float(v) for u, v in zip(res.pareto_k[dim].values, k)}},
    }
    return summary, np.asarray(res.elpd_i).ravel()


def relative_ess(data) -> float:
    """The relative ESS of the posterior ArviZ's ``loo`` uses by default: 1 for one chain, else the
    mean ESS (method "mean") over every posterior variable and element divided by the draws."""
    post = data["posterior"]
    n = post.sizes["chain"] * post.sizes["draw"]
    if post.sizes["chain"] == 1:
        return 1.0
    ess = post.to_dataset().azstats.ess(method="mean")
    return float(np.hstack([np.ravel(ess[v].values) for v in ess.data_vars]).mean() / n)


def psis_weights(log_lik: xr.DataArray, dim: str, reff: float) -> tuple[xr.DataArray, xr.DataArray]:
    """Pareto-smoothed log weights and k of each observation along ``dim`` (ArviZ's ``psislw``); an observation
    with no tail to fit (a stuck chain), for which ArviZ raises, keeps its raw weights and a NaN k instead."""
    weights, ks = [], []
    for i in range(log_lik.sizes[dim]):
        one = log_lik.isel({dim: slice(i, i + 1)})
        try:
            w, k = one.azstats.psislw(r_eff=reff, dim=["chain", "draw"])
        except ValueError as err:
            if "tail" not in str(err):
                raise
            raw = -one.transpose(dim, "chain", "draw")
            w = raw - np.logaddexp.reduce(raw.values.ravel())
            k = xr.full_like(one.isel(chain=0, draw=0, drop=True), np.nan, dtype=float)
        weights.append(w)
        ks.append(k)
    return xr.concat(weights, dim), xr.concat(ks, dim)


#: The smallest importance-sampling ESS (``is_ess_loo``) of any subject for a leave-one-subject-out comparison to
#: count as reliable: a Monte Carlo SE of about 1 / sqrt(ESS) ≤ 0.1 nats (docs/decisions/loso-reliability.md).
LOSO_ESS_MIN = 100


def comparison_reliability(a: dict, b: dict) -> dict:
    """Whether the ELPD difference of two models' summaries holds: ``reliable`` (every Pareto k below its threshold
    and, leaving subjects out, every importance-sampling ESS at least :data:`LOSO_ESS_MIN`), ``unreliable_because``
    and ``importance`` (the smallest ESS and the difference's Monte Carlo SE, sqrt(Σ 1 / ESS) over both models)."""
    why = []
    if a["pareto_k"]["n_gt_threshold"] + b["pareto_k"]["n_gt_threshold"]:
        why.append("Pareto k above the threshold")
    out = {"importance": None}
    if "is_ess_loo_by_subject" in a and "is_ess_loo_by_subject" in b:
        ess = np.array([*a["is_ess_loo_by_subject"].values(), *b["is_ess_loo_by_subject"].values()], dtype=float)
        out["importance"] = {"is_ess_loo_min": float(ess.min()), "threshold": LOSO_ESS_MIN,
                             "mcse": float(np.sqrt(np.sum(1.0 / ess)))}
        if ess.min() < LOSO_ESS_MIN:
            why.append(f"importance-sampling ESS below {LOSO_ESS_MIN}")
    return {"reliable": not why, "unreliable_because": why, **out}


def reliability_words(d: dict) -> str:
    """'reliable' or 'UNRELIABLE (...)' for a difference of :func:`elpd_difference` or the human models."""
    if d["reliable"]:
        return "reliable"
    return f"UNRELIABLE ({'; '.join(d.get('unreliable_because') or ['Pareto k above the threshold'])})"


def elpd_difference(out: dict, pointwise: dict) -> dict:
    """ELPD(condition) − ELPD(pooled) ± SE, the preference and its reliability; the SE ``sqrt(n) · sd(d)`` with
    the variance over n − 1, as R's ``loo_compare`` (Vehtari et al. 2017, Eq. 24); ArviZ's ``compare`` uses n."""
    diff_i = pointwise["condition"] - pointwise["pooled"]
    n = diff_i.shape[0]
    diff, se = float(diff_i.sum()), float(np.sqrt(n * diff_i.var(ddof=1)))
    return {"elpd_diff": diff, "se": se, "z": diff / se if se > 0 else float("inf"),
            "preferred": "condition" if diff > 0 else "pooled",
            **comparison_reliability(out["condition"], out["pooled"]),
            "n_favouring_condition": int((diff_i > 0).sum()), "n": int(n)}


def loo_comparison(idata, idata_pooled) -> dict:
    """PSIS-LOO of both models and their ELPD difference (condition − pooled) ± SE; with one segment per unit many
    Pareto k exceed the threshold (a left-out segment holds every datum on its unit's θ), and it says so."""
    out, pointwise = {}, {}
    for name, d in (("condition", idata), ("pooled", idata_pooled)):
        out[name], pointwise[name] = psis_summary(d, "u_H", "segment")
    out["difference"] = elpd_difference(out, pointwise)
    out["difference"]["note"] = (
        "Pareto k above the threshold for some segments: the PSIS estimate of those "
        "segments' ELPD (and so the difference) is unreliable; with one segment per "
        "unit this is expected, see the model docstring" if not out["difference"]["reliable"]
        else "all Pareto k below the threshold")
    return out

#: Posterior draws kept (evenly thinned) for the leave-one-subject-out integrals.
LOSO_DRAWS = 1000

#: Importance-sampling points per subject for them.
LOSO_POINTS = 2000


def thinned_posterior(idata) -> tuple[dict, object]:
    """The posterior thinned evenly to :data:`LOSO_DRAWS` draws: flat arrays (draws first) and the Dataset."""
    post = idata["posterior"].to_dataset()
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    step = max(1, (n_chain * n_draw) // LOSO_DRAWS)
    keep = post.isel(draw=slice(0, None, step))
    flat = {v: np.asarray(keep[v].transpose("chain", "draw", ...).values, dtype=float).reshape(
        (-1,) + keep[v].shape[2:]) for v in keep.data_vars}
    return flat, keep


def subject_elpd(idata, batch, index, plant, rng: np.random.Generator, levels, *, condition_effects: bool = True,
                 extra=None, points: int = LOSO_POINTS) -> tuple[dict, np.ndarray]:
    """Leave-one-subject-out of one model by integrated PSIS: its summary and the ELPD of each subject; ``extra(flat)``
    builds another human model's terms (:func:`scioc.models.bayes.subject_loo.subject_loglik`) from the flat draws."""
    flat, keep = thinned_posterior(idata)
    order = [str(x) for x in keep["log_theta1"].coords["subject"].values]
    if order != [str(x) for x in index.subjects]:
        raise ValueError("posterior subjects are not in the order of the study index")
    if [str(x) for x in keep["log_theta1"].coords["condition"].values] != [str(v) for v in levels]:
        raise ValueError("posterior condition levels are not the study's levels, baseline first")
    res = subject_loglik(flat, batch, index.subject_idx, index.condition_idx, plant, rng,
                         condition_effects=condition_effects, M=int(points),
                         extra=None if extra is None else extra(flat))
    ll = xr.DataArray(res.loglik.reshape(keep.sizes["chain"], keep.sizes["draw"], -1),
                      dims=("chain", "draw", "subject"), coords={"subject": order})
    tree = xr.DataTree.from_dict({"posterior": keep[["mu_log_theta1"]], "log_likelihood": xr.Dataset({"y": ll})})
    summary, pointwise = psis_summary(tree, "y", "subject")
    summary.update(is_ess_min=float(res.is_ess.min()), is_ess_median=float(np.median(res.is_ess)),
                   is_ess_loo_min=float(res.is_ess_loo.min()), is_ess_loo_median=float(np.median(res.is_ess_loo)),
                   is_ess_loo_by_subject=dict(zip(order, map(float, res.is_ess_loo))),
                   draws=int(res.loglik.shape[0]), proposal_points_per_subject=int(points),
                   proposal_points_outside=int(res.n_outside.sum()))
    return summary, pointwise


def subject_loo_comparison(idata, idata_pooled, batch, subjects, conditions, plant, rng: np.random.Generator,
                           levels=CONDITIONS) -> dict:
    """Leave-one-subject-out ELPD of both models by integrated PSIS, and their difference.

    The pointwise term is ``log p(y_i | ψ_s)``, subject i's data with its unit parameters integrated out under
    population draw ψ_s (:mod:`scioc.models.bayes.subject_loo`); PSIS then reweights only the population draws, which
    one subject of many barely moves, so the Pareto k stay low where the segment-wise PSIS-LOO fails.
    """
    index = index_study(subjects, conditions, levels)
    out, pointwise = {}, {}
    for name, d, effects in (("condition", idata, True), ("pooled", idata_pooled, False)):
        out[name], pointwise[name] = subject_elpd(d, batch, index, plant, rng, levels, condition_effects=effects)
    out["difference"] = elpd_difference(out, pointwise)
    return out
