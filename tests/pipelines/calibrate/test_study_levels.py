"""Study-level SBC of an experiment with more than two levels: β, σ_β, β_R and σ_βR ranked once per contrast."""

import numpy as np
import pytest

from scioc.pipelines.calibrate.config import CalibrationConfig, level_configs, replication_seed
from scioc.pipelines.calibrate.study import population_targets, study_replication
from scioc.pipelines.experiment import load_experiment

THREE = "data/examples/three-assistants/experiment.toml"


def test_population_targets_split_a_contrast_axis():
    draws = np.arange(24, dtype=float).reshape(2, 6, 2)
    out = population_targets("beta", draws, np.array([-0.3, -0.7]), ("none", "weak", "strong"))
    assert [t.label for t in out] == ["beta[weak]", "beta[strong]"]
    assert out[1].truth == -0.7 and np.array_equal(out[1].draws, draws[..., 1])
    scalar = population_targets("mu_log_R", draws[..., 0], 1.5, ("MC", "SC"))
    assert len(scalar) == 1 and scalar[0].label == "mu_log_R" and scalar[0].truth == 1.5
    assert np.array_equal(scalar[0].draws, draws[..., 0])


@pytest.mark.validation
def test_one_three_level_replication_ranks_every_contrast():
    design = load_experiment(THREE)
    (_, cfg), _ = level_configs("study", design=design, replications=1, n_subjects=3, seconds=0.5)
    cfg = CalibrationConfig(**{**cfg.__dict__, "chains": 1, "tune": 100, "draws": 100, "L": 19})
    res = study_replication(cfg, 0, replication_seed(cfg.seed, 0))
    for name in ("beta", "sigma_beta", "beta_log_R", "sigma_beta_log_R"):
        for level in ("weak", "strong"):
            assert 0 <= res["ranks"][f"{name}[{level}]"] <= cfg.L
    assert "beta" not in res["ranks"] and "loglik" in res["ranks"]
    assert {"mu_log_theta1", "log_theta1[0,1]"} <= set(res["ranks"])
