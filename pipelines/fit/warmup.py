"""How long a fit warms up: the default warm-up, and the delayed fit's pilot run (``--adaptation pilot``).

The delayed fit's default coordinates are measured on a pilot run's draws (:mod:`models.bayes.whiten_draws`,
:func:`pipelines.fit.whiten.sample_whitened`). The run after it starts inside the posterior's bulk in coordinates
in which each subject's block is near the identity, so it needs a shorter warm-up than a fit from the mode on the
Hessian's coordinates: measured on the full-size ``kbl`` study (README, "Speed"), after the first tenth of its 300
warm-up draws its trees were as deep as the kept draws'.
"""

from __future__ import annotations

from models.bayes.delayed_model import ADAPTATIONS, PILOT

#: The pilot run of the ``pilot`` adaptation, (warm-up, kept) draws per chain, at most (pipelines/fit/whiten.py;
#: :func:`pilot_runs`; measured: README, "Speed").
PILOT_RUNS = ((100, 100),)
#: Warm-up draws per chain of a fit without a pilot run (``scioc fit --tune``'s default), and of the run after it:
#: the pilot's draws measured the coordinates and its last draw is where the chains start (README, "Speed").
TUNE = 1000
TUNE_AFTER_PILOT = 300


def pilot_runs(adaptation: str | None, delay_mode: str, tune: int, draws: int) -> tuple | None:
    """The pilot runs of a delayed fit: :data:`PILOT_RUNS` for the ``pilot`` adaptation (the default) with profile
    delays, each no longer than the fit's own warm-up and draws (a small fit gets a small pilot; at least 2 draws);
    None otherwise."""
    if delay_mode != "profile" or (adaptation or ADAPTATIONS[0]) != PILOT:
        return None
    return tuple((min(t, int(tune)), max(2, min(d, int(draws)))) for t, d in PILOT_RUNS)


def default_tune(human_model: str | None, delay_mode: str = "profile", adaptation: str | None = None) -> int:
    """``scioc fit``'s warm-up draws per chain when ``--tune`` is not given: :data:`TUNE_AFTER_PILOT` for a delayed fit
    with a pilot run (:func:`pilot_runs`), else :data:`TUNE`."""
    if human_model == "delayed" and pilot_runs(adaptation, delay_mode, TUNE, TUNE) is not None:
        return TUNE_AFTER_PILOT
    return TUNE


__all__ = ["PILOT_RUNS", "TUNE", "TUNE_AFTER_PILOT", "default_tune", "pilot_runs"]
