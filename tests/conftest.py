import numpy as np
import pytest

import scioc

scioc.configure()  # before any kernel compiles: numba's cache, PyTensor's fast-math off

from scioc.models.plant import discretize
from scioc.models.segment import Feedback, Segment


@pytest.fixture(scope="session")
def plant():
    return discretize(0.01)


def random_segment(rng: np.random.Generator, K: int, shared: bool) -> Segment:
    """A segment with a smooth random reference, random x0, random torques; random u_A in SC."""
    t = np.arange(K + 1) * 0.01
    ref = rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
    u_A = rng.normal(0.0, 0.3, K) if shared else np.zeros(K)
    return Segment(rng.normal(0.0, 0.1, 2), ref, rng.normal(0.0, 0.5, K), u_A)


def random_window_inputs(rng: np.random.Generator, plant, K: int, M: int, mode: str):
    """A window's inputs for the delayed human's tests: a smooth random reference over K + M + 1 samples, x0, the
    assistant's law and a random u_A (K + M); ``kw`` gives the assistant ``mode`` says ("MC", "SC feedback",
    "SC exogenous") as sample_delayed's keywords. Returns (ref, x0, feedback, u_A, kw)."""
    t = np.arange(K + M + 1) * plant.dt
    ref = rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
    x0 = rng.normal(0.0, 0.1, 2)
    fb = Feedback(np.array([rng.uniform(0.5, 5.0), rng.uniform(0.0, 0.5)]), rng.normal(0.0, 0.3, K + M))
    u_A = rng.normal(0.0, 0.3, K + M)
    kw = {"feedback": fb} if mode == "SC feedback" else {"u_A": u_A} if mode == "SC exogenous" else {}
    return ref, x0, fb, u_A, kw


def random_theta(rng: np.random.Generator, q22_zero: bool) -> np.ndarray:
    return np.array([rng.uniform(1.0, 300.0), 0.0 if q22_zero else rng.uniform(0.01, 2.0), rng.uniform(0.1, 5.0)])
