"""Unit-level SBC replication of the ``delayed`` human: one unit, its parameters from the prior, one window.

θ, τ_nm, σ_m and the delay d ~ :class:`scioc.models.bayes.unit_delayed.DelayedUnitPrior`; one draw over the
analysis window, exactly as the fitted likelihood describes it:

- ``torques``: from rest, the torque held over each sample (:func:`scioc.models.delayed.sample_delayed` with
  ``physical=False``), the human's torques recorded;
- ``angles``: on the physically lagged wheel, the velocity and arm torque at the start drawn from the angle
  likelihood's start prior (:data:`scioc.models.delayed.angles.START_SD`), the angles read with Gaussian noise of
  the experiment's encoder SD.

The fit samples θ1, θ2, R, τ_nm, σ_m and the delay together
(:class:`scioc.models.bayes.unit_delayed.UnitDelayedSampler`: NUTS and
:class:`scioc.models.bayes.delay_step.DelayMetropolis`), so the delay's uncertainty reaches the other
parameters. Ranked: those and the log-likelihood. Negative controls: ``no-delay`` conditions on d = 0
(sampled with nutpie), ``inertia`` fits a wheel 10 % too heavy.
"""

from __future__ import annotations

import warnings

import numpy as np

from scioc.models.bayes.angle_op import AngleLoglikOp
from scioc.models.bayes.unit_delayed import (
    DELAY_INDEX,
    UNIT_DELAYED_PARAMETERS,
    DelayedUnitPrior,
    UnitDelayedSampler,
    build_unit_angle_model,
    build_unit_delayed_model,
    unit_angle_data,
    unit_delayed_data,
)
from scioc.models.delayed import loglik_grad, sample_delayed
from scioc.models.delayed.angles import START_SD, AngleWindow
from scioc.models.design import STUDY, Design
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.calibrate.ranking import LOGLIK, Target, sample_and_rank
from scioc.pipelines.calibrate.simulation import INERTIA_ERROR, cached, config_design, rest_segment, window_inputs


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
                          sigma_m=truth["sigma_m"], delay=truth["delay"], params=design.wheel, physical=False)
    return draw.segments[0]


def simulate_unit_angles(truth: dict, condition: str, K: int, rng: np.random.Generator, design: Design = STUDY):
    """One draw of the delayed human over the analysis window as the encoder records it (an AngleWindow)."""
    ref, laws = window_inputs(K, design)
    if not design.encoder_sd > 0:
        raise ValueError("the angle calibration reads the angles through the experiment's encoder: "
                         "encoder.counts_per_rev must be > 0")
    plant = discretize(design.dt, design.wheel)
    vel0, tau0 = rng.normal(0.0, START_SD)
    draw = sample_delayed(truth["theta"], [ref[0], vel0], ref, plant, rng, feedback=laws[condition],
                          tau_nm=truth["tau_nm"], sigma_m=truth["sigma_m"], delay=truth["delay"], tau0=tau0,
                          params=design.wheel)
    angles = draw.x[:, 0] + rng.normal(0.0, design.encoder_sd, K + 1)
    return AngleWindow(angles, ref, None, laws[condition], 0.0, None)


def rest_window(K: int, design: Design = STUDY) -> AngleWindow:
    """A placeholder window (angles at 0) that gives the angle model its shapes before the data."""
    ref = window_inputs(K, design)[0]
    return AngleWindow(np.zeros(K + 1), ref, None, None, 0.0, None)


def _build(K: int, negative_control, design: Design, likelihood: str, delay):
    """The unit model of ``likelihood`` for windows of K samples, the delay given (0) or sampled (None)."""
    wheel = fit_wheel(negative_control, design)
    plant = discretize(design.dt, wheel)
    prior = DelayedUnitPrior.for_design(design)
    if likelihood == "angles":
        windows = [rest_window(K, design)]
        if delay is None:
            return UnitDelayedSampler.of_angles(windows, plant, prior, sigma_y=design.encoder_sd, params=wheel)
        return build_unit_angle_model(windows, plant, prior, sigma_y=design.encoder_sd, delay=delay, params=wheel)
    batch = prepare_batch(plant, [rest_segment(K, design)])
    if delay is None:
        return UnitDelayedSampler.of_torques(batch, plant, prior, params=wheel)
    return build_unit_delayed_model(batch, plant, prior, delay=delay, params=wheel)


def compiled_unit_delayed(K: int, negative_control, design: Design = STUDY, likelihood: str = "torques"):
    """The unit model with the delay at 0, compiled by nutpie for windows of K samples of ``design`` (cached per
    worker)."""

    def build():
        import nutpie  # lazy: nutpie imports numba-compiled PyMC machinery (seconds)

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return nutpie.compile_pymc_model(_build(K, negative_control, design, likelihood, 0), backend="numba")

    return cached(("unit-delayed", K, negative_control, design, likelihood), build)


