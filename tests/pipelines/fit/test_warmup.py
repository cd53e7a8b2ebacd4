"""The delayed fit's pilot run and default warm-up (pipelines/fit/warmup.py)."""

from scioc.pipelines.fit.warmup import (
    PILOT_CHAINS,
    PILOT_MAX_TREE_DEPTH,
    PILOT_RUNS,
    PILOT_TARGET_ACCEPT,
    TUNE,
    TUNE_AFTER_PILOT,
    default_tune,
    pilot_runs,
)


def test_the_pilot_runs_on_at_most_its_own_chains_and_no_longer_than_the_fit():
    (tune, draws), = PILOT_RUNS
    # a full fit of 4 chains: the pilot on PILOT_CHAINS of them, as long as PILOT_RUNS says
    assert pilot_runs("profile", 300, 1000, 4) == ((tune, draws, min(PILOT_CHAINS, 4), PILOT_TARGET_ACCEPT,
                                                   PILOT_MAX_TREE_DEPTH),)
    assert PILOT_CHAINS < 4  # the pilot is cheaper than the fit's own chains on this 2-core machine
    # its trees as deep as the fit's: a cap was measured and not adopted (warmup.py, "Tree depth")
    assert PILOT_MAX_TREE_DEPTH is None
    # a fit of one chain gets a pilot of one chain; a short fit a short pilot (at least 2 draws)
    assert pilot_runs("profile", 10, 1, 1) == ((10, 2, 1, PILOT_TARGET_ACCEPT, PILOT_MAX_TREE_DEPTH),)
    # no pilot for a sampled delay
    assert pilot_runs("sampled", 300, 1000, 4) is None


def test_the_default_warm_up_is_shorter_only_after_a_pilot():
    from scioc.pipelines.human_model import get

    assert default_tune() == TUNE_AFTER_PILOT < TUNE
    assert default_tune(delay_mode="sampled") == TUNE
    assert get("delayed").default_tune({}) == TUNE_AFTER_PILOT
    assert get("delayed").default_tune({"delay": "sampled"}) == TUNE
    assert get("maxent").default_tune({}) == TUNE

