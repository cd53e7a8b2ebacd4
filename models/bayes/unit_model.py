"""Bayesian model of one unit (one subject in one condition): the per-unit posterior of unit-level SBC.

θ in the paper's normalized parameters (Section V-A), the prior centred on the simulated study's population::

    log θ1 ~ N(log 20, 0.75)      θ1 = q11 / R, 1/rad²
    θ2     ~ HalfNormal(0.05)     θ2 = q22 / R, 1/(rad/s)²
    log R  ~ N(log 20, 0.5)       R, 1/(N·m)², at 100 Hz (R ∝ dt: :meth:`UnitPrior.for_design`)
    u_H    ~ max-ent(θ | x0, angle_ref, u_A)          (paper Eq. 8)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pymc as pm
import pytensor.tensor as pt

from scioc.models.bayes.op import DATA_NAMES, MaxEntLoglikDataOp
from scioc.models.cost import from_normalized
from scioc.models.design import Design
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Names of the parameters SBC ranks.
UNIT_PARAMETERS = ("theta1", "theta2", "R")


@dataclass(frozen=True)
class UnitPrior:
    """Prior of one unit's normalized cost (see the module docstring), R at 100 Hz."""

    log_theta1: tuple[float, float] = (float(np.log(20.0)), 0.75)
    theta2_scale: float = 0.05
    log_R: tuple[float, float] = (float(np.log(20.0)), 0.5)

    @classmethod
    def for_design(cls, design: Design, **overrides) -> "UnitPrior":
        """The prior at ``design``'s sample time: log R's centre + log(dt / 0.01); exactly ``UnitPrior()`` at 100 Hz."""
        base = cls(**overrides)
        centre, sd = base.log_R
        return replace(base, log_R=(centre + math.log(design.r_scale), sd))

    def draw(self, rng: np.random.Generator) -> dict:
        """One draw: ``theta1``, ``theta2``, ``R`` and the raw ``theta`` = [q11, q22, R]."""
        t1 = float(np.exp(rng.normal(*self.log_theta1)))
        t2 = float(abs(rng.normal(0.0, self.theta2_scale)))
        R = float(np.exp(rng.normal(*self.log_R)))
        return {"theta1": t1, "theta2": t2, "R": R, "theta": from_normalized(t1, t2, R)}

    def variance(self, name: str, rng: np.random.Generator, n: int = 20000) -> float:
        """Prior variance of a parameter (by simulation), for posterior contraction."""
        draws = [self.draw(rng)[name] for _ in range(n)]
        return float(np.var(draws))


def build_unit_model(batch: SegmentBatch, plant: DiscretePlant, prior: UnitPrior = UnitPrior()) -> pm.Model:
    """PyMC model of segments sharing one θ: free ``log_theta1``, ``theta2``, ``log_R``, the data in ``pm.Data``
    (:data:`scioc.models.bayes.op.DATA_NAMES`, for ``pm.set_data`` or ``with_data``), the likelihood a potential."""
    op = MaxEntLoglikDataOp(plant)
    with pm.Model() as model:
        data = [pm.Data(name, getattr(batch, name)) for name in DATA_NAMES]
        lt1 = pm.Normal("log_theta1", *prior.log_theta1)
        t2 = pm.HalfNormal("theta2", prior.theta2_scale)
        lR = pm.Normal("log_R", *prior.log_R)
        pm.Deterministic("theta1", pt.exp(lt1))
        R = pm.Deterministic("R", pt.exp(lR))
        n = batch.n
        # θ as models.cost.from_log_normalized writes it, in the graph.
        theta = pt.stack([pt.exp(lt1 + lR) * pt.ones(n), t2 * R * pt.ones(n), R * pt.ones(n)])
        ll, _ = op(theta, *data)
        pm.Potential("loglik", ll.sum())
    return model
