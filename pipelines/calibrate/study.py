"""Study-level SBC replication: the hierarchical model against studies drawn from its own prior.

Per replication: population and unit parameters drawn by PyMC from the model graph of
:func:`scioc.models.bayes.hierarchical.build_model`; a study simulated exactly from the max-ent model
(:func:`scioc.pipelines.calibrate.simulation.simulate_unit`); the model, compiled once per worker with
``pm.Data`` containers, refitted with nutpie. Ranked: the population parameters (per non-baseline level,
``beta[weak]``, with more than two levels), the first subject's unit parameters, the log-likelihood.
"""

from __future__ import annotations

import warnings

import numpy as np

from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS, build_model
from scioc.models.cost import from_normalized
from scioc.pipelines.calibrate.ranking import LOGLIK, Target, loglik_draws, sample_and_rank
from scioc.pipelines.calibrate.simulation import (
    cached,
    config_design,
    fit_plant,
    fitted_batch,
    rest_segment,
    simulate_unit,
)

#: Unit parameters ranked (first subject), as (variable, condition index).
UNITS = (("log_theta1", 0), ("log_theta1", 1), ("log_R", 0), ("theta2", 0))


def study_labels(n_subjects: int, levels=("MC", "SC")):
    """Subjects and conditions of a simulated study's segments: S00 MC, S00 SC, S01 MC, ... (levels baseline first)."""
    subjects = [f"S{i:02d}" for i in range(n_subjects) for _ in levels]
    return subjects, list(levels) * n_subjects


def population_targets(name: str, draws: np.ndarray, truth, levels) -> list:
    """Targets of one population parameter: ``draws`` (chains, draws) and a scalar ``truth``, or with a contrast
    axis (chains, draws, L - 1) and (L - 1,), one target per non-baseline level of ``levels``."""
    draws = np.asarray(draws, dtype=float)
    if draws.ndim == 2:
        return [Target(name, draws, float(truth))]
    truth = np.asarray(truth, dtype=float)
    return [Target(f"{name}[{level}]", draws[..., j], float(truth[j])) for j, level in enumerate(levels[1:])]


def template(config, negative_control):
    """The hierarchical model with data containers for the study design of ``config`` (cached per worker)."""
    design = config_design(config)
    levels = design.ordered_levels

    def build():
        plant = fit_plant(negative_control, design)
        batch, _ = fitted_batch([rest_segment(config.K, design)] * (len(levels) * config.n_subjects), negative_control,
                                design)
        subjects, conditions = study_labels(config.n_subjects, levels)
        return build_model(subjects, conditions, batch, plant, data_containers=True, levels=levels)

    return cached(("study-model", config.K, config.n_subjects, negative_control, design), build)


def compiled_study(config, negative_control):
    """:func:`template` compiled by nutpie (cached per worker)."""

    def build():
        import nutpie  # lazy: nutpie imports numba-compiled PyMC machinery (seconds)

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return nutpie.compile_pymc_model(template(config, negative_control), backend="numba")

    return cached(("study-compiled", config.K, config.n_subjects, negative_control), build)


def unit_label(v: str, c) -> str:
    """The label of the first subject's ``v``: in level index ``c``, or per subject (``c`` None)."""
    return f"{v}[0]" if c is None else f"{v}[0,{c}]"


def unit_entry(values: np.ndarray, c) -> np.ndarray:
    """The first subject's entry of a (..., subject[, condition]) array (``c`` None: per subject)."""
    return values[..., 0] if c is None else values[..., 0, c]


def unit_targets(post, truth: dict, units) -> list:
    """Targets of the first subject's unit parameters ``units``, (variable, level index or None)."""
    return [Target(unit_label(v, c), unit_entry(post[v].values, c), float(unit_entry(truth[v], c))) for v, c in units]


def prior_values(model, names, rng) -> dict:
    """One draw of the variables ``names`` from ``model``'s own prior (``pm.draw``)."""
    import pymc as pm  # lazy: PyMC takes seconds to import

    values = pm.draw([model[n] for n in names], random_seed=rng)
    return {n: np.asarray(v, dtype=float) for n, v in zip(names, values)}


def prior_variance_table(model, names, population, units, levels) -> dict:
    """Prior variance of every ranked quantity over 4000 draws of ``names`` (seed 0): each ``population``
    parameter (once per non-baseline level where it has a contrast axis) and each of ``units`` (:func:`unit_label`)."""
    import pymc as pm  # lazy: PyMC takes seconds to import

    draws = pm.draw([model[n] for n in names], draws=4000, random_seed=np.random.default_rng(0))
    var = {}
    for n, d in zip(names, draws):
        d = np.asarray(d, dtype=float)
        if n in population:
            if d.ndim == 1:
                var[n] = float(d.var())
            else:  # one per non-baseline level
                for j, level in enumerate(levels[1:]):
                    var[f"{n}[{level}]"] = float(d[:, j].var())
        for v, c in units:
            if v == n:
                var[unit_label(v, c)] = float(unit_entry(d, c).var())
    return var


def prior_draw(config, rng) -> dict:
    """One draw of the population and unit parameters from the model's own prior (``pm.draw``)."""
    names = list(POPULATION_PARAMETERS) + sorted({v for v, _ in UNITS} | {"theta1", "R"})
    return prior_values(template(config, None), names, rng)


def prior_variances(config) -> dict:
    """Prior variance of every ranked parameter (4000 prior draws, seed 0; cached per worker)."""

    def build():
        names = list(POPULATION_PARAMETERS) + sorted({v for v, _ in UNITS})
        return prior_variance_table(template(config, None), names, POPULATION_PARAMETERS, UNITS,
                                    config_design(config).ordered_levels)

    return cached(("study-prior-var", config.K, config.n_subjects, config_design(config)), build)


def study_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Replication ``i``: draw a population and its units, simulate a study, refit, rank."""
    rng = np.random.default_rng(seed)
    design = config_design(config)
    truth = prior_draw(config, rng)
    levels = design.ordered_levels
    segs, thetas = [], []
    for s in range(config.n_subjects):
        for c, condition in enumerate(levels):
            theta = from_normalized(truth["theta1"][s, c], truth["theta2"][s, c], truth["R"][s, c])
            segs.append(simulate_unit(theta, condition, config.K, config.negative_control, rng, design))
            thetas.append(theta)
    plant = fit_plant(config.negative_control, design)
    batch, data = fitted_batch(segs, config.negative_control, design)
    compiled = compiled_study(config, config.negative_control).with_data(**data)

    def targets(post):
        out = [t for n in POPULATION_PARAMETERS for t in population_targets(n, post[n].values, truth[n], levels)]
        out += unit_targets(post, truth, UNITS)
        # θ of every segment per draw, in segment order (subject-major, levels in order, baseline first).
        t1, t2, r = (post[v].values.reshape(post[v].shape[:2] + (-1,)) for v in ("theta1", "theta2", "R"))
        ll = loglik_draws(np.moveaxis(from_normalized(t1, t2, r), 0, -2), batch, plant)
        return out + [Target(LOGLIK, ll, loglik_draws(np.column_stack(thetas), batch, plant))]

    return sample_and_rank(compiled, config, rng, targets, prior_variances(config))
