"""Bayesian model of one unit of the ``delayed`` human: the per-unit posterior that unit-level SBC checks.

The max-ent unit model (:mod:`scioc.models.bayes.unit_model`) with the lag and motor noise, θ the commands' cost::

    log θ1 ~ N(log 20, 0.75)      θ2 ~ HalfNormal(0.05)      log R ~ N(log 20, 0.5)
    log τ_nm ~ N(log 0.06, 0.5)   σ_m ~ HalfNormal(0.3)      d ~ uniform on the delay grid (0-300 ms)
    u_H ~ delayed(θ, τ_nm, σ_m, d | x0, angle_ref, assistant, τ_0)

or, for a rig without a torque sensor, the encoder's angles ~ delayed(θ, τ_nm, σ_m, d | the window's start, ...)
(:func:`build_unit_angle_model`).

τ_nm's prior covers the neuromuscular time constants of manual control (about 0.1 s: McRuer & Jex 1967; Kleinman,
Baron & Levison 1970), σ_m's KBL's motor noise (0.25 N·m per sample) with room on both sides. The delay is
sampled (docs/decisions/delayed-plugin-delay.md), or given (the ``no-delay`` negative control gives 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
import pymc as pm
import pytensor.tensor as pt

from scioc.models.bayes.angle_op import ANGLE_DATA_NAMES, AngleLoglikDataOp, angle_data
from scioc.models.bayes.delay_step import DelayMetropolis
from scioc.models.bayes.delayed_op import DELAYED_DATA_NAMES, DelayedLoglikDataOp, pack_tau0
from scioc.models.bayes.delayed_value import DelayedLoglikValueOp  # noqa: F401 (registers its rewrite)
from scioc.models.bayes.op import DATA_NAMES
from scioc.models.cost import from_normalized
from scioc.models.delayed.angles import AngleWindow
from scioc.models.delayed.identify import delay_grid
from scioc.models.design import Design, WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Names of the parameters SBC ranks.
UNIT_DELAYED_PARAMETERS = ("theta1", "theta2", "R", "tau_nm", "sigma_m")
#: Name of the sampled delay's grid index in a model with ``delay=None``.
DELAY_INDEX = "delay_index"


@dataclass(frozen=True)
class DelayedUnitPrior:
    """Prior of one unit of the ``delayed`` human (module docstring), R at 100 Hz."""

    log_theta1: tuple[float, float] = (float(np.log(20.0)), 0.75)
    theta2_scale: float = 0.05
    log_R: tuple[float, float] = (float(np.log(20.0)), 0.5)
    log_tau_nm: tuple[float, float] = (float(np.log(0.06)), 0.5)
    sigma_m_scale: float = 0.3
    dt: float = 0.01

    @classmethod
    def for_design(cls, design: Design, **overrides) -> DelayedUnitPrior:
        """The prior at ``design``'s sample time: log R's centre + log(dt / 0.01), the delay grid at dt."""
        base = cls(**overrides)
        centre, sd = base.log_R
        return replace(base, log_R=(centre + math.log(design.r_scale), sd), dt=float(design.dt))

    def delays(self) -> np.ndarray:
        """The delay grid, samples."""
        return delay_grid(self.dt)

    def draw(self, rng: np.random.Generator) -> dict:
        """One draw: ``theta1``, ``theta2``, ``R``, ``tau_nm``, ``sigma_m``, ``delay`` (samples) and ``theta``."""
        t1 = float(np.exp(rng.normal(*self.log_theta1)))
        t2 = float(abs(rng.normal(0.0, self.theta2_scale)))
        R = float(np.exp(rng.normal(*self.log_R)))
        tau = float(np.exp(rng.normal(*self.log_tau_nm)))
        sig = float(abs(rng.normal(0.0, self.sigma_m_scale)))
        grid = self.delays()
        d = int(grid[rng.integers(grid.shape[0])])
        return {"theta1": t1, "theta2": t2, "R": R, "tau_nm": tau, "sigma_m": sig, "delay": d,
                "theta": from_normalized(t1, t2, R)}

    def variance(self, name: str, rng: np.random.Generator, n: int = 20000) -> float:
        """Prior variance of a parameter (by simulation), for posterior contraction."""
        return float(np.var([self.draw(rng)[name] for _ in range(n)]))


def unit_delayed_data(batch: SegmentBatch, delay, tau0=0.0) -> dict:
    """The model's data containers for ``batch`` with the given delay(s) (samples; None: sampled) and τ_0."""
    warm, start, tstart = pack_tau0(tau0, batch.n)
    d = np.ascontiguousarray(np.broadcast_to(np.asarray(0 if delay is None else delay, dtype=np.int64), (batch.n,)))
    return {**{name: getattr(batch, name) for name in DATA_NAMES}, "delay": d, "warm": warm, "warm_start": start,
            "tau_start": tstart}


