"""Benchmark of the ``delayed`` likelihood with gradient on the default study batch, beside the max-ent kernel.

The batch is the default study's windows as ``scioc run`` prepares them, each at its true θ; lag and
motor noise are the simulated humans' (:mod:`scioc.models.humans`), and the delay is varied, since the
kernel's cost depends on them, not on the data. :func:`bench_angles` times the likelihood of the same
windows' encoder angles (:mod:`scioc.models.delayed.angles`) on one core, beside its dense reference.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from scioc.models.delayed import loglik as delayed_loglik
from scioc.models.delayed import loglik_grad as delayed_loglik_grad
from scioc.models.delayed import window_loglik
from scioc.models.delayed.angles import START_SD
from scioc.models.delayed.dense import angle_loglik_dense
from scioc.models.design import STUDY
from scioc.models.humans import MOTOR_SD, TAU_NM
from scioc.models.maxent import loglik_grad as maxent_loglik_grad
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.bench.common import timeit
from scioc.pipelines.identify import angle_windows

#: Delays timed, in samples of 0.01 s (0 to 300 ms).
DELAYS = (0, 10, 30)


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


def bench_angles(study: dict, *, delays=DELAYS, tau_nm: float = TAU_NM, sigma_m: float = MOTOR_SD,
                 preview: float = 2.0, dense_K: int = 500) -> dict:
    """Time the angle likelihood of every window (one core) per delay, and the dense joint Gaussian against the
    filter on the first window cut to ``dense_K`` samples; times in s."""
    plant = discretize(DT_HUMAN)
    segs = study[preview]
    theta = study["theta"]
    sy = STUDY.encoder_sd
    wins = angle_windows(segs, range(len(segs)))
    before = numba.get_num_threads()
    rows, dense = [], []
    try:
        numba.set_num_threads(1)
        for d in delays:
            res = timeit(lambda: [window_loglik(theta[:, i], tau_nm, sigma_m, d, w, plant, sigma_y=sy)
                                  for i, w in enumerate(wins)])
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
    finally:
        numba.set_num_threads(before)
    return {"n": len(wins), "K": int(segs[0].segment.K), "tau_nm": float(tau_nm), "sigma_m": float(sigma_m),
            "rows": rows, "dense": dense}


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
    return "\n".join(lines)


__all__ = ["DELAYS", "bench_angles", "bench_delayed", "format_angles", "format_delayed"]
