"""Benchmark of the likelihood kernels: dense Eq. 11-16 against the linear-time recursion, one core.

All ratios are measured in the same run on the same machine. BLAS is limited to one
thread while the dense reference runs, so both sides use one core.
"""

from __future__ import annotations

import time
import tracemalloc

import numpy as np
from threadpoolctl import threadpool_limits

from scioc.models.maxent import loglik_grad, sample_maxent
from scioc.models.maxent_dense import loglik_dense
from scioc.models.plant import DT_HUMAN, discretize
from scioc.models.segment import Segment, prepare_batch
from scioc.pipelines.bench.common import timeit

#: Segment lengths compared against the dense reference.
DENSE_K = (250, 500, 1000, 1500)

#: A whole 4-minute run at 100 Hz.
LONG_K = 24000

BENCH_THETA = (60.0, 0.0, 1.0)


def synthetic_segments(n: int, K: int, seed: int = 0) -> list[Segment]:
    """``n`` max-ent demonstrations of length K under :data:`BENCH_THETA` (sines as reference), half with a u_A."""
    rng = np.random.default_rng(seed)
    plant = discretize(DT_HUMAN)
    t = np.arange(K + 1) * DT_HUMAN
    segs = []
    for i in range(n):
        phase = rng.uniform(0, 2 * np.pi, 3)
        ref = 0.25 * np.sin(2 * np.pi * 0.1 * t + phase[0]) + 0.15 * np.sin(2 * np.pi * 0.23 * t + phase[1])
        ref += 0.1 * np.sin(2 * np.pi * 0.47 * t + phase[2])
        u_A = 0.2 * np.sin(2 * np.pi * 0.3 * t[:-1] + phase[0]) if i % 2 else np.zeros(K)
        x0 = np.array([ref[0], 0.0])
        demo = sample_maxent(BENCH_THETA, x0, ref, u_A, plant, rng)
        segs.append(Segment(x0, ref, demo.u_H, u_A))
    return segs


def bench_likelihood(study: dict, *, dense_k=DENSE_K, long_k: int = LONG_K, seed: int = 0) -> dict:
    """Time dense vs linear-time likelihood with gradient per K (``rows``), a whole run (``long``) and the
    study batch of :func:`scioc.pipelines.bench.common.default_study_segments`; times in s."""
    plant = discretize(DT_HUMAN)
    rows = []
    for K in dense_k:
        seg = synthetic_segments(1, K, seed)[0]
        b = prepare_batch(plant, [seg])
        lin = timeit(lambda: loglik_grad(BENCH_THETA, b, plant))
        with threadpool_limits(limits=1):
            dense = timeit(lambda: loglik_dense(BENCH_THETA, seg, plant), min_time=0.0, max_repeat=3)
        rows.append(
            {
                "K": K,
                "dense_s": dense["min_s"],
                "linear_s": lin["min_s"],
                "ratio": dense["min_s"] / lin["min_s"],
                "dense_matrix_bytes": 8 * K * K,
            }
        )
    seg = synthetic_segments(1, long_k, seed)[0]
    tracemalloc.start()
    b = prepare_batch(plant, [seg])
    loglik_grad(BENCH_THETA, b, plant)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    lin = timeit(lambda: loglik_grad(BENCH_THETA, b, plant))
    out = {}
    long = {
        "K": long_k,
        "linear_s": lin["min_s"],
        "linear_peak_bytes": int(peak),
        "dense": "infeasible",
        "dense_matrix_bytes": 8 * long_k * long_k,
    }
    for label, preview in (("batch", 0.0), ("batch_preview", 2.0)):
        segs = [p.segment for p in study[preview]]
        b = prepare_batch(plant, segs)
        thetas = study["theta"]
        lin = timeit(lambda: loglik_grad(thetas, b, plant))
        t0 = time.perf_counter()
        prepare_batch(plant, segs)
        prep = time.perf_counter() - t0
        out[label] = {"n": b.n, "K": b.K, "preview_steps": b.a.shape[1] - b.K, "linear_s": lin["min_s"],
                      "median_s": lin["median_s"], "prepare_s": prep}
    out["rows"], out["long"] = rows, long
    return out


def format_likelihood(res: dict) -> str:
    """The likelihood benchmark as a plain-text table."""
    lines = [
        "Max-ent log-likelihood with gradient, one segment, one core",
        f"{'K':>7} {'dense (s)':>11} {'linear (µs)':>12} {'dense/linear':>13}",
    ]
    for r in res["rows"]:
        lines.append(f"{r['K']:>7} {r['dense_s']:>11.3f} {r['linear_s'] * 1e6:>12.1f} {r['ratio']:>13.0f}")
    lg = res["long"]
    lines.append(
        f"{lg['K']:>7} {'infeasible':>11} {lg['linear_s'] * 1e6:>12.1f} {'':>13}"
        f"  (dense K×K matrix: {lg['dense_matrix_bytes'] / 1e9:.1f} GB; linear peak memory "
        f"{lg['linear_peak_bytes'] / 1e6:.1f} MB)"
    )
    for key, what in (("batch", "the paper's horizon, plan ends with the window"),
                      ("batch_preview", "plan looks 2 s past the window (scioc's default)")):
        bt = res[key]
        lines += [
            "",
            f"Default study batch {bt['n']} segments × K = {bt['K']} ({what}): {bt['linear_s'] * 1e3:.2f} ms "
            f"(median {bt['median_s'] * 1e3:.2f} ms; {bt['linear_s'] / bt['n'] * 1e6:.1f} µs per segment; "
            f"θ-independent state propagation once per data set: {bt['prepare_s'] * 1e3:.1f} ms)",
        ]
    return "\n".join(lines)
