# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Posterior diagnostics of the hierarchical fit
#
# Reads the artifacts of `scioc fit` (it never refits): `posterior.nc` (model with
# condition effects: one DataTree with the groups `posterior`, `sample_stats`,
# `log_likelihood`, `observed_data`, `posterior_predictive` and `constant_data`),
# `posterior_pooled.nc` (β = 0) and the sidecar `posterior.json` beside them, through
# `scioc.open_run`, which reads a run folder as the report does (a part made from another study is
# left out, with why). Set `SCIOC_RUN` to another run folder (`scioc run`, `scioc analyse`, or the
# stages alone); the default is the one `make run` writes.
#
# Steps: the sampler's own statistics and the verdict, then trace, rank, energy, pair
# and forest plots (ArviZ, matplotlib backend), the posterior predictive draws against
# the observed torques, then the PSIS-LOO comparison with its Pareto k diagnostics.

# %%
import os
import warnings

import arviz as az
import arviz_plots as azp
import matplotlib.pyplot as plt
import numpy as np

from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS

import scioc

RUN = scioc.open_run(os.environ.get("SCIOC_RUN", "reports/default-study"))
FIT = RUN.models["maxent"]
if RUN.left_out:
    print("left out of this run folder:", RUN.left_out)
print("verdicts:", FIT.verdicts)
POSTERIOR = FIT.fit_dir / "posterior.nc"
POOLED = FIT.fit_dir / "posterior_pooled.nc"
POPULATION = list(POPULATION_PARAMETERS)
BACKEND = "matplotlib"

idata = FIT.posterior()
print(f"posterior: {POSTERIOR}")
print(idata)

# %% [markdown]
# ## Sampler statistics and the verdict
#
# The sidecar holds the verdict against the acceptance criteria (no divergence,
# R-hat ≤ 1.01, bulk and tail ESS ≥ 400 for every population parameter). The table is
# recomputed here from the draws. Select the variables *before* calling ArviZ (its
# `var_names` filter on a Dataset changes later results in arviz-stats 1.x).

# %%
if FIT.sidecar is not None:
    side = FIT.sidecar
    print("seed", side["seed"], "| sampler", side["sampler"])
    for name, verdict in side["convergence_verdict"].items():
        print(f"{name}: {verdict}")
post = idata["posterior"].to_dataset()[POPULATION]
table = az.summary(post, ci_prob=0.94)
print(table)
ss = idata["sample_stats"].to_dataset()
print("divergences:", int(ss["diverging"].sum()), "| max tree depth:", int(ss["depth"].max()),
      "| E-BFMI per chain:", np.round(np.atleast_1d(az.bfmi(idata)["energy"].values), 3))

# %% [markdown]
# ## Trace plots
#
# Each chain's draws (right) and their densities (left) for the population parameters;
# divergent transitions are marked on the draw axis.

# %%
azp.plot_trace_dist(idata, var_names=POPULATION, backend=BACKEND)
plt.show()

# %% [markdown]
# ## Rank plots
#
# The ranks of every chain's draws among all chains should be uniform: the fractional
# rank ECDF of each chain stays inside the envelope when the chains mix.

# %%
azp.plot_rank(idata, var_names=POPULATION, backend=BACKEND)
plt.show()

# %% [markdown]
# ## Energy
#
# Marginal energy against energy transitions: similar widths (E-BFMI above 0.3) mean
# the momentum resampling explores the energy levels the posterior needs.

# %%
azp.plot_energy(idata, backend=BACKEND)
plt.show()

# %% [markdown]
# ## Pair plot
#
# β against the spread of the change σ_β and the MC mean μ: σ_β's lower end is the
# funnel-shaped region the non-centred change is there to sample.

# %%
azp.plot_pair(idata, var_names=["beta", "sigma_beta", "mu_log_theta1"], backend=BACKEND)
plt.show()

# %% [markdown]
# ## Forest plots
#
# The population parameters, then each subject's MC→SC change of log θ1
# (log θ1[SC] − log θ1[MC]), with their 94 % HDIs.

