"""What ``scioc fit`` advises when its sampler-convergence verdict fails (:func:`scioc.pipelines.fit.diagnostics.remedies`)."""

import pytest

from scioc.pipelines.fit.diagnostics import ESS_MIN, RHAT_MAX, remedies


def _diag(divergences=0, population=None):
    population = population or {"beta": {"rhat": 1.001, "ess_bulk": 2000.0, "ess_tail": 1800.0}}
    failed = divergences or any(p["rhat"] > RHAT_MAX or min(p["ess_bulk"], p["ess_tail"]) < ESS_MIN
                                for p in population.values())
    return {"sampler": {"divergences": divergences}, "population": population, "passed": not failed}


def test_a_passing_fit_gets_no_advice():
    assert remedies(_diag(), chains=4, draws=1000, target_accept=0.9) == []


@pytest.mark.parametrize("ta, higher", [(None, "0.9"), (0.8, "0.9"), (0.9, "0.95"), (0.95, "0.975")])
def test_divergences_ask_for_a_higher_target_acceptance_halving_the_distance_to_1(ta, higher):
    (text,) = remedies(_diag(divergences=3), chains=4, draws=1000, target_accept=ta)
    assert text.startswith("3 divergent transitions: refit with --target-accept " + higher + " ")
    assert f"(this fit: {0.8 if ta is None else ta:g};" in text and "form must change" in text


def test_short_ess_projects_the_draws_that_would_reach_the_threshold_from_the_slowest_parameter():
    pop = {"beta": {"rhat": 1.002, "ess_bulk": 900.0, "ess_tail": 800.0},
           "sigma_m_scale": {"rhat": 1.008, "ess_bulk": 299.0, "ess_tail": 419.0},
           "mu_log_R": {"rhat": 1.004, "ess_bulk": 390.0, "ess_tail": 500.0}}
    (text,) = remedies(_diag(population=pop), chains=4, draws=1000, target_accept=0.9)
    # 400 / 299 × 1000 = 1337.8 draws per chain, rounded up to 1400
    assert text.startswith("ESS of sigma_m_scale 299 of 400 (2 parameters short): ")
    assert "--draws 1400 per chain (now 1000, 4 chains)" in text


def test_high_rhat_and_divergences_are_both_advised_and_a_stuck_parameter_is_not_sent_for_more_draws():
    pop = {"mu_log_R": {"rhat": 1.059, "ess_bulk": 0.0, "ess_tail": 0.0},
           "beta": {"rhat": 1.02, "ess_bulk": 700.0, "ess_tail": 650.0}}
    out = remedies(_diag(divergences=1, population=pop), chains=4, draws=1000, target_accept=0.9)
    assert out[0].startswith("1 divergent transition: refit with --target-accept 0.95")
    assert out[1] == "ESS of mu_log_R is 0: the chains do not move in it; more draws will not help"
    assert out[2].startswith("R-hat of mu_log_R 1.059 > 1.01 (2 parameters): the chains disagree")


def test_draws_cut_at_the_largest_tree_depth_are_advised_on_only_when_the_verdict_fails():
    pop = {"beta": {"rhat": 1.002, "ess_bulk": 350.0, "ess_tail": 500.0}}
    diag = _diag(population=pop)
    diag["sampler"].update(max_tree_depth=6, draws_at_max_tree_depth=7)
    out = remedies(diag, chains=4, draws=1000, target_accept=0.9)
    assert out[0].startswith("ESS of beta 350 of 400")
    assert out[1] == ("7 draws stopped at the largest tree depth (6): shorter trajectories than NUTS would have run; "
                      "valid draws but less independent ones, which more --draws make up for")
    passing = _diag()
    passing["sampler"].update(max_tree_depth=6, draws_at_max_tree_depth=7)
    assert remedies(passing, chains=4, draws=1000, target_accept=0.9) == []


def test_a_parameter_that_never_moved_fails_the_verdict_and_is_advised_on():
    # NaN R-hat and ESS (a constant parameter): the verdict's checks fail on NaN, so the advice must say something.
    nan = float("nan")
    pop = {"s_m": {"rhat": nan, "ess_bulk": nan, "ess_tail": nan},
           "beta": {"rhat": 1.02, "ess_bulk": 700.0, "ess_tail": 650.0}}
    diag = {"sampler": {"divergences": 0}, "population": pop, "passed": False}
    out = remedies(diag, chains=4, draws=1000, target_accept=0.9)
    assert out == ["ESS of s_m is nan: the chains do not move in it; more draws will not help",
                   "R-hat of s_m nan > 1.01 (2 parameters): the chains disagree; refit with a longer --tune and more "
                   "--draws, then judge again; an R-hat that stays high means chains in different regions"]


