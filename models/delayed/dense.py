"""The dense reference of the ``delayed`` likelihood: the joint Gaussian of the observed torques.

The generative closed loop (:func:`models.delayed.sample.closed_loop`) is affine in the
noises ξ = (ε_0..ε_{K-1}, m_{-d}..m_{K-1}): ``u_H = μ + G ξ``. μ is the loop with every
noise zero; the columns of G are the loop with every offset zero (initial state,
reference, feedforward or recorded u_A) driven by one unit impulse each. With
``ξ ~ N(0, diag(1/(2 S_k), σ_m²))``::

    u_H ~ N(μ, G diag(...) Gᵀ),   log p(u_H) by a Cholesky factorization.

What this conditions on is what the fast kernel conditions on: the initial state z_0 =
(x_0, τ_0), the reference and the plan's known input, the assistant (a given torque
sequence, or its law acting on the simulated state), θ, and the pre-window motor noises
at their prior, independent of z_0. It never uses the recorded states: with the law,
the fast kernel's observed states come from the recorded u_A, so the two agree when the
recorded u_A follows the law (as in a draw of :func:`models.delayed.sample.sample_delayed`).

O(K²) memory and O(K³) time (and O(K² d) for the loop); for tests and the benchmark only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from models.delayed.sample import closed_loop, delayed_setup
from models.design import WheelParameters
from models.maxent import HALF_LOG_2PI
from models.plant import DiscretePlant
from models.segment import Segment, check_segment


class DelayedDense(NamedTuple):
    """The joint Gaussian of one window's observed torques and the log-density of the recorded ones.

    Attributes
    ----------
    loglik : float
        Nats.
    mean : ndarray, shape (K,)
        N·m.
    cov : ndarray, shape (K, K)
        (N·m)².
    """

    loglik: float
    mean: np.ndarray
    cov: np.ndarray


def loglik_dense(theta, segment: Segment, plant: DiscretePlant, *, tau_nm: float = 0.0, sigma_m: float = 0.0,
                 delay: int = 0, tau0: float = 0.0, params: WheelParameters = WheelParameters()) -> DelayedDense:
    """log p(u_H) of one window under the ``delayed`` human, from the dense joint Gaussian.

    Parameters
    ----------
    theta : array_like, shape (3,)
    segment : Segment
        With :class:`models.segment.Feedback` the assistant is its law (the recorded u_A
        is not used); otherwise the recorded u_A is a given input.
    plant : DiscretePlant
    tau_nm, sigma_m, delay, tau0 : float, float, int, float
        As :func:`models.delayed.likelihood.loglik_grad`.
    params : WheelParameters

    Returns
    -------
    DelayedDense
    """
    seg = check_segment(segment)
    K, d = seg.K, int(delay)
    if d != delay or d < 0:
        raise ValueError(f"delay must be a whole number of samples >= 0; got {delay!r}")
    if seg.feedback is None:
        setup = delayed_setup(theta, seg.angle_ref, plant, u_A=seg.u_A, tau_nm=tau_nm, params=params)
    else:
        setup = delayed_setup(theta, seg.angle_ref, plant, feedback=seg.feedback, tau_nm=tau_nm, params=params)
    pol = setup.policy

    def run(z0, known, f, eps, m):
        return closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                           setup.feedback, known, pol.L, f, z0, eps, m, d, setup.true_A, setup.true_b, False)[1]

    z0 = np.array([seg.x0[0], seg.x0[1], float(tau0)])
    mean = run(z0, setup.known, pol.f, np.zeros((K, 1)), np.zeros((K + d, 1)))[:, 0]
    n_xi = 2 * K + d
    eps = np.zeros((K, n_xi))
    m = np.zeros((K + d, n_xi))
    eps[:, :K] = np.eye(K)
    m[:, K:] = np.eye(K + d)
    zero = np.zeros_like(setup.known)
    G = run(np.zeros(3), zero, zero, eps, m)
    var = np.concatenate([0.5 / pol.S[:K], np.full(K + d, float(sigma_m) ** 2)])
    cov = (G * var) @ G.T
    c = cho_factor(cov, lower=True)
    e = seg.u_H - mean
    ll = -0.5 * e @ cho_solve(c, e) - np.sum(np.log(np.diag(c[0]))) - K * HALF_LOG_2PI
    return DelayedDense(float(ll), mean, cov)


__all__ = ["DelayedDense", "loglik_dense"]