# %%
azp.plot_forest(idata, var_names=["beta", "sigma_beta", "beta_log_R", "sigma_beta_log_R"], backend=BACKEND)
plt.show()

lt1 = idata["posterior"]["log_theta1"]
change = (lt1.sel(condition="SC") - lt1.sel(condition="MC")).rename("change_log_theta1")
azp.plot_forest(change.to_dataset(), backend=BACKEND)
plt.show()

# %% [markdown]
# ## Posterior predictive draws
#
# Exact max-ent draws of one subject's torques (`posterior_predictive`, the dims of
# `observed_data`), with the time axis from `constant_data`: the observed torque of each
# of that subject's segments against its pointwise 5-95 % predictive band. `scioc fit`
# stores the same bands in `ppc.parquet` for the report.

# %%
pp = idata["posterior_predictive"]["u_H"]
obs = idata["observed_data"]["u_H"]
t = idata["constant_data"]["t"]
fig, axes = plt.subplots(pp.sizes["segment"], 1, figsize=(9, 2.6 * pp.sizes["segment"]), squeeze=False)
for ax, seg in zip(axes[:, 0], pp["segment"].values):
    draws = pp.sel(segment=seg).stack(sample=("chain", "draw")).transpose("sample", "step").values
    lo, hi = np.quantile(draws, [0.05, 0.95], axis=0)
    time = t.sel(segment=seg).values[:-1]
    ax.fill_between(time, lo, hi, alpha=0.3, label="posterior predictive 5-95 %")
    ax.plot(time, obs.sel(segment=seg).values, lw=0.5, color="k", label="u_H (observed)")
    ax.set_title(str(seg))
    ax.set_ylabel("u_H (N·m)")
axes[-1, 0].set_xlabel("time t (s)")
axes[0, 0].legend(fontsize=7)
plt.show()

# %% [markdown]
# ## PSIS-LOO: condition effects against the pooled model
#
# One log-likelihood value per segment (a subject in one condition). Leaving a segment
# out removes all the data on that unit's θ, so large Pareto k are expected: the k
# plot says which segments' estimates to distrust, and the ELPD difference is
# indicative only when many k exceed the threshold.

# %%
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    loo_cond = az.loo(idata, pointwise=True, var_name="u_H")
print(loo_cond)
azp.plot_khat(loo_cond, backend=BACKEND)
plt.show()

if POOLED.exists():
    pooled = az.from_netcdf(POOLED)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cmp = az.compare({"condition effects": idata, "pooled (beta = 0)": pooled})
    print(cmp)
    azp.plot_compare(cmp, backend=BACKEND)
    plt.show()
else:
    print(f"no pooled fit at {POOLED}")

# %% [markdown]
# ## Leaving out whole subjects
#
# The reliable comparison: each subject's own parameters integrated out by importance
# sampling, then PSIS over the population draws only (`models/bayes/subject_loo.py`).
# `scioc fit` stores it in `contrasts.json`; every Pareto k should lie below the threshold.

# %%
CONTRASTS = FIT.fit_dir / "contrasts.json"
if FIT.contrasts is not None and "loo_subject" in (res := FIT.contrasts):
    ls = res["loo_subject"]
    for name in ("condition", "pooled"):
        m = ls[name]
        print(f"{name:>9}: ELPD {m['elpd_loo']:.1f} ± {m['se']:.1f}, max Pareto k {m['pareto_k']['max']:.2f} "
              f"({m['pareto_k']['n_gt_threshold']} of {m['pareto_k']['n']} above {m['pareto_k']['threshold']:.2f}), "
              f"importance-sampling ESS min {m['is_ess_min']:.0f}")
    d = ls["difference"]
    print(f"difference (condition - pooled): {d['elpd_diff']:.1f} ± {d['se']:.1f}; "
          f"{d['n_favouring_condition']} of {d['n']} subjects better predicted with condition effects")
else:
    print(f"no leave-one-subject-out comparison at {CONTRASTS}")
