"""Leave-one-subject-out of the ``delayed`` hierarchical model: its terms in the integrated importance sampling.

:class:`DelayedSubjectTerms` adds a subject's lag and motor noise to
:func:`scioc.models.bayes.subject_loo.subject_loglik`: to the Student-t proposal as (log τ_nm, log σ_m), their
Jacobians in the weights, and for half the points τ_nm from its population on a grid of s_τ (where the data leave
τ_nm near 0, the target under each draw is that half-normal cut off at its s_τ, which a t fitted to draws pooled
over all s_τ misses); to the conditional prior, with the baseline log R of a ``policy_scale`` or ``unpooled``
population; and the segments' likelihood is the delayed one at each segment's plug-in delay. A subject's elpd is
then comparable between the human models: both are densities of the same torques.
"""

from __future__ import annotations

import numpy as np
from scipy import special

from scioc.models.bayes.delayed_op import pack_tau0, warmups_of
from scioc.models.bayes.subject_loo import halfnorm_logpdf
from scioc.models.cost import from_normalized
from scioc.models.delayed.lag import arm_torque, lag_coefficients
from scioc.models.delayed.likelihood import loglik_grad
from scioc.models.design import WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.segment import SegmentBatch

#: Points of the geometric grid of the population scale s_τ in the proposal's population half.
SCALE_GRID = 64


class DelayedSubjectTerms:
    """The lag and motor-noise terms (``extra``) of :func:`scioc.models.bayes.subject_loo.subject_loglik`.

    ``post``: flattened draws (S first) of ``tau_nm``, ``sigma_m`` (S, n_subjects), ``tau_nm_scale``,
    ``sigma_m_scale`` and ``rho_scale`` if any (S,); ``batch``, ``plant``, ``delay`` (samples), ``tau0``, ``params``
    as the model was built; ``chunk`` points per kernel call; ``baseline_log_R_prior``: (m, s) of an ``unpooled`` model.
    """

    def __init__(self, post: dict, batch: SegmentBatch, plant: DiscretePlant, delay, tau0=0.0,
                 params: WheelParameters = WheelParameters(), chunk: int = 256, baseline_log_R_prior=None):
        self._population(post, baseline_log_R_prior)
        self.batch, self.plant, self.params, self.chunk = batch, plant, params, int(chunk)
        self.delay = np.broadcast_to(np.asarray(delay, dtype=np.int64), (batch.n,))
        self.warmups = warmups_of(tau0, batch.n)
        self.tau0_fixed = pack_tau0(tau0, batch.n)[2] if self.warmups is None else None

    def _population(self, post: dict, baseline_log_R_prior) -> None:
        """The draws of τ_nm, σ_m and their population scales, and the population of the baseline log R."""
        self.log_tau = np.log(np.asarray(post["tau_nm"], dtype=float))
        self.log_sig = np.log(np.asarray(post["sigma_m"], dtype=float))
        self.s_t = np.asarray(post["tau_nm_scale"], dtype=float)[:, None]
        self.s_m = np.asarray(post["sigma_m_scale"], dtype=float)[:, None]
        lo = self.s_t.min() + 1e-300
        self.grid = np.geomspace(lo, max(self.s_t.max() + 1e-300, lo), SCALE_GRID)
        if "rho_scale" in post:  # R_population="policy_scale": ρ = R^(-1/2) ~ HalfNormal(s_ρ)
            self.s_rho = np.asarray(post["rho_scale"], dtype=float)[:, None]
            self.baseline_log_R_logpdf = self._policy_scale_logpdf
        if baseline_log_R_prior is not None:  # R_population="unpooled": a fixed N(m, s) per subject
            if "rho_scale" in post:
                raise ValueError("baseline_log_R_prior is the unpooled model's; these draws have a policy_scale population")
            self.m_R, self.s_R = (float(v) for v in baseline_log_R_prior)
            self.n_draws = self.s_t.shape[0]
            self.baseline_log_R_logpdf = self._unpooled_logpdf

    def columns(self, i: int) -> list:
        """Posterior draws of subject i's (log τ_nm, log σ_m), each (S,)."""
        return [self.log_tau[:, i], self.log_sig[:, i]]

    def representable(self, z: np.ndarray) -> np.ndarray:
        """(M,) bool: τ_nm = exp(z[:, 0]) and σ_m = exp(z[:, 1]) are finite (elsewhere their prior is 0)."""
        with np.errstate(over="ignore"):
            return np.all(np.isfinite(np.exp(z)), axis=1)

    #: The columns (of :meth:`columns`) the proposal also draws from their population: log τ_nm.
    grid_columns = (0,)

    def prior_grid_draw(self, rng: np.random.Generator, M: int) -> np.ndarray:
        """(M, 1) points log τ_nm, τ_nm from HalfNormal(s) with s drawn from the grid of s_τ."""
        return np.log(np.abs(self.grid[rng.integers(0, SCALE_GRID, M)] * rng.standard_normal(M)))[:, None]

    def prior_grid_logpdf(self, z: np.ndarray) -> np.ndarray:
        """(M,): the density of :meth:`prior_grid_draw` at z (M, 1), the Jacobian τ_nm included."""
        tau = np.exp(z[:, 0])
        mix = special.logsumexp(halfnorm_logpdf(tau[:, None], self.grid[None, :]), axis=1) - np.log(SCALE_GRID)
        return mix + z[:, 0]

    def log_prior(self, z: np.ndarray) -> np.ndarray:
        """(S, M): log p(log τ_nm, log σ_m | ψ_s) at the M points z (M, 2), the Jacobians τ_nm σ_m included."""
        tau, sig = np.exp(z[:, 0]), np.exp(z[:, 1])
        return (halfnorm_logpdf(tau[None, :], self.s_t) + halfnorm_logpdf(sig[None, :], self.s_m)
                + (z[:, 0] + z[:, 1])[None, :])

    def _policy_scale_logpdf(self, log_R: np.ndarray) -> np.ndarray:
        """(S, M): log p(log R[i, baseline] | s_ρ) of ρ = exp(-log R / 2) ~ HalfNormal(s_ρ), Jacobian ρ/2 included."""
        rho = np.exp(-0.5 * np.asarray(log_R, dtype=float))
        return halfnorm_logpdf(rho[None, :], self.s_rho) + (np.log(0.5 * rho))[None, :]

    def _unpooled_logpdf(self, log_R: np.ndarray) -> np.ndarray:
        """(S, M): log N(log R[i, baseline]; m, s), the same under every draw."""
        z = (np.asarray(log_R, dtype=float) - self.m_R) / self.s_R
        row = -0.5 * z * z - np.log(self.s_R) - 0.5 * np.log(2.0 * np.pi)
        return np.broadcast_to(row[None, :], (self.n_draws, row.shape[0]))

    def _tau0(self, j: int, tau: np.ndarray) -> np.ndarray:
        if self.warmups is None:
            return np.full(tau.shape[0], self.tau0_fixed[j])
        w = self.warmups[j]
        if w is None:
            return np.zeros(tau.shape[0])
        lag = lag_coefficients(tau, self.plant.dt, self.params)
        return np.array([arm_torque(w.u, a, al, w.tau_start).tau[-1] for a, al in zip(lag.a, lag.alpha)])

    def segment_loglik(self, j: int, lt1, lR, t2, z) -> np.ndarray:
        """Exact delayed log-likelihood of segment j at the M points (cost and (log τ_nm, log σ_m) z)."""
        M = lt1.shape[0]
        tau, sig = np.exp(z[:, 0]), np.exp(z[:, 1])
        out = np.empty(M)
        for a in range(0, M, self.chunk):
            b = min(M, a + self.chunk)
            theta = from_normalized(np.exp(lt1[a:b]), t2[a:b], np.exp(lR[a:b]))
            out[a:b] = loglik_grad(theta, self.batch.repeat(j, b - a), self.plant, tau_nm=tau[a:b],
                                   sigma_m=sig[a:b], delay=int(self.delay[j]), tau0=self._tau0(j, tau[a:b]),
                                   params=self.params).loglik
        return out


