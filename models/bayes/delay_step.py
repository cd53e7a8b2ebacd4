"""Exact sampling of discrete perceptual delays beside NUTS: a Metropolis-within-Gibbs step per group.

The ``delayed`` human's delay d is a whole number of samples on a grid
(:func:`scioc.models.delayed.identify.delay_grid`, 0-300 ms). Its posterior is not smooth in d
(a few nats between neighbours) and, on windows of seconds, wide: on 6-s windows the
likelihood at the true parameters is within 2 nats over 100 ms of delays, and on the
default study each subject (two 15-s windows) keeps a median of 25 of the 31 grid delays
within 10 nats of its best. Conditioning on the best delay (a plug-in) therefore ignores
real uncertainty: the unit-level SBC of the plug-in fails (README "Human models").

Marginalizing the delay inside the likelihood (a log-sum-exp over the grid) is exact but
evaluates 31 delays at every gradient: measured 37 times the plug-in's sampling time for
one 6-s unit. Sampling the delay instead costs a few likelihood evaluations per
iteration. The model gets an integer variable per group (a unit, or a subject whose
segments share one delay), ``delay_index`` with a uniform prior over the grid, and
:class:`DelayMetropolis` updates it while NUTS updates the continuous parameters
(PyMC's compound step: each leaves the joint posterior invariant, so the chain samples
the joint posterior, and its continuous draws are the delay-marginal posterior).

The update. Given everything else, the groups' delays are independent (each group's
delay enters only its own segments' likelihood, and the prior is uniform per group), so
one vectorized Metropolis sweep updates all groups at once: a proposal for every group,
one evaluation of the per-group log-likelihood at the proposed delays, an independent
accept/reject per group. The uniform prior cancels; proposals are symmetric:
alternately a uniform draw from the other grid delays (reaches any delay in one step)
and a local move of 1-3 grid steps (accepted often where the posterior is peaked; a move
off the grid is rejected). :data:`SWEEPS` sweeps per iteration.
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

    Parameters
    ----------
    vars : list with one variable
        The integer delay-index variable (shape (G,) or scalar), uniform over 0..n_grid-1.
    group_loglik : TensorVariable, shape (G,)
        The log-likelihood of each group's data as a graph of the model's random
        variables (it must contain every term that depends on the delay index).
    n_grid : int
        Number of grid delays.
    sweeps : int
        Sweeps per iteration (default :data:`SWEEPS`).
    mode : str, optional
        PyTensor compilation mode of the log-likelihood function (e.g. ``"NUMBA"``).
    model : pymc.Model, optional
    rng : optional
        As PyMC's step methods take it.
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
