"""How long a fit warms up: the default warm-up, and the delayed fit's pilot run (with profile delays).

The pilot's draws measure each subject's whitened coordinates again (:mod:`scioc.models.bayes.whiten_draws`,
:func:`scioc.pipelines.fit.whiten.sample_whitened`); the run whose draws are kept then starts inside the posterior's
bulk, on coordinates near the identity, and needs a shorter warm-up. See docs/decisions/delayed-pilot-run.md and
docs/decisions/delayed-tune-after-pilot.md.
"""

from __future__ import annotations

#: The pilot runs, (warm-up, kept) draws per chain, at most (:func:`pilot_runs`).
PILOT_RUNS = ((100, 100),)
#: The pilot's chains, at most the fit's: its draws only measure the coordinates.
PILOT_CHAINS = 2
#: The pilot's NUTS target acceptance rate; None: the fit's own (docs/decisions/delayed-target-accept.md).
PILOT_TARGET_ACCEPT = None
#: Warm-up draws per chain (``scioc fit --tune``'s default), and after a pilot run
#: (docs/decisions/delayed-tune-after-pilot.md).
TUNE = 1000
TUNE_AFTER_PILOT = 150
#: nutpie's largest tree depth in the pilot run; None: nutpie's own (docs/decisions/delayed-pilot-run.md).
PILOT_MAX_TREE_DEPTH = None


def pilot_runs(delay_mode: str, tune: int, draws: int, chains: int = PILOT_CHAINS) -> tuple | None:
    """The pilot runs, (tune, draws, chains, target_accept, max_tree_depth) each, for
    :func:`scioc.pipelines.fit.whiten.sample_whitened`: :data:`PILOT_RUNS` with profile delays, each no longer than
    the fit's own warm-up and draws (at least 2 draws); None with sampled delays."""
    if delay_mode != "profile":
        return None
    return tuple((min(t, int(tune)), max(2, min(d, int(draws))), min(PILOT_CHAINS, int(chains)), PILOT_TARGET_ACCEPT,
                  PILOT_MAX_TREE_DEPTH) for t, d in PILOT_RUNS)


def default_tune(delay_mode: str = "profile") -> int:
    """The warm-up draws per chain when ``--tune`` is not given: :data:`TUNE_AFTER_PILOT` after a pilot run
    (:func:`pilot_runs`), else :data:`TUNE`."""
    return TUNE_AFTER_PILOT if pilot_runs(delay_mode, TUNE, TUNE) is not None else TUNE


__all__ = ["PILOT_CHAINS", "PILOT_MAX_TREE_DEPTH", "PILOT_RUNS", "PILOT_TARGET_ACCEPT", "TUNE", "TUNE_AFTER_PILOT",
           "default_tune", "pilot_runs"]
