"""The ``delayed`` human: perceptual delay, neuromuscular lag and motor noise, with an exact likelihood.

- :mod:`.likelihood`: the model; :func:`loglik_grad`, :func:`innovations`
- :mod:`.lag`: τ_nm -> (a, α); the planning plant; the arm torque from observed torques
- :mod:`.riccati`, :mod:`.reverse`: the plan (3-state LQ recursion) and its reverse sweep (numba)
- :mod:`.innovations`, :mod:`.schur`: log N(r; 0, Σ) for banded Σ and its reverse mode (numba)
- :mod:`.kernel`: one segment and the batch: assembly and chain rule (numba)
- :mod:`.sample`: the generative closed loop, :func:`sample_delayed`, :func:`forward_delayed`
- :mod:`.dense`: the dense joint Gaussians, references of the tests
- :mod:`.angles`: the likelihood of encoder angles (Kalman filter), without a torque sensor
- :mod:`.identify`, :mod:`.search`: maximum likelihood, the delay by profile
- :mod:`.bootstrap`: the parametric bootstrap of the adequacy checks

With delay, lag and motor noise at zero the model is the paper's (:mod:`scioc.models.maxent`).
"""

from scioc.models.delayed.angles import AngleWindow, angle_loglik, window_loglik
from scioc.models.delayed.dense import DelayedDense, loglik_dense
from scioc.models.delayed.identify import DELAY_GRID_S, DelayedEstimate, delay_grid, identify_unit_delayed
from scioc.models.delayed.lag import (
                                ArmTorque,
                                LagCoefficients,
                                LaggedPlanningPlant,
                                Warmup,
                                arm_torque,
                                lag_coefficients,
                                lagged_planning_plant,
                                window_tau0,
)
from scioc.models.delayed.likelihood import PARAMETERS, DelayedLoglikGrad, innovations, loglik, loglik_grad
from scioc.models.delayed.sample import DelayedDraw, closed_loop, forward_delayed, sample_delayed

__all__ = [
    "AngleWindow",
    "angle_loglik",
    "window_loglik",
    "DELAY_GRID_S",
    "PARAMETERS",
    "ArmTorque",
    "DelayedEstimate",
    "Warmup",
    "arm_torque",
    "delay_grid",
    "identify_unit_delayed",
    "window_tau0",
    "DelayedDense",
    "DelayedDraw",
    "DelayedLoglikGrad",
    "LagCoefficients",
    "LaggedPlanningPlant",
    "closed_loop",
    "forward_delayed",
    "innovations",
    "lag_coefficients",
    "lagged_planning_plant",
    "loglik",
    "loglik_dense",
    "loglik_grad",
    "sample_delayed",
]
