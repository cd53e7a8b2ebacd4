"""Unit-level SBC of the delayed human: the configuration, one replication, and a small run with its negative control.

The full calibrations (500 replications from torques and from angles, 100 studies from angles) run outside the tests:
reports/README.md gives their commands.
"""

import dataclasses

import numpy as np
import pytest

from scioc.models.bayes.unit_delayed import UNIT_DELAYED_PARAMETERS, DelayedUnitPrior
from scioc.models.design import STUDY
from scioc.pipelines.calibrate import CalibrationConfig, calibrate, level_configs
from scioc.pipelines.calibrate.config import replication_seed
from scioc.pipelines.calibrate.unit_delayed import simulate_unit_angles, unit_delayed_replication


def test_configurations_of_the_delayed_model():
    (name, cfg), (nname, ncfg) = level_configs("unit", human_model="delayed")
    assert (name, nname) == ("unit-delayed", "unit-delayed-negative")
    assert cfg.human_model == "delayed" and cfg.negative_control is None and ncfg.negative_control == "no-delay"
    # the paper's human model keeps its folders and its fingerprints
    (m, mc), _ = level_configs("unit")
    assert m == "unit" and mc.fingerprint() == dataclasses.replace(mc, human_model="maxent").fingerprint()
    assert cfg.fingerprint() != dataclasses.replace(cfg, human_model="maxent").fingerprint()
    with pytest.raises(ValueError, match="at the study level through angles; got likelihood 'torques'"):
        CalibrationConfig(level="study", human_model="delayed")
    with pytest.raises(ValueError, match="negative_control of the delayed model"):
        CalibrationConfig(human_model="delayed", negative_control="ignore-uA")
    with pytest.raises(ValueError, match="negative_control of the maxent model"):
        CalibrationConfig(negative_control="no-delay")
    with pytest.raises(ValueError, match="human model must be one of"):
        CalibrationConfig(human_model="crossover")


def test_configurations_of_the_angle_calibration():
    (name, cfg), (nname, ncfg) = level_configs("unit", human_model="delayed", likelihood="angles")
    assert (name, nname) == ("unit-delayed-angles", "unit-delayed-angles-negative")
    assert cfg.likelihood == ncfg.likelihood == "angles" and ncfg.negative_control == "no-delay"
    torques = level_configs("unit", human_model="delayed")[0][1]
    assert cfg.fingerprint() != torques.fingerprint()
    # the torque calibration's stored runs keep resuming: its fingerprint leaves the default likelihood out
    assert torques.fingerprint() == CalibrationConfig(**{**dataclasses.asdict(torques), "likelihood": "torques"}
                                                      ).fingerprint()
    with pytest.raises(ValueError, match="at the unit level through torques; got likelihood 'angles'"):
        CalibrationConfig(likelihood="angles")
    with pytest.raises(ValueError, match="encoder.counts_per_rev"):  # refused before any worker starts
        level_configs("unit", human_model="delayed", likelihood="angles",
                      design=dataclasses.replace(STUDY, encoder_counts=0))
    with pytest.raises(ValueError, match="encoder"):
        simulate_unit_angles(DelayedUnitPrior().draw(np.random.default_rng(0)), "MC", 100, np.random.default_rng(0),
                             dataclasses.replace(STUDY, encoder_counts=0))


def test_an_angle_replications_window_is_the_delayed_human_read_by_the_encoder():
    """The simulated window: the draw's angles plus Gaussian noise of the encoder's SD, from the reference's start,
    the assistant's law on SC; the same seed gives the same window."""
    prior = DelayedUnitPrior.for_design(STUDY)
    truth = prior.draw(np.random.default_rng(3))
    w = simulate_unit_angles(truth, "SC", 300, np.random.default_rng(4), STUDY)
    again = simulate_unit_angles(truth, "SC", 300, np.random.default_rng(4), STUDY)
    np.testing.assert_array_equal(w.angles, again.angles)
    assert w.angles.shape == (301,) and w.feedback is not None and w.u_A is None and w.warmup is None
    assert abs(w.angles[0] - w.angle_ref[0]) < 6 * STUDY.encoder_sd
    assert simulate_unit_angles(truth, "MC", 300, np.random.default_rng(4), STUDY).feedback is None


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


