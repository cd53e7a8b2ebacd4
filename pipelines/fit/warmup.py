"""How long a fit warms up: the default warm-up, and the delayed fit's pilot run (``--adaptation pilot``).

The delayed fit's default coordinates are measured on a pilot run's draws (:mod:`scioc.models.bayes.whiten_draws`,
:func:`scioc.pipelines.fit.whiten.sample_whitened`). The run after it starts inside the posterior's bulk in coordinates
in which each subject's block is near the identity, so it needs a shorter warm-up than a fit from the mode on the
Hessian's coordinates: measured on the full-size ``kbl`` study (README, "Speed"), after the first tenth of its 300
warm-up draws its trees were as deep as the kept draws'.

Tree depth (tried, not the default). On the Hessian's coordinates the pilot's trees are deep: at full size (``scioc
bench --parts fit_delayed --humans kbl`` at f484bf1) 82 leapfrog steps per warm-up draw and 67 per kept one, while
every draw of the run after it was a tree of depth 5 (31 steps); and the first tenth of that run's warm-up took 169
steps per draw, where nutpie starts its adaptation again. A cap on the trees' depth (nutpie's ``maxdepth``; a capped
tree is still a valid NUTS transition, only a shorter one) bounds both. Measured on the twelve subjects of
:mod:`scioc.pipelines.fit.delayed_forms`' last table (``scioc fit h12/study.parquet --human-model delayed --estimates
h12/delayed/estimates.parquet --experiment h12/experiment.toml --chains 4 --draws 300 --adequacy-boot 19 --seed S
--R-population policy_scale --rho-form folded_centred``, the cap set for the pilot and the kept run alike by a
wrapper that added ``maxdepth`` to nutpie's options; 2026-12-06; gradients of the pilot, the warm-up and the kept
draws)::

    seed  depth   pilot    warm-up  kept     total    kept steps  smallest ESS   largest R-hat  div
    1     10      15 825   37 445   33 856   87 126   28.2        σ_βR 331       1.014          0
    1     6       14 995   32 978   33 526   81 499   27.9        σ_βR 359       1.009          2
    2     10      22 898   39 546   32 416   94 860   27.0        σ_βR 256       1.007          0
    2     6       16 245   33 101   33 264   82 610   27.7        τ_θ2 367       1.010          0
    3     10      15 281   37 924   32 880   86 085   27.4        σ_βR 340       1.018          0
    3     6       14 065   34 002   32 864   80 931   27.4        σ_βR 344       1.006          0

8.6 % fewer gradients, mostly in the first tenth of the kept run's warm-up (38-45 steps per draw against 71-98).
At full size (the bench above, ``kbl`` human, seed 2018): capped at 6 for both runs (66c842a), 183 k gradients
against 209 k, but 3 divergent transitions in 3 of the 4 chains (step sizes 0.151-0.168 against 0.139-0.158), which
fails the convergence verdict; the pilot alone capped (b435019: its draws only choose coordinates), 197 k gradients
and 0 divergent, but R-hat 1.014 for σ_β, which fails it too. Each is one run, and the uncapped default passed in
one (R-hat 1.005): whether the cap or chance failed them is not known, so :data:`PILOT_MAX_TREE_DEPTH` is None
(nutpie's own 10) until a cap passes at full size. Depth 5 (the twelve, seed 1) saved 15 % but cut 7 kept draws
short, and its smallest ESS fell to 233.

The warm-up after the pilot. The run whose draws are kept starts inside the posterior's bulk, on coordinates in
which each subject's block is near the identity, so nutpie's adaptation has less to learn than from the mode; its
schedule (a first 30 % with the mass matrix re-estimated every few draws, windows of 80 draws after it, the last
15 % for the step size alone) fits in 150 draws with one full window. Measured on the twelve subjects above (the
same command with ``--tune T``, no wrapper, 2026-12-06 and 07; two fits at a time, so by gradients, not seconds; the
``300`` rows are the table above's depth-10 rows, the same command at its commit)::

    seed  tune   pilot    warm-up  kept     total    kept steps  smallest ESS   largest R-hat  div
    1     300    15 825   37 445   33 856   87 126   28.2        σ_βR 331       1.014          0
    1     200    15 825   27 269   35 152   78 246   29.3        σ_β 282        1.012          0
    1     150    15 825   20 957   34 336   71 118   28.6        σ_β 288        1.006          0
    2     300    22 898   39 546   32 416   94 860   27.0        σ_βR 256       1.007          0
    2     200    22 898   28 682   30 304   81 884   25.3        σ_βR 253       1.021          0
    2     150    22 898   24 354   33 920   81 172   28.3        σ_βR 339       1.008          0
    3     300    15 281   37 924   32 880   86 085   27.4        σ_βR 340       1.018          0
    3     200    16 917   24 527   33 216   74 660   27.7        σ_βR 364       1.006          0
    3     150    16 917   19 143   31 732   67 792   26.4        σ_βR 292       1.008          0

(σ_β: sigma_beta_log_theta1; σ_βR: sigma_beta_log_R.) 150 warm-up draws took 45-51 % fewer warm-up gradients
than 300, with as many steps per kept draw and no worse mixing over the three seeds, so
:data:`TUNE_AFTER_PILOT` is 150. At full size: README, "Speed".

The target acceptance rate after the pilot (tried then; the default since 41cd710, with the pivots' tail maps
below). nutpie's 0.8 instead of the delayed fit's 0.9 (:data:`scioc.models.bayes.delayed_model.WHITENED_TARGET_ACCEPT`,
chosen before the pilot existed) on the twelve subjects
(the same command with ``--target-accept 0.8``, which the pilot follows too; 300 warm-up draws; 2026-12-07)::

    seed  rate  pilot    warm-up  kept     total    kept steps  step size    smallest ESS  largest R-hat  div
    1     0.8   13 771   30 367   20 804   64 942   17.3        0.25-0.28    σ_βR 133      1.026          9
    2     0.8   17 019   32 373   19 440   68 832   16.2        0.24-0.27    σ_βR 290      1.010          1
    3     0.8   15 081   28 775   18 899   62 755   15.8        0.24-0.29    σ_βR 196      1.011          12

against the 0.9 rows above (27.0-28.2 steps per kept draw at steps of 0.18-0.22, no divergent transition). The
larger step makes most kept trees one level shallower (15 leapfrog steps instead of 31), 40 % fewer kept gradients,
but every run diverged: at each of the 22 divergent draws one subject's ρ and τ_nm were both above their 95th
percentiles (28-33 % of all draws have such a subject; read ad hoc from the posteriors), the far end of its ridge
between ρ² and τ_nm. The convergence verdict fails on one, so the rate stayed 0.9 then; coordinates that follow that ridge
to its end are the lead (README, "Speed").

The pivot's tails, and θ2's form (2026-12-07). Where the divergences at 0.8 start was then read from nutpie's own
record (``store_divergences``, set by a wrapper that also saved each run's whitened draws and coordinates; ad hoc):
on seeds 1 and 3 (θ2 already in the quantile form below), four of the five divergent trajectories ended on one
subject's pivot (S04's ρ̃) beyond the largest |ρ̃| among its 1200 draws (0.52-0.54), at |ρ̃| of 0.81-1.69, their last
step moving ρ̃ by 0.3-2.4 (its draws span about 1.05), with energy errors of 4·10³-4·10¹⁰; the fifth at the
population's β_R and σ_βR, 5-7 of their scales out. That is the wall at the ridge's end, where the data hold ρ²
(:mod:`scioc.models.bayes.pivot_tails`), rather than a bend that the parabola misses. In the same draws each
unit's log z = log(θ2/τ) had its prior's quantiles, and the whitened coordinates' excess kurtosis was 1-10 for the
two θ2 coordinates and log σ_m of every subject, against about 0 for the rest. Two changes followed: θ2 in the
``quantile`` form (:func:`scioc.models.bayes.blocks.theta2_block`, :data:`scioc.pipelines.fit.delayed_forms.THETA2_FORM`), and
the pivot's tail map, its b chosen on the pilot's draws (:func:`scioc.models.bayes.pivot_tails.tail_scale`). The same
command as above with ``--target-accept R`` (three runs' code differs from any commit, as said; two fits at a time,
so by gradients; the 0.9 rows without either are the table above's tune-150 rows)::

    seed  rate  θ2 form     pivot        pilot    warm-up  kept     total    kept steps  step size    smallest ESS  R-hat  div
    1     0.9   log z       affine       15 825   20 957   34 336   71 118   28.6        -            σ_β 288       1.006  0
    1     0.8   log z       affine       13 618   19 633   19 878   53 129   16.6        0.22-0.28    σ_βR 189      1.028  2
    1     0.8   quantile    affine       15 054   13 627   18 334   47 015   15.3        0.25-0.30    σ_β 198       1.022  4
    1     0.8   quantile    b ≥ SD/4     15 054   22 387   37 200   74 641   31.0        0.14-0.18    σ_βR 244      1.011  0
    1     0.8   quantile    b ≥ SD       15 054   14 417   19 280   48 751   16.1        0.25-0.27    β_R 156       1.028  0
    1     0.9   quantile    b ≥ SD       18 834   16 731   27 824   63 389   23.2        0.19-0.26    σ_βR 217      1.009  0
    3     0.9   log z       affine       16 917   19 143   31 732   67 792   26.4        -            σ_βR 292      1.008  0
    3     0.8   log z       affine       12 024   17 111   22 359   51 494   18.6        0.21-0.24    σ_βR 97       1.018  3
    3     0.8   quantile    affine       12 863   15 568   18 091   46 522   15.1        0.24-0.28    σ_βR 209      1.010  1
    3     0.8   quantile    b ≥ SD/4     12 863   21 314   33 696   67 873   28.1        0.16-0.23    σ_βR 143      1.039  0
    3     0.8   quantile    b ≥ SD       12 863   13 543   18 120   44 526   15.1        0.25-0.29    σ_βR 182      1.036  0
    3     0.9   quantile    b ≥ SD       14 747   15 644   26 672   57 063   22.2        0.19-0.23    σ_βR 288      1.016  0

(log z: the ``noncentred`` form before; "quantile, affine": the quantile form without the tail map, an edit of
0e997e7; "b ≥ SD/4": :data:`scioc.models.bayes.pivot_tails.TAIL_GRID` with 0.5 and 0.25 added, where the likelihood chose
0.25 for all 24 subject-runs, the map's bend then inside the bulk, the steps smaller and the trees as deep as at
0.9; "b ≥ SD": the grid as it is, which chose 1 for all 24.) The quantile form took 10-12 % fewer gradients at 0.8
and the tail map removed the divergences (0 in both seeds against 4 and 1) at as few gradients. With 300 kept draws
per chain the smaller ESS and larger R-hat at 0.8 are within the spread of these runs; at full size: README, "Speed".
"""