def _delay_input(prior: DelayedUnitPrior, n: int):
    """The sampled delay's grid index (uniform) and the delay it gives each of n windows, samples."""
    grid = prior.delays()
    index = pm.DiscreteUniform(DELAY_INDEX, 0, grid.shape[0] - 1)
    return pt.as_tensor(grid.astype(np.int64))[index] * pt.ones(n, "int64")


def _unit_parameters(prior: DelayedUnitPrior, n: int):
    """The unit's priors (module docstring): θ (3, n) as q11, q22, R, and τ_nm, σ_m (n,)."""
    lt1 = pm.Normal("log_theta1", *prior.log_theta1)
    t2 = pm.HalfNormal("theta2", prior.theta2_scale)
    lR = pm.Normal("log_R", *prior.log_R)
    ltau = pm.Normal("log_tau_nm", *prior.log_tau_nm)
    sig = pm.HalfNormal("sigma_m", prior.sigma_m_scale)
    pm.Deterministic("theta1", pt.exp(lt1))
    R = pm.Deterministic("R", pt.exp(lR))
    tau = pm.Deterministic("tau_nm", pt.exp(ltau))
    ones = pt.ones(n)
    theta = pt.stack([pt.exp(lt1 + lR) * ones, t2 * R * ones, R * ones])
    return theta, tau * ones, sig * ones


def build_unit_delayed_model(batch: SegmentBatch, plant: DiscretePlant, prior: DelayedUnitPrior = DelayedUnitPrior(),
                             *, delay=0, tau0=0.0, params: WheelParameters = WheelParameters()) -> pm.Model:
    """PyMC model of one unit's segments (one θ, τ_nm, σ_m) under the ``delayed`` human, data in ``pm.Data``,
    the likelihood a potential. ``delay``: the delay conditioned on, samples, or None to sample one (``delay_index``,
    with :class:`UnitDelayedSampler`); ``tau0``: as :func:`scioc.models.bayes.delayed_op.pack_tau0`."""
    op = DelayedLoglikDataOp(plant, params)
    values = unit_delayed_data(batch, delay, tau0)
    n = batch.n
    with pm.Model() as model:
        data = [pm.Data(name, values[name]) for name in DELAYED_DATA_NAMES]
        if delay is None:
            data[DELAYED_DATA_NAMES.index("delay")] = _delay_input(prior, n)
        ll, _ = op(*_unit_parameters(prior, n), *data)
        pm.Potential("loglik", ll.sum())
    return model


def unit_angle_data(windows: Sequence[AngleWindow], delay) -> dict:
    """The angle model's data containers for ``windows`` with the given delay(s) (samples; None: sampled)."""
    return angle_data(windows, 0 if delay is None else delay)