@pytest.mark.validation
def test_one_angle_replication_ranks_every_parameter_and_the_loglik():
    cfg = CalibrationConfig(level="unit", replications=2, K=300, chains=1, tune=150, draws=150, L=19,
                            human_model="delayed", likelihood="angles")
    res = unit_delayed_replication(cfg, 1, replication_seed(cfg.seed, 1))
    assert res["condition"] == "SC"
    assert set(res["ranks"]) == {*UNIT_DELAYED_PARAMETERS, "loglik"}
    assert all(0 <= r <= cfg.L for r in res["ranks"].values())
    unit_delayed_replication(cfg, 0, replication_seed(cfg.seed, 0))  # the compiled sampler serves another fit between
    again = unit_delayed_replication(cfg, 1, replication_seed(cfg.seed, 1))
    assert again["ranks"] == res["ranks"] and again["delay_mean"] == res["delay_mean"]  # same seed, same result
    assert all(np.array_equal(again["thinned"][k], res["thinned"][k]) for k in res["thinned"])


@pytest.mark.validation
def test_small_angle_sbc_passes_and_catches_an_ignored_delay(tmp_path, measured):
    # Smoke size of the angle calibration (the full one, 500 replications of 6-s windows, is in the README): 30
    # replications of 3-s windows. The correct model's check has a family-wise false-alarm rate of 1 %; the
    # negative control fixes the delay at 0 where it is drawn from 0-300 ms.
    base = dict(level="unit", replications=30, K=300, chains=2, tune=200, draws=200, L=39, batch_size=5, seed=12,
                human_model="delayed", likelihood="angles")
    good = calibrate(CalibrationConfig(**base), tmp_path / "good", show_progress=False)
    bad = calibrate(CalibrationConfig(**base, negative_control="no-delay"), tmp_path / "bad", show_progress=False)
    worst = min(good["parameters"], key=lambda k: good["parameters"][k]["p_value"])
    measured("unit-level SBC from angles, 30 replications: smallest KS p",
                      good["parameters"][worst]["p_value"], "passes at 0.01 family-wise")
    caught = min(bad["parameters"], key=lambda k: bad["parameters"][k]["p_value"])
    measured("unit-level SBC from angles, negative control (delay fixed at 0): smallest KS p",
                      bad["parameters"][caught]["p_value"], "fails")
    assert good["passed"]
    assert not bad["passed"]


def test_the_study_level_of_the_delayed_human_is_calibrated_through_its_angles():
    (name, cfg), (nname, ncfg) = level_configs("study", human_model="delayed", likelihood="angles")
    assert (name, nname) == ("study-delayed-angles", "study-delayed-angles-negative")
    assert cfg.likelihood == "angles" and ncfg.negative_control == "no-delay"
    assert cfg.fingerprint() != level_configs("unit", human_model="delayed", likelihood="angles")[0][1].fingerprint()


@pytest.mark.validation
def test_one_study_replication_of_the_angle_fit_ranks_the_population_and_a_subject():
    from scioc.pipelines.calibrate.study_angles import study_angle_replication

    cfg = CalibrationConfig(level="study", replications=1, K=100, n_subjects=3, chains=2, tune=60, draws=40, L=19,
                            human_model="delayed", likelihood="angles")
    res = study_angle_replication(cfg, 0, replication_seed(cfg.seed, 0))
    expected = {"mu_log_theta1", "beta", "sigma_log_theta1", "sigma_beta", "mu_log_R", "beta_log_R", "sigma_log_R",
                "sigma_beta_log_R", "tau_theta2", "tau_nm_scale", "sigma_m_scale", "log_theta1[0,0]",
                "log_theta1[0,1]", "log_R[0,0]", "theta2[0,0]", "tau_nm[0]", "sigma_m[0]", "loglik"}
    assert set(res["ranks"]) == expected
    assert all(0 <= r <= cfg.L for r in res["ranks"].values())
    assert len(res["delays_true"]) == 3 and all(0 <= d <= 30 for d in res["delays_true"])
    again = study_angle_replication(cfg, 0, replication_seed(cfg.seed, 0))
    assert again["ranks"] == res["ranks"] and again["truth"] == res["truth"]  # same seed, same result
