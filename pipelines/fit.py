"""``scioc fit``: the hierarchical Bayesian model of a study, its diagnostics and contrasts.

The segments are cut and reconstructed exactly as ``scioc identify`` does
(:func:`pipelines.identify.prepare_segment`), then two models of
:func:`models.bayes.hierarchical.build_model` are sampled with nutpie through ``pm.sample``:
the model with condition effects (β, the mean SC change of log θ1, is the paper's
question) and the pooled model without them (log θ1 the same in MC and SC), which only
serves the PSIS-LOO comparison.

Artifacts in ``--out DIR``:

* ``posterior.nc``, ``posterior_pooled.nc`` — the posteriors (NetCDF, ArviZ DataTree) with
  sample statistics and the pointwise log-likelihood (one value per segment).
* ``posterior.json`` — sidecar: seeds, sampler settings, diagnostics of both fits with a
  verdict (no divergences, R-hat ≤ 1.01, bulk and tail ESS ≥ 400 for every population
  parameter), wall times, ESS per second, inputs and package versions.
* ``contrasts.json`` — β (mean, SD, 94 % HDI, P(β < 0)), the ratio exp(β) with its HDI,
  per-subject MC→SC contrasts of log θ1, the LOO comparisons (PSIS over segments, which
  one segment per unit defeats, and integrated PSIS leaving out whole subjects,
  :func:`subject_loo_comparison`), the frequentist mixed-model
  cross-check on the per-segment ML estimates and, for a simulated study, the truth check.
* ``ppc.parquet`` — posterior predictive angle and torque of one subject (both
  conditions): 5/50/95 % bands over posterior draws, exact max-ent draws of the human
  the likelihood assumes (:func:`models.maxent.sample_maxent`), beside the data.

Randomness: the root ``seed`` is split with ``SeedSequence(seed).spawn(4)`` into the seeds
of the two samplers, of the posterior predictive draws and of the leave-one-subject-out
importance sampling; the same seed gives the same
draws and numbers (file bytes differ only by the time stamps NetCDF attributes carry).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sys
import threading
import time
import warnings
from dataclasses import asdict
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pandas as pd

from models.bayes.hierarchical import POPULATION_PARAMETERS, build_model
from models.cost import from_normalized
from models.design import CONDITIONS
from models.maxent import forward_optimal_control, sample_maxent
from models.plant import DT_HUMAN, discretize
from models.segment import plan_inputs, prepare_batch
from models.units import index_study
from pipelines.adequacy import assess_study, format_adequacy, not_checked
from pipelines.identify import IdentifySettings, paper_assistant, prepare_segment
from pipelines.io import (InputDataError, atomic_path, check_output_dir, load_study, refuse_inputs_inside, staged_dir,
                          write_table_atomic, write_text_atomic)
from pipelines.progress import progress
from pipelines.provenance import versions

#: Unit-level quantities (subject × condition) whose diagnostics are reported too.
UNITS = ("log_theta1", "log_R", "theta2")
#: Probability of every highest-density interval reported.
HDI_PROB = 0.94
#: Acceptance criteria of a fit (population parameters).
RHAT_MAX = 1.01
ESS_MIN = 400
#: E-BFMI below this flags a chain (reported, advisory: not part of the verdict).
EBFMI_MIN = 0.3
#: Posterior draws used for the posterior predictive bands.
PPC_DRAWS = 100
#: Pareto k above this marks an unreliable PSIS estimate (ArviZ/loo's 0.7, lowered by
#: arviz for small sample sizes: ``min(1 - 1/log10(S), 0.7)``).
PARETO_K_BAD = 0.7


class PreparedStudy(NamedTuple):
    """A study file cut and reconstructed for the likelihood, one entry per segment."""

    path: str
    subjects: list
    conditions: list
    segments: list  # of PreparedSegment

    @property
    def labels(self) -> list:
        return [f"{s}/{c}" for s, c in zip(self.subjects, self.conditions)]


def prepare_study(study_path, settings: IdentifySettings = IdentifySettings(), *,
                  show_progress: bool = False) -> PreparedStudy:
    """Load, validate and cut every segment as ``scioc identify`` does, then check the design.

    Raises
    ------
    pipelines.io.StudyFileError
        For a malformed file (naming file, column and row).
    ValueError
        From :func:`models.units.index_study`: a subject without one of the
        conditions, or no SC (MC) segment at all.
    """
    study = load_study(study_path)
    # The design is checked before the (slow) reconstruction: bad input fails at once.
    try:
        index_study([s.subject for s in study.segments], [s.condition for s in study.segments])
    except ValueError as exc:  # the data do not have the design the model needs: bad input (exit 3)
        raise InputDataError(f"{study_path}: {exc}") from None
    plant = discretize(DT_HUMAN)
    prepared = [prepare_segment(s, settings, plant, study.path)
                for s in progress(study.segments, desc="reconstruct", enabled=show_progress)]
    return PreparedStudy(study.path, [p.data.subject for p in prepared], [p.data.condition for p in prepared],
                         prepared)


# --------------------------------------------------------------------------- sampling


def _child_seeds(seed: int) -> dict:
    sampler, pooled, ppc, loso = np.random.SeedSequence(int(seed)).spawn(4)
    return {"condition": int(sampler.generate_state(1)[0]), "pooled": int(pooled.generate_state(1)[0]),
            "ppc": int(ppc.generate_state(1)[0]), "loso": int(loso.generate_state(1)[0])}


def sample_model(model, *, seed: int, chains: int, draws: int, tune: int, cores: int | None = None,
                 show_progress: bool = False, log_likelihood: bool = True):
    """Sample ``model`` with nutpie (through ``pm.sample``) and add the pointwise log-likelihood.

    ``log_likelihood=False`` skips the pointwise log-likelihood (for timing the fit alone).
    ``cores`` (chains run in parallel) defaults to ``os.cpu_count()``. It is passed
    explicitly because PyMC's own default halves the CPU count (it assumes hardware
    threads): on a 2-core machine nutpie then ran the chains one at a time, measured
    2.0× slower sampling on the default study.

    Returns
    -------
    idata : DataTree
    seconds : dict
        ``compile_and_sample`` (wall time of ``pm.sample``), ``sample`` (nutpie's own
        sampling time, tuning included, compilation excluded) and ``log_likelihood``.
    """
    import pymc as pm

    t0 = time.perf_counter()
    with stdout_to_stderr(), interrupt_guard() as interrupted:
        idata = pm.sample(draws=draws, tune=tune, chains=chains, cores=cores or os.cpu_count() or 1,
                          random_seed=seed, nuts_sampler="nutpie", progressbar=show_progress,
                          quiet=not show_progress, model=model)
    if interrupted():
        # nutpie stops on Ctrl-C and returns the draws so far; a partial posterior is not a result.
        raise KeyboardInterrupt
    t1 = time.perf_counter()
    if log_likelihood:
        pm.compute_log_likelihood(idata, model=model, progressbar=False)
    t2 = time.perf_counter()
    return idata, {"compile_and_sample": t1 - t0, "sample": float(idata["posterior"].attrs["sampling_time"]),
                   "log_likelihood": t2 - t1}


@contextlib.contextmanager
def stdout_to_stderr():
    """Send everything written to standard output, by Python or by compiled code, to standard error.

    The sampler's progress tables are progress, not results: results go to stdout.
    """
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


@contextlib.contextmanager
def interrupt_guard():
    """Note a Ctrl-C (SIGINT) even if the code inside catches it; yields a function that tells.

    The previous handler still runs (Python's raises KeyboardInterrupt), so the code inside
    stops as it would; afterwards the caller can refuse a result the interruption cut short.
    """
    seen = []
    if threading.current_thread() is not threading.main_thread():
        yield lambda: False
        return
    previous = signal.getsignal(signal.SIGINT)

    def handler(signum, frame):
        seen.append(signum)
        if callable(previous):
            previous(signum, frame)
        else:
            raise KeyboardInterrupt

    signal.signal(signal.SIGINT, handler)
    try:
        yield lambda: bool(seen)
    finally:
        signal.signal(signal.SIGINT, previous)


def diagnostics(idata, sample_seconds: float) -> dict:
    """Sampler and convergence diagnostics of one fit, with the verdict.

    Population parameters get R-hat (rank-normalized), bulk and tail ESS and bulk ESS
    per second of sampling; unit-level quantities the worst of each over their elements.
    The verdict requires no divergences, R-hat ≤ :data:`RHAT_MAX` and bulk and tail ESS
    ≥ :data:`ESS_MIN` for every population parameter; E-BFMI and tree depth are reported
    beside it.
    """
    import arviz as az

    post = idata["posterior"].to_dataset()
    ss = idata["sample_stats"].to_dataset()
    names = [v for v in POPULATION_PARAMETERS if v in post]
    # Select before calling ArviZ: with var_names, arviz-stats 1.x leaves the Dataset's
    # cached accessor holding only those variables for later calls.
    pop = post[names]
    rhat, bulk, tail = az.rhat(pop), az.ess(pop, method="bulk"), az.ess(pop, method="tail")
    population = {
        v: {"rhat": float(rhat[v]), "ess_bulk": float(bulk[v]), "ess_tail": float(tail[v]),
            "ess_bulk_per_s": float(bulk[v]) / sample_seconds}
        for v in names
    }
    units = {}
    for v in UNITS:
        ds = post[[v]]
        r, b, t = az.rhat(ds)[v].values, az.ess(ds, method="bulk")[v].values, az.ess(ds, method="tail")[v].values
        units[v] = {"rhat_max": float(np.nanmax(r)), "ess_bulk_min": float(np.nanmin(b)),
                    "ess_tail_min": float(np.nanmin(t))}
    bfmi = np.atleast_1d(az.bfmi(idata)["energy"].values).astype(float)
    n_steps = ss["n_steps"].values
    sampler = {
        "divergences": int(ss["diverging"].values.sum()),
        "ebfmi": [float(x) for x in bfmi],
        "max_tree_depth": int(ss["depth"].values.max()),
        "draws_at_max_tree_depth": int(ss["maxdepth_reached"].values.sum()),
        "mean_steps_per_draw": float(n_steps.mean()),
        "max_steps_per_draw": int(n_steps.max()),
        "step_size": [float(x) for x in ss["step_size"].values[:, -1]],
    }
    worst_rhat = max(population.values(), key=lambda p: p["rhat"])
    worst_ess = min(population.items(), key=lambda kv: min(kv[1]["ess_bulk"], kv[1]["ess_tail"]))
    checks = {
        "no_divergences": sampler["divergences"] == 0,
        f"rhat_le_{RHAT_MAX}": all(p["rhat"] <= RHAT_MAX for p in population.values()),
        f"ess_bulk_tail_ge_{ESS_MIN}": all(min(p["ess_bulk"], p["ess_tail"]) >= ESS_MIN for p in population.values()),
    }
    failed = [k for k, ok in checks.items() if not ok]
    return {
        "sampler": sampler,
        "population": population,
        "units": units,
        "checks": checks,
        "advisory": {f"ebfmi_ge_{EBFMI_MIN}": bool((bfmi >= EBFMI_MIN).all()),
                     "no_draw_at_max_tree_depth": sampler["draws_at_max_tree_depth"] == 0},
        "worst": {"rhat": worst_rhat["rhat"], "ess_parameter": worst_ess[0],
                  "ess": min(worst_ess[1]["ess_bulk"], worst_ess[1]["ess_tail"]),
                  "min_ess_bulk_per_s": min(p["ess_bulk_per_s"] for p in population.values())},
        "convergence_verdict": "pass" if not failed else "fail: " + ", ".join(failed),
        "passed": not failed,
    }


# --------------------------------------------------------------------------- contrasts


def _hdi(x: np.ndarray, prob: float = HDI_PROB) -> list:
    """Shortest interval holding ``prob`` of the draws (flattened)."""
    s = np.sort(np.ravel(x))
    n = s.shape[0]
    m = int(np.ceil(prob * n))
    widths = s[m - 1:] - s[: n - m + 1]
    i = int(np.argmin(widths))
    return [float(s[i]), float(s[i + m - 1])]


def _summary(x: np.ndarray) -> dict:
    x = np.ravel(x)
    return {"mean": float(x.mean()), "sd": float(x.std(ddof=1)), "median": float(np.median(x)), "hdi": _hdi(x)}


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
    lt1 = post["log_theta1"]
    change = (lt1.sel(condition="SC") - lt1.sel(condition="MC")).transpose("chain", "draw", "subject")
    subjects = []
    for j, s in enumerate(change["subject"].values):
        d = change.values[:, :, j]
        subjects.append({"subject": str(s), **_summary(d), "p_negative": float((d < 0).mean())})
    return {
        "hdi_prob": HDI_PROB,
        "beta": {**_summary(beta), "p_negative": float((beta < 0).mean())},
        "ratio": {"median": float(np.median(ratio)), "mean": float(ratio.mean()), "hdi": _hdi(ratio)},
        "sigma_beta": _summary(post["sigma_beta"].values),
        "beta_log_R": _summary(post["beta_log_R"].values),
        "subjects": subjects,
        "subjects_with_hdi_below_zero": int(sum(s["hdi"][1] < 0 for s in subjects)),
    }


def _psis_summary(data, var_name: str, dim: str) -> tuple[dict, np.ndarray]:
    """PSIS-LOO of one model: ELPD, SE, p_loo and the Pareto k summary; and the pointwise ELPD.

    ``dim`` names the left-out unit (the k of each are listed under ``by_<dim>``). A k that
    cannot be estimated (NaN: degenerate tail, e.g. repeated draws of a stuck chain)
    counts as above the threshold.
    """
    import arviz as az

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the k warning is reported with numbers instead
        res = az.loo(data, pointwise=True, var_name=var_name)
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


def _elpd_difference(out: dict, pointwise: dict) -> dict:
    """ELPD(condition) − ELPD(pooled) ± SE from the pointwise values, the preference and its reliability."""
    diff_i = pointwise["condition"] - pointwise["pooled"]
    n = diff_i.shape[0]
    diff, se = float(diff_i.sum()), float(np.sqrt(n * diff_i.var(ddof=1)))
    bad = out["condition"]["pareto_k"]["n_gt_threshold"] + out["pooled"]["pareto_k"]["n_gt_threshold"]
    return {"elpd_diff": diff, "se": se, "z": diff / se if se > 0 else float("inf"),
            "preferred": "condition" if diff > 0 else "pooled", "reliable": bad == 0,
            "n_favouring_condition": int((diff_i > 0).sum()), "n": int(n)}


def loo_comparison(idata, idata_pooled) -> dict:
    """PSIS-LOO of both models and their ELPD difference (condition − pooled) ± SE.

    With one segment per subject × condition, leaving a segment out removes every datum
    on that unit's θ, so the importance ratios are heavy-tailed and many Pareto k exceed
    the threshold: the comparison is then unreliable and says so (``reliable``).
    """
    out, pointwise = {}, {}
    for name, d in (("condition", idata), ("pooled", idata_pooled)):
        out[name], pointwise[name] = _psis_summary(d, "u_H", "segment")
    out["difference"] = _elpd_difference(out, pointwise)
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


def subject_loo_comparison(idata, idata_pooled, batch, subjects, conditions, plant, rng: np.random.Generator) -> dict:
    """Leave-one-subject-out ELPD of both models by integrated PSIS, and their difference.

    The pointwise term is ``log p(y_i | ψ_s)``, subject i's data with its unit parameters
    integrated out under population draw ψ_s (:mod:`models.bayes.subject_loo`); PSIS then
    reweights only the population draws, which one subject of many barely moves, so the
    Pareto k stay low where the segment-wise PSIS-LOO fails. The posterior is thinned
    evenly to :data:`LOSO_DRAWS` draws over the chains.
    """
    import xarray as xr

    from models.bayes.subject_loo import subject_loglik
    from models.units import index_study

    index = index_study(subjects, conditions)
    out, pointwise = {}, {}
    for name, d, effects in (("condition", idata, True), ("pooled", idata_pooled, False)):
        post = d["posterior"].to_dataset()
        n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
        step = max(1, (n_chain * n_draw) // LOSO_DRAWS)
        keep = post.isel(draw=slice(0, None, step))
        flat = {v: np.asarray(keep[v].transpose("chain", "draw", ...).values, dtype=float).reshape(
            (-1,) + keep[v].shape[2:]) for v in keep.data_vars}
        order = [str(x) for x in keep["log_theta1"].coords["subject"].values]
        if order != [str(x) for x in index.subjects]:
            raise ValueError("posterior subjects are not in the order of the study index")
        res = subject_loglik(flat, batch, index.subject_idx, index.condition_idx, plant, rng,
                             condition_effects=effects, M=LOSO_POINTS)
        ll = xr.DataArray(res.loglik.reshape(keep.sizes["chain"], keep.sizes["draw"], -1),
                          dims=("chain", "draw", "subject"), coords={"subject": order})
        tree = xr.DataTree.from_dict({"posterior": keep[["mu_log_theta1"]], "log_likelihood": xr.Dataset({"y": ll})})
        out[name], pointwise[name] = _psis_summary(tree, "y", "subject")
        out[name].update(is_ess_min=float(res.is_ess.min()), is_ess_median=float(np.median(res.is_ess)),
                         draws=int(res.loglik.shape[0]))
    out["difference"] = _elpd_difference(out, pointwise)
    return out


def mixedlm_check(estimates: pd.DataFrame) -> dict:
    """Frequentist cross-check: linear mixed model of log θ1 from the per-segment ML estimates.

    ``log θ1 ~ 1 + SC`` with a random intercept per subject (REML, statsmodels
    ``MixedLM``); the SC coefficient estimates β. The ML estimates enter as data: their
    own standard errors are ignored.
    """
    import statsmodels.formula.api as smf

    d = estimates[["subject", "condition", "theta1"]].copy()
    d["log_theta1"] = np.log(d["theta1"].astype(float))
    d["SC"] = (d["condition"] == "SC").astype(float)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = smf.mixedlm("log_theta1 ~ SC", d, groups=d["subject"]).fit(reml=True)
    lo, hi = (float(x) for x in fit.conf_int(alpha=0.05).loc["SC"])
    coef = float(fit.fe_params["SC"])
    return {
        "formula": "log_theta1 ~ 1 + SC, random intercept per subject (REML)",
        "coef": coef, "se": float(fit.bse_fe["SC"]), "ci95": [lo, hi], "p_value": float(fit.pvalues["SC"]),
        "ratio": float(np.exp(coef)), "ratio_ci95": [float(np.exp(lo)), float(np.exp(hi))],
        "intercept": float(fit.fe_params["Intercept"]),
        "subject_sd": float(np.sqrt(fit.cov_re.values[0, 0])), "residual_sd": float(np.sqrt(fit.scale)),
        "n_obs": int(fit.nobs), "n_subjects": int(d["subject"].nunique()), "converged": bool(fit.converged),
        "warnings": sorted({str(w.message) for w in caught}),
    }


#: simulation.json population names for the model's population parameters.
TRUE_NAMES = {"mu_log_theta1": "log_theta1_mc", "sigma_log_theta1": "sd_log_theta1", "beta": "beta",
              "sigma_beta": "sd_change", "mu_log_R": "log_R", "sigma_log_R": "sd_log_R", "beta_log_R": "gamma",
              "sigma_beta_log_R": "sd_R_change", "tau_theta2": "theta2"}


def truth_check(idata, truth_dir, estimates: pd.DataFrame | None = None) -> dict:
    """Compare the posterior with the simulator's truth (``simulation.json``, ``truth.parquet``).

    Returns the true β, whether it is in the 94 % HDI and by how much the posterior mean
    misses it (also in posterior SDs); the realized mean of the 42 true changes; every
    population parameter against its true value (a scale whose truth is 0 against the
    one-sided interval [0, q94]); how many per-subject HDIs hold the true change; and,
    with ``estimates``, the mean log error of the ML θ1 per condition (the closed-loop
    bias of the likelihood plus the reconstruction). None when the simulated human has
    no cost θ (``truth.parquet`` holds NaN).
    """
    truth_dir = Path(truth_dir)
    sim = json.loads((truth_dir / "simulation.json").read_text())
    truth = pd.read_parquet(truth_dir / "truth.parquet")
    if not np.isfinite(truth["theta1"].to_numpy(dtype=float)).any():
        return None  # a simulated human without a cost θ (the crossover operator): nothing to check against
    pop = sim["population"]
    post = idata["posterior"]
    out = {"source": str(truth_dir)}
    params = {}
    for v, key in TRUE_NAMES.items():
        if v not in post or key not in pop:
            continue
        x = post[v].values.ravel()
        t = float(pop[key])
        if t == 0.0 and x.min() >= 0.0:
            lo, hi, kind = 0.0, float(np.quantile(x, HDI_PROB)), "one-sided [0, q94]"
        else:
            (lo, hi), kind = _hdi(x), "hdi94"
        params[v] = {"truth": t, "mean": float(x.mean()), "interval": [lo, hi], "interval_kind": kind,
                     "in_interval": bool(lo <= t <= hi)}
    out["population"] = params
    w = truth.pivot_table(index="subject", columns="condition", values="theta1")
    true_change = np.log(w["SC"] / w["MC"])
    b = params["beta"]
    sd = float(post["beta"].values.std(ddof=1))
    out["beta"] = {"truth": b["truth"], "hdi": b["interval"], "in_hdi": b["in_interval"],
                   "posterior_mean": b["mean"], "discrepancy": b["mean"] - b["truth"],
                   "discrepancy_in_sd": (b["mean"] - b["truth"]) / sd,
                   "realized_mean_change": float(true_change.mean()),
                   "realized_in_hdi": bool(b["interval"][0] <= true_change.mean() <= b["interval"][1])}
    lt1 = post["log_theta1"]
    change = (lt1.sel(condition="SC") - lt1.sel(condition="MC")).transpose("chain", "draw", "subject")
    covered = []
    for j, s in enumerate(change["subject"].values):
        lo, hi = _hdi(change.values[:, :, j])
        covered.append(bool(lo <= true_change[str(s)] <= hi))
    out["subjects"] = {"n": len(covered), "true_change_in_hdi": int(sum(covered))}
    if estimates is not None:
        m = estimates.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))
        out["ml_log_error"] = {c: float(np.mean(np.log(m.theta1[m.condition == c] / m.theta1_true[m.condition == c])))
                               for c in CONDITIONS}
        out["ml_log_error"]["SC_minus_MC"] = out["ml_log_error"]["SC"] - out["ml_log_error"]["MC"]
    return out


# --------------------------------------------------------------------------- posterior predictive


def posterior_predictive(idata, prepared: PreparedStudy, subject: str, rng: np.random.Generator,
                         n_draws: int = PPC_DRAWS) -> pd.DataFrame:
    """Posterior predictive angle and torque of one subject, both conditions.

    ``n_draws`` posterior draws, evenly spaced over chains × draws; for each, one exact
    max-ent demonstration per segment given its x0 and reference, from the human the
    likelihood assumes (planning with the recorded u_A, or in closed loop with the
    assistant's law; preview included, the first K torques kept); then the 5/50/95 %
    quantiles per time step. Also the forward optimal control at the posterior median θ.

    Returns
    -------
    DataFrame
        One row per window sample k = 0..K: subject, condition, t (s), angle_ref, angle
        (measured), u_H (reconstructed or recorded), u_A (N·m), ``angle_q05/q50/q95``
        (rad), ``u_H_q05/q50/q95`` (N·m), ``angle_opt``, ``u_H_opt``; torques NaN at k = K.
    """
    plant = discretize(DT_HUMAN)
    post = idata["posterior"]
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    flat = np.linspace(0, n_chain * n_draw - 1, min(n_draws, n_chain * n_draw)).round().astype(int)
    ci, di = np.divmod(flat, n_draw)
    frames = []
    for p in prepared.segments:
        if p.data.subject != subject:
            continue
        cond = p.data.condition
        sel = {"subject": subject, "condition": cond}
        lt1 = post["log_theta1"].sel(sel).values[ci, di]
        lR = post["log_R"].sel(sel).values[ci, di]
        t2 = post["theta2"].sel(sel).values[ci, di]
        seg, K = p.segment, p.segment.K
        # The human the likelihood assumes: with Feedback the draws run in closed loop.
        plan_plant, known = plan_inputs(seg, plant)
        ang = np.empty((flat.size, K + 1))
        tq = np.empty((flat.size, K))
        for j in range(flat.size):
            theta = from_normalized(np.exp(lt1[j]), t2[j], np.exp(lR[j]))
            demo = sample_maxent(theta, seg.x0, seg.angle_ref, known, plan_plant, rng)
            ang[j] = demo.x[: K + 1, 0]
            tq[j] = demo.u_H[:K]
        theta = from_normalized(np.exp(np.median(lt1)), np.median(t2), np.exp(np.median(lR)))
        opt = forward_optimal_control(theta, seg.x0, seg.angle_ref, known, plan_plant)
        qa = np.quantile(ang, [0.05, 0.5, 0.95], axis=0)
        qu = np.quantile(tq, [0.05, 0.5, 0.95], axis=0)
        pad = lambda x: np.append(x, np.nan)  # noqa: E731  torques act from k to k + 1: none at k = K
        frames.append(pd.DataFrame({
            "subject": subject, "condition": cond, "t": p.data.t[p.rows], "angle_ref": seg.angle_ref[: K + 1],
            "angle": p.data.angle[p.rows], "u_H": pad(p.u_H[:K]), "u_A": pad(seg.u_A[:K]),
            "angle_q05": qa[0], "angle_q50": qa[1], "angle_q95": qa[2],
            "u_H_q05": pad(qu[0]), "u_H_q50": pad(qu[1]), "u_H_q95": pad(qu[2]),
            "angle_opt": opt.x[: K + 1, 0], "u_H_opt": pad(opt.u_H[:K]),
        }))
    if not frames:
        raise ValueError(f"subject {subject!r} is not in the study (subjects: {', '.join(dict.fromkeys(prepared.subjects))})")
    return pd.concat(frames, ignore_index=True)


def ppc_coverage(ppc: pd.DataFrame) -> dict:
    """Share of the data inside the 5-95 % band, per condition (0.9 if calibrated per sample)."""
    out = {}
    for c, d in ppc.groupby("condition", sort=False):
        u = d.dropna(subset=["u_H_q05"])
        out[c] = {"u_H": float(((u.u_H >= u.u_H_q05) & (u.u_H <= u.u_H_q95)).mean()),
                  "angle": float(((d.angle >= d.angle_q05) & (d.angle <= d.angle_q95)).mean())}
    return out


# --------------------------------------------------------------------------- the stage


def _default_inputs(study_path: Path, estimates_path, truth_dir):
    """Inputs beside the study in the run-folder layout of ``scioc run`` when not given.

    The estimates are taken from ``<run>/identify/`` only if its ``identify.json`` says they
    were identified from this very study file.
    """
    if estimates_path is None:
        guess = study_path.parent.parent / "identify"
        try:
            meta = json.loads((guess / "identify.json").read_text())
            same = (guess / meta["study_relative"]).resolve() == study_path.resolve()
        except (OSError, ValueError, KeyError, TypeError):
            same = False
        estimates_path = guess / "estimates.parquet" if same and (guess / "estimates.parquet").exists() else None
    if truth_dir is None:
        folder = study_path.parent
        if (folder / "simulation.json").exists() and (folder / "truth.parquet").exists():
            truth_dir = folder
    return estimates_path, truth_dir


def _json(obj) -> str:
    """Strict JSON: non-finite numbers (an undefined k, a z of 0/0) become null."""

    def clean(x):
        if isinstance(x, float) and not np.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x

    return json.dumps(clean(obj), indent=2, allow_nan=False) + "\n"


def _require_netcdf() -> None:
    """Fail before minutes of sampling, not after, if NetCDF cannot be written."""
    try:
        import h5netcdf  # noqa: F401
        import h5py  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"writing posterior.nc needs the packages h5netcdf and h5py ({exc}); "
                          "install them with `pip install h5netcdf h5py`") from exc


def _write_netcdf(idata, path: Path) -> Path:
    with atomic_path(path) as tmp:
        idata.to_netcdf(tmp, engine="h5netcdf")
    return path


def fit_to_dir(study_path, out, *, seed: int = 2018, chains: int = 4, draws: int = 1000, tune: int = 500,
               settings: IdentifySettings = IdentifySettings(), subject: str | None = None,
               estimates_path=None, truth_dir=None, cores: int | None = None, show_progress: bool = False,
               force: bool = False) -> dict:
    """Fit both hierarchical models to a study file and write every artifact (see the module docstring).

    Parameters
    ----------
    study_path : str or Path
        Study file in the data convention.
    out : str or Path
        Output folder (created).
    seed : int
        Root seed (split into the samplers' and the predictive draws' seeds).
    chains, draws, tune : int
        nutpie chains, and draws kept per chain after ``tune`` warm-up draws.
    settings : IdentifySettings
        Window, preview and reconstruction, as for ``scioc identify``.
    subject : str, optional
        Subject of the posterior predictive bands (default: the third in sorted order,
        as in the report's Fig. 6).
    estimates_path : str or Path, optional
        ``estimates.parquet`` of ``scioc identify`` for the mixed-model cross-check
        (default: ``../identify/estimates.parquet`` from the study's folder, if present).
    truth_dir : str or Path, optional
        Folder with ``simulation.json`` and ``truth.parquet`` (default: the study's own
        folder, if it has them).
    cores : int, optional
        Chains sampled in parallel (default: ``os.cpu_count()``); the draws do not
        depend on it.
    show_progress : bool
        Progress bars on standard error.
    force : bool
        Replace an existing non-empty ``out`` (as a whole; see :func:`pipelines.io.staged_dir`).

    Returns
    -------
    dict
        Paths of the written files.

    Raises
    ------
    ValueError
        For a bad study design (a subject lacking a condition, no SC at all: the message
        of :func:`models.units.index_study`), a malformed file, or an unknown
        ``subject``; nothing is written then.
    """
    _require_netcdf()
    for name, v, low in (("seed", seed, 0), ("chains", chains, 1), ("draws", draws, 1), ("tune", tune, 1)):
        if int(v) != v or v < low:
            raise ValueError(f"--{name} must be an integer >= {low}; got {v!r}")
    study_path, out = Path(study_path), Path(out)
    estimates_path, truth_dir = _default_inputs(study_path, estimates_path, truth_dir)
    refuse_inputs_inside(out, study_path, estimates_path, truth_dir)
    check_output_dir(out, force=force)  # before minutes of sampling, not after
    t_start = time.perf_counter()
    prepared = prepare_study(study_path, settings, show_progress=show_progress)
    subjects = sorted(dict.fromkeys(prepared.subjects))
    subject = subject or (subjects[2] if len(subjects) > 2 else subjects[0])
    if subject not in subjects:
        raise ValueError(f"--subject {subject!r} is not in the study (subjects: {', '.join(subjects)})")
    t_prepared = time.perf_counter()
    plant = discretize(DT_HUMAN)
    batch = prepare_batch(plant, [p.segment for p in prepared.segments])
    seeds = _child_seeds(seed)
    fits, timing = {}, {"prepare_s": t_prepared - t_start}
    for name, effects in (("condition", True), ("pooled", False)):
        t0 = time.perf_counter()
        model = build_model(prepared.subjects, prepared.conditions, batch, plant, segment_ids=prepared.labels,
                            condition_effects=effects)
        t1 = time.perf_counter()
        idata, sec = sample_model(model, seed=seeds[name], chains=chains, draws=draws, tune=tune, cores=cores,
                                  show_progress=show_progress)
        fits[name] = idata
        timing[name] = {"build_s": t1 - t0, **{f"{k}_s": v for k, v in sec.items()}}
    diag = {name: diagnostics(d, timing[name]["sample_s"]) for name, d in fits.items()}

    t0 = time.perf_counter()
    res = {"model": "hierarchical max-ent, condition effects on log θ1 and log R (models.bayes.hierarchical)",
           **contrasts(fits["condition"])}
    res["loo"] = loo_comparison(fits["condition"], fits["pooled"])
    res["loo_subject"] = subject_loo_comparison(fits["condition"], fits["pooled"], batch, prepared.subjects,
                                                prepared.conditions, plant, np.random.default_rng(seeds["loso"]))
    estimates = pd.read_parquet(estimates_path) if estimates_path is not None else None
    if estimates is not None:
        units = set(zip(prepared.subjects, prepared.conditions))
        theirs = set(zip(estimates["subject"].astype(str), estimates["condition"].astype(str)))
        if units != theirs:
            raise InputDataError(
                f"{estimates_path}: its subjects × conditions ({len(theirs)}) are not those of {study_path} "
                f"({len(units)}); e.g. {sorted(units ^ theirs)[:3]}. Pass the estimates identified from this study "
                "with --estimates")
    res["mixedlm"] = mixedlm_check(estimates) if estimates is not None else None
    res["truth"] = truth_check(fits["condition"], truth_dir, estimates) if truth_dir is not None else None
    ppc = posterior_predictive(fits["condition"], prepared, subject, np.random.default_rng(seeds["ppc"]))
    res["ppc"] = {"subject": subject, "draws": int(min(PPC_DRAWS, chains * draws)), "coverage_5_95": ppc_coverage(ppc),
                  "note": "exact max-ent draws of the human the likelihood assumes (in SC: " + settings.assistant_model
                          + " assistant model); "
                          "u_H is the reconstructed torque where the file has none"}
    timing["contrasts_and_ppc_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    res["adequacy"] = posterior_adequacy(fits["condition"], prepared, settings, plant)
    timing["adequacy_s"] = time.perf_counter() - t0

    timing["total_s"] = time.perf_counter() - t_start
    sidecar = {
        "study": str(study_path),
        "seed": int(seed),
        "seeds": seeds,
        "sampler": {"name": "nutpie", "via": "pymc.sample(nuts_sampler='nutpie')", "chains": int(chains),
                    "draws": int(draws), "tune": int(tune), "cores": int(min(chains, cores or os.cpu_count() or 1)),
                    "target_accept": 0.8, "adaptation": "diag (nutpie default)"},
        "identify_settings": asdict(settings),
        "n_segments": len(prepared.segments),
        "n_subjects": len(subjects),
        "K": int(batch.K),
        "criteria": {"divergences": 0, "rhat_max": RHAT_MAX, "ess_bulk_and_tail_min": ESS_MIN,
                     "applies_to": "population parameters", "ebfmi_min_advisory": EBFMI_MIN},
        "diagnostics": diag,
        "convergence_verdict": {name: d["convergence_verdict"] for name, d in diag.items()},
        "seconds": timing,
        "inputs": {"estimates": None if estimates_path is None else str(estimates_path),
                   "truth_dir": None if truth_dir is None else str(truth_dir)},
        "note_timing": "wall-clock times on a shared machine: other jobs may have competed for the CPU",
        "versions": versions(),
    }
    # Everything or nothing: the folder holds this fit's files only, or what it held before.
    with staged_dir(out, force=force) as tmp:
        _write_netcdf(fits["condition"], tmp / "posterior.nc")
        _write_netcdf(fits["pooled"], tmp / "posterior_pooled.nc")
        write_table_atomic(ppc, tmp / "ppc.parquet")
        write_text_atomic(tmp / "posterior.json", _json(sidecar))
        write_text_atomic(tmp / "contrasts.json", _json(res))
    names = {"posterior": "posterior.nc", "posterior_pooled": "posterior_pooled.nc", "ppc": "ppc.parquet",
             "sidecar": "posterior.json", "contrasts": "contrasts.json"}
    return {k: str(out / v) for k, v in names.items()}


def posterior_adequacy(idata, prepared: PreparedStudy, settings: IdentifySettings, plant) -> dict:
    """Model adequacy (:func:`pipelines.adequacy.assess_study`) at each segment's posterior θ.

    The plug-in θ of a segment is exp(posterior mean of log θ1) and of log R, and the
    posterior mean of θ2, of its subject × condition.
    """
    if settings.adequacy_boot == 0:
        return not_checked("switched off (adequacy bootstrap size 0)")
    post = idata["posterior"]
    lt1 = post["log_theta1"].mean(("chain", "draw"))
    lr = post["log_R"].mean(("chain", "draw"))
    t2 = post["theta2"].mean(("chain", "draw"))
    sel = [dict(subject=s, condition=c) for s, c in zip(prepared.subjects, prepared.conditions)]
    theta = from_normalized([float(np.exp(lt1.sel(**k))) for k in sel], [float(t2.sel(**k)) for k in sel],
                            [float(np.exp(lr.sel(**k))) for k in sel])
    _, summary = assess_study(prepared.segments, theta.T, plant, assistant_model=settings.assistant_model,
                              resolution=settings.resolution, n_boot=settings.adequacy_boot,
                              seed=settings.adequacy_seed, assistant=paper_assistant())
    summary["theta"] = "posterior means of log θ1, log R and θ2 per subject × condition (plug-in)"
    return summary


def format_fit(out) -> str:
    """A few lines summarizing a fit folder's sidecar and contrasts, the adequacy verdict first."""
    out = Path(out)
    side = json.loads((out / "posterior.json").read_text())
    res = json.loads((out / "contrasts.json").read_text())
    b, r, loo = res["beta"], res["ratio"], res["loo"]["difference"]
    conv = side["convergence_verdict"]
    adequacy = res.get("adequacy") or not_checked("not in this fit's contrasts.json")
    lines = [format_adequacy(adequacy)]
    if adequacy["verdict"] == "fail":
        lines.append("CAVEAT: the numbers below assume a human model that fails its adequacy checks; "
                     "beta may be an artifact of model misfit")
    lines += [
        f"sampler convergence: condition model {conv['condition']}; pooled model {conv['pooled']}",
        f"beta (mean SC change of log theta1): {b['mean']:.3f} ± {b['sd']:.3f}, 94 % HDI "
        f"[{b['hdi'][0]:.3f}, {b['hdi'][1]:.3f}], P(beta < 0) = {b['p_negative']:.3f}",
        f"exp(beta): {r['median']:.3f} (94 % HDI {r['hdi'][0]:.3f}-{r['hdi'][1]:.3f})",
        f"LOO: elpd(condition) - elpd(pooled) = {loo['elpd_diff']:.1f} ± {loo['se']:.1f} "
        f"({'reliable' if loo['reliable'] else 'Pareto k high: unreliable'})",
    ]
    if res.get("loo_subject"):
        ls = res["loo_subject"]["difference"]
        se = "n/a (one subject)" if ls.get("se") is None else f"{ls['se']:.1f}"
        lines.append(f"leave-one-subject-out: elpd(condition) - elpd(pooled) = {ls['elpd_diff']:.1f} ± {se} "
                     f"({'reliable' if ls['reliable'] else 'Pareto k high: unreliable'})")
    if res.get("truth"):
        t = res["truth"]["beta"]
        lines.append(f"true beta {t['truth']:g}: {'inside' if t['in_hdi'] else 'outside'} the HDI "
                     f"(posterior mean - truth = {t['discrepancy']:+.3f})")
    return "\n".join(lines)


# --------------------------------------------------------------------------- CLI hook


def cmd_fit(args) -> int:
    """Run ``scioc fit``; errors (ValueError, OSError) propagate to ``scioc``'s exit code 2."""
    from pipelines.cli import _window

    paths = fit_to_dir(args.study, args.out, seed=args.seed, chains=args.chains, draws=args.draws, tune=args.tune,
                       settings=_window(args), subject=args.subject, estimates_path=args.estimates,
                       truth_dir=args.truth, cores=args.cores, show_progress=True, force=args.force)
    print(format_fit(args.out))
    for k, v in paths.items():
        print(f"{k}: {v}")
    # Exit 1 when the sampler did not converge or the human model fails its adequacy checks.
    side = json.loads(Path(paths["sidecar"]).read_text())
    res = json.loads(Path(paths["contrasts"]).read_text())
    converged = all(v == "pass" for v in side["convergence_verdict"].values())
    return 0 if converged and res["adequacy"]["verdict"] != "fail" else 1


__all__ = ["fit_to_dir", "prepare_study", "sample_model", "diagnostics", "contrasts", "loo_comparison",
           "mixedlm_check", "truth_check", "posterior_predictive", "ppc_coverage", "cmd_fit",
           "format_fit"]
