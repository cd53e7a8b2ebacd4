import numpy as np
import pytest

from models.plant import discretize
from models.segment import Segment


@pytest.fixture(scope="session")
def plant():
    return discretize(0.01)


def random_segment(rng: np.random.Generator, K: int, shared: bool) -> Segment:
    """A segment with a smooth random reference, random x0, random torques; random u_A in SC."""
    t = np.arange(K + 1) * 0.01
    ref = rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * rng.uniform(0.1, 0.6) * t + rng.uniform(0, 2 * np.pi))
    u_A = rng.normal(0.0, 0.3, K) if shared else np.zeros(K)
    return Segment(rng.normal(0.0, 0.1, 2), ref, rng.normal(0.0, 0.5, K), u_A)


def random_theta(rng: np.random.Generator, q22_zero: bool) -> np.ndarray:
    return np.array([rng.uniform(1.0, 300.0), 0.0 if q22_zero else rng.uniform(0.01, 2.0), rng.uniform(0.1, 5.0)])
