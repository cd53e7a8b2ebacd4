"""The ``delayed`` human: perceptual delay, neuromuscular lag and motor noise, with an exact likelihood.

=========================  ===========================================================
module                     what it holds
=========================  ===========================================================
:mod:`.likelihood`         the model, its derivation, :func:`loglik_grad`, :func:`innovations`
:mod:`.lag`                τ_nm -> (a, α) with derivatives; the plant the human plans on
:mod:`.riccati`            the plan: 3-state LQ recursion with tangents, its adjoint (numba)
:mod:`.innovations`        log N(r; 0, Σ) for banded Σ: Schur algorithm, rows, reverse mode (numba)
:mod:`.kernel`             one segment and the batch: assembly and chain rule (numba)
:mod:`.sample`             the generative closed loop and :func:`sample_delayed`
:mod:`.dense`              the dense joint Gaussian, the reference of the tests
=========================  ===========================================================

With delay, lag and motor noise at zero the model is the paper's (:mod:`models.maxent`).
"""

from models.delayed.dense import DelayedDense, loglik_dense
from models.delayed.lag import LagCoefficients, LaggedPlanningPlant, lag_coefficients, lagged_planning_plant
from models.delayed.likelihood import PARAMETERS, DelayedLoglikGrad, innovations, loglik_grad
from models.delayed.sample import DelayedDraw, closed_loop, sample_delayed

__all__ = [
    "PARAMETERS",
    "DelayedDense",
    "DelayedDraw",
    "DelayedLoglikGrad",
    "LagCoefficients",
    "LaggedPlanningPlant",
    "closed_loop",
    "innovations",
    "lag_coefficients",
    "lagged_planning_plant",
    "loglik_dense",
    "loglik_grad",
    "sample_delayed",
]
