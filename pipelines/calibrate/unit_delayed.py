"""Unit-level SBC replication of the ``delayed`` human: one unit, its parameters from the prior, one window.

θ, τ_nm, σ_m and the delay d ~ :class:`models.bayes.unit_delayed.DelayedUnitPrior`; one
draw of the delayed human over the experiment's analysis window from rest at the
reference (:func:`models.delayed.sample_delayed` with a physical arm: the wheel feels the
arm torque continuously within each sample, the recorded u_H is its ZOH-equivalent
torque, so the likelihood's held-torque convention is part of what is checked);
replication i is in level i mod L of the experiment's levels, and on an assisted level
the human plans with the assistant's law, which acts on the true state. The fit then
runs what the pipeline runs: the delay is the maximum of the profile likelihood
(:func:`models.delayed.identify.identify_unit_delayed`), and the posterior of θ1, θ2, R,
τ_nm and σ_m given that delay is sampled with nutpie
(:func:`models.bayes.unit_delayed.build_unit_delayed_model`). Ranked: those five and the
log-likelihood of the data.

Negative controls (same draws, a wrong fit): ``no-delay`` conditions on d = 0 (a human
whose delay is ignored); ``inertia`` fits with the wheel inertia 10 % too high.
"""

from __future__ import annotations

import warnings

import numpy as np

from models.bayes.unit_delayed import (UNIT_DELAYED_PARAMETERS, DelayedUnitPrior, build_unit_delayed_model,
                                       unit_delayed_data)
from models.delayed import loglik_grad, sample_delayed
from models.delayed.identify import identify_unit_delayed
from models.design import STUDY, Design
from models.plant import discretize
from models.segment import prepare_batch
from pipelines.calibrate.ranking import LOGLIK, Target, sample_and_rank
from pipelines.calibrate.simulation import INERTIA_ERROR, cached, config_design, rest_segment, window_inputs


def fit_wheel(negative_control, design: Design = STUDY):
    """The wheel the fit assumes: the experiment's, or 10 % too heavy for the ``inertia`` negative control."""
    wheel = design.wheel
    if negative_control == "inertia":
        wheel = wheel._replace(inertia=wheel.inertia * (1 + INERTIA_ERROR))
    return wheel


def simulate_unit_delayed(truth: dict, condition: str, K: int, rng: np.random.Generator, design: Design = STUDY):
    """One draw of the delayed human over the analysis window from rest (a Segment with the assistant's Feedback)."""
    ref, laws = window_inputs(K, design)
    fb = laws[condition]
    plant = discretize(design.dt, design.wheel)
    draw = sample_delayed(truth["theta"], [ref[0], 0.0], ref, plant, rng, feedback=fb, tau_nm=truth["tau_nm"],
                          sigma_m=truth["sigma_m"], delay=truth["delay"], params=design.wheel)
    return draw.segments[0]


def compiled_unit_delayed(K: int, negative_control, design: Design = STUDY):
    """The unit model compiled by nutpie for windows of K samples of ``design`` (cached per worker)."""

    def build():
        import nutpie  # lazy: nutpie imports numba-compiled PyMC machinery (seconds)

        wheel = fit_wheel(negative_control, design)
        plant = discretize(design.dt, wheel)
        batch = prepare_batch(plant, [rest_segment(K, design)])
        prior = DelayedUnitPrior.for_design(design)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return nutpie.compile_pymc_model(build_unit_delayed_model(batch, plant, prior, params=wheel),
                                             backend="numba")

    return cached(("unit-delayed", K, negative_control, design), build)


def prior_variances(prior: DelayedUnitPrior) -> dict:
    """Prior variance of every ranked parameter (by simulation, seed 0; cached per worker)."""
    rng = np.random.default_rng(0)
    return cached(("prior_var_delayed", prior),
                  lambda: {name: prior.variance(name, rng, n=5000) for name in UNIT_DELAYED_PARAMETERS})


def unit_delayed_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Replication ``i``: draw the parameters and a window, choose the delay, fit, rank."""
    rng = np.random.default_rng(seed)
    design = config_design(config)
    prior = DelayedUnitPrior.for_design(design)
    truth = prior.draw(rng)
    levels = design.ordered_levels
    condition = levels[i % len(levels)]
    seg = simulate_unit_delayed(truth, condition, config.K, rng, design)
    wheel = fit_wheel(config.negative_control, design)
    plant = discretize(design.dt, wheel)
    batch = prepare_batch(plant, [seg])
    if config.negative_control == "no-delay":
        delay = 0
    else:
        delay = int(identify_unit_delayed([batch], plant, params=wheel).delay)
    compiled = compiled_unit_delayed(config.K, config.negative_control, design)
    compiled = compiled.with_data(**unit_delayed_data(batch, delay))

    def loglik(theta, tau, sig):
        """Summed log-likelihood of the data at each of N parameter sets (theta (3, N))."""
        many = batch.repeat(0, theta.shape[1])
        return loglik_grad(theta, many, plant, tau_nm=tau, sigma_m=sig, delay=delay, params=wheel).loglik

    def targets(post):
        out = [Target(name, post[name].values, truth[name]) for name in UNIT_DELAYED_PARAMETERS]
        shape = post["theta1"].values.shape
        t1, t2, R = (post[v].values.reshape(-1) for v in ("theta1", "theta2", "R"))
        theta = np.vstack([t1 * R, t2 * R, R])
        ll = loglik(theta, post["tau_nm"].values.reshape(-1), post["sigma_m"].values.reshape(-1)).reshape(shape)
        ll_true = loglik(np.asarray(truth["theta"], dtype=float)[:, None], np.array([truth["tau_nm"]]),
                         np.array([truth["sigma_m"]]))[0]
        return out + [Target(LOGLIK, ll, ll_true)]

    out = sample_and_rank(compiled, config, rng, targets, prior_variances(prior))
    return {"condition": condition, "delay_true": int(truth["delay"]), "delay_fit": delay, **out}
