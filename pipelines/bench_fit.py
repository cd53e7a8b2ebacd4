"""Measured cost and quality of a hierarchical fit with nutpie on a simulated study.

``python -m pipelines.bench_fit [--subjects 42] [--K 1500] [--draws 1000] [--tune 500]
[--chains 4] [--seed 0] [--theta1-mc mean] [--adaptation diag] ...``
prints a JSON report: wall times per stage, divergences, tree depth, leapfrog steps,
R-hat, bulk/tail ESS and ESS per second and per gradient evaluation of every
population-level parameter, and whether each true value lies in its 94 % HDI.

The simulated study here was written as a stand-in for :mod:`models.simulate` (which now
exists and should replace it; the numbers in :mod:`models.hierarchical` come from this one):
every subject
tracks the study reference (:mod:`models.reference`) over the analysis window once
without assistance (u_A = 0) and once with the MPC assistant. The SC assistant torques
come from a closed-loop run of the assistant with the human's policy
(:func:`models.assistant.simulate_closed_loop`); the human torques are then drawn exactly
from the max-ent model given that u_A sequence (:func:`models.maxent.sample_maxent`), so
the data follow the fitted model exactly.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import time
from typing import NamedTuple

import numpy as np

from models.assistant import design_assistant, simulate_closed_loop
from models.hierarchical import CONDITIONS, Parameterization, build_model
from models.lq import lq_policy
from models.maxent import Segment, sample_maxent
from models.plant import DT_HUMAN, discretize
from models.reference import reference_trajectory, window_slice

#: Population values of the default simulated study (log scale unless named otherwise).
TRUTH = {
    "mu_log_theta1": float(np.log(60.0)),
    "sigma_log_theta1": 0.4,
    "beta": -0.7,
    "sigma_beta": 0.2,
    "mu_log_R": 0.0,
    "sigma_log_R": 0.3,
    "beta_log_R": 0.2,
    "sigma_beta_log_R": 0.1,
    "tau_theta2": 0.0,
}
#: Population-level parameters checked by the benchmark.
POPULATION = tuple(TRUTH)
#: Extra reference samples given to the assistant beyond the window (its 1-s preview).
PREVIEW = 100


class SimulatedStudy(NamedTuple):
    """A simulated study in the form :func:`models.hierarchical.build_model` takes.

    Attributes
    ----------
    subjects, conditions : list of str, length n
    segments : list of Segment, length n
    log_theta1, log_R, theta2 : ndarray, shape (n_subjects, 2)
        True unit parameters, columns MC, SC.
    truth : dict
        Population values used.
    """

    subjects: list
    conditions: list
    segments: list
    log_theta1: np.ndarray
    log_R: np.ndarray
    theta2: np.ndarray
    truth: dict


def simulate_study(n_subjects: int = 42, K: int = 1500, seed: int = 0, truth: dict | None = None) -> SimulatedStudy:
    """Simulate ``n_subjects`` × {MC, SC} segments of K steps from the hierarchical model.

    Parameters
    ----------
    n_subjects : int
    K : int
        Steps per segment (at most 1500, the 15-s window at 100 Hz).
    seed : int
    truth : dict, optional
        Population values; :data:`TRUTH` by default.

    Returns
    -------
    SimulatedStudy
    """
    tr = dict(TRUTH if truth is None else truth)
    rng = np.random.default_rng(seed)
    plant = discretize(DT_HUMAN)
    assistant = design_assistant()
    full = reference_trajectory().angle
    win = window_slice()
    ref_ext = full[win.start : win.start + K + 1 + PREVIEW]
    ref = ref_ext[: K + 1]
    x0 = np.array([ref[0], (ref[1] - ref[0]) / DT_HUMAN])
    z = rng.standard_normal((4, n_subjects))
    lt1_mc = tr["mu_log_theta1"] + tr["sigma_log_theta1"] * z[0]
    lt1_sc = lt1_mc + tr["beta"] + tr["sigma_beta"] * z[1]
    lR_mc = tr["mu_log_R"] + tr["sigma_log_R"] * z[2]
    lR_sc = lR_mc + tr["beta_log_R"] + tr["sigma_beta_log_R"] * z[3]
    log_theta1 = np.column_stack([lt1_mc, lt1_sc])
    log_R = np.column_stack([lR_mc, lR_sc])
    theta2 = tr["tau_theta2"] * np.abs(rng.standard_normal((n_subjects, 2)))
    subjects, conditions, segments = [], [], []
    for i in range(n_subjects):
        for c, cname in enumerate(CONDITIONS):
            R = np.exp(log_R[i, c])
            theta = np.array([np.exp(log_theta1[i, c]) * R, theta2[i, c] * R, R])
            if cname == "MC":
                u_A = np.zeros(K)
            else:
                # The assistant's torques in closed loop with this human (policy planned
                # against u_A = 0, with max-ent noise); then the human's torques are drawn
                # exactly given that u_A, as the likelihood assumes.
                pol = lq_policy(plant, theta, ref_ext, np.zeros(K + PREVIEW))
                noise = rng.standard_normal(K + PREVIEW) / np.sqrt(2.0 * pol.S)
                run = simulate_closed_loop(plant, assistant, x0, ref_ext, pol.L, pol.f, noise)
                u_A = run.u_A[:K].copy()
            demo = sample_maxent(theta, x0, ref, u_A, plant, rng)
            subjects.append(f"S{i + 1:02d}")
            conditions.append(cname)
            segments.append(Segment(x0.copy(), ref.copy(), demo.u_H, u_A))
    return SimulatedStudy(subjects, conditions, segments, log_theta1, log_R, theta2, tr)


def _population_diagnostics(idata, truth: dict, sample_seconds: float, n_grad: int) -> dict:
    import arviz as az

    post = idata["posterior"]
    names = [v for v in POPULATION if v in post]
    ds = post.to_dataset()[names]
    ess_bulk = az.ess(ds, method="bulk")
    ess_tail = az.ess(ds, method="tail")
    rhat = az.rhat(ds)
    hdi = az.hdi(ds, prob=0.94)
    out = {}
    for v in names:
        lo, hi = (float(x) for x in hdi[v].values)
        t = truth.get(v)
        if t == 0.0 and float(ds[v].min()) >= 0.0:
            # A truth on the boundary of a scale's support is never inside an HDI of a
            # continuous posterior on (0, ∞): check it against the one-sided 94 % interval.
            lo, hi = 0.0, float(ds[v].quantile(0.94))
            kind = "one-sided [0, q94]"
        else:
            kind = "hdi94"
        out[v] = {
            "mean": float(ds[v].mean()),
            "sd": float(ds[v].std()),
            "interval": [lo, hi],
            "interval_kind": kind,
            "truth": t,
            "truth_in_interval": None if t is None else bool(lo <= t <= hi),
            "rhat": float(rhat[v]),
            "ess_bulk": float(ess_bulk[v]),
            "ess_tail": float(ess_tail[v]),
            "ess_bulk_per_s": float(ess_bulk[v]) / sample_seconds,
            "ess_bulk_per_1000_grad": 1000.0 * float(ess_bulk[v]) / n_grad,
        }
    return out


def bench_fit(
    n_subjects: int = 42,
    K: int = 1500,
    draws: int = 1000,
    tune: int = 500,
    chains: int = 4,
    seed: int = 0,
    *,
    parameterization: Parameterization = Parameterization(),
    cores: int | None = None,
    target_accept: float = 0.8,
    adaptation: str = "diag",
) -> dict:
    """Simulate a study, fit it with nutpie, and report time, diagnostics and recovery.

    Parameters
    ----------
    n_subjects, K : int
        Study size (default: the full study, 42 subjects × 2 conditions × 1500 steps).
    draws, tune, chains : int
        Per chain: draws kept after ``tune`` warm-up draws.
    seed : int
        Seeds the simulation (``seed``) and nutpie (``seed + 1``).
    parameterization : Parameterization
    cores : int, optional
        Chains run in parallel (default: all cores).
    target_accept : float
    adaptation : str
        nutpie's mass-matrix adaptation ("diag", "low_rank", ...).

    Returns
    -------
    dict
        ``seconds`` (simulate, build, compile, sample, total), ``sampler`` (divergences,
        max tree depth, mean and max leapfrog steps per draw after tuning, gradient
        evaluations in total and after tuning), ``population`` (per parameter: mean,
        sd, 94 % HDI (one-sided [0, q94] for a scale whose truth is 0), truth, truth in
        that interval, R-hat, bulk/tail ESS, ESS per second and per
        1000 gradient evaluations), ``checks`` (the model's acceptance criteria) and
        ``settings``.
    """
    import nutpie

    ncores = cores or os.cpu_count() or 1
    t0 = time.perf_counter()
    study = simulate_study(n_subjects, K, seed)
    t1 = time.perf_counter()
    plant = discretize(DT_HUMAN)
    model = build_model(study.subjects, study.conditions, study.segments, plant, parameterization=parameterization)
    t2 = time.perf_counter()
    compiled = nutpie.compile_pymc_model(model)
    t3 = time.perf_counter()
    kw = {} if cores is None else {"cores": cores}
    idata = nutpie.sample(
        compiled, draws=draws, tune=tune, chains=chains, seed=seed + 1, progress_bar=False,
        target_accept=target_accept, adaptation=adaptation, **kw,
    )
    t4 = time.perf_counter()
    ss = idata["sample_stats"]
    wss = idata["warmup_sample_stats"] if "warmup_sample_stats" in idata.children else None
    n_steps = ss["n_steps"].values
    n_grad_post = int(n_steps.sum())
    n_grad_warm = int(wss["n_steps"].values.sum()) if wss is not None else 0
    sample_s = t4 - t3
    sampler = {
        "divergences": int(ss["diverging"].values.sum()),
        "max_depth": int(ss["depth"].values.max()),
        "maxdepth_reached": int(ss["maxdepth_reached"].values.sum()),
        "mean_steps_per_draw": float(n_steps.mean()),
        "max_steps_per_draw": int(n_steps.max()),
        "grad_evals_after_tuning": n_grad_post,
        "grad_evals_total": n_grad_post + n_grad_warm,
        # Sampling time × busy cores / evaluations: the cost of one logp-and-gradient call.
        "seconds_per_grad_eval_per_core": sample_s * min(ncores, chains) / max(1, n_grad_post + n_grad_warm),
        "step_size": [float(x) for x in ss["step_size"].values[:, -1]],
    }
    pop = _population_diagnostics(idata, study.truth, sample_s, n_grad_post + n_grad_warm)
    checks = {
        "no_divergences": sampler["divergences"] == 0,
        "rhat_le_1.01": all(p["rhat"] <= 1.01 for p in pop.values()),
        "ess_bulk_tail_ge_400": all(min(p["ess_bulk"], p["ess_tail"]) >= 400 for p in pop.values()),
        "beta_in_hdi94": bool(pop["beta"]["truth_in_interval"]),
        "wall_le_180s": (t4 - t2) <= 180.0,
    }
    return {
        "seconds": {
            "simulate": t1 - t0,
            "build": t2 - t1,
            "compile": t3 - t2,
            "sample": sample_s,
            "build_compile_sample": t4 - t1,
            "total": t4 - t0,
        },
        "sampler": sampler,
        "population": pop,
        "checks": checks,
        "settings": {
            "n_subjects": n_subjects,
            "K": K,
            "draws": draws,
            "tune": tune,
            "chains": chains,
            "cores": ncores,
            "seed": seed,
            "target_accept": target_accept,
            "adaptation": adaptation,
            "parameterization": dataclasses.asdict(parameterization),
            "machine": platform.machine(),
            "cpu_count": os.cpu_count(),
            "versions": _versions(),
        },
    }


def _versions() -> dict:
    from importlib.metadata import version

    return {pkg: version(pkg) for pkg in ("pymc", "pytensor", "nutpie", "arviz", "numba", "numpy")}


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--subjects", type=int, default=42)
    p.add_argument("--K", type=int, default=1500)
    p.add_argument("--draws", type=int, default=1000)
    p.add_argument("--tune", type=int, default=500)
    p.add_argument("--chains", type=int, default=4)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--target-accept", type=float, default=0.8)
    p.add_argument("--adaptation", default="diag", choices=["diag", "draw_diag", "low_rank"])
    for f in dataclasses.fields(Parameterization):
        p.add_argument(f"--{f.name.replace('_', '-')}", choices=["centred", "noncentred", "mean"], default=f.default)
    a = p.parse_args(argv)
    res = bench_fit(
        a.subjects, a.K, a.draws, a.tune, a.chains, a.seed,
        parameterization=Parameterization(**{f.name: getattr(a, f.name) for f in dataclasses.fields(Parameterization)}),
        target_accept=a.target_accept, adaptation=a.adaptation,
    )
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
