"""Checks of the fit against other evidence: a frequentist mixed model, the simulator's truth, model adequacy."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import statsmodels.formula.api as smf

from models.cost import from_normalized
from models.design import CONDITIONS, SHARED
from pipelines.adequacy import assess_study, not_checked
from pipelines.fit.contrasts import HDI_PROB, condition_change, hdi
from pipelines.prepare import PreparedStudy


def mixedlm_check(estimates: pd.DataFrame) -> dict:
    """Frequentist cross-check: linear mixed model of log θ1 from the per-segment ML estimates.

    ``log θ1 ~ 1 + SC`` with a random intercept per subject (REML, statsmodels
    ``MixedLM``); the SC coefficient estimates β. The ML estimates enter as data: their
    own standard errors are ignored.
    """
    d = estimates[["subject", "condition", "theta1"]].copy()
    d["log_theta1"] = np.log(d["theta1"].astype(float))
    d["SC"] = (d["condition"] == SHARED).astype(float)
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
            (lo, hi), kind = hdi(x), "hdi94"
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
    change = condition_change(post)
    covered = []
    for j, s in enumerate(change["subject"].values):
        lo, hi = hdi(change.values[:, :, j])
        covered.append(bool(lo <= true_change[str(s)] <= hi))
    out["subjects"] = {"n": len(covered), "true_change_in_hdi": int(sum(covered))}
    if estimates is not None:
        m = estimates.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))
        out["ml_log_error"] = {c: float(np.mean(np.log(m.theta1[m.condition == c] / m.theta1_true[m.condition == c])))
                               for c in CONDITIONS}
        out["ml_log_error"]["SC_minus_MC"] = out["ml_log_error"]["SC"] - out["ml_log_error"]["MC"]
    return out


def posterior_adequacy(idata, prepared: PreparedStudy, plant) -> dict:
    """Model adequacy (:func:`pipelines.adequacy.assess_study`) at each segment's posterior θ.

    The plug-in θ of a segment is exp(posterior mean of log θ1) and of log R, and the
    posterior mean of θ2, of its subject × condition.
    """
    if prepared.settings.adequacy_boot == 0:
        return not_checked("switched off (adequacy bootstrap size 0)")
    post = idata["posterior"]
    lt1 = post["log_theta1"].mean(("chain", "draw"))
    lr = post["log_R"].mean(("chain", "draw"))
    t2 = post["theta2"].mean(("chain", "draw"))
    sel = [dict(subject=s, condition=c) for s, c in zip(prepared.subjects, prepared.conditions)]
    theta = from_normalized([float(np.exp(lt1.sel(**k))) for k in sel], [float(t2.sel(**k)) for k in sel],
                            [float(np.exp(lr.sel(**k))) for k in sel])
    _, summary = assess_study(prepared.segments, theta.T, plant, prepared.settings)
    summary["theta"] = "posterior means of log θ1, log R and θ2 per subject × condition (plug-in)"
    return summary
