"""The baseline-R prior the leave-one-subject-out comparison takes from a delayed fit's sidecar."""

import pytest

from scioc.models.bayes.delayed_blocks import DelayedPriors
from scioc.models.bayes.hierarchical import Priors
from scioc.pipelines.fit.human_models import unpooled_log_R_prior
from scioc.pipelines.io import InputDataError


def test_unpooled_prior_is_read_from_the_sidecar(tmp_path):
    priors = {"mu_log_R": [2.5, 0.8], "sigma_log_R": 0.6}
    side = {"priors": priors, "delayed_priors": {"R_population": "unpooled"}}
    expected = DelayedPriors.unpooled_log_R_prior(Priors(mu_log_R=(2.5, 0.8), sigma_log_R=0.6))
    assert unpooled_log_R_prior(side, tmp_path) == expected == (2.5, pytest.approx(1.0))
    # A pooled population needs no such prior (the draws hold μ_R, σ_R or s_ρ).
    for population in ("lognormal", "policy_scale"):
        assert unpooled_log_R_prior({**side, "delayed_priors": {"R_population": population}}, tmp_path) is None
    assert unpooled_log_R_prior({"priors": priors}, tmp_path) is None  # a sidecar from before the option
    with pytest.raises(InputDataError, match="posterior.json.*mu_log_R"):
        unpooled_log_R_prior({"delayed_priors": {"R_population": "unpooled"}}, tmp_path)
