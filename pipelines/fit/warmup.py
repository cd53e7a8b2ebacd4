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
#: The pilot's chains (at most the fit's): its draws only measure the coordinates, and on a 2-core machine two chains
#: take half the time of four. Measured on the twelve subjects of README "Speed" (``scioc fit h12/study.parquet
#: --human-model delayed --chains 4 --draws 300 --seed 1 --R-population policy_scale --rho-form folded_centred``,
#: against the same with this constant set to 4 by a wrapper; by gradients, as another fit shared the machine): the
#: pilot's gradients fell from 30.8 k to 15.8 k; the kept draws' steps (28.3 and 28.2 per draw) and the smallest
#: population ESS (327 and 331, σ_βR) stayed.
PILOT_CHAINS = 2
#: The pilot's NUTS target acceptance rate (None: the fit's own). 0.8 on two chains (the same command through the
#: wrapper) took 34.4 steps per pilot draw against 39.6 but left 3 divergent transitions in the kept run (0 at the
#: fit's own 0.9).
PILOT_TARGET_ACCEPT = None
#: Warm-up draws per chain of a fit without a pilot run (``scioc fit --tune``'s default), and of the run after it:
#: the pilot's draws measured the coordinates and its last draw is where the chains start (README, "Speed").
TUNE = 1000
TUNE_AFTER_PILOT = 300


def pilot_runs(adaptation: str | None, delay_mode: str, tune: int, draws: int, chains: int = PILOT_CHAINS
               ) -> tuple | None:
    """The pilot runs of a delayed fit, as (tune, draws, chains, target_accept) for
    :func:`pipelines.fit.whiten.sample_whitened`: :data:`PILOT_RUNS` for the ``pilot`` adaptation (the default) with
    profile delays, each no longer than the fit's own warm-up and draws (a small fit gets a small pilot; at least 2
    draws), on :data:`PILOT_CHAINS` chains (at most the fit's) at :data:`PILOT_TARGET_ACCEPT`; None otherwise."""
    if delay_mode != "profile" or (adaptation or ADAPTATIONS[0]) != PILOT:
        return None
    return tuple((min(t, int(tune)), max(2, min(d, int(draws))), min(PILOT_CHAINS, int(chains)), PILOT_TARGET_ACCEPT)
                 for t, d in PILOT_RUNS)


def default_tune(human_model: str | None, delay_mode: str = "profile", adaptation: str | None = None) -> int:
    """``scioc fit``'s warm-up draws per chain when ``--tune`` is not given: :data:`TUNE_AFTER_PILOT` for a delayed fit
    with a pilot run (:func:`pilot_runs`), else :data:`TUNE`."""
    if human_model == "delayed" and pilot_runs(adaptation, delay_mode, TUNE, TUNE) is not None:
        return TUNE_AFTER_PILOT
    return TUNE


__all__ = ["PILOT_CHAINS", "PILOT_RUNS", "PILOT_TARGET_ACCEPT", "TUNE", "TUNE_AFTER_PILOT", "default_tune",
           "pilot_runs"]
