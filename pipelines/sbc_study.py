"""Study-level SBC replications: the hierarchical model against studies drawn from its own prior.

Per replication: population and unit parameters are drawn from the prior of
:func:`models.bayes.hierarchical.build_model` (by PyMC itself, from the model graph, so the
draws follow exactly the model that is fitted); a whole study is simulated exactly from
the max-ent model (``n_subjects`` × MC and SC, windows of K samples of the study
reference from rest; in SC the human plans with the assistant's law and the assistant
reacts to the sampled trajectory, :func:`pipelines.sbc_replications.simulate_unit`);
the model compiled once per
worker (data in ``pm.Data`` containers) is refitted with nutpie; ranks of the population
parameters and of the first subject's unit parameters are recorded.

The negative controls are those of the unit level (:mod:`pipelines.sbc_replications`).
"""

from __future__ import annotations

import warnings

import numpy as np

from models.bayes.hierarchical import POPULATION_PARAMETERS
from models.cost import from_normalized
from models.sbc import rank, thin
from models.segment import Segment, prepare_batch
from pipelines.sbc_replications import _CACHE, _fit_plant, _reference, batch_data, simulate_unit

#: Unit parameters ranked (first subject), as (variable, condition index).
UNITS = (("log_theta1", 0), ("log_theta1", 1), ("log_R", 0), ("theta2", 0))


def _labels(n_subjects: int):
    subjects = [f"S{i:02d}" for i in range(n_subjects) for _ in range(2)]
    conditions = ["MC", "SC"] * n_subjects
    return subjects, conditions


def _template(config, negative_control):
    key = ("study-model", config.K, config.n_subjects, negative_control)
    if key not in _CACHE:
        from models.bayes.hierarchical import build_model

        plant = _fit_plant(negative_control)
        ref = _reference(config.K)
        seg = Segment(np.array([ref[0], 0.0]), ref, np.zeros(config.K), np.zeros(config.K))
        batch = prepare_batch(plant, [seg] * (2 * config.n_subjects))
        subjects, conditions = _labels(config.n_subjects)
        _CACHE[key] = build_model(subjects, conditions, batch, plant, data_containers=True)
    return _CACHE[key]


def _compiled(config, negative_control):
    key = ("study-compiled", config.K, config.n_subjects, negative_control)
    if key not in _CACHE:
        import nutpie

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _CACHE[key] = nutpie.compile_pymc_model(_template(config, negative_control), backend="numba")
    return _CACHE[key]


def _prior_draw(config, rng) -> dict:
    import pymc as pm

    model = _template(config, None)
    names = list(POPULATION_PARAMETERS) + sorted({v for v, _ in UNITS} | {"theta1", "R"})
    values = pm.draw([model[n] for n in names], random_seed=rng)
    return {n: np.asarray(v, dtype=float) for n, v in zip(names, values)}


def _prior_variances(config) -> dict:
    key = ("study-prior-var", config.K, config.n_subjects)
    if key not in _CACHE:
        import pymc as pm

        model = _template(config, None)
        names = list(POPULATION_PARAMETERS) + sorted({v for v, _ in UNITS})
        draws = pm.draw([model[n] for n in names], draws=4000, random_seed=np.random.default_rng(0))
        var = {}
        for n, d in zip(names, draws):
            d = np.asarray(d, dtype=float)
            if d.ndim == 1:
                var[n] = float(d.var())
            else:
                for v, c in UNITS:
                    if v == n:
                        var[f"{n}[0,{c}]"] = float(d[:, 0, c].var())
        _CACHE[key] = var
    return _CACHE[key]


def study_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    import nutpie

    rng = np.random.default_rng(seed)
    truth = _prior_draw(config, rng)
    K = config.K
    segs = []
    for s in range(config.n_subjects):
        for c in (0, 1):
            theta = from_normalized(truth["theta1"][s, c], truth["theta2"][s, c], truth["R"][s, c])
            segs.append(simulate_unit(theta, "MC" if c == 0 else "SC", K, config.negative_control, rng))
    batch = prepare_batch(_fit_plant(config.negative_control), segs)
    compiled = _compiled(config, config.negative_control).with_data(**batch_data(batch))
    trace = nutpie.sample(compiled, chains=config.chains, tune=config.tune, draws=config.draws,
                          seed=int(rng.integers(2**62)), cores=1, progress_bar=False)
    post = trace["posterior"]
    prior_var = _prior_variances(config)
    out = {"truth": {}, "ranks": {}, "pit_u": {}, "ess": {}, "contraction": {}}
    targets = [(n, n, None) for n in POPULATION_PARAMETERS] + [(f"{v}[0,{c}]", v, c) for v, c in UNITS]
    for label, var, c in targets:
        draws = np.asarray(post[var].values, dtype=float)
        true = truth[var]
        if c is not None:
            draws, true = draws[:, :, 0, c], true[0, c]
        true = float(true)
        kept, ess = thin(draws, config.L)
        out["truth"][label] = true
        out["ranks"][label] = rank(kept, true)
        out["pit_u"][label] = float(rng.uniform())
        out["ess"][label] = ess
        out["contraction"][label] = float(1.0 - draws.var() / prior_var[label])
    out["divergences"] = int(np.asarray(trace["sample_stats"]["diverging"].values).sum())
    return out
