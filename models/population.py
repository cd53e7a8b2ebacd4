"""The population the simulated subjects' costs are drawn from, per condition level.

R is stated at the paper's 100 Hz; :mod:`scioc.models.simulate` scales θ to the recording's sample
time (docs/decisions/cost-rate-scaling.md).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np

from scioc.models.cost import from_log_normalized


@dataclass(frozen=True)
class Population:
    """The population θ per subject and condition is drawn from (natural logs). For subject i::

        log θ1[i, MC] ~ N(log_theta1_mc, sd_log_theta1)          θ1 = q11 / R, 1/rad²
        log θ1[i, SC] = log θ1[i, MC] + beta + N(0, sd_change)
        log R[i, MC]  ~ N(log_R, sd_log_R)                      R, 1/(N·m)²
        log R[i, SC]  = log R[i, MC] + gamma + N(0, sd_R_change)
        θ2[i, c] = q22 / R = theta2

    The defaults show the paper's qualitative findings: q22 = 0, and in SC θ1 about halves for nearly
    every subject, with spread. ``betas``: with more levels, each non-baseline level's mean shift
    (empty: ``beta`` each); every level draws its own changes.
    """

    log_theta1_mc: float = float(np.log(20.0))
    sd_log_theta1: float = 0.5
    beta: float = -0.7
    sd_change: float = 0.2
    log_R: float = float(np.log(20.0))
    sd_log_R: float = 0.3
    gamma: float = 0.0
    sd_R_change: float = 0.1
    theta2: float = 0.0
    betas: tuple[float, ...] = ()

    def __post_init__(self):
        if not all(np.isfinite(b) for b in self.betas):
            raise ValueError(f"population parameter betas must be finite; got {self.betas!r}")
        for name, value in asdict(self).items():
            if name == "betas":
                continue
            if not np.isfinite(value):
                raise ValueError(f"population parameter {name} must be finite; got {value!r}")
            if name.startswith("sd") and value < 0:
                raise ValueError(f"population parameter {name} must be >= 0; got {value!r}")
        if self.theta2 < 0:
            raise ValueError(f"population parameter theta2 must be >= 0; got {self.theta2!r}")

    def effects(self, n_contrasts: int) -> tuple[float, ...]:
        """The mean shift of log θ1 of each of ``n_contrasts`` non-baseline levels (``betas``, else ``beta`` each)."""
        betas = tuple(self.betas) if self.betas else (self.beta,) * n_contrasts
        if len(betas) != n_contrasts:
            raise ValueError(f"the population gives {len(betas)} condition effects (betas) for {n_contrasts} "
                             "non-baseline levels")
        return betas


class SubjectTheta(NamedTuple):
    """One subject's true θ per level (``thetas``, baseline first) and the ``order`` its runs were performed in."""

    thetas: tuple
    order: tuple

    @property
    def mc(self) -> np.ndarray:
        return self.thetas[0]

    @property
    def sc(self) -> np.ndarray:
        return self.thetas[1]

    @property
    def sc_first(self) -> bool:
        return self.order[0] == 1


def draw_subjects(population: Population, n_subjects: int, rng: np.random.Generator,
                  n_levels: int = 2) -> list[SubjectTheta]:
    """A :class:`SubjectTheta` for each of ``n_subjects``: θ per level (``n_levels``, baseline first) and run order."""
    if int(n_subjects) != n_subjects or n_subjects < 1:
        raise ValueError(f"n_subjects must be a positive integer; got {n_subjects!r}")
    if int(n_levels) != n_levels or n_levels < 2:
        raise ValueError(f"n_levels must be an integer >= 2; got {n_levels!r}")
    p = population
    c = n_levels - 1
    betas = p.effects(c)
    out = []
    for _ in range(int(n_subjects)):
        # z = (θ1 base, θ1 change per level, R base, R change per level).
        z = rng.standard_normal(2 + 2 * c)
        lt1 = p.log_theta1_mc + p.sd_log_theta1 * z[0]
        lr = p.log_R + p.sd_log_R * z[1 + c]
        thetas = [from_log_normalized(lt1, p.theta2, lr)]
        for j in range(c):
            thetas.append(from_log_normalized(lt1 + betas[j] + p.sd_change * z[1 + j], p.theta2,
                                              lr + p.gamma + p.sd_R_change * z[2 + c + j]))
        if n_levels == 2:
            order = (1, 0) if bool(rng.integers(0, 2)) else (0, 1)
        else:
            order = tuple(int(v) for v in rng.permutation(n_levels))
        out.append(SubjectTheta(tuple(thetas), order))
    return out


__all__ = ["Population", "SubjectTheta", "draw_subjects"]
