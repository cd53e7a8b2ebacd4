"""Sampler and convergence diagnostics of one fit, and the verdict on the sampler."""

from __future__ import annotations

import math

import arviz as az
import numpy as np

from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS

#: Unit-level quantities (subject × condition) whose diagnostics are reported too.
UNITS = ("log_theta1", "log_R", "theta2")

#: The convergence verdict's criteria (every population parameter).
RHAT_MAX = 1.01
ESS_MIN = 400

#: E-BFMI below this flags a chain (reported, advisory: not part of the verdict).
EBFMI_MIN = 0.3

#: Unit blocks whose baseline has a normal population, and that population's mean: their pooling factor is reported.
POOLED_BASELINES = {"log_theta1": "mu_log_theta1", "log_R": "mu_log_R"}

#: A pooling factor at least this: the population carries more of each subject's baseline than its data do.
LOOSE_POOLING = 0.5


def pooling_factor(eps: np.ndarray) -> float:
    """Gelman & Pardoe's (2006) pooling factor λ = 1 - V_j(E[ε_j]) / E[V_j(ε_j)] of draws ``eps`` (..., J) of each
    unit's deviation from its population mean (V_j over the units, E over the draws). In the normal model it is the
    shrinkage s² / (s² + σ²): near 0 where each unit's data fix it, near 1 where the population does."""
    e = np.asarray(eps, dtype=float).reshape(-1, np.shape(eps)[-1])
    return float(1.0 - np.var(e.mean(axis=0), ddof=1) / np.mean(np.var(e, axis=1, ddof=1)))


def _elements(draws):
    """``(label, selection)`` of each element of a population parameter: the name alone for a scalar,
    ``name[level]`` per element along its one further dim (``contrast``)."""
    extra = [d for d in draws.dims if d not in ("chain", "draw")]
    if not extra:
        return [(draws.name, {})]
    (dim,) = extra
    return [(f"{draws.name}[{c}]", {dim: c}) for c in draws[dim].values]


def diagnostics(idata, sample_seconds: float, parameters=POPULATION_PARAMETERS, unit_names=UNITS) -> dict:
    """Sampler and convergence diagnostics of one fit, with the verdict.

    Population parameters (one per non-baseline level, ``beta[level]``) get R-hat (rank-normalized), bulk and tail ESS
    and bulk ESS per second; unit quantities the worst of each. The verdict requires no divergences, R-hat ≤
    :data:`RHAT_MAX` and bulk and tail ESS ≥ :data:`ESS_MIN` for every population parameter.
    """
    post = idata["posterior"].to_dataset()
    ss = idata["sample_stats"].to_dataset()
    names = [v for v in parameters if v in post]
    # Select first: with var_names, arviz-stats 1.x leaves the Dataset's cached accessor holding only those variables.
    pop = post[names]
    rhat, bulk, tail = az.rhat(pop), az.ess(pop, method="bulk"), az.ess(pop, method="tail")
    population = {}
    for v in names:
        for label, at in _elements(pop[v]):
            b = float(bulk[v].sel(at))
            population[label] = {"rhat": float(rhat[v].sel(at)), "ess_bulk": b, "ess_tail": float(tail[v].sel(at)),
                                 "ess_bulk_per_s": b / sample_seconds}
    units = {}
    for v in unit_names:
        ds = post[[v]]
        r, b, t = az.rhat(ds)[v].values, az.ess(ds, method="bulk")[v].values, az.ess(ds, method="tail")[v].values
        units[v] = {"rhat_max": float(np.nanmax(r)), "ess_bulk_min": float(np.nanmin(b)),
                    "ess_tail_min": float(np.nanmin(t))}
        mean = POOLED_BASELINES.get(v)
        if mean in post and "condition" in post[v].dims:  # the baseline level is the first
            units[v]["pooling_factor"] = pooling_factor((post[v].isel(condition=0) - post[mean])
                                                        .transpose("chain", "draw", ...).values)
    bfmi = np.atleast_1d(az.bfmi(idata)["energy"].values).astype(float)
    n_steps = ss["n_steps"].values
    sampler = {
        "divergences": int(ss["diverging"].values.sum()),
        "ebfmi": [float(x) for x in bfmi],
        # nutpie's names, else PyMC's own NUTS's (a compound step: the delayed human's sampled delays)
        "max_tree_depth": int(ss["depth" if "depth" in ss else "tree_depth"].values.max()),
        "draws_at_max_tree_depth": int(ss["maxdepth_reached" if "maxdepth_reached" in ss
                                          else "reached_max_treedepth"].values.sum()),
        "mean_steps_per_draw": float(n_steps.mean()),
        "max_steps_per_draw": int(n_steps.max()),
        # the warm-up's (nutpie: pipelines.fit.sampling.keep_tuning_steps), None where not counted
        "tuning_mean_steps_per_draw": (ss.attrs["tuning_leapfrog_steps"] / (ss.attrs["tuning_draws"] * n_steps.shape[0])
                                       if ss.attrs.get("tuning_draws") else None),
        # ... and in each tenth of the warm-up, in order (which phase of the adaptation took them)
        "tuning_steps_by_tenth": ([round(float(x), 1) for x in np.atleast_1d(ss.attrs["tuning_steps_by_tenth"])]
                                  if "tuning_steps_by_tenth" in ss.attrs else None),
        "step_size": [float(x) for x in ss["step_size"].values[:, -1]],
    }
    worst_rhat = max(population.values(), key=lambda p: p["rhat"])
    worst_ess = min(population.items(), key=lambda kv: nan_first(smaller_ess(kv[1])))
    checks = {
        "no_divergences": sampler["divergences"] == 0,
        f"rhat_le_{RHAT_MAX}": all(p["rhat"] <= RHAT_MAX for p in population.values()),
        f"ess_bulk_tail_ge_{ESS_MIN}": all(smaller_ess(p) >= ESS_MIN for p in population.values()),
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
                  "ess": smaller_ess(worst_ess[1]),
                  "min_ess_bulk_per_s": min(p["ess_bulk_per_s"] for p in population.values())},
        "convergence_verdict": "pass" if not failed else "fail: " + ", ".join(failed),
        "passed": not failed,
    }


