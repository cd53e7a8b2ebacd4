"""Unit-level SBC of the delayed human: the configuration, one replication, and a small run with its negative control.

The full calibration (500 replications, ``reports/calibration-delayed-sampled``) is in the README.
"""

import dataclasses

import numpy as np
import pytest

from scioc.models.bayes.unit_delayed import UNIT_DELAYED_PARAMETERS, DelayedUnitPrior
from scioc.pipelines.calibrate import CalibrationConfig, calibrate, level_configs
from scioc.pipelines.calibrate.config import replication_seed
from scioc.pipelines.calibrate.unit_delayed import unit_delayed_replication


def test_configurations_of_the_delayed_model():
    (name, cfg), (nname, ncfg) = level_configs("unit", human_model="delayed")
    assert (name, nname) == ("unit-delayed", "unit-delayed-negative")
    assert cfg.human_model == "delayed" and cfg.negative_control is None and ncfg.negative_control == "no-delay"
    # the paper's human model keeps its folders and its fingerprints
    (m, mc), _ = level_configs("unit")
    assert m == "unit" and mc.fingerprint() == dataclasses.replace(mc, human_model="maxent").fingerprint()
    assert cfg.fingerprint() != dataclasses.replace(cfg, human_model="maxent").fingerprint()
    with pytest.raises(ValueError, match="unit level only"):
        CalibrationConfig(level="study", human_model="delayed")
    with pytest.raises(ValueError, match="negative_control of the delayed model"):
        CalibrationConfig(human_model="delayed", negative_control="ignore-uA")
    with pytest.raises(ValueError, match="negative_control of the maxent model"):
        CalibrationConfig(negative_control="no-delay")
    with pytest.raises(ValueError, match="human model must be one of"):
        CalibrationConfig(human_model="crossover")


def test_prior_draws_cover_the_literature_ranges():
    prior = DelayedUnitPrior()
    rng = np.random.default_rng(0)
    draws = [prior.draw(rng) for _ in range(4000)]
    tau = np.array([d["tau_nm"] for d in draws])
    delay = np.array([d["delay"] for d in draws])
    assert 0.05 < np.median(tau) < 0.07 and np.mean((tau > 0.02) & (tau < 0.17)) > 0.94
    assert delay.min() == 0 and delay.max() == 30 and len(np.unique(delay)) == 31
    assert set(UNIT_DELAYED_PARAMETERS) <= set(draws[0])


@pytest.mark.validation
def test_one_replication_ranks_every_parameter_and_the_loglik():
    cfg = CalibrationConfig(level="unit", replications=2, K=600, chains=1, tune=150, draws=150, L=19,
                            human_model="delayed")
    res = unit_delayed_replication(cfg, 1, replication_seed(cfg.seed, 1))
    assert res["condition"] == "SC"
    assert set(res["ranks"]) == {*UNIT_DELAYED_PARAMETERS, "loglik"}
    assert all(0 <= r <= cfg.L for r in res["ranks"].values())
    # The worker compiles the model once and reuses it: another replication in between (rep 0, on MC) must not
    # change what the same seed gives (the steps' tuning state is restored before every fit).
    unit_delayed_replication(cfg, 0, replication_seed(cfg.seed, 0))
    again = unit_delayed_replication(cfg, 1, replication_seed(cfg.seed, 1))
    assert again["ranks"] == res["ranks"] and again["delay_mean"] == res["delay_mean"]  # same seed, same result
    assert all(np.array_equal(again["thinned"][k], res["thinned"][k]) for k in res["thinned"])
    assert 0.0 <= res["delay_below"] + res["delay_equal"] <= 1.0


@pytest.mark.validation
def test_small_delayed_sbc_catches_an_ignored_delay(tmp_path):
    # 40 replications of 4-s windows with the delay fixed at 0: ignoring a delay drawn from 0-300 ms biases
    # tau_nm and sigma_m in most replications (100 replications of 6-s windows: KS p about 1e-14). The correct
    # model is not asserted to pass here: at 500 replications its plug-in delay is measurably overconfident
    # (README, "Human models"), and a small run that passed would say nothing.
    base = dict(level="unit", replications=40, K=400, chains=2, tune=250, draws=250, L=39, batch_size=5, seed=11,
                human_model="delayed")
    bad = calibrate(CalibrationConfig(**base, negative_control="no-delay"), tmp_path / "bad", show_progress=False)
    assert not bad["passed"]
