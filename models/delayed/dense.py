"""The dense references of the ``delayed`` likelihoods: the joint Gaussians of the torques and of the angles,
and of the max-ent human's angles (the ``delayed`` one without delay, lag or motor noise).

The closed loop (:func:`.sample.closed_loop`) is affine in the noises ξ: ``u_H = μ + G ξ``, μ
the loop without noise, G's columns the loop without offsets driven by unit impulses, and
``u_H ~ N(μ, G Cov(ξ) Gᵀ)``. It never uses the recorded states: with the assistant's law it
agrees with the fast kernel when the recorded u_A follows the law. O(K³): for tests only.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from scioc.models.delayed.angles import angle_setup, check_angles
from scioc.models.delayed.sample import closed_loop, delayed_setup
from scioc.models.design import WheelParameters
from scioc.models.lq import lq_policy
from scioc.models.maxent import HALF_LOG_2PI
from scioc.models.plant import DiscretePlant
from scioc.models.segment import Feedback, Segment, check_segment, planning_plant


class DelayedDense(NamedTuple):
    """One window's torques: log-density of the recorded ones (nats), mean (K,) N·m, covariance (K, K) (N·m)²."""

    loglik: float
    mean: np.ndarray
    cov: np.ndarray


def loglik_dense(theta, segment: Segment, plant: DiscretePlant, *, tau_nm: float = 0.0, sigma_m: float = 0.0,
                 delay: int = 0, tau0: float = 0.0, params: WheelParameters = WheelParameters()) -> DelayedDense:
    """log p(u_H) of one window from the dense joint Gaussian; arguments as :func:`.likelihood.loglik_grad`.

    With :class:`scioc.models.segment.Feedback` the assistant is its law and the recorded u_A is
    not used; otherwise the recorded u_A is a given input.
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


class AngleDense(NamedTuple):
    """One window's angles y_0..y_K: log p(y_1..y_K | y_0) (nats), mean (K + 1,) and covariance."""

    loglik: float
    mean: np.ndarray
    cov: np.ndarray


def angle_loglik_dense(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None,
                       feedback: Feedback | None = None, tau_nm: float = 0.0, sigma_m: float = 0.0, delay: int = 0,
                       sigma_y: float, z0_mean, z0_cov, params: WheelParameters = WheelParameters()) -> AngleDense:
    """The dense reference of :func:`.angles.angle_loglik`: the angles' joint Gaussian from the physically lagged loop.

    The covariance comes from the loop driven by the columns of z0_cov's square root and by
    unit impulses in each ε_k and m_k, plus σ_y² on the diagonal; then log N(y) - log N(y_0).
    """
    setup = angle_setup(theta, angle_ref, plant, u_A, feedback, tau_nm, params)
    y, d, mu0, P0 = check_angles(angles, setup.known.shape[0], delay, sigma_m, sigma_y, z0_mean, z0_cov)
    K = y.shape[0] - 1
    pol = setup.policy

    def run(z0, known, f, eps, m):
        return closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                           setup.feedback, known, pol.L, f, z0, eps, m, d, setup.true_A, setup.true_b,
                           setup.physical)[0][:, 0, :]

    mean = run(mu0, setup.known, pol.f, np.zeros((K, 1)), np.zeros((K + d, 1)))[:, 0]
    zero = np.zeros_like(setup.known)
    w, V = np.linalg.eigh(P0)
    root = V * np.sqrt(np.clip(w, 0.0, None))
    cols = [run(root[:, i], zero, zero, np.zeros((K, 1)), np.zeros((K + d, 1))) for i in range(3)]
    eps = np.diag(np.sqrt(0.5 / pol.S[:K]))
    m = float(sigma_m) * np.eye(K + d)
    cols.append(run(np.zeros(3), zero, zero, eps, np.zeros((K + d, K))))
    cols.append(run(np.zeros(3), zero, zero, np.zeros((K, K + d)), m))
    Gm = np.hstack(cols)
    cov = Gm @ Gm.T + float(sigma_y) ** 2 * np.eye(K + 1)
    return AngleDense(_conditional_loglik(y, mean, cov), mean, cov)


def _conditional_loglik(y, mean, cov) -> float:
    """log N(y; mean, cov) - log N(y_0; mean_0, cov_00): the density of y_1..y_K given y_0."""
    K = y.shape[0] - 1
    c = cho_factor(cov, lower=True)
    e = y - mean
    ll_all = -0.5 * e @ cho_solve(c, e) - np.sum(np.log(np.diag(c[0]))) - (K + 1) * HALF_LOG_2PI
    return float(ll_all + 0.5 * e[0] ** 2 / cov[0, 0] + 0.5 * np.log(cov[0, 0]) + HALF_LOG_2PI)


def maxent_angle_loglik_dense(theta, angles, angle_ref, plant: DiscretePlant, *, u_A=None,
                              feedback: Feedback | None = None, sigma_y: float, x0_mean, x0_cov) -> AngleDense:
    """log p(y_1..y_K | y_0) of the paper's max-ent human seen through the encoder, from its dense joint Gaussian.

    The closed loop ``x_{k+1} = A x_k + b (-L_k x_k + f_k + ε_k + u_A,k)`` (A closed by the
    assistant's law with ``feedback``), ``ε_k ~ N(0, 1 / (2 S_k))`` (:func:`scioc.models.lq.lq_policy`),
    stacked over the window; ``y_k = x_k[0] + v_k``, ``v_k ~ N(0, sigma_y²)``, x_0 ~ N(``x0_mean``
    (2,), ``x0_cov`` (2, 2)). The ``delayed`` human with no delay, lag or motor noise. O(K³).
    """
    y = np.asarray(angles, dtype=float)
    K = y.shape[0] - 1
    if feedback is not None:
        pp, known = planning_plant(plant, feedback.gain), np.asarray(feedback.feedforward, dtype=float)
    else:
        pp = plant
        known = np.zeros(len(angle_ref) - 1) if u_A is None else np.asarray(u_A, dtype=float)
    pol = lq_policy(pp, theta, angle_ref, known)
    w, V = np.linalg.eigh(np.asarray(x0_cov, dtype=float))
    x = np.asarray(x0_mean, dtype=float).copy()
    X = np.zeros((2, 2 + K))  # x_k's loading on (x_0's root, ε_0..ε_{K-1})
    X[:, :2] = V * np.sqrt(np.clip(w, 0.0, None))
    mean = np.empty(K + 1)
    rows = np.empty((K + 1, 2 + K))
    mean[0], rows[0] = x[0], X[0]
    for k in range(K):
        F = pp.A - np.outer(pp.b, pol.L[k])
        x = F @ x + pp.b * (pol.f[k] + known[k])
        X = F @ X
        X[:, 2 + k] += pp.b * np.sqrt(0.5 / pol.S[k])
        mean[k + 1], rows[k + 1] = x[0], X[0]
    cov = rows @ rows.T + float(sigma_y) ** 2 * np.eye(K + 1)
    return AngleDense(_conditional_loglik(y, mean, cov), mean, cov)


__all__ = ["AngleDense", "DelayedDense", "angle_loglik_dense", "loglik_dense", "maxent_angle_loglik_dense"]
