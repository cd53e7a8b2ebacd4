"""Measured cost of the hierarchical ``delayed`` fit, and how sharply the data fix the delay.

* :func:`bench_delay_profile`: the drop of each unit's ML profile log-likelihood one and two samples
  from its maximum (:func:`scioc.models.delayed.identify.identify_unit_delayed`) on windows drawn from
  the ``delayed`` model, which backs the plug-in delay of :mod:`scioc.models.bayes.delayed_model`.
* :func:`bench_fit_delayed` (``scioc bench-fit --human-model delayed``): the full fit of a default-size
  study drawn from the ``delayed`` model at true delays, to compare parameterizations. It has no ML
  start and no whitening, so its times are not the goal :mod:`scioc.pipelines.bench.delayed_workflow` judges.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict

import numpy as np

from scioc.models.bayes.delayed_model import (
    DELAYED_NUTS,
    DELAYED_PARAMETERIZATION,
    DELAYED_POPULATION_PARAMETERS,
    DelayedForm,
    DelayedPriors,
    build_delayed_model,
)
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS
from scioc.models.delayed.identify import identify_unit_delayed
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.population import Population
from scioc.models.segment import prepare_batch
from scioc.pipelines.fit.contrasts import hdi
from scioc.pipelines.fit.diagnostics import diagnostics
from scioc.pipelines.fit.sampling import sample_model

#: Unit-level quantities of the delayed model whose diagnostics are reported.
DELAYED_UNITS = ("log_theta1", "log_R", "theta2", "tau_nm", "sigma_m")


def bench_delay_profile(n_subjects: int = 6, *, seed: int = 2018, delay: int = 12, tau_nm: float = 0.06,
                        sigma_m: float = 0.25) -> dict:
    """The ML profile over the delay of each unit of a small study drawn from the ``delayed`` model.

    Per unit: its argmax (samples) and the drops ``profile[argmax ± j] - max``, j = 1, 2, and at the
    truth (nats, NaN off the grid); per level, their medians and ranges and the argmax's errors.
    """
    plant = discretize(DT_HUMAN)
    w = delayed_windows(n_subjects, np.random.default_rng(seed), delay=(delay, delay), tau_nm=(tau_nm, tau_nm),
                        sigma_m=(sigma_m, sigma_m))
    t0 = time.perf_counter()
    units = []
    for j, seg in enumerate(w.segments):
        est = identify_unit_delayed([prepare_batch(plant, [seg])], plant, delay_search="grid")  # the whole profile
        grid, prof = np.asarray(est.delays), np.asarray(est.profile)
        k = int(np.argmax(prof))

        def drop(i):
            return float(prof[i] - prof[k]) if 0 <= i < grid.size else float("nan")

        units.append({"subject": w.subjects[j], "condition": w.conditions[j], "argmax": int(grid[k]),
                      "drop_m2": drop(k - 2), "drop_m1": drop(k - 1), "drop_p1": drop(k + 1), "drop_p2": drop(k + 2),
                      "drop_at_truth": drop(int(np.flatnonzero(grid == delay)[0]))})
    summary = {}
    for level in dict.fromkeys(w.conditions):
        rows = [u for u in units if u["condition"] == level]
        one = [v for u in rows for v in (u["drop_m1"], u["drop_p1"]) if np.isfinite(v)]
        two = [v for u in rows for v in (u["drop_m2"], u["drop_p2"]) if np.isfinite(v)]
        err = [u["argmax"] - delay for u in rows]
        summary[level] = {"drop_1_median": float(np.median(one)), "drop_1_range": [float(min(one)), float(max(one))],
                          "drop_2_median": float(np.median(two)), "drop_2_range": [float(min(two)), float(max(two))],
                          "argmax_error": err}
    return {"settings": {"n_subjects": n_subjects, "seed": seed, "delay": delay, "tau_nm": tau_nm,
                         "sigma_m": sigma_m, "K": w.segments[0].K},
            "units": units, "summary": summary, "seconds": time.perf_counter() - t0}


def bench_fit_delayed(*, n_subjects: int = 42, seed: int = 2018, chains: int = 4, draws: int = 1000,
                      tune: int = 1000, delayed_form=None, parameterization=None, delayed_priors=None,
                      idata_path=None) -> dict:
    """Fit a default-size study of the ``delayed`` human once and time it (module docstring).

    Returns ``settings``, ``seconds``, ``diagnostics``, ``recovery`` (β, τ_nm, σ_m) and ``grad_evals``;
    ``idata_path`` also keeps the posterior; nutpie samples with :data:`scioc.models.bayes.delayed_model.DELAYED_NUTS`.
    """
    plant = discretize(DT_HUMAN)
    w = delayed_windows(n_subjects, np.random.default_rng(np.random.SeedSequence(seed)))
    # The defaults resolved once: the model is built with them and the JSON records them.
    delayed_priors = DelayedPriors() if delayed_priors is None else delayed_priors
    delayed_form = DelayedForm() if delayed_form is None else delayed_form
    parameterization = DELAYED_PARAMETERIZATION if parameterization is None else parameterization
    t0 = time.perf_counter()
    model = build_delayed_model(w.subjects, w.conditions, w.segments, plant, delay=w.delay, tau0=w.tau0,
                                delayed_priors=delayed_priors, delayed_form=delayed_form,
                                parameterization=parameterization)
    t1 = time.perf_counter()
    idata, sec = sample_model(model, seed=seed, chains=chains, draws=draws, tune=tune, log_likelihood=False,
                              nuts=DELAYED_NUTS)
    diag = diagnostics(idata, sec["sample"], POPULATION_PARAMETERS + DELAYED_POPULATION_PARAMETERS, DELAYED_UNITS)
    post = idata["posterior"]
    recovery = {}
    for name, truth in (("tau_nm", w.tau_nm[::2]), ("sigma_m", w.sigma_m[::2])):
        x = np.asarray(post[name].transpose("chain", "draw", "subject").values).reshape(-1, n_subjects)
        inside = [bool(lo <= t <= hi) for (lo, hi), t in zip((hdi(x[:, i]) for i in range(n_subjects)), truth)]
        recovery[name] = {"n_in_hdi94": int(sum(inside)), "n": n_subjects,
                          "mean_error": float(np.mean(x.mean(axis=0) - truth))}
    beta = np.asarray(post["beta"].values, dtype=float).ravel()
    interval = hdi(beta)
    recovery["beta"] = {"mean": float(beta.mean()), "hdi94": interval, "truth": Population().beta,
                        "truth_in_hdi": bool(interval[0] <= Population().beta <= interval[1])}
    fit_s = (t1 - t0) + sec["compile_and_sample"]
    if idata_path is not None:
        idata.to_netcdf(idata_path, engine="h5netcdf")
    return {"settings": {"segments": len(w.segments), "K": w.segments[0].K, "preview_steps": w.segments[0].preview,
                         "chains": chains, "draws": draws, "tune": tune, "seed": seed, "cpus": os.cpu_count(),
                         "delays": [int(w.delay.min()), int(w.delay.max())],
                         "delayed_priors": asdict(delayed_priors), "delayed_form": asdict(delayed_form),
                         "parameterization": asdict(parameterization),
                         "nuts": dict(DELAYED_NUTS)},
            "seconds": {"build": t1 - t0, "compile_and_sample": sec["compile_and_sample"], "sample": sec["sample"],
                        "fit": fit_s},
            "diagnostics": diag, "recovery": recovery,
            "grad_evals": int(np.asarray(idata["sample_stats"]["n_steps"].values).sum())}


def format_delay_profile(res: dict) -> str:
    """The profile measurement as plain text."""
    st = res["settings"]
    lines = ["", f"Profile log-likelihood over the delay ({st['n_subjects']} subjects × MC, SC drawn from the delayed "
                 f"model: delay {st['delay']} samples, τ_nm {st['tau_nm']} s, σ_m {st['sigma_m']} N·m, K = {st['K']}); "
                 "drop from the maximum, nats"]
    for level, s in res["summary"].items():
        lines.append(f"  {level}: ±1 sample median {s['drop_1_median']:.1f} (range {s['drop_1_range'][0]:.1f} to "
                     f"{s['drop_1_range'][1]:.1f}); ±2 median {s['drop_2_median']:.1f} (range {s['drop_2_range'][0]:.1f} "
                     f"to {s['drop_2_range'][1]:.1f}); argmax - truth {s['argmax_error']}")
    return "\n".join(lines)


def _tuning_text(sampler: dict) -> str:
    t, tenths = sampler.get("tuning_mean_steps_per_draw"), sampler.get("tuning_steps_by_tenth")
    if t is None:
        return "warm-up: not counted"
    return f"warm-up: {t:.1f}" + ("" if not tenths else ", by tenth " + " ".join(f"{x:.0f}" for x in tenths))


def format_fit_delayed(res: dict) -> str:
    """The delayed fit benchmark as plain text."""
    s, d, st, rec = res["seconds"], res["diagnostics"], res["settings"], res["recovery"]
    lines = [
        "",
        f"Hierarchical fit of the delayed human ({st['segments']} segments × K = {st['K']}, plan +{st['preview_steps']} "
        f"steps, delays {st['delays'][0]}-{st['delays'][1]} samples; {st['chains']} chains × {st['draws']} draws after "
        f"{st['tune']} tuning; nutpie, all cores)",
        f"  baseline R population: {st['delayed_priors']['R_population']}"
        + (f" (ρ {st['delayed_form']['rho']})" if st['delayed_priors']['R_population'] == "policy_scale" else "")
        + f"; mass matrix: {st['nuts'].get('adaptation')}",
        f"  wall: build {s['build']:.1f} s + compile and sample {s['compile_and_sample']:.1f} s = {s['fit']:.1f} s "
        f"(no ML start, no whitening: not scioc fit's path, whose time scioc bench --parts fit_delayed measures); "
        f"sampling alone {s['sample']:.1f} s",
        f"  sampler: {d['sampler']['divergences']} divergences, mean {d['sampler']['mean_steps_per_draw']:.1f} leapfrog "
        f"steps per draw ({_tuning_text(d['sampler'])}), {res['grad_evals']} gradient evaluations after tuning; "
        f"sampler convergence: {d['convergence_verdict']}",
        f"  worst population parameter: R-hat {d['worst']['rhat']:.3f}, ESS {d['worst']['ess']:.0f} "
        f"({d['worst']['ess_parameter']})",
        f"  τ_nm: {rec['tau_nm']['n_in_hdi94']} of {rec['tau_nm']['n']} subjects' truths in their 94 % HDI; σ_m: "
        f"{rec['sigma_m']['n_in_hdi94']} of {rec['sigma_m']['n']}; β = {rec['beta']['mean']:.3f} "
        f"[{rec['beta']['hdi94'][0]:.3f}, {rec['beta']['hdi94'][1]:.3f}] (truth {rec['beta']['truth']:g})",
    ]
    return "\n".join(lines)


__all__ = ["bench_delay_profile", "bench_fit_delayed", "format_delay_profile",
           "format_fit_delayed"]