class AngleSubjectTerms(DelayedSubjectTerms):
    """:class:`DelayedSubjectTerms` of a fit scored by the encoder's angles: each window's angle likelihood
    (``op``, an :class:`scioc.models.bayes.angle_op.AngleLoglikOp` of the fitted windows at their delays)."""

    def __init__(self, post: dict, op, baseline_log_R_prior=None):
        self._population(post, baseline_log_R_prior)
        self.op = op

    def segment_loglik(self, j: int, lt1, lR, t2, z) -> np.ndarray:
        theta = from_normalized(np.exp(lt1), t2, np.exp(lR))
        return self.op.window_values(j, theta, np.exp(z[:, 0]), np.exp(z[:, 1]))


class MaxentAngleTerms:
    """The terms (``extra``) of :func:`scioc.models.bayes.subject_loo.subject_loglik` that score the max-ent human by
    the encoder's angles: no parameters besides the cost, each window's angle likelihood with no delay, lag or motor
    noise (``op`` built with delay 0)."""

    def __init__(self, op):
        self.op = op

    def columns(self, i: int) -> list:
        return []

    def log_prior(self, z: np.ndarray) -> float:
        return 0.0

    def segment_loglik(self, j: int, lt1, lR, t2, z) -> np.ndarray:
        theta = from_normalized(np.exp(lt1), t2, np.exp(lR))
        zero = np.zeros(lt1.shape[0])
        return self.op.window_values(j, theta, zero, zero)


__all__ = ["AngleSubjectTerms", "DelayedSubjectTerms", "MaxentAngleTerms", "SCALE_GRID"]