def unit_delayed_sampler(K: int, negative_control, design: Design = STUDY,
                         likelihood: str = "torques") -> UnitDelayedSampler:
    """The sampled-delay unit model and its steps, compiled once per worker for windows of K samples of ``design``."""
    return cached(("unit-delayed-sampled", K, negative_control, design, likelihood),
                  lambda: _build(K, negative_control, design, likelihood, None))


def prior_variances(prior: DelayedUnitPrior) -> dict:
    """Prior variance of every ranked parameter (by simulation, seed 0; cached per worker)."""
    rng = np.random.default_rng(0)
    return cached(("prior_var_delayed", prior),
                  lambda: {name: prior.variance(name, rng, n=5000) for name in UNIT_DELAYED_PARAMETERS})


def _observe(config, truth, condition, rng, design, wheel, plant):
    """(the model's data with the delay at 0, loglik(θ (3, N), τ_nm (N,), σ_m (N,), delay (N,)) -> (N,)) of one
    simulated unit, as the configuration's likelihood sees it."""
    if config.likelihood == "angles":
        window = simulate_unit_angles(truth, condition, config.K, rng, design)

        def loglik(theta, tau, sig, delay):
            out = np.empty(theta.shape[1])
            for d in np.unique(delay):  # one Op per delay among the points
                at = np.flatnonzero(delay == d)
                op = AngleLoglikOp([window], plant, delay=int(d), sigma_y=design.encoder_sd, params=wheel)
                out[at] = op.window_values(0, theta[:, at], tau[at], sig[at])
            return out

        return unit_angle_data([window], 0), loglik
    seg = simulate_unit_delayed(truth, condition, config.K, rng, design)
    batch = prepare_batch(plant, [seg])

    def loglik(theta, tau, sig, delay):
        many = batch.repeat(0, theta.shape[1])
        return loglik_grad(theta, many, plant, tau_nm=tau, sigma_m=sig, delay=delay, params=wheel).loglik

    return unit_delayed_data(batch, 0), loglik


def unit_delayed_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Replication ``i``: draw the parameters and a window, fit (the delay sampled, or 0 for ``no-delay``), rank."""
    rng = np.random.default_rng(seed)
    design = config_design(config)
    prior = DelayedUnitPrior.for_design(design)
    truth = prior.draw(rng)
    levels = design.ordered_levels
    condition = levels[i % len(levels)]
    wheel = fit_wheel(config.negative_control, design)
    plant = discretize(design.dt, wheel)
    data, loglik = _observe(config, truth, condition, rng, design, wheel, plant)
    grid = prior.delays()
    if config.negative_control == "no-delay":
        compiled = compiled_unit_delayed(config.K, config.negative_control, design, config.likelihood)
        compiled = compiled.with_data(**data)
        sample = None
    else:
        compiled = None
        sampler = unit_delayed_sampler(config.K, config.negative_control, design, config.likelihood)

        def sample(seed):
            return sampler.sample(data, draws=config.draws, tune=config.tune, chains=config.chains, seed=seed)

    delays = []

    def targets(post):
        out = [Target(name, post[name].values, truth[name]) for name in UNIT_DELAYED_PARAMETERS]
        shape = post["theta1"].values.shape
        t1, t2, R = (post[v].values.reshape(-1) for v in ("theta1", "theta2", "R"))
        theta = np.vstack([t1 * R, t2 * R, R])
        d = (grid[post[DELAY_INDEX].values.reshape(-1).astype(int)] if DELAY_INDEX in post
             else np.zeros(theta.shape[1], dtype=np.int64))
        delays.append(d)
        ll = loglik(theta, post["tau_nm"].values.reshape(-1), post["sigma_m"].values.reshape(-1), d).reshape(shape)
        ll_true = loglik(np.asarray(truth["theta"], dtype=float)[:, None], np.array([truth["tau_nm"]]),
                         np.array([truth["sigma_m"]]), np.array([truth["delay"]]))[0]
        return out + [Target(LOGLIK, ll, ll_true)]

    out = sample_and_rank(compiled, config, rng, targets, prior_variances(prior), sample=sample)
    extra = {}
    if sample is not None:
        post = delays[0]  # every draw's delay, samples
        extra = {"delay_mean": float(post.mean()), "delay_below": float(np.mean(post < truth["delay"])),
                 "delay_equal": float(np.mean(post == truth["delay"]))}
    return {"condition": condition, "delay_true": int(truth["delay"]), **extra, **out}
