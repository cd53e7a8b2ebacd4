"""One SBC replication per call: draw the truth, simulate exactly, fit, rank.

Runs inside Dask workers. Compiled models are cached per worker process (compiling takes
seconds, a unit fit a fraction of one), keyed by everything that changes the graph. Each
fit runs its chains one after the other (``cores=1``): the parallelism is across
replications, one worker per core; nutpie's chains are seeded each on their own, so the
draws do not depend on this.

Unit level: θ ~ :class:`models.bayes.unit_model.UnitPrior`; one exact max-ent demonstration
over the study's 15-s analysis window (the fixed reference) from rest at the reference;
even replications are manual control (u_A = 0), odd ones shared control, where the
human plans with the assistant's feedback law and the assistant reacts to the actual
state (:func:`simulate_unit`, the simulator's SC human); the likelihood is the
:class:`models.segment.Feedback` model, as in the pipeline; the posterior is sampled with
nutpie.

Negative controls (same draws, same sizes, a wrong fit): ``inertia`` fits with the wheel
inertia 10 % too high (0.044 instead of 0.04 kg·m²), ``ignore-uA`` attributes the
assistant's torque to the human.
"""

from __future__ import annotations

import warnings

import numpy as np

from models.bayes.op import DATA_NAMES
from models.design import WINDOW_START
from models.maxent import sample_maxent
from models.plant import DT_HUMAN, WheelParameters, discretize
from models.reference import reference_trajectory
from models.sbc import rank, thin
from models.segment import Segment, planning_plant, prepare_batch

_CACHE: dict = {}
#: Relative error of the inertia in the ``inertia`` negative control.
INERTIA_ERROR = 0.10


def _fit_plant(negative_control):
    if negative_control == "inertia":
        return discretize(DT_HUMAN, WheelParameters(inertia=0.04 * (1 + INERTIA_ERROR)))
    return discretize(DT_HUMAN)


def _reference(K: int) -> np.ndarray:
    return _window_inputs(K)[0]


def _window_inputs(K: int):
    """The window's reference (K + 1,) and the assistant's feedback over it (gain, feedforward (K,))."""
    key = ("ref", K)
    if key not in _CACHE:
        from models.assistant import design_assistant, human_feedback

        i0 = int(round(WINDOW_START / DT_HUMAN))
        ref = reference_trajectory(WINDOW_START + K * DT_HUMAN + 2.0).angle  # the assistant previews 1 s
        fb = human_feedback(design_assistant(), ref)
        _CACHE[key] = (np.ascontiguousarray(ref[i0 : i0 + K + 1]), fb.window(i0, K))
    return _CACHE[key]


def simulate_unit(theta, condition: str, K: int, negative_control, rng: np.random.Generator) -> Segment:
    """One exact max-ent demonstration over the analysis window, as the fit will see it.

    MC: u_A = 0. SC: the human plans with the assistant's law on the closed wheel (the
    simulator's human), the assistant's recorded torque is ``-gain @ x_k + feedforward_k``
    along the sampled trajectory. The returned segment carries the Feedback the
    likelihood plans with, except for ``ignore-uA``, which attributes the assistant's
    torque to the human and plans without it.
    """
    ref, fb = _window_inputs(K)
    plant = discretize(DT_HUMAN)
    x0 = np.array([ref[0], 0.0])
    if condition == "MC":
        demo = sample_maxent(theta, x0, ref, np.zeros(K), plant, rng)
        u_A, feedback = np.zeros(K), None
    else:
        demo = sample_maxent(theta, x0, ref, fb.feedforward, planning_plant(plant, fb.gain), rng)
        u_A, feedback = fb.feedforward - demo.x[:K] @ fb.gain, fb
    if negative_control == "ignore-uA":
        return Segment(x0, ref, demo.u_H + u_A, np.zeros(K))
    return Segment(x0, ref, demo.u_H, u_A, feedback)


def _compiled_unit(K: int, negative_control):
    key = ("unit", K, negative_control)
    if key not in _CACHE:
        import nutpie

        from models.bayes.unit_model import build_unit_model

        plant = _fit_plant(negative_control)
        ref = _reference(K)
        dummy = prepare_batch(plant, [Segment(np.array([ref[0], 0.0]), ref, np.zeros(K), np.zeros(K))])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _CACHE[key] = nutpie.compile_pymc_model(build_unit_model(dummy, plant), backend="numba")
    return _CACHE[key]


def batch_data(batch) -> dict:
    """A batch's arrays by the names of the models' data containers."""
    return {name: getattr(batch, name) for name in DATA_NAMES}


def _prior_variances(prior) -> dict:
    key = ("prior_var", prior)
    if key not in _CACHE:
        rng = np.random.default_rng(0)
        _CACHE[key] = {name: prior.variance(name, rng) for name in ("theta1", "theta2", "R")}
    return _CACHE[key]


def unit_replication(config, i: int, seed: np.random.SeedSequence) -> dict:
    import nutpie

    from models.bayes.unit_model import UNIT_PARAMETERS, UnitPrior

    rng = np.random.default_rng(seed)
    prior = UnitPrior()
    truth = prior.draw(rng)
    K = config.K
    condition = "MC" if i % 2 == 0 else "SC"
    seg = simulate_unit(truth["theta"], condition, K, config.negative_control, rng)
    batch = prepare_batch(_fit_plant(config.negative_control), [seg])
    compiled = _compiled_unit(K, config.negative_control).with_data(**batch_data(batch))
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
