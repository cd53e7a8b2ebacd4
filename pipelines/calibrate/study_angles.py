"""Study-level SBC replication of the ``delayed`` human's fit from the encoder's angles.

Per replication: the population and unit parameters drawn by PyMC from the hierarchical angle model's own graph
(:func:`scioc.models.bayes.angle_model.build_angle_model` with the log-normal population of R, which ``scioc fit``
chooses or replaces by the data; here the fit keeps the one the studies are drawn from), each subject's delay
uniform on the delay grid; each subject × level window simulated as the unit level's
(:func:`scioc.pipelines.calibrate.unit_delayed.simulate_unit_angles`). The model is refitted as ``scioc fit`` samples
it (:func:`fit_study`: whitened coordinates curved along each subject's ridge, the pilot runs, nutpie), from PyMC's
initial point, given the true delays (``no-delay``: given 0). The fit conditions on the delays, so this calibrates
the model, its likelihood and its sampler; what fixing each subject's delay at its profile maximum costs is
measured by recovery (docs/decisions/delayed-angle-fit.md). Ranked: the population parameters, the first subject's
unit parameters and the log-likelihood.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from scioc.models.bayes.angle_model import ANGLE_PARAMETERIZATION, build_angle_model
from scioc.models.bayes.angle_op import AngleLoglikOp
from scioc.models.bayes.delayed_blocks import DELAYED_POPULATION_PARAMETERS, DelayedForm, DelayedPriors, ridge_pivots
from scioc.models.bayes.delayed_model import nutpie_options
from scioc.models.bayes.hierarchical import POPULATION_PARAMETERS
from scioc.models.cost import from_normalized
from scioc.models.delayed.identify import delay_grid
from scioc.models.plant import discretize
from scioc.pipelines.calibrate.ranking import LOGLIK, Target, sample_and_rank
from scioc.pipelines.calibrate.simulation import cached, config_design
from scioc.pipelines.calibrate.study import (
    population_targets,
    prior_values,
    prior_variance_table,
    study_labels,
    unit_targets,
)
from scioc.pipelines.calibrate.unit_delayed import fit_wheel, rest_window, simulate_unit_angles
from scioc.pipelines.fit.delayed_forms import THETA2_FORM, log_R_form
from scioc.pipelines.fit.warmup import pilot_runs
from scioc.pipelines.fit.whiten import sample_whitened

#: Unit parameters ranked (first subject): (variable, condition index or None for a per-subject one).
UNITS = (("log_theta1", 0), ("log_theta1", 1), ("log_R", 0), ("theta2", 0), ("tau_nm", None), ("sigma_m", None))


#: What the studies are drawn from and fitted with: the log-normal population of R and the default block forms.
DELAYED_PRIORS = DelayedPriors()
DELAYED_FORM = DelayedForm()


def fit_parameterization():
    """The cost blocks' forms as ``scioc fit`` gives them with :data:`DELAYED_FORM`."""
    log_R, _ = log_R_form(DELAYED_FORM)
    return replace(ANGLE_PARAMETERIZATION, R_mc=log_R, R_sc=log_R, theta2=THETA2_FORM)


def study_model(windows, config, negative_control, delays):
    """The hierarchical angle model of a simulated study's windows, given each window's delay."""
    design = config_design(config)
    wheel = fit_wheel(negative_control, design)
    subjects, conditions = study_labels(config.n_subjects, design.ordered_levels)
    return build_angle_model(subjects, conditions, windows, discretize(design.dt, wheel), delay=delays,
                             sigma_y=design.encoder_sd, delayed_priors=DELAYED_PRIORS,
                             parameterization=fit_parameterization(), delayed_form=DELAYED_FORM,
                             levels=design.ordered_levels, params=wheel)


def template(config):
    """The model on placeholder windows, for the prior draws (cached per worker)."""
    design = config_design(config)

    def build():
        windows = [rest_window(config.K, design)] * (config.n_subjects * len(design.ordered_levels))
        return study_model(windows, config, None, 0)

    return cached(("study-angles-model", config.K, config.n_subjects, design), build)


