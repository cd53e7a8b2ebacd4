"""Measured cost of the hierarchical fit of the default study, as ``scioc fit`` runs it.

The default study's condition model (:func:`scioc.models.bayes.hierarchical.build_model`) is sampled by
:func:`scioc.pipelines.fit.sampling.sample_model` with chains in parallel on all cores. Reported: wall
times, the sampler's diagnostics, ESS per second, β against the truth, and a lower bound on the same
fit with the dense O(K³) likelihood: the gradient evaluations after tuning times a dense evaluation.
"""

from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

from scioc.models.bayes.hierarchical import Parameterization, build_model
from scioc.models.design import WINDOW_SECONDS
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.simulate import Population
from scioc.pipelines.bench.common import default_study_segments
from scioc.pipelines.fit.contrasts import hdi
from scioc.pipelines.fit.diagnostics import diagnostics
from scioc.pipelines.fit.sampling import sample_model

#: The speed goal for the full fit (build, compile and sample), s.
FIT_GOAL_S = 180.0


def bench_fit(study: dict, *, seed: int = 2018, chains: int = 4, draws: int = 1000, tune: int = 1000,
              dense_s_per_segment: float | None = None, linear_s_per_batch: float | None = None,
              parameterization=None) -> dict:
    """Fit the default study's 2-s-preview segments once and time it.

    ``dense_s_per_segment`` and ``linear_s_per_batch``: likelihood-and-gradient times (s) of one dense
    segment and of the linear-time batch, for the dense projection. Returns ``settings``, ``seconds``,
    ``diagnostics``, ``beta`` (mean, 94 % HDI, truth), ``grad_evals_after_tuning``, ``dense`` and the goal.
    """
    form = parameterization or Parameterization()
    prepared = study[2.0]
    plant = discretize(DT_HUMAN)
    t0 = time.perf_counter()
    model = build_model([p.data.subject for p in prepared], [p.data.condition for p in prepared],
                        [p.segment for p in prepared], plant, parameterization=form)
    t1 = time.perf_counter()
    idata, sec = sample_model(model, seed=seed, chains=chains, draws=draws, tune=tune, log_likelihood=False)
    diag = diagnostics(idata, sec["sample"])
    beta = np.asarray(idata["posterior"]["beta"].values, dtype=float).ravel()
    interval = hdi(beta)
    truth = Population().beta
    n_grad = int(np.asarray(idata["sample_stats"]["n_steps"].values).sum())
    fit_s = (t1 - t0) + sec["compile_and_sample"]
    out = {
        "settings": {"segments": len(prepared), "K": prepared[0].segment.K, "preview_steps": prepared[0].segment.preview,
                     "chains": chains, "draws": draws, "tune": tune, "seed": seed,
                     "parameterization": dataclasses.asdict(form)},
        "seconds": {"build": t1 - t0, "compile_and_sample": sec["compile_and_sample"], "sample": sec["sample"],
                    "fit": fit_s},
        "diagnostics": diag,
        "beta": {"mean": float(beta.mean()), "hdi94": interval, "truth": truth,
                 "truth_in_hdi": bool(interval[0] <= truth <= interval[1])},
        "grad_evals_after_tuning": n_grad,
        "goal_s": FIT_GOAL_S,
        "within_goal": fit_s <= FIT_GOAL_S,
    }
    if dense_s_per_segment is not None:
        dense_eval = dense_s_per_segment * len(prepared)
        # The chains run in parallel, one per core.
        out["dense"] = {"s_per_eval": dense_eval,
                        "projected_s_lower_bound": n_grad * dense_eval / min(chains, os.cpu_count() or 1),
                        "ratio_per_eval": dense_eval / linear_s_per_batch if linear_s_per_batch else None}
    return out


def format_fit(res: dict) -> str:
    """The fit benchmark as plain text."""
    s, d, b = res["seconds"], res["diagnostics"], res["beta"]
    st = res["settings"]
    lines = [
        "",
        f"Hierarchical fit of the default study ({st['segments']} segments × K = {st['K']}, plan +{st['preview_steps']} "
        f"steps; {st['chains']} chains × {st['draws']} draws after {st['tune']} tuning; nutpie, all cores)",
        f"  wall: build {s['build']:.1f} s + compile and sample {s['compile_and_sample']:.1f} s = {s['fit']:.1f} s "
        f"(goal ≤ {res['goal_s']:.0f} s: {'met' if res['within_goal'] else 'NOT met'}); sampling alone {s['sample']:.1f} s",
        f"  sampler: {d['sampler']['divergences']} divergences, mean {d['sampler']['mean_steps_per_draw']:.1f} leapfrog "
        f"steps per draw, {res['grad_evals_after_tuning']} gradient evaluations after tuning; sampler convergence: {d['convergence_verdict']}",
        f"  {'parameter':<18} {'R-hat':>6} {'ESS bulk':>9} {'ESS tail':>9} {'ESS/s':>7}",
    ]
    for v, p in d["population"].items():
        lines.append(f"  {v:<18} {p['rhat']:>6.3f} {p['ess_bulk']:>9.0f} {p['ess_tail']:>9.0f} {p['ess_bulk_per_s']:>7.1f}")
    lines.append(f"  β = {b['mean']:.3f}, 94 % HDI [{b['hdi94'][0]:.3f}, {b['hdi94'][1]:.3f}]; the population's "
                 f"{b['truth']:g} is {'inside' if b['truth_in_hdi'] else 'OUTSIDE'}")
    if "dense" in res:
        dn = res["dense"]
        ratio = f"{dn['ratio_per_eval']:.0f}× the linear-time batch; " if dn["ratio_per_eval"] else ""
        lines.append(f"  with the dense likelihood one evaluation of all segments takes {dn['s_per_eval']:.0f} s "
                     f"({ratio}the sampling after tuning alone would take ≥ {dn['projected_s_lower_bound'] / 86400:.0f} "
                     "days on this machine)")
    return "\n".join(lines)


def bench_parameterization(parameterization: Parameterization, *, study_seed: int = 2018,
                           window_seconds: float = WINDOW_SECONDS, seed: int = 2018) -> dict:
    """One fit of the default simulated study in ``parameterization`` (``scioc bench-fit``).

    ``study_seed`` seeds the study, ``window_seconds`` shortens its window, ``seed`` seeds the sampler;
    returns :func:`bench_fit`'s result with the study's seed and window in its settings.
    """
    res = bench_fit(default_study_segments(seed=study_seed, window_seconds=window_seconds), seed=seed,
                    parameterization=parameterization)
    res["settings"]["study_seed"] = study_seed
    res["settings"]["window_seconds"] = window_seconds
    return res
