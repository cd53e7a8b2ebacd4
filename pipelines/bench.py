"""``scioc bench``: measured speed of the likelihood kernels (and, as they arrive, the workflow).

All ratios are measured in the same run on the same machine. BLAS is limited to one
thread while the dense reference runs, so both sides use one core.
"""

from __future__ import annotations

import json
import os
import platform
import time
import tracemalloc
from collections.abc import Callable

import numpy as np
from threadpoolctl import threadpool_limits

from models.design import WINDOW_SECONDS
from models.maxent import loglik_grad, sample_maxent
from models.maxent_dense import loglik_dense
from models.plant import DT_HUMAN, discretize
from models.segment import Segment, prepare_batch

#: Segment lengths compared against the dense reference.
DENSE_K = (250, 500, 1000, 1500)
#: A whole 4-minute run at 100 Hz.
LONG_K = 24000
BENCH_THETA = (60.0, 0.0, 1.0)


def _timeit(fn: Callable[[], object], *, min_time: float = 0.3, max_repeat: int = 200) -> dict:
    """Run ``fn`` repeatedly (after one warm-up call); min and median wall time in s."""
    fn()
    times = []
    start = time.perf_counter()
    while len(times) < max_repeat and (len(times) < 3 or time.perf_counter() - start < min_time):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return {"min_s": float(np.min(times)), "median_s": float(np.median(times)), "repeats": len(times)}


def synthetic_segments(n: int, K: int, seed: int = 0) -> list[Segment]:
    """``n`` max-ent demonstrations of length K under :data:`BENCH_THETA`, half with a random u_A.

    The reference is a sum of three sines (0.1-0.5 Hz, about ±0.5 rad); what matters for
    speed is only K.
    """
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
    """Time dense vs linear-time likelihood with gradient, the long run and the study batch.

    ``study`` comes from :func:`default_study_segments`.

    Returns
    -------
    dict
        ``rows`` (one per K with dense and linear timings and their ratio), ``long``
        and ``batch`` entries; times in seconds.
    """
    plant = discretize(DT_HUMAN)
    rows = []
    for K in dense_k:
        seg = synthetic_segments(1, K, seed)[0]
        b = prepare_batch(plant, [seg])
        lin = _timeit(lambda: loglik_grad(BENCH_THETA, b, plant))
        with threadpool_limits(limits=1):
            dense = _timeit(lambda: loglik_dense(BENCH_THETA, seg, plant), min_time=0.0, max_repeat=3)
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
    lin = _timeit(lambda: loglik_grad(BENCH_THETA, b, plant))
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
        lin = _timeit(lambda: loglik_grad(thetas, b, plant))
        t0 = time.perf_counter()
        prepare_batch(plant, segs)
        prep = time.perf_counter() - t0
        out[label] = {"n": b.n, "K": b.K, "preview_steps": b.a.shape[1] - b.K, "linear_s": lin["min_s"],
                      "median_s": lin["median_s"], "prepare_s": prep}
    out["rows"], out["long"] = rows, long
    return out


def default_study_segments(n_subjects: int = 42, seed: int = 2018, window_seconds: float = WINDOW_SECONDS) -> dict:
    """The default simulated study's analysis windows, reconstructed from the angle as ``scioc run`` does.

    ``window_seconds`` shortens the window (from its usual start) for studies with less
    data per unit. Returns a dict with the prepared segments for preview 0 s and 2 s, the
    true θ per segment (3, n) and the reconstruction time.
    """
    from models.simulate import simulate_study
    from pipelines.identify import IdentifySettings, prepare_segment
    from pipelines.io import validate_table
    from pipelines.simulate import study_table

    t, sim = simulate_study(n_subjects, np.random.default_rng(np.random.SeedSequence(seed)))
    study = validate_table(study_table(t, sim), "<default study>")
    plant = discretize(DT_HUMAN)
    out = {"theta": np.column_stack([s.theta for s in sim])}
    for preview in (0.0, 2.0):
        t0 = time.perf_counter()
        settings = IdentifySettings(preview=preview, window_seconds=window_seconds)
        out[preview] = [prepare_segment(seg, settings, plant) for seg in study.segments]
        out[f"reconstruct_s_{preview}"] = time.perf_counter() - t0
    return out


def bench_identify(study: dict) -> dict:
    """Wall time of maximum-likelihood identification of every segment, of its reconstruction, and of the
    model-adequacy checks (bootstrap included) at the default settings, as a fraction of the two."""
    from models.identify import identify_segment
    from pipelines.adequacy import assess_study
    from pipelines.identify import IdentifySettings, paper_assistant

    plant = discretize(DT_HUMAN)
    out = {}
    for preview in (0.0, 2.0):
        batches = [prepare_batch(plant, [p.segment]) for p in study[preview]]
        identify_segment(batches[0], plant)  # compile
        t0 = time.perf_counter()
        ests = [identify_segment(b, plant) for b in batches]
        out[f"preview_{preview:g}s"] = {
            "segments": len(batches),
            "identify_s": time.perf_counter() - t0,
            "reconstruct_s": study[f"reconstruct_s_{preview}"],
            "converged": int(sum(e.converged for e in ests)),
        }
    settings = IdentifySettings()
    kw = {"assistant_model": settings.assistant_model, "resolution": settings.resolution,
          "n_boot": settings.adequacy_boot, "seed": settings.adequacy_seed, "assistant": paper_assistant()}
    assess_study(study[2.0][:2], [e.theta for e in ests[:2]], plant, **kw)  # compile
    t0 = time.perf_counter()
    _, verdict = assess_study(study[2.0], [e.theta for e in ests], plant, **kw)
    r = out["preview_2s"]
    r["adequacy_s"] = time.perf_counter() - t0
    r["adequacy_boot"] = settings.adequacy_boot
    r["adequacy_verdict"] = verdict["verdict"]
    r["adequacy_fraction_of_identify"] = r["adequacy_s"] / (r["identify_s"] + r["reconstruct_s"])
    return out