def fit_study(model, config, seed: int):
    """Sample ``model`` as ``scioc fit`` samples the delayed model with profile delays, from PyMC's initial point."""
    pivots = ridge_pivots(DELAYED_PRIORS, DELAYED_FORM, config.n_subjects)
    idata, _, _ = sample_whitened(model, None, seed=seed, chains=config.chains, draws=config.draws, tune=config.tune,
                                  cores=1, nuts=nutpie_options(False), pivots=pivots,
                                  pilot=pilot_runs("profile", config.tune, config.draws, config.chains))
    return idata


def population_names(model) -> list:
    """The population parameters this model has (the R population's form decides which)."""
    return [n for n in (*POPULATION_PARAMETERS, *DELAYED_POPULATION_PARAMETERS) if n in model.named_vars]


def _drawn(config) -> list:
    model = template(config)
    return population_names(model) + sorted({v for v, _ in UNITS} | {"theta1", "R"})


def prior_draw(config, rng) -> dict:
    """One draw of the population and unit parameters from the model's own prior (``pm.draw``)."""
    return prior_values(template(config), _drawn(config), rng)


def prior_variances(config) -> dict:
    """Prior variance of every ranked parameter (4000 prior draws, seed 0; cached per worker)."""

    def build():
        model = template(config)
        return prior_variance_table(model, _drawn(config), population_names(model), UNITS,
                                    config_design(config).ordered_levels)

    return cached(("study-angles-prior-var", config.K, config.n_subjects, config_design(config)), build)


def study_angle_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Replication ``i``: draw a population, its units and delays, simulate a study's angles, refit, rank."""
    rng = np.random.default_rng(seed)
    design = config_design(config)
    truth = prior_draw(config, rng)
    levels = design.ordered_levels
    grid = delay_grid(design.dt)
    delays = grid[rng.integers(grid.shape[0], size=config.n_subjects)]
    windows, thetas, window_delays, taus, sigmas = [], [], [], [], []
    for s in range(config.n_subjects):
        for c, condition in enumerate(levels):
            theta = from_normalized(truth["theta1"][s, c], truth["theta2"][s, c], truth["R"][s, c])
            unit = {"theta": theta, "tau_nm": float(truth["tau_nm"][s]), "sigma_m": float(truth["sigma_m"][s]),
                    "delay": int(delays[s])}
            windows.append(simulate_unit_angles(unit, condition, config.K, rng, design))
            thetas.append(theta)
            window_delays.append(int(delays[s]))
            taus.append(unit["tau_nm"])
            sigmas.append(unit["sigma_m"])
    given = np.zeros(len(windows), dtype=np.int64) if config.negative_control == "no-delay" else window_delays
    model = study_model(windows, config, config.negative_control, given)
    wheel = fit_wheel(config.negative_control, design)
    op = AngleLoglikOp(windows, discretize(design.dt, wheel), delay=given, sigma_y=design.encoder_sd, params=wheel)

    def loglik(theta, tau, sig) -> float:
        return float(op.values([theta, tau, sig], grad=False)[0].sum())

    def targets(post):
        out = [t for n in population_names(model) for t in population_targets(n, post[n].values, truth[n], levels)]
        out += unit_targets(post, truth, UNITS)
        # every window's parameters per draw, in window order (subject-major, levels in order)
        t1, t2, r = (post[v].values.reshape(post[v].shape[:2] + (-1,)) for v in ("theta1", "theta2", "R"))
        th = from_normalized(t1, t2, r)  # (3, chains, draws, windows)
        n_levels = len(levels)
        tau = np.repeat(post["tau_nm"].values, n_levels, axis=-1)
        sig = np.repeat(post["sigma_m"].values, n_levels, axis=-1)
        ll = np.array([[loglik(th[:, a, b], tau[a, b], sig[a, b]) for b in range(th.shape[2])]
                       for a in range(th.shape[1])])
        true = loglik(np.column_stack(thetas), np.array(taus), np.array(sigmas))
        return out + [Target(LOGLIK, ll, true)]

    res = sample_and_rank(None, config, rng, targets, prior_variances(config),
                          sample=lambda seed: fit_study(model, config, seed))
    return {"delays_true": [int(d) for d in delays], **res}


__all__ = ["DELAYED_FORM", "DELAYED_PRIORS", "UNITS", "fit_parameterization", "fit_study", "population_names",
           "prior_draw", "prior_variances", "study_angle_replication", "study_model", "template"]
