"""Exact sampling of discrete perceptual delays beside NUTS: a Metropolis-within-Gibbs step per group.

Each group (a unit, or a subject's segments) has an integer ``delay_index``, uniform over the delay grid. PyMC's
compound step leaves the joint posterior invariant, so the continuous draws are delay-marginal
(docs/decisions/delayed-plugin-delay.md). The groups' delays are independent given the rest, so one vectorized
sweep proposes for every group, evaluates the per-group log-likelihood once, and accepts each on its own. The
symmetric proposals alternate a uniform draw from the other grid delays and a local move of up to
:data:`LOCAL_STEP` grid steps (off the grid: rejected).
"""

from __future__ import annotations

import numpy as np
import pymc as pm
from pymc.step_methods.compound import BlockedStep, StepMethodState
from pymc.util import get_random_generator, get_value_vars_from_user_vars

#: Metropolis sweeps over all groups per sampler iteration (half uniform, half local proposals).
SWEEPS = 4
#: Largest local move, grid steps.
LOCAL_STEP = 3


class DelayMetropolis(BlockedStep):
    """Metropolis-within-Gibbs update of per-group delay indices (module docstring).

    ``vars``: the integer delay-index variable ((G,) or scalar, uniform over 0..``n_grid``-1); ``group_loglik`` (G,):
    each group's log-likelihood, a graph with every term the index enters; ``sweeps`` per iteration; ``mode``:
    PyTensor's compilation mode of ``group_loglik``; ``model``, ``rng``: as PyMC's steps.
    """

    name = "delay_metropolis"
    stats_dtypes_shapes = {"delay_accept": (np.float64, [])}
    _state_class = StepMethodState

    def __init__(self, vars, group_loglik, n_grid: int, *, sweeps: int = SWEEPS, mode=None, model=None, rng=None,
                 blocked: bool = True):
        model = pm.modelcontext(model)
        vars = get_value_vars_from_user_vars(vars, model)
        if len(vars) != 1:
            raise ValueError("DelayMetropolis updates exactly one delay-index variable")
        self.vars = vars
        self.var_names = [vars[0].name]
        self.n_grid = int(n_grid)
        if self.n_grid < 2:
            raise ValueError(f"n_grid must be >= 2; got {n_grid}")
        self.sweeps = int(sweeps)
        (out,) = model.replace_rvs_by_values([group_loglik])
        self.loglik = model.compile_fn(out, inputs=model.value_vars, on_unused_input="ignore", point_fn=True,
                                       mode=mode)
        self.rng = get_random_generator(rng)
        self.blocked = blocked

    def _proposal(self, idx: np.ndarray, sweep: int) -> np.ndarray:
        if sweep % 2 == 0:
            return (idx + self.rng.integers(1, self.n_grid, size=idx.shape)) % self.n_grid
        step = self.rng.integers(1, LOCAL_STEP + 1, size=idx.shape) * self.rng.choice([-1, 1], size=idx.shape)
        return idx + step

    def step(self, point):
        name = self.var_names[0]
        idx = np.asarray(point[name]).copy()
        current = np.asarray(self.loglik(point), dtype=float).reshape(idx.shape)
        accepted = 0.0
        for sweep in range(self.sweeps):
            prop = self._proposal(idx, sweep)
            inside = (prop >= 0) & (prop < self.n_grid)
            trial = np.where(inside, prop, idx).astype(idx.dtype)
            new = np.asarray(self.loglik({**point, name: trial}), dtype=float).reshape(idx.shape)
            with np.errstate(invalid="ignore"):
                ok = inside & (np.log(self.rng.random(idx.shape)) < new - current)
            idx = np.where(ok, trial, idx).astype(idx.dtype)
            current = np.where(ok, new, current)
            accepted += float(np.mean(ok))
        return {**point, name: idx}, [{"delay_accept": accepted / self.sweeps}]

    @staticmethod
    def competence(var, has_grad):
        from pymc.step_methods.compound import Competence

        return Competence.INCOMPATIBLE


__all__ = ["LOCAL_STEP", "SWEEPS", "DelayMetropolis"]
