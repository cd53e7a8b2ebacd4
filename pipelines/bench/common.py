"""What the benchmarks share: a timer, the machine, and the default study prepared as ``scioc run`` does."""

from __future__ import annotations

import os
import platform
import time
from collections.abc import Callable

import numba
import numpy as np
import scipy

from scioc.models.design import WINDOW_SECONDS
from scioc.models.simulate import simulate_study
from scioc.pipelines.io import validate_table
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.simulate import study_table


def timeit(fn: Callable[[], object], *, min_time: float = 0.3, max_repeat: int = 200) -> dict:
    """Run ``fn`` repeatedly (after one warm-up call); min and median wall time in s."""
    fn()
    times = []
    start = time.perf_counter()
    while len(times) < max_repeat and (len(times) < 3 or time.perf_counter() - start < min_time):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return {"min_s": float(np.min(times)), "median_s": float(np.median(times)), "repeats": len(times)}


def default_study_segments(n_subjects: int = 42, seed: int = 2018, window_seconds: float = WINDOW_SECONDS) -> dict:
    """The default simulated study's windows (``window_seconds`` long), reconstructed as ``scioc run`` does.

    Returns the prepared segments for preview 0 s and 2 s, the true θ (3, n) and the reconstruction times.
    """
    t, sim = simulate_study(n_subjects, np.random.default_rng(np.random.SeedSequence(seed)))
    study = validate_table(study_table(t, sim), "<default study>")
    out = {"theta": np.column_stack([s.theta for s in sim])}
    for preview in (0.0, 2.0):
        prepared = prepare_study(study, IdentifySettings(preview=preview, window_seconds=window_seconds))
        out[preview] = list(prepared.segments)
        out[f"reconstruct_s_{preview}"] = prepared.seconds
    return out


def machine_info() -> dict:
    return {
        "python": platform.python_version(),
        "machine": platform.machine(),
        "processor": platform.processor() or platform.machine(),
        "cpus": os.cpu_count(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
    }
