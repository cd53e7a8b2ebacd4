"""Benchmark of the ``delayed`` likelihood with gradient on the default study batch, beside the max-ent kernel.

The batch is the default study's windows as ``scioc run`` prepares them, each at its true θ; lag and
motor noise are the simulated humans' (:mod:`scioc.models.humans`), and the delay is varied, since the
kernel's cost depends on them, not on the data. :func:`bench_angles` times the likelihood of the same
windows' encoder angles (:mod:`scioc.models.delayed.angles`) on one core, beside its dense reference, with
its exact gradient, and the identification of units from their angles.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from scioc.models.bayes.angle_op import AngleLoglikOp
from scioc.models.delayed import identify_unit_delayed, window_loglik, window_loglik_grad
from scioc.models.delayed import loglik as delayed_loglik
from scioc.models.delayed import loglik_grad as delayed_loglik_grad
from scioc.models.delayed.angles import START_SD
from scioc.models.delayed.dense import angle_loglik_dense
from scioc.models.design import STUDY
from scioc.models.humans import MOTOR_SD, TAU_NM
from scioc.models.maxent import loglik_grad as maxent_loglik_grad
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.bench.common import timeit
from scioc.pipelines.prepare import angle_windows

#: Delays timed, in samples of 0.01 s (0 to 300 ms).
DELAYS = (0, 10, 30)
#: The delay (samples of 0.01 s, 100 ms) at which the angle likelihood is timed with its gradient.
GRADIENT_DELAY = 10
#: Units of the default study identified from their angles (one window each), by each search.
N_IDENTIFY = 6


def bench_delayed(study: dict, *, delays=DELAYS, tau_nm: float = TAU_NM, sigma_m: float = MOTOR_SD,
                  threads=None, preview: float = 2.0) -> dict:
    """Time the ``delayed`` log-likelihood + gradient of the study batch per delay (samples) and thread count.

    ``study`` from :func:`scioc.pipelines.bench.common.default_study_segments`; ``tau_nm`` (s), ``sigma_m``
    (N·m per sample); ``threads`` default 1 and all. Returns ``n``, ``K``, ``preview_steps``, ``maxent``
    (:func:`scioc.pipelines.bench.common.timeit`) and per (delay, threads) ``min_s``, ``median_s``, the
    ratio to the max-ent kernel and ``value_min_s`` (the log-likelihood alone).
    """
    plant = discretize(DT_HUMAN)
    batch = prepare_batch(plant, [p.segment for p in study[preview]])
    theta = study["theta"]
    before = numba.get_num_threads()
    threads = tuple(threads) if threads is not None else tuple(sorted({1, before}))
    rows = []
    try:
        numba.set_num_threads(before)
        maxent = timeit(lambda: maxent_loglik_grad(theta, batch, plant))
        for d in delays:
            for t in threads:
                numba.set_num_threads(t)
                res = timeit(lambda: delayed_loglik_grad(theta, batch, plant, tau_nm=tau_nm, sigma_m=sigma_m,
                                                         delay=d))
                value = timeit(lambda: delayed_loglik(theta, batch, plant, tau_nm=tau_nm, sigma_m=sigma_m, delay=d))
                rows.append({"delay": int(d), "threads": int(t), "min_s": res["min_s"], "median_s": res["median_s"],
                             "ratio_to_maxent": res["min_s"] / maxent["min_s"], "value_min_s": value["min_s"]})
    finally:
        numba.set_num_threads(before)
    return {"n": batch.n, "K": batch.K, "preview_steps": int(batch.a.shape[1] - batch.K), "tau_nm": float(tau_nm),
            "sigma_m": float(sigma_m), "maxent": maxent, "rows": rows}


def format_delayed(res: dict) -> str:
    """The benchmark as a plain-text table."""
    lines = [
        f"Delayed human: log-likelihood with gradient, {res['n']} segments × K = {res['K']} "
        f"(+{res['preview_steps']} preview steps), τ_nm = {res['tau_nm']} s, σ_m = {res['sigma_m']} N·m",
        f"max-ent kernel on the same batch: {res['maxent']['min_s'] * 1e3:.2f} ms",
        f"{'delay (samples)':>16} {'threads':>8} {'min (ms)':>9} {'median (ms)':>12} {'× max-ent':>10} "
        f"{'value alone, min (ms)':>22}",
    ]
    for r in res["rows"]:
        lines.append(f"{r['delay']:>16} {r['threads']:>8} {r['min_s'] * 1e3:>9.2f} {r['median_s'] * 1e3:>12.2f} "
                     f"{r['ratio_to_maxent']:>10.1f} {r['value_min_s'] * 1e3:>22.2f}")
    return "\n".join(lines)


#: The goal for identifying every unit of the paper's study (84) from its angles on one core, s.
IDENTIFY_ANGLES_GOAL_S = 120.0
#: The units that goal is for: the paper's 42 subjects in two conditions.
IDENTIFY_ANGLES_GOAL_UNITS = 84


def _identify_units(segs, wins, plant, n: int) -> dict:
    """Seconds per unit to identify every unit: from angles and from the torques; for the first ``n`` also by the
    grid search of the delay, with the delays searched and whether the two searches chose the same delay."""
    sy = STUDY.encoder_sd
    out = {"angles": [], "angles_grid": [], "torques": [], "searched": [], "same_delay": []}

    def run(i, **kw):
        t0 = time.perf_counter()
        est = identify_unit_delayed([prepare_batch(plant, [segs[i].segment])], plant, tau0=[[segs[i].warmup]], **kw)
        return est, time.perf_counter() - t0

    run(0, angles=[wins[0]], sigma_y=sy, delays=[0, 1])  # compile
    run(0, delays=[0, 1])
    for i in range(len(segs)):
        est, t = run(i, angles=[wins[i]], sigma_y=sy)
        _, t_torque = run(i)
        out["angles"].append(t)
        out["torques"].append(t_torque)
        if i < n:
            grid, t_grid = run(i, angles=[wins[i]], sigma_y=sy, delay_search="grid")
            out["angles_grid"].append(t_grid)
            out["searched"].append(int(np.isfinite(est.profile).sum()))
            out["same_delay"].append(bool(est.delay == grid.delay))
    out["grid_size"] = int(est.profile.size)
    out["angles_total_s"] = float(np.sum(out["angles"]))
    out["torques_total_s"] = float(np.sum(out["torques"]))
    out["within_goal"] = (None if len(segs) < IDENTIFY_ANGLES_GOAL_UNITS else
                          bool(out["angles_total_s"] <= IDENTIFY_ANGLES_GOAL_S
                               and out["angles_total_s"] <= out["torques_total_s"]))
    return out


def bench_angles(study: dict, *, delays=DELAYS, tau_nm: float = TAU_NM, sigma_m: float = MOTOR_SD,
                 preview: float = 2.0, dense_K: int = 500, n_identify: int = N_IDENTIFY) -> dict:
    """Time the angle likelihood of every window (one core) per delay, with its gradient at
    :data:`GRADIENT_DELAY`, the dense joint Gaussian against the filter on the first window cut to ``dense_K``
    samples, and the identification of ``n_identify`` units from their angles; times in s."""
    plant = discretize(DT_HUMAN)
    segs = study[preview]
    theta = study["theta"]
    sy = STUDY.encoder_sd
    wins = angle_windows(segs, range(len(segs)))
    before = numba.get_num_threads()
    rows, dense = [], []

    def study_loglik(d, fn):
        return [fn(theta[:, i], tau_nm, sigma_m, d, w, plant, sigma_y=sy) for i, w in enumerate(wins)]

    try:
        numba.set_num_threads(1)
        for d in delays:
            res = timeit(lambda: study_loglik(d, window_loglik))
            rows.append({"delay": int(d), "min_s": res["min_s"], "median_s": res["median_s"]})
            w = wins[0]
            cut = w._replace(angles=w.angles[: dense_K + 1])
            kw = dict(u_A=cut.u_A, feedback=cut.feedback, tau_nm=tau_nm, sigma_m=sigma_m, delay=d, sigma_y=sy,
                      z0_mean=[cut.angles[0], cut.velocity0, 0.0], z0_cov=np.diag([sy ** 2, START_SD[0] ** 2, START_SD[1] ** 2]))
            t0 = time.perf_counter()
            angle_loglik_dense(theta[:, 0], cut.angles, cut.angle_ref, plant, **kw)
            t_dense = time.perf_counter() - t0
            fast = timeit(lambda: window_loglik(theta[:, 0], tau_nm, sigma_m, d, cut, plant, sigma_y=sy))
            dense.append({"delay": int(d), "K": dense_K, "dense_s": t_dense, "filter_s": fast["min_s"]})
        value = timeit(lambda: study_loglik(GRADIENT_DELAY, window_loglik))
        grad = timeit(lambda: study_loglik(GRADIENT_DELAY, window_loglik_grad))
        # the fit's Op: every window in one compiled call, as the sampler evaluates it
        op = AngleLoglikOp(wins, plant, delay=GRADIENT_DELAY, sigma_y=sy)
        point = [theta, np.full(len(wins), tau_nm), np.full(len(wins), sigma_m)]
        op_value = timeit(lambda: op.values(point, grad=False))
        op_grad = timeit(lambda: op.values(point))
        gradient = {"delay": GRADIENT_DELAY, "value_s": value["min_s"], "value_grad_s": grad["min_s"],
                    "ratio": grad["min_s"] / value["min_s"], "op_value_s": op_value["min_s"],
                    "op_value_grad_s": op_grad["min_s"]}
        identify = _identify_units(segs, wins, plant, n_identify)
    finally:
        numba.set_num_threads(before)
    return {"n": len(wins), "K": int(segs[0].segment.K), "tau_nm": float(tau_nm), "sigma_m": float(sigma_m),
            "rows": rows, "dense": dense, "gradient": gradient, "identify": identify}


def format_angles(res: dict) -> str:
    """The angle benchmark as a plain-text table."""
    lines = [f"Delayed human from the encoder's angles: log-likelihood (no gradient), {res['n']} windows × "
             f"K = {res['K']}, one core, τ_nm = {res['tau_nm']} s, σ_m = {res['sigma_m']} N·m",
             f"{'delay (samples)':>16} {'min (ms)':>9} {'median (ms)':>12} {'per window (ms)':>16}"]
    for r in res["rows"]:
        lines.append(f"{r['delay']:>16} {r['min_s'] * 1e3:>9.1f} {r['median_s'] * 1e3:>12.1f} "
                     f"{r['min_s'] * 1e3 / res['n']:>16.2f}")
    for r in res["dense"]:
        lines.append(f"  dense joint Gaussian, one window cut to K = {r['K']}, delay {r['delay']}: {r['dense_s']:.3f} s "
                     f"against {r['filter_s'] * 1e3:.2f} ms for the filter ({r['dense_s'] / r['filter_s']:.0f}×)")
    g = res["gradient"]
    lines.append(f"  the whole study at delay {g['delay']} (100 ms): value {g['value_s'] * 1e3:.1f} ms, value and exact "
                 f"gradient {g['value_grad_s'] * 1e3:.1f} ms ({g['ratio']:.2f}× the value)")
    if "op_value_s" in g:
        lines.append(f"  the fit's Op (every window in one compiled call): value {g['op_value_s'] * 1e3:.1f} ms, value "
                     f"and exact gradient {g['op_value_grad_s'] * 1e3:.1f} ms "
                     f"({g['op_value_grad_s'] / g['op_value_s']:.2f}× the value)")
    ident = res["identify"]
    n = len(ident["angles_grid"])
    if n:
        mean = {k: float(np.mean(ident[k][:n])) for k in ("angles", "angles_grid", "torques")}
        lines.append(f"  identifying a unit (one core, the first {n} units): from angles {mean['angles']:.2f} s "
                     f"({np.mean(ident['searched']):.1f} of {ident['grid_size']} delays searched), every delay "
                     f"searched {mean['angles_grid']:.2f} s, from torques {mean['torques']:.2f} s; the same delay from "
                     f"both searches in {sum(ident['same_delay'])} of {n}")
        verdict = {None: "not this size", True: "met", False: "NOT met"}[ident["within_goal"]]
        lines.append(f"  identifying all {len(ident['angles'])} units (one core): from angles "
                     f"{ident['angles_total_s']:.1f} s (max {max(ident['angles']):.2f} s a unit), from torques "
                     f"{ident['torques_total_s']:.1f} s; goal ≤ {IDENTIFY_ANGLES_GOAL_S:.0f} s for the paper's "
                     f"{IDENTIFY_ANGLES_GOAL_UNITS} "
                     f"units and no slower than from torques: {verdict}")
    return "\n".join(lines)


__all__ = ["DELAYS", "GRADIENT_DELAY", "IDENTIFY_ANGLES_GOAL_S", "IDENTIFY_ANGLES_GOAL_UNITS", "N_IDENTIFY",
           "bench_angles", "bench_delayed", "format_angles", "format_delayed"]
