"""One SBC replication per call: draw the truth, simulate exactly, fit, rank.

Runs inside Dask workers. Compiled models are cached per worker process (compiling takes
seconds, a unit fit a fraction of one), keyed by everything that changes the graph. Each
fit runs its chains one after the other (``cores=1``): the parallelism is across
replications, one worker per core; nutpie's chains are seeded each on their own, so the
draws do not depend on this.

Unit level: θ ~ :class:`models.unit_model.UnitPrior`; one exact max-ent demonstration
over the study's 15-s analysis window (the fixed reference) from rest at the reference;
even replications are manual control (u_A = 0), odd ones shared control, where u_A is
the assistant's response to the subject's plan (the fixed point of
:func:`models.simulate.plan_against_assistant`), replayed as the known input the
likelihood assumes; the posterior is sampled with nutpie.

Negative controls (same draws, same sizes, a wrong fit): ``inertia`` fits with the wheel
inertia 10 % too high (0.044 instead of 0.04 kg·m²), ``ignore-uA`` attributes the
assistant's torque to the human.
"""

from __future__ import annotations

import warnings

import numpy as np

from models.maxent import Segment, prepare_batch, sample_maxent
from models.plant import DT_HUMAN, WheelParameters, discretize
from models.reference import WINDOW_START, reference_trajectory
from models.sbc import rank, thin

_CACHE: dict = {}
#: Relative error of the inertia in the ``inertia`` negative control.
INERTIA_ERROR = 0.10


def _fit_plant(negative_control):
    if negative_control == "inertia":
        return discretize(DT_HUMAN, WheelParameters(inertia=0.04 * (1 + INERTIA_ERROR)))
    return discretize(DT_HUMAN)


def _reference(K: int) -> np.ndarray:
    key = ("ref", K)
    if key not in _CACHE:
        i0 = int(round(WINDOW_START / DT_HUMAN))
        ref = reference_trajectory(WINDOW_START + K * DT_HUMAN + 1.0).angle
        _CACHE[key] = np.ascontiguousarray(ref[i0 : i0 + K + 1])
    return _CACHE[key]


def _compiled_unit(K: int, negative_control):
    key = ("unit", K, negative_control)
    if key not in _CACHE:
        import nutpie

        from models.unit_model import build_unit_model

        plant = _fit_plant(negative_control)
        ref = _reference(K)
        dummy = prepare_batch(plant, [Segment(np.array([ref[0], 0.0]), ref, np.zeros(K), np.zeros(K))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _CACHE[key] = nutpie.compile_pymc_model(build_unit_model(dummy, plant), backend="numba")
    return _CACHE[key]


def _prior_variances(prior) -> dict:
    key = ("prior_var", prior)
    if key not in _CACHE:
        rng = np.random.default_rng(0)
        _CACHE[key] = {name: prior.variance(name, rng) for name in ("theta1", "theta2", "R")}
    return _CACHE[key]


def unit_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    import nutpie

    from models.assistant import design_assistant
    from models.simulate import plan_against_assistant
    from models.unit_model import UNIT_PARAMETERS, UnitPrior

    rng = np.random.default_rng(seed)
    prior = UnitPrior()
    truth = prior.draw(rng)
    K = config.K
    plant = discretize(DT_HUMAN)
    ref = _reference(K)
    x0 = np.array([ref[0], 0.0])
    condition = "MC" if i % 2 == 0 else "SC"
    if condition == "SC":
        if "assistant" not in _CACHE:
            _CACHE["assistant"] = design_assistant()
        u_A = plan_against_assistant(truth["theta"], x0, ref, plant, _CACHE["assistant"]).expected_u_A
    else:
        u_A = np.zeros(K)
    demo = sample_maxent(truth["theta"], x0, ref, u_A, plant, rng)
    if config.negative_control == "ignore-uA":
        seg = Segment(x0, ref, demo.u_H + u_A, np.zeros(K))
    else:
        seg = Segment(x0, ref, demo.u_H, u_A)
    batch = prepare_batch(_fit_plant(config.negative_control), [seg])
    compiled = _compiled_unit(K, config.negative_control).with_data(x1=batch.x1, x2=batch.x2, r=batch.r,
                                                                    u=batch.u, a=batch.a)
    trace = nutpie.sample(compiled, chains=config.chains, tune=config.tune, draws=config.draws,
                          seed=int(rng.integers(2**62)), cores=1, progress_bar=False)
    post = trace["posterior"]
    prior_var = _prior_variances(prior)
    out = {"condition": condition, "truth": {k: truth[k] for k in UNIT_PARAMETERS},
           "ranks": {}, "pit_u": {}, "ess": {}, "contraction": {}}
    for name in UNIT_PARAMETERS:
        draws = np.asarray(post[name].values, dtype=float)
        kept, ess = thin(draws, config.L)
        out["ranks"][name] = rank(kept, truth[name])
        out["pit_u"][name] = float(rng.uniform())
        out["ess"][name] = ess
        out["contraction"][name] = float(1.0 - draws.var() / prior_var[name])
    out["divergences"] = int(np.asarray(trace["sample_stats"]["diverging"].values).sum())
    return out


def run(config, i: int, seed: np.random.SeedSequence) -> dict:
    """Dispatch one replication by level."""
    if config.level == "unit":
        return unit_replication(config, i, seed)
    from pipelines.sbc_study import study_replication

    return study_replication(config, i, seed)