def build_unit_angle_model(windows: Sequence[AngleWindow], plant: DiscretePlant,
                           prior: DelayedUnitPrior = DelayedUnitPrior(), *, sigma_y: float, delay=0,
                           params: WheelParameters = WheelParameters()) -> pm.Model:
    """:func:`build_unit_delayed_model` of a unit's recorded angles (:class:`scioc.models.delayed.AngleWindow`), read
    by an encoder of noise SD ``sigma_y``, rad: the likelihood :class:`scioc.models.bayes.angle_op.AngleLoglikDataOp`'s,
    the windows in ``pm.Data``."""
    op = AngleLoglikDataOp(plant, sigma_y=sigma_y, params=params)
    values = unit_angle_data(windows, delay)
    n = len(windows)
    with pm.Model() as model:
        data = [pm.Data(name, values[name]) for name in ANGLE_DATA_NAMES]
        if delay is None:
            data[ANGLE_DATA_NAMES.index("delay")] = _delay_input(prior, n)
        ll, _ = op(*_unit_parameters(prior, n), *data)
        pm.Potential("loglik", ll.sum())
    return model


class UnitDelayedSampler:
    """A sampled-delay unit model with its NUTS and :class:`scioc.models.bayes.delay_step.DelayMetropolis` steps
    compiled once (numba) for every data set of one shape; :meth:`sample` swaps the data in and restores the steps'
    initial state, so a fit does not depend on the fits before it. Built by :meth:`of_torques` or :meth:`of_angles`."""

    def __init__(self, model: pm.Model, prior: DelayedUnitPrior, data: dict):
        self.shapes = {name: np.shape(v) for name, v in data.items()}
        self.model = model
        with self.model:
            continuous = [v for v in self.model.free_RVs if v.name != DELAY_INDEX]
            nuts = pm.NUTS(continuous, compile_kwargs={"mode": "NUMBA"})
            delay = DelayMetropolis([self.model[DELAY_INDEX]], self.model["loglik"][None], prior.delays().shape[0],
                                    mode="NUMBA")
        self.steps = [nuts, delay]
        self._initial = [step.sampling_state for step in self.steps]

    @classmethod
    def of_torques(cls, batch: SegmentBatch, plant: DiscretePlant, prior: DelayedUnitPrior = DelayedUnitPrior(), *,
                   params: WheelParameters = WheelParameters()) -> UnitDelayedSampler:
        """For segments of ``batch``'s shapes (:func:`build_unit_delayed_model`); data by :func:`unit_delayed_data`."""
        return cls(build_unit_delayed_model(batch, plant, prior, delay=None, params=params), prior,
                   unit_delayed_data(batch, None))

    @classmethod
    def of_angles(cls, windows: Sequence[AngleWindow], plant: DiscretePlant,
                  prior: DelayedUnitPrior = DelayedUnitPrior(), *, sigma_y: float,
                  params: WheelParameters = WheelParameters()) -> UnitDelayedSampler:
        """For windows of ``windows``' lengths (:func:`build_unit_angle_model`); data by :func:`unit_angle_data`."""
        return cls(build_unit_angle_model(windows, plant, prior, sigma_y=sigma_y, delay=None, params=params), prior,
                   unit_angle_data(windows, None))

    def sample(self, data: dict, *, draws: int, tune: int, chains: int, seed: int):
        """Sample the posterior given ``data`` (the model's containers, of the built shapes), chains in turn: PyMC's
        DataTree."""
        shapes = {name: np.shape(v) for name, v in data.items()}
        if shapes != self.shapes:
            raise ValueError(f"the sampler was built for data of shapes {self.shapes}; got {shapes}")
        for step, state in zip(self.steps, self._initial):
            step.sampling_state = state
        with self.model:
            pm.set_data(data)
            return pm.sample(draws=draws, tune=tune, chains=chains, cores=1, step=self.steps, random_seed=seed,
                             progressbar=False, quiet=True, compute_convergence_checks=False,
                             compile_kwargs={"mode": "NUMBA"})


__all__ = ["DELAY_INDEX", "UNIT_DELAYED_PARAMETERS", "DelayedUnitPrior", "UnitDelayedSampler",
           "build_unit_angle_model", "build_unit_delayed_model", "unit_angle_data", "unit_delayed_data"]
