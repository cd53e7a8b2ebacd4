"""Unit-level SBC replication: one subject in one condition, θ from its prior, one analysis window.

θ ~ :class:`scioc.models.bayes.unit_model.UnitPrior`; one exact max-ent demonstration over the analysis
window from rest (:func:`scioc.pipelines.calibrate.simulation.simulate_unit`); replication i is in level
i mod L of the experiment's L levels (baseline first). The likelihood plans with the assistant's
:class:`scioc.models.segment.Feedback`, as the pipeline does. nutpie runs the chains one after the other
(``cores=1``): the parallelism is across replications.
"""

from __future__ import annotations

import warnings

import numpy as np

from scioc.models.bayes.unit_model import UNIT_PARAMETERS, UnitPrior, build_unit_model
from scioc.models.cost import from_normalized
from scioc.models.design import STUDY, Design
from scioc.pipelines.calibrate.ranking import LOGLIK, Target, loglik_draws, sample_and_rank
from scioc.pipelines.calibrate.simulation import (
    cached,
    config_design,
    fit_plant,
    fitted_batch,
    rest_segment,
    simulate_unit,
)


def compiled_unit(K: int, negative_control, design: Design = STUDY):
    """The unit model compiled by nutpie for windows of K samples of ``design`` (cached per worker)."""

    def build():
        import nutpie  # lazy: nutpie imports numba-compiled PyMC machinery (seconds)

        plant = fit_plant(negative_control, design)
        batch, _ = fitted_batch([rest_segment(K, design)], negative_control, design)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return nutpie.compile_pymc_model(build_unit_model(batch, plant), backend="numba")

    return cached(("unit", K, negative_control, design), build)


def prior_variances(prior: UnitPrior) -> dict:
    """Prior variance of θ1, θ2 and R (by simulation, seed 0; cached per worker)."""
    rng = np.random.default_rng(0)
    return cached(("prior_var", prior), lambda: {name: prior.variance(name, rng) for name in UNIT_PARAMETERS})


def unit_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Replication ``i``: draw θ, simulate one window, fit, rank θ1, θ2, R and the log-likelihood."""
    rng = np.random.default_rng(seed)
    design = config_design(config)
    prior = UnitPrior()
    truth = prior.draw(rng)
    levels = design.ordered_levels
    condition = levels[i % len(levels)]
    seg = simulate_unit(truth["theta"], condition, config.K, config.negative_control, rng, design)
    plant = fit_plant(config.negative_control, design)
    batch, data = fitted_batch([seg], config.negative_control, design)
    compiled = compiled_unit(config.K, config.negative_control, design).with_data(**data)

    def targets(post):
        out = [Target(name, post[name].values, truth[name]) for name in UNIT_PARAMETERS]
        thetas = from_normalized(post["theta1"].values, post["theta2"].values, post["R"].values)  # (3, chain, draw)
        ll = loglik_draws(np.moveaxis(thetas, 0, -1)[..., None], batch, plant)
        return out + [Target(LOGLIK, ll, loglik_draws(np.asarray(truth["theta"], dtype=float)[:, None], batch, plant))]

    out = sample_and_rank(compiled, config, rng, targets, prior_variances(prior))
    return {"condition": condition, **out}
