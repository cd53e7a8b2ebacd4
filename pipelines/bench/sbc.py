"""Benchmark of simulation-based calibration: unit-level throughput with one and with two Dask workers."""

from __future__ import annotations

import tempfile
import time

from scioc.pipelines.calibrate import CalibrationConfig, calibrate


def bench_sbc(n_reps: int = 200, seed: int = 99) -> dict:
    """Unit-level SBC throughput with one and with two local Dask workers; ``n_reps`` is large enough for the
    fits to outweigh starting the cluster and compiling once per worker."""
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