def test_undefined_values_read_back_from_a_sidecar_are_advised_on_as_nan():
    # posterior.json stores NaN as null (a one-chain fit's R-hat): read back, the advice is the NaN case's, not a crash
    pop = {"s_m": {"rhat": None, "ess_bulk": None, "ess_tail": 12.0},
           "beta": {"rhat": None, "ess_bulk": 700.0, "ess_tail": 650.0}}
    diag = {"sampler": {"divergences": 0}, "population": pop, "passed": False}
    out = remedies(diag, chains=1, draws=30, target_accept=0.9)
    assert out[0] == "ESS of s_m is nan: the chains do not move in it; more draws will not help"
    assert out[1].startswith("R-hat of s_m nan > 1.01 (2 parameters)")


@pytest.mark.parametrize("bulk, tail", [(None, 12.0), (12.0, None)])
def test_a_nan_bulk_or_tail_ess_reads_as_nan_whichever_it_is(bulk, tail):
    # Python's min(nan, x) is nan but min(x, nan) is x: the smaller ESS must not depend on which of the two is NaN
    import math

    from scioc.pipelines.fit.diagnostics import smaller_ess

    p = {"ess_bulk": math.nan if bulk is None else bulk, "ess_tail": math.nan if tail is None else tail}
    assert math.isnan(smaller_ess(p))
    assert smaller_ess({"ess_bulk": 12.0, "ess_tail": 30.0}) == 12.0
    pop = {"s_m": {"rhat": 1.0, "ess_bulk": bulk, "ess_tail": tail}}
    out = remedies({"sampler": {"divergences": 0}, "population": pop, "passed": False}, chains=2, draws=30,
                   target_accept=0.9)
    assert out[0] == "ESS of s_m is nan: the chains do not move in it; more draws will not help"


@pytest.mark.parametrize("s, expected", [(0.2, 0.04 / 1.04), (1.0, 0.5), (3.0, 0.9)])
def test_the_pooling_factor_is_the_shrinkage_of_the_normal_model(s, expected):
    # ε_j ~ N(0, 1), data y_j ~ N(ε_j, s²): the posterior of ε_j is N(b y_j, b s²), b = 1 / (1 + s²), and Gelman and
    # Pardoe's λ is s² / (1 + s²). 400 units, 2000 exact posterior draws each.
    import numpy as np

    from scioc.pipelines.fit.diagnostics import pooling_factor

    rng = np.random.default_rng(11)
    y = rng.normal(0.0, 1.0, 400) + rng.normal(0.0, s, 400)
    b = 1.0 / (1.0 + s**2)
    draws = b * y + np.sqrt(b) * s * rng.standard_normal((2, 1000, 400))
    assert pooling_factor(draws) == pytest.approx(expected, abs=0.05)


def _delayed_diag(pooling):
    pop = {"beta": {"rhat": 1.001, "ess_bulk": 2000.0, "ess_tail": 1800.0},
           "sigma_m_scale": {"rhat": 1.001, "ess_bulk": 2000.0, "ess_tail": 1800.0},
           "sigma_log_R": {"rhat": 1.024, "ess_bulk": 109.0, "ess_tail": 300.0}}
    diag = _diag(population=pop)
    diag["units"] = {"log_R": {"rhat_max": 1.05, "ess_bulk_min": 50.0, "ess_tail_min": 60.0, "pooling_factor": pooling}}
    return diag


def test_a_loose_R_whose_population_does_not_mix_is_sent_to_the_policy_scale_population():
    out = remedies(_delayed_diag(0.78), chains=4, draws=1000, target_accept=0.9)
    assert out[-1].startswith("the data barely fix each subject's R (pooling factor of its baseline log R 0.78, ")
    assert "refit with R_population = \"policy_scale\" (" in out[-1] and "--sampler-config" in out[-1]
    # negative controls: R fixed by the data (the max-ent human's 0.07), or a max-ent fit (no motor noise), or no
    # pooling factor at all: the same failing σ_R gets only the generic advice
    assert not any("policy_scale" in t for t in remedies(_delayed_diag(0.07), chains=4, draws=1000, target_accept=0.9))
    maxent = _delayed_diag(0.78)
    del maxent["population"]["sigma_m_scale"]
    assert not any("policy_scale" in t for t in remedies(maxent, chains=4, draws=1000, target_accept=0.9))
    bare = _delayed_diag(0.78)
    del bare["units"]
    assert len(remedies(bare, chains=4, draws=1000, target_accept=0.9)) == len(out) - 1