def smaller_ess(p: dict) -> float:
    """The smaller of a parameter's bulk and tail ESS, NaN where either is (Python's ``min`` depends on the order)."""
    return float(np.minimum(p["ess_bulk"], p["ess_tail"]))


def nan_first(ess: float) -> float:
    """A sort key that puts an undefined (NaN) ESS below every defined one: the worst."""
    return -1.0 if math.isnan(ess) else ess


#: nutpie's target acceptance rate where a fit sets none (the max-ent fits; nutpie's default).
NUTPIE_TARGET_ACCEPT = 0.8


def remedies(diag: dict, *, chains: int, draws: int, target_accept: float | None) -> list[str]:
    """What to try when a fit's sampler-convergence verdict fails, from the fit's own numbers; [] when it passes.

    * Divergent transitions: a target acceptance rate halfway to 1; divergences that persist call for another form.
    * ESS below :data:`ESS_MIN`: the draws at which the slowest parameter would reach it, if its ESS grows in
      proportion (a projection, not a promise). R-hat above :data:`RHAT_MAX`: a longer warm-up and more draws.
    * Draws at the largest tree depth: valid but less independent ones, which more draws make up for.
    * μ_R or σ_R failing in a delayed fit whose baseline log R has a pooling factor of at least
      :data:`LOOSE_POOLING`: the policy-scale population of R (docs/decisions/delayed-R-population.md).
    """
    if diag.get("passed", False):
        return []
    out = []
    n_div = diag["sampler"]["divergences"]
    if n_div:
        ta = NUTPIE_TARGET_ACCEPT if target_accept is None else float(target_accept)
        higher = round(1.0 - (1.0 - ta) / 2.0, 4)
        out.append(f"{n_div} divergent transition{'s' * (n_div != 1)}: refit with --target-accept {higher:g} "
                   f"(this fit: {ta:g}; smaller steps, deeper trees); divergences that persist mark a region the "
                   "sampler cannot enter, and the model's form must change there, not the number of draws")
    # NaN (a parameter that never moved) fails the verdict, so it is advised on too; a sidecar stores it as null.
    pop = {k: {m: math.nan if p.get(m) is None else float(p[m]) for m in ("ess_bulk", "ess_tail", "rhat")}
           for k, p in diag["population"].items()}
    low = {k: smaller_ess(p) for k, p in pop.items() if not smaller_ess(p) >= ESS_MIN}
    if low:
        worst = min(low, key=lambda k: nan_first(low[k]))
        ess = low[worst]
        if ess > 0:
            need = int(math.ceil(ESS_MIN / ess * draws / 100.0) * 100)
            out.append(f"ESS of {worst} {ess:.0f} of {ESS_MIN} ({len(low)} parameter{'s' * (len(low) != 1)} short): "
                       f"at this fit's ESS per draw about --draws {need} per chain (now {draws}, {chains} chains) "
                       "would reach it, if the ESS grows in proportion to the draws")
        else:
            out.append(f"ESS of {worst} is {ess:.0f}: the chains do not move in it; more draws will not help")
    high = [k for k, p in pop.items() if not p["rhat"] <= RHAT_MAX]
    if high:
        worst = max(high, key=lambda k: math.inf if math.isnan(pop[k]["rhat"]) else pop[k]["rhat"])
        out.append(f"R-hat of {worst} {pop[worst]['rhat']:.3f} > {RHAT_MAX} ({len(high)} parameter"
                   f"{'s' * (len(high) != 1)}): the chains disagree; refit with a longer --tune and more --draws, "
                   "then judge again; an R-hat that stays high means chains in different regions")
    n_cut = int(diag["sampler"].get("draws_at_max_tree_depth") or 0)
    if n_cut:
        out.append(f"{n_cut} draw{'s' * (n_cut != 1)} stopped at the largest tree depth "
                   f"({diag['sampler'].get('max_tree_depth')}): shorter trajectories than NUTS would have run; valid "
                   "draws but less independent ones, which more --draws make up for")
    lam = diag.get("units", {}).get("log_R", {}).get("pooling_factor", math.nan)
    if {"mu_log_R", "sigma_log_R"} & (set(low) | set(high)) and "sigma_m_scale" in pop and lam >= LOOSE_POOLING:
        out.append(f"the data barely fix each subject's R (pooling factor of its baseline log R {lam:.2f}, at least "
                   f"{LOOSE_POOLING}): a population of log R is then held by its prior and each subject's lower bound "
                   "and mixes slowly in any form; refit with R_population = \"policy_scale\" (R^(-1/2) half-normal) in "
                   "--sampler-config (docs/decisions/delayed-R-population.md)")
    return out