from __future__ import annotations

from scioc.models.bayes.delayed_model import ADAPTATIONS, PILOT

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
#: The pilot's NUTS target acceptance rate (None: the fit's own, 0.8 since 41cd710, module docstring). Before the
#: tail maps, 0.8 for the pilot alone on two chains (the same command through the wrapper) took 34.4 steps per pilot
#: draw against 39.6 but left 3 divergent transitions in the kept run (0 at the fit's own 0.9 then).
PILOT_TARGET_ACCEPT = None
#: Warm-up draws per chain of a fit without a pilot run (``scioc fit --tune``'s default), and of the run after it:
#: the pilot's draws measured the coordinates and its last draw is where the chains start (README, "Speed"; 150
#: against 300: module docstring, "The warm-up after the pilot").
TUNE = 1000
TUNE_AFTER_PILOT = 150
#: nutpie's largest tree depth in the pilot run; None: nutpie's own (10), as the kept run's (module docstring, "Tree
#: depth": a cap of 6 was measured, and both full-size fits with it failed the convergence verdict).
PILOT_MAX_TREE_DEPTH = None


def pilot_runs(adaptation: str | None, delay_mode: str, tune: int, draws: int, chains: int = PILOT_CHAINS
               ) -> tuple | None:
    """The pilot runs of a delayed fit, as (tune, draws, chains, target_accept, max_tree_depth) for
    :func:`scioc.pipelines.fit.whiten.sample_whitened`: :data:`PILOT_RUNS` for the ``pilot`` adaptation (the default) with
    profile delays, each no longer than the fit's own warm-up and draws (a small fit gets a small pilot; at least 2
    draws), on :data:`PILOT_CHAINS` chains (at most the fit's) at :data:`PILOT_TARGET_ACCEPT`, its trees no deeper
    than :data:`PILOT_MAX_TREE_DEPTH` (None: the fit's own); None otherwise."""
    if delay_mode != "profile" or (adaptation or ADAPTATIONS[0]) != PILOT:
        return None
    return tuple((min(t, int(tune)), max(2, min(d, int(draws))), min(PILOT_CHAINS, int(chains)), PILOT_TARGET_ACCEPT,
                  PILOT_MAX_TREE_DEPTH) for t, d in PILOT_RUNS)


def default_tune(human_model: str | None, delay_mode: str = "profile", adaptation: str | None = None) -> int:
    """``scioc fit``'s warm-up draws per chain when ``--tune`` is not given: :data:`TUNE_AFTER_PILOT` for a delayed fit
    with a pilot run (:func:`pilot_runs`), else :data:`TUNE`."""
    if human_model == "delayed" and pilot_runs(adaptation, delay_mode, TUNE, TUNE) is not None:
        return TUNE_AFTER_PILOT
    return TUNE


__all__ = ["PILOT_CHAINS", "PILOT_MAX_TREE_DEPTH", "PILOT_RUNS", "PILOT_TARGET_ACCEPT", "TUNE", "TUNE_AFTER_PILOT",
           "default_tune", "pilot_runs"]