def machine_info() -> dict:
    import numba
    import scipy

    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
    }


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


def format_identify(res: dict) -> str:
    lines = ["", "Identification of every segment of the default study (SLSQP, exact gradient, one core)"]
    for key, r in res.items():
        lines.append(
            f"  {key}: {r['segments']} segments in {r['identify_s']:.2f} s ({r['converged']} converged); "
            f"reconstruction from the angle beforehand: {r['reconstruct_s']:.2f} s"
        )
        if "adequacy_s" in r:
            lines.append(
                f"    model adequacy ({r['adequacy_boot']} bootstrap data sets per segment, verdict "
                f"{r['adequacy_verdict']}): {r['adequacy_s']:.2f} s = {r['adequacy_fraction_of_identify']:.0%} of "
                f"reconstruction + identification (goal: <= 50 %)")
    return "\n".join(lines)


def bench_sbc(n_reps: int = 200, seed: int = 99) -> dict:
    """Unit-level SBC throughput with one and with two local Dask workers.

    Wall time includes starting the cluster and compiling the model once per worker (about
    15 s), so ``n_reps`` is large enough for the fits to dominate.
    """
    import tempfile

    from pipelines.calibrate import CalibrationConfig, calibrate

    out = {}
    for workers in (1, 2):
        cfg = CalibrationConfig(level="unit", replications=n_reps, seed=seed, batch_size=5)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            summary = calibrate(cfg, tmp, n_workers=workers, show_progress=False)
            wall = time.perf_counter() - t0
        out[f"{workers}_worker"] = {"replications": n_reps, "wall_s": wall, "reps_per_s": n_reps / wall,
                                    "fit_s_per_rep": summary["fit_seconds_total"] / n_reps}
    out["speedup_2_vs_1"] = out["1_worker"]["wall_s"] / out["2_worker"]["wall_s"]
    return out


def format_sbc(res: dict) -> str:
    lines = ["", "Unit-level SBC throughput (K = 1500, 2 chains × 500 draws, wall time incl. cluster start and compiling)"]
    for key in ("1_worker", "2_worker"):
        r = res[key]
        lines.append(f"  {key.replace('_', ' ')}: {r['replications']} replications in {r['wall_s']:.1f} s = "
                     f"{r['reps_per_s']:.2f} per s ({r['fit_s_per_rep']:.2f} s per fit)")
    lines.append(f"  speed-up with two workers: {res['speedup_2_vs_1']:.2f}×")
    return "\n".join(lines)


#: The parts of ``scioc bench``, in the order they run.
PARTS = ("likelihood", "identify", "fit", "sbc")


def run_bench(json_path=None, *, quick: bool = False, parts=PARTS) -> dict:
    """Run the benchmarks; print tables; optionally write JSON (atomically).

    Parameters
    ----------
    json_path : str or Path, optional
    quick : bool
        Smaller sizes (for tests of the command itself; not for quoting). Leaves out the
        fit and SBC parts, which have no small version worth timing.
    parts : sequence of str
        Any of :data:`PARTS`. The fit's dense comparison needs the likelihood part.
    """
    from pipelines.io import write_text_atomic

    unknown = set(parts) - set(PARTS)
    if unknown:
        raise ValueError(f"unknown benchmark part(s) {sorted(unknown)}; choose from {', '.join(PARTS)}")
    kw = {"dense_k": (50, 100), "long_k": 2000} if quick else {}
    study = default_study_segments(n_subjects=2 if quick else 42)
    result = {"machine": machine_info(), "quick": quick}
    if "likelihood" in parts:
        result["likelihood"] = bench_likelihood(study, **kw)
        print(format_likelihood(result["likelihood"]), flush=True)
    if "identify" in parts:
        result["identify"] = bench_identify(study)
        print(format_identify(result["identify"]), flush=True)
    if "fit" in parts and not quick:
        from pipelines.bench_fit import bench_fit, format_fit

        lik = result.get("likelihood", {})
        dense = {r["K"]: r["dense_s"] for r in lik.get("rows", [])}
        K = study[2.0][0].segment.K
        result["fit"] = bench_fit(study, dense_s_per_segment=dense.get(K),
                                  linear_s_per_batch=lik.get("batch_preview", {}).get("linear_s"))
        print(format_fit(result["fit"]), flush=True)
    if "sbc" in parts and not quick:
        result["sbc"] = bench_sbc()
        print(format_sbc(result["sbc"]), flush=True)
    if json_path is not None:
        write_text_atomic(json_path, json.dumps(result, indent=2) + "\n")
    return result
