"""The ``delayed`` human: perceptual delay, neuromuscular lag and motor noise, with an exact likelihood.

=========================  ===========================================================
module                     what it holds
=========================  ===========================================================
:mod:`.likelihood`         the model, its derivation, :func:`loglik_grad`, :func:`innovations`
:mod:`.lag`                τ_nm -> (a, α) with derivatives; the plant the human plans on; the
                           arm torque from observed torques (a window's τ_0 from its warm-up)
:mod:`.riccati`            the plan: 3-state LQ recursion, its tape and stationary adjoint (numba)
:mod:`.reverse`            the plan's reverse sweep: its derivative in q11, q22 and the lag (numba)
:mod:`.innovations`        log N(r; 0, Σ) for banded Σ: Schur algorithm, rows, reverse mode (numba)
:mod:`.schur`              one Schur step on a banded Toeplitz generator, and its reverse (numba)
:mod:`.kernel`             one segment and the batch: assembly and chain rule (numba)
:mod:`.sample`             the generative closed loop, :func:`sample_delayed` and :func:`forward_delayed`
:mod:`.dense`              the dense joint Gaussian, the reference of the tests
:mod:`.angles`             the likelihood of the encoder's angles (Kalman filter), for recordings
                           without a torque sensor, and its dense reference
:mod:`.identify`           maximum likelihood: θ, τ_nm, σ_m, and the delay by profile
=========================  ===========================================================

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
