"""The ``delayed`` human: perceptual delay, neuromuscular lag and motor noise, with an exact likelihood.

- :mod:`.likelihood`: the model; :func:`loglik_grad`, :func:`innovations`
- :mod:`.lag`: τ_nm -> (a, α); the planning plant; the arm torque from observed torques
- :mod:`.riccati`, :mod:`.reverse`: the plan (3-state LQ recursion) and its reverse sweep (numba)
- :mod:`.innovations`, :mod:`.schur`: log N(r; 0, Σ) for banded Σ and its reverse mode (numba)
- :mod:`.kernel`: one segment and the batch: assembly and chain rule (numba)
- :mod:`.sample`: the generative closed loop, :func:`sample_delayed`, :func:`forward_delayed`
- :mod:`.dense`: the dense joint Gaussians (torques, angles, the max-ent human's angles), references of the tests
- :mod:`.angles`: the likelihood of encoder angles without a torque sensor, and its exact gradient
- :mod:`.kalman`, :mod:`.angle_kernel`: its Kalman filter with the reverse sweep, and one window's kernel (numba)
- :mod:`.identify`, :mod:`.search`: maximum likelihood, the delay by profile
- :mod:`.bootstrap`: the parametric bootstrap of the adequacy checks

With delay, lag and motor noise at zero the model is the paper's (:mod:`scioc.models.maxent`).
"""

from scioc.models.delayed.angles import (
                                AngleLoglikGrad,
                                AngleWindow,
                                angle_loglik,
                                angle_loglik_grad,
                                window_loglik,
                                window_loglik_grad,
)
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
    "DELAY_GRID_S",
    "PARAMETERS",
    "AngleLoglikGrad",
    "AngleWindow",
    "ArmTorque",
    "DelayedDense",
    "DelayedDraw",
    "DelayedEstimate",
    "DelayedLoglikGrad",
    "LagCoefficients",
    "LaggedPlanningPlant",
    "Warmup",
    "angle_loglik",
    "angle_loglik_grad",
    "arm_torque",
    "closed_loop",
    "delay_grid",
    "forward_delayed",
    "identify_unit_delayed",
    "innovations",
    "lag_coefficients",
    "lagged_planning_plant",
    "loglik",
    "loglik_dense",
    "loglik_grad",
    "sample_delayed",
    "window_loglik",
    "window_loglik_grad",
    "window_tau0",
]
