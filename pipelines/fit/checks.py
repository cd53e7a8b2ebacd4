"""Checks of the fit against other evidence: a frequentist mixed model, the simulator's truth, model adequacy."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import statsmodels.formula.api as smf

from scioc.models.cost import from_normalized
from scioc.models.design import CONDITIONS, STUDY, Design
from scioc.pipelines.adequacy import assess_study, not_checked
from scioc.pipelines.fit.contrasts import HDI_PROB, condition_change, effect_draws, hdi, levels_of
from scioc.pipelines.prepare import PreparedStudy
from scioc.pipelines.simulate import read_truth


def _fixed_effect(fit, column: str) -> dict:
    lo, hi = (float(x) for x in fit.conf_int(alpha=0.05).loc[column])
    coef = float(fit.fe_params[column])
    return {"coef": coef, "se": float(fit.bse_fe[column]), "ci95": [lo, hi], "p_value": float(fit.pvalues[column]),
            "ratio": float(np.exp(coef)), "ratio_ci95": [float(np.exp(lo)), float(np.exp(hi))]}


def mixedlm_check(estimates: pd.DataFrame, levels=CONDITIONS) -> dict:
    """Frequentist cross-check: a linear mixed model of log θ1 on the per-unit ML estimates.

    ``log θ1 ~ 1 + SC`` with a random intercept per subject (REML, statsmodels ``MixedLM``): the SC coefficient
    estimates β; with more ``levels``, one coefficient per non-baseline level. The estimates enter as data, one row per
    unit (ValueError if a unit has several); their SEs are ignored.
    """
    levels = tuple(levels)
    d = estimates[["subject", "condition", "theta1"]].copy()
    d["subject"], d["condition"] = d["subject"].astype(str), d["condition"].astype(str)
    twice = d.duplicated(["subject", "condition"])
    if twice.any():
        first = d[twice].iloc[0]
        raise ValueError("the mixed-model check needs one estimate per subject × condition; got several for "
                         f"subject {first.subject!r}, condition {first.condition!r}")
    d["log_theta1"] = np.log(d["theta1"].astype(float))
    # Indicator columns with formula-safe names (level labels may be any text).
    columns = ["SC"] if len(levels) == 2 else [f"level_{j}" for j in range(1, len(levels))]
    for column, level in zip(columns, levels[1:]):
        d[column] = (d["condition"] == level).astype(float)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = smf.mixedlm("log_theta1 ~ " + " + ".join(columns), d, groups=d["subject"]).fit(reml=True)
    common = {
        "intercept": float(fit.fe_params["Intercept"]),
        "subject_sd": float(np.sqrt(fit.cov_re.values[0, 0])), "residual_sd": float(np.sqrt(fit.scale)),
        "n_obs": int(fit.nobs), "n_subjects": int(d["subject"].nunique()), "converged": bool(fit.converged),
        "warnings": sorted({str(w.message) for w in caught}),
    }
    if len(levels) == 2:
        return {"formula": "log_theta1 ~ 1 + SC, random intercept per subject (REML)",
                **_fixed_effect(fit, "SC"), **common}
    return {"formula": f"log_theta1 ~ 1 + one indicator per level other than the baseline {levels[0]}, "
                       "random intercept per subject (REML)",
            "baseline": levels[0],
            "coefficients": {level: _fixed_effect(fit, column) for column, level in zip(columns, levels[1:])},
            **common}


#: simulation.json population names for the model's population parameters.
TRUE_NAMES = {"mu_log_theta1": "log_theta1_mc", "sigma_log_theta1": "sd_log_theta1", "beta": "beta",
              "sigma_beta": "sd_change", "mu_log_R": "log_R", "sigma_log_R": "sd_log_R", "beta_log_R": "gamma",
              "sigma_beta_log_R": "sd_R_change", "tau_theta2": "theta2"}


def _interval(x: np.ndarray, t: float) -> dict:
    """The posterior draws ``x`` of one parameter against its true value ``t``."""
    if t == 0.0 and x.min() >= 0.0:
        lo, hi, kind = 0.0, float(np.quantile(x, HDI_PROB)), "one-sided [0, q94]"
    else:
        (lo, hi), kind = hdi(x), "hdi94"
    return {"truth": t, "mean": float(x.mean()), "interval": [lo, hi], "interval_kind": kind,
            "in_interval": bool(lo <= t <= hi)}


def _true_population(pop: dict, v: str, key: str, j: int, design: Design) -> float:
    """The simulator's value of the model's population parameter ``v`` (non-baseline level ``j``, from 0)."""
    if v == "beta" and pop.get("betas"):
        return float(pop["betas"][j])
    if v == "mu_log_R":  # the population's R is stated at 100 Hz; the model's at the recording's rate
        return float(pop[key]) + math.log(design.r_scale)
    return float(pop[key])


def _contrast_truth(post, level: str, b: dict, true_change: pd.Series) -> tuple[dict, dict]:
    """β of ``level`` against its truth and the realized mean change; per-subject HDIs holding the true change."""
    sd = float(effect_draws(post, "beta", level).std(ddof=1))
    beta = {"truth": b["truth"], "hdi": b["interval"], "in_hdi": b["in_interval"],
            "posterior_mean": b["mean"], "discrepancy": b["mean"] - b["truth"],
            "discrepancy_in_sd": (b["mean"] - b["truth"]) / sd,
            "realized_mean_change": float(true_change.mean()),
            "realized_in_hdi": bool(b["interval"][0] <= true_change.mean() <= b["interval"][1])}
    change = condition_change(post, level=level)
    covered = []
    for j, s in enumerate(change["subject"].values):
        lo, hi = hdi(change.values[:, :, j])
        covered.append(bool(lo <= true_change[str(s)] <= hi))
    return beta, {"n": len(covered), "true_change_in_hdi": int(sum(covered))}


def truth_check(idata, truth_dir, estimates: pd.DataFrame | None = None, design: Design = STUDY) -> dict:
    """Compare the posterior with the simulator's truth (``simulation.json``, ``truth.parquet``).

    The true β, whether the 94 % HDI holds it and the posterior mean's miss (also in posterior SDs); every population
    parameter against its truth (a scale whose truth is 0 against the one-sided [0, q94]); how many per-subject HDIs
    hold the true change; with ``estimates``, the ML θ1's mean log error per level. With more than two levels, per
    level under ``contrasts``. None when the simulated human has no cost θ.
    """
    truth_dir = Path(truth_dir)
    sim = json.loads((truth_dir / "simulation.json").read_text())
    truth = pd.read_parquet(truth_dir / "truth.parquet")
    if not np.isfinite(truth["theta1"].to_numpy(dtype=float)).any():
        return None  # a simulated human without a cost θ (the crossover operator): nothing to check against
    truth = truth.drop_duplicates(["subject", "condition"]).drop(columns=["trial"], errors="ignore")
    pop = sim["population"]
    post = idata["posterior"]
    levels = levels_of(post)
    out = {"source": str(truth_dir)}
    params = {}
    for v, key in TRUE_NAMES.items():
        if v not in post or key not in pop:
            continue
        if "contrast" not in post[v].dims:
            params[v] = _interval(post[v].values.ravel(), _true_population(pop, v, key, 0, design))
            continue
        for j, level in enumerate(levels[1:]):
            x = effect_draws(post, v, level).ravel()
            params[f"{v}[{level}]"] = _interval(x, _true_population(pop, v, key, j, design))
    out["population"] = params
    w = truth.pivot_table(index="subject", columns="condition", values="theta1")
    blocks = {c: _contrast_truth(post, c, params["beta" if len(levels) == 2 else f"beta[{c}]"],
                                 np.log(w[c] / w[levels[0]]))
              for c in levels[1:]}
    if len(levels) == 2:
        out["beta"], out["subjects"] = blocks[levels[1]]
    else:
        out["contrasts"] = {c: {"beta": b, "subjects": n} for c, (b, n) in blocks.items()}
    if estimates is not None:
        m = estimates.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))
        out["ml_log_error"] = {c: float(np.mean(np.log(m.theta1[m.condition == c] / m.theta1_true[m.condition == c])))
                               for c in levels}
        for c in levels[1:]:
            out["ml_log_error"][f"{c}_minus_{levels[0]}"] = out["ml_log_error"][c] - out["ml_log_error"][levels[0]]
    return out


def motor_truth(idata, truth_dir) -> dict | None:
    """The delayed fit's per-subject τ_nm and σ_m against the simulator's: how many intervals hold the truth, the
    mean error, the median posterior median and the largest upper end; None when the truth has neither."""
    truth = read_truth(Path(truth_dir) / "truth.parquet")
    if not {"tau_nm", "motor_sd"} <= set(truth.columns):
        return None
    first = truth.drop_duplicates("subject")
    truth = first.set_index(first["subject"].astype(str))
    post = idata["posterior"]
    out = {}
    for name, col in (("tau_nm", "tau_nm"), ("sigma_m", "motor_sd")):
        x = post[name]
        draws = {s: x.sel(subject=s).values.ravel() for s in x["subject"].values}
        rows = [(_interval(d, float(truth.loc[str(s), col])), float(np.median(d))) for s, d in draws.items()]
        out[name] = {"n": len(rows), "truth_in_interval": sum(r["in_interval"] for r, _ in rows),
                     "interval_kinds": sorted({r["interval_kind"] for r, _ in rows}),
                     "mean_error": float(np.mean([r["mean"] - r["truth"] for r, _ in rows])),
                     "truth_max": max(r["truth"] for r, _ in rows),
                     "median_posterior_median": float(np.median([m for _, m in rows])),
                     "largest_upper": max(r["interval"][1] for r, _ in rows)}
    return out


#: Where the adequacy check at the posterior takes its one parameter point (``adequacy_at`` in ``scioc fit --sampler-config``): ``draw``,
#: one joint posterior draw (the default), or ``means``, each parameter's posterior mean on its own
#: (docs/decisions/adequacy-at-a-posterior-draw.md).
ADEQUACY_POINTS = ("draw", "means")


def posterior_point(post, at: str, seed: int):
    """The parameter point of the adequacy check at the posterior ``post`` (:data:`ADEQUACY_POINTS`): every posterior
    variable without ``chain`` and ``draw``, and what it is (``at``; for ``draw`` the chain and draw that
    ``default_rng([seed, 1])`` picks uniformly among all chains × draws)."""
    if at not in ADEQUACY_POINTS:
        raise ValueError(f"the adequacy check's point must be one of {', '.join(ADEQUACY_POINTS)}; got {at!r}")
    if at == "means":
        return post.mean(("chain", "draw")), {"at": "means", "what": "each parameter's posterior mean on its own "
                                              "(log θ1, log R, θ2, and τ_nm, σ_m)"}
    rng = np.random.default_rng([int(seed), 1])
    flat = int(rng.integers(post.sizes["chain"] * post.sizes["draw"]))
    c, d = divmod(flat, post.sizes["draw"])
    point = post.isel(chain=c, draw=d)
    return point, {"at": "draw", "chain": int(post["chain"].values[c]), "draw": int(post["draw"].values[d]),
                   "what": "one joint posterior draw, picked by the adequacy seed (Johnson 2007)"}


def unit_theta(point, prepared: PreparedStudy) -> np.ndarray:
    """θ of every segment (rows: segments) at a :func:`posterior_point`: its subject × condition's θ1, θ2, R."""
    sel = [dict(subject=s, condition=c) for s, c in zip(prepared.subjects, prepared.conditions)]
    theta = from_normalized([float(np.exp(point["log_theta1"].sel(**k))) for k in sel],
                            [float(point["theta2"].sel(**k)) for k in sel],
                            [float(np.exp(point["log_R"].sel(**k))) for k in sel])
    return theta.T


def posterior_adequacy(idata, prepared: PreparedStudy, plant, at: str = "draw") -> dict:
    """Model adequacy (:func:`scioc.pipelines.adequacy.assess_study`) at one posterior point of θ (``at``,
    :func:`posterior_point`), each segment at its unit's θ; ``plant`` is the wheel at the recording's sample time."""
    if prepared.settings.adequacy_boot == 0:
        return not_checked("switched off (adequacy bootstrap size 0)")
    point, described = posterior_point(idata["posterior"], at, prepared.settings.adequacy_seed)
    _, summary = assess_study(prepared.segments, unit_theta(point, prepared), plant, prepared.settings)
    summary["theta"] = f"θ per subject × condition at {described['what']}"
    summary["point"] = described
    return summary
