"""The forms of the ``delayed`` model's blocks for the data at hand (``scioc fit --human-model delayed``).

Centred or non-centred is a choice of coordinates, not of model: the posterior is the same,
the sampler's geometry is not. Centred suits a block whose values the data fix more tightly
than the population spreads them; non-centred one the data leave loose (Papaspiliopoulos,
Roberts & Sköld 2007). Which holds differs between a human with lag and motor noise and one
without, so the fit measures the data by their ML estimates (``scioc identify --human-model
delayed``, or the fit's own delay profile) and records each choice and its reason in the
sidecar (``delayed_form``).

The baseline log R (both levels). Policy noise (variance 1/(2S), S ∝ R) and motor noise explain
the same torque variability but for the motor noise's moving average. With motor noise in the
data, R is barely fixed per unit (SD of log R about 0.4, against a population SD of about 0.3:
:mod:`scioc.models.bayes.delayed_model`, "Geometry"), so non-centred. Without it, the policy noise
carries the variability alone and fixes R as in the max-ent model, whose default is centred:
in the full-size fit of the max-ent human (README "Measured: the paper's study with a torque
sensor"), which was non-centred, each unit's posterior SD of log R was 0.05 (median) against
σ_R 0.33, and μ_R and σ_R mixed worst (R-hat 1.059 and 1.016, ESS 78 and 127, 8 divergences).
:func:`log_R_form` therefore follows the motor noise's block: centred where the estimates find
no motor noise. Measured on 12 subjects of each human (``scioc fit S/study.parquet
--human-model delayed --estimates S/delayed/estimates.parquet --chains 2 --draws 300 --tune
300 --adequacy-boot 19 --seed N --log-R-form F``; the max-ent human of ``scioc simulate
--experiment data/examples/paper-torque-sensor/experiment.toml --subjects 12`` and the ``kbl`` human of README "Which part
of the warm-up", each identified by ``scioc identify --human-model delayed``; whitened; steps
per warm-up and kept draw, divergences; of the population parameters the smallest ESS (of bulk
and tail) and the largest R-hat, each with its parameter; of the units' log R the smallest ESS and
the largest R-hat; of 600 draws)::

    human   log R, seed     steps        div   population                    units' log R
    maxent  noncentred, 1   50.5  32.9    9    μ_R 27; μ_R 1.067             21, 1.072
    maxent  noncentred, 2   59.2  34.2    3    μ_R 14; μ_R 1.131             16, 1.111
    maxent  centred, 1      47.6  30.4    3    s_m 99; μ_log θ1 1.033        169, 1.017
    maxent  centred, 2      40.7  30.2    5    s_m 63; β_R 1.020             54, 1.025
    kbl     noncentred, 1   56.4  46.7    3    σ_R 51; σ_R 1.054             91, 1.037
    kbl     noncentred, 2   56.3  48.1    1    σ_R 87; μ_R 1.024             116, 1.029
    kbl     centred, 1      27.7  27.3   26    μ_R 6; μ_R 1.282              9, 1.187
    kbl     centred, 2      25.5  26.0   22    σ_βR 15; σ_βR 1.134           26, 1.078

(2026-12-05, with the kernel before its reverse-mode plan, other jobs beside them: steps and
ESS, not seconds.) Centred, the max-ent human's log R and population mix several times better;
the ``kbl`` human's do not mix at all and diverge (the funnel of a loose block under its scale).
Divergences remain with either form on the max-ent human; 17 of its 20 divergent draws had the
motor-noise scale s_m above its posterior median (σ_m non-centred, ``s_m z``, on data where σ_m is
near 0: a funnel between s_m and z).

Motor noise. Where the estimates find none, every σ_m sits near 0 and the data bound it from
above only. The likelihood depends on σ_m through σ_m² (the covariance diag(1/(2S)) + σ_m² C Cᵀ,
:mod:`scioc.models.delayed.kernel`), about -κ σ_m² near 0. Non-centred, the sampler moves log z
(PyMC's log transform of z ~ HalfNormal(1)), where that bound is the doubly exponential wall
exp(-κ s_m² e^(2 log z)); folded (σ_m = s_m |z|, z ~ N(0, 1) unconstrained; the law of σ_m is
the same half-normal) it is the Gaussian exp(-κ s_m² z²) around the interior point z = 0. So
:data:`LOOSE_FORM` folds σ_m. τ_nm stays non-centred: near 0 the likelihood is linear in τ_nm
(α ≈ τ_nm (Φ b_w)_1 / b_1, :mod:`scioc.models.bayes.delayed_lag`), so folded it has a kink at z = 0;
one run with both blocks folded took 265.7 leapfrog steps per kept draw with 74 divergent
transitions. Measured on the 12-subject max-ent study above, target acceptance 0.9 (the
default), log R centred, seeds 1-4; the forms by a wrapper that replaces
:func:`choose_delayed_form`'s σ_m (and with it, the s_m prior of
:class:`scioc.models.bayes.delayed_blocks.DelayedPriors`), as ``scioc fit`` has no option for them;
divergent transitions per run, leapfrog steps per kept draw, ESS (smaller of bulk and tail, of
600 draws) of s_m and the smallest of the units' σ_m::

    σ_m block, s_m prior       divergent   kept steps            s_m ESS          units' σ_m ESS
    non-centred, half-normal   1 0 1 1     40.0 31.8 31.1 31.7   52 77 80 13      53 90 71 19
    folded, half-normal        0 0 0 0     31.1 31.2 31.6 31.0   59 29 26 91      71 29 37 90
    folded, Gamma(2, rate 8)   0 0 0 0     31.2 31.1 31.0 31.6   108 46 109 76    117 74 192 138

(2026-12-05; seeds 1-2 of the first row are the "Whitened" table's 0.9 rows of
:mod:`scioc.models.bayes.delayed_model`.) Folding removed the divergences; s_m itself mixed no
better, as below its data's upper bound s_m's posterior is its prior, and the half-normal's
(flat at 0) is an exponential tail in log s_m (log s_m from -7.7 to -2.9, 1 % to 99 %, seed 2). The Gamma prior (the default since,
:class:`scioc.models.bayes.delayed_blocks.DelayedPriors`) shortens that tail (-6.4 to -2.5) and about
doubled the ESS of s_m and the units' σ_m; β, the units' σ_m upper ends and the steps did not
change. Holding s_m, for the whitening and the start, at the half-normal ML scale of the subjects'
σ_m estimates (0.068 here) instead of PyMC's initial point (0.3) did not help s_m's mixing (two
runs: 0 and 3 divergent, s_m ESS 22 and 49). Since a6bd517 every population scale is held at its
units' spread all the same (:func:`scioc.pipelines.fit.start.scale_estimate`), for the warm-up's first
draws, which no longer travel down to it; s_m's ESS was no better at full size (README, "The
start of the population").

The motor-noise scale's prior and σ_m's folded centred form (the defaults since 2026-12-05's
last change). Below the data's bound s_m's posterior is its prior, so what mixes is the prior's
tail towards 0, and the form that suits it depends on that tail. An inverse gamma on s_m²
(:class:`scioc.models.bayes.delayed_blocks.DelayedPriors`, ``sigma_m_variance_inverse_gamma``, IG(1, 0.03):
s_m's median 0.21 N·m as the Gamma's) vanishes at 0 faster than any power, so s_m stays where
the 42 (here 12) subjects' σ_m fix it, and centred is then the form whose coordinates are nearly
independent: each σ_m held by its data's bound, s_m by the σ_m (a conditional SD of about
1/sqrt(2n) in log s_m, about its marginal one). Folded, s_m |z| with s_m held off 0, presses
every z against its bound instead (at full size 72 leapfrog steps per draw against 31, session
notes of 2026-12-05). So σ_m's loose form is ``folded_centred``, |v| with v ~ N(0, s_m)
unconstrained (:func:`scioc.models.bayes.delayed_blocks.half_normal_block`): the half-normal law,
centred, without the log transform's tail at σ_m -> 0. Measured as the table above (12
subjects of the max-ent human, 2 chains × (300 + 300) draws, log R centred, whitened, defaults
of 2f87f97 otherwise; the prior and form by a wrapper that replaces
:func:`scioc.models.bayes.delayed_blocks.motor_blocks`; per run: leapfrog steps per warm-up and kept
draw, divergent transitions, s_m's bulk and tail ESS, its 5-50-95 % quantiles, the smallest of
the units' σ_m ESS)::

    s_m prior, σ_m block          seed   steps       div   s_m ESS      s_m, N·m            units' σ_m
    Gamma(2, 8), folded           1      43.2 31.1   4     30 / 20      0.009 0.028 0.058   54
    Gamma(2, 8), folded           2      48.0 32.0   0     37 / 41      0.008 0.026 0.046   53
    Gamma(2, 8), folded centred   1      35.7 30.6   8     59 / 62      0.006 0.026 0.050   62
    Gamma(2, 8), folded centred   2      35.2 31.0   0     28 / 131     0.011 0.029 0.054   53
    Gamma(2, 8), partial (w 0.5)  1      35.5 28.9   0     72 / 165     0.009 0.026 0.053   102
    Gamma(2, 8), partial (w 0.5)  2      37.8 30.7   0     115 / 186    0.010 0.026 0.050   113
    IG(1, 0.03) on s_m², folded   1      51.9 34.2   0     126 / 137    0.059 0.080 0.113   137
    IG(1, 0.03) on s_m², folded   2      50.3 34.9   0     177 / 198    0.058 0.078 0.107   121
    IG(1, 0.03), folded centred   1      40.2 31.7   0     1110 / 406   0.058 0.076 0.113   128
    IG(1, 0.03), folded centred   2      39.6 31.9   0     1667 / 480   0.058 0.078 0.108   127
    the same, ``scioc fit``       1      40.1 32.2   0     892 / 505    0.059 0.077 0.104   92
    the same, ``scioc fit``       2      40.2 32.9   0     837 / 272    0.056 0.077 0.111   66

(the partial form: v ~ N(0, s_m^w), σ_m = s_m^(1-w) |v|; the last two rows are the defaults since
a00806a, by ``scioc fit s12/study.parquet --human-model delayed --estimates s12/delayed/estimates.parquet
--chains 2 --draws 300 --tune 300 --seed N``, not the wrapper; the first two rows are the defaults of
before; the folded IG rows ran the session before, at the commit before a6bd517, when the same
defaults gave s_m an ESS of 93 / 113 and 80 / 81 with these seeds.) Only the inverse gamma with the
centred form moves s_m freely (ESS above the 600 draws in bulk); the Gamma's tail towards 0 is
slow in either form, and its centred form is a funnel there (8 divergent transitions in one
run). β's 94 % interval is the same in every row to within 0.03. The price is the prior: it puts
s_m below 0.05 N·m at odds of about 1 in 160 000, so on a human without motor noise the
population's scale sits near 0.06-0.08 N·m (the Gamma's posterior: 0.006-0.05) while each
subject's σ_m stays below its data's bound. Human motor noise is never absent (Kleinman, Baron
& Levison 1970; the ``kbl`` human's 0.25 N·m), and the subjects' σ_m, not s_m, are what the
likelihood sees.

The ridge's pivot with a signed ρ (``--R-population policy_scale`` with ρ folded or folded centred;
:func:`scioc.models.bayes.delayed_blocks.ridge_pivots`). On the 12 subjects of the ``kbl`` human of README
"Which part of the warm-up", fitted with ρ folded centred and the bend along σ_m (README, "Not yet"), 10
of the 12 subjects' ρ̃ changed sign within a chain (positive in 25-85 % of a chain's draws; the other two
kept one sign), and every subject's σ_m fell as |ρ̃| grew (correlation of |ρ̃| and σ_m -0.21 to -0.73;
read ad hoc from that fit's posterior): the arch that ridge_pivots' docstring describes, which a bend
along σ_m cannot follow. Bent along ρ̃ (``scioc fit s12/study.parquet --human-model delayed --estimates
s12/delayed/estimates.parquet --chains 2 --draws 300 --tune 300 --adequacy-boot 19 --seed N
--R-population policy_scale --rho-form folded_centred``; the first two rows at b564776, before
the ridge's pivot; per run the leapfrog steps per warm-up and kept draw, divergent transitions, of the
population parameters the smallest ESS (of bulk and tail) and the largest R-hat, of the units' log R
the smallest bulk ESS and the largest R-hat; of 600 draws)::

    bend along   seed   steps        div   population                    units' log R
    σ_m          1      92.1  95.1   1     σ_βR 141; ρ's scale 1.010     62, 1.042
    σ_m          2      120.2 83.2   0     σ_βR 186; s_m 1.022           54, 1.031
    ρ̃            1      39.3  31.9   0     σ_βR 86; σ_βR 1.019           77, 1.027
    ρ̃            2      37.6  31.2   0     β_R 178; β 1.016              220, 1.010

A third of the leapfrog steps, as many as the lognormal population's (33.3 and 33.6 with the same
seeds, whose worst population parameter, μ_R, had ESS 48 and 12): per gradient about 1.8 and 2.5 times
the population ESS of the bend along σ_m, and the units' log R mix at least as well.

The form of ρ (:func:`choose_delayed_form`). On the max-ent human the same options go wrong the
other way: its data fix each ρ far from the fold (ρ̂/SE about 10), so a signed ρ̃ has two modes,
±ρ, each a few thousandths wide, joined only over the arch through large σ_m; and σ_m, not ρ,
sits at its fold. The 12-subject max-ent study above, the same command with ``--rho-form F`` (per
run as the table above; "ρ̃" at e524099, the others at f0acfef, whose
:func:`scioc.models.bayes.whiten.nearest_fold` bent every one of the 12 subjects along σ_m; "lognormal":
no ``--R-population``, the default)::

    ρ's form, bend              seed   steps        div   population                    units' log R
    folded centred, ρ̃           1      113.1 82.0   13    σ_β 146; σ_β 1.014            26, 1.070
    folded centred, per subject 1      47.0  30.7   1     σ_β 175; ρ's scale 1.020      268, 1.019
    folded centred, per subject 2      150.6 144.8  2     τ_nm's scale 114; ρ's scale   89, 1.028
                                                          1.012
    centred, σ_m                1      27.9  24.6   0     σ_β 152; σ_βR 1.010           223, 1.013
    centred, σ_m                2      26.2  28.2   4     σ_β 81; σ_β 1.042             182, 1.011
    lognormal, σ_m              1      25.5  20.8   0     σ_β 138; τ_nm's scale 1.012   274, 1.011
    lognormal, σ_m              2      25.0  19.7   0     τ_nm's scale 67; τ_nm's       338, 1.025
                                                          scale 1.015

Per subject, the bend follows the arch (seed 1) until a subject crosses it (seed 2: S07's ρ̃ sat at
-ρ in one chain and +ρ in the other, and the whitening had given its σ_m a scale ten times the
others'; read ad hoc from the fit and its whitening). Centred, ρ has one mode, its block mixes as the lognormal's, and
only the motor-noise funnel's rare divergences remain (seed 2: all four in one chain with s_m above
its 95 % quantile). So ρ is centred where the estimates fix it, like τ_nm's and σ_m's blocks, and
folded centred (the ``kbl`` rows above) where they do not.

Per subject (``mixed``, :func:`scioc.models.bayes.noise_blocks.mixed_half_normal_block`). A study of the
``kbl`` human has both kinds of subject. In its full-size fit with ρ folded centred (README, "Not
yet": the run that passed the verdict at 2540 s of sampling), the 9 subjects whose posterior |ρ| was
at least 3.4 of its SDs from 0 changed the sign of ρ̃ 0-16 times in a chain of 1000 draws, the other
33 13-604 times: for those 9 the two modes ±ρ are nearly apart, as on the max-ent human (read ad hoc
from that fit's posterior). Their units' estimates, combined (:func:`rho_pinned`), flag 14 subjects,
those 9 among them. ``mixed`` makes ρ's block centred for the subjects the estimates flag and folded
centred for the others, each subject bending along ρ̃ where it is signed and along σ_m elsewhere
(:func:`scioc.models.bayes.delayed_blocks.ridge_pivots`). On the 12-subject ``kbl`` study above
(``--R-population policy_scale``, seed 1, run before e7cd12a was committed; its sidecar records
``mixed`` with 3 of 12 subjects centred): 40.0 and 31.7 leapfrog steps per warm-up and kept draw, 0
divergent, of the population β_R's ESS 144 the smallest and σ_β's R-hat 1.015 the largest, the
units' log R at least ESS 79 and at most R-hat 1.028: as the folded centred rows (12 subjects have
few that the data pin). At full size it did worse (the same study and estimates, ``scioc fit ...
--R-population policy_scale --seed 2018`` at e7cd12a, when the data chose ``mixed``: 14 of 42
subjects centred): 27 divergent transitions in its first 3754 of 8000 draws, at 80 leapfrog steps
per draw, where the folded centred form had none at 78; stopped there (where they diverged was not
read). So the data choose folded centred unless they fix every subject's ρ, and ``mixed`` is an
option (``--rho-form mixed``), not a default.

Polar, squared, and the low-rank mass matrix, on the hard twelve. The 12 subjects of the full-size
``kbl`` study (``scioc bench --parts fit_delayed --humans kbl``'s, seed 2018) whose posterior read
worst in session 33's diagnosis (S04, S08, S10, S14, S20, S21, S22, S23, S28, S39, S40, S42), cut
from its ``study.parquet`` and ``estimates.parquet`` by subject (pandas, ad hoc), fitted as the
12-subject rows above with ``--R-population policy_scale --rho-form F`` (``lr``: ``--adaptation
curved_low_rank``, then run through a wrapper that patched ``nutpie_options``; 2026-12-06, with other
fits beside some of them, which moves no step count)::

    ρ's form (bend)        mass matrix  steps        div  step size    population: smallest ESS; R-hat   units' log R
    folded centred (ρ̃)     diagonal     49.7  58.0   0    0.131 0.099  β_R 84; β_R 1.023                 43, 1.050
    polar (φ)              diagonal     45.6  43.7   0    0.158 0.115  σ_βR 141; σ_βR 1.019              33, 1.044
    squared (u)            diagonal     36.6  30.7   33   0.175 0.208  σ_βR 96; τ_θ2 1.015               37, 1.031
    folded centred (ρ̃)     low rank     76.0  33.2   0    0.141 0.146  σ_βR 107; σ_β 1.016               41, 1.036
    polar (φ)              low rank     84.4  31.6   0    0.174 0.147  σ_βR 77; σ_βR 1.045               130, 1.030
    squared (u)            low rank     60.7  30.6   1    0.189 0.160  σ_βR 191; s_ρ 1.015               147, 1.021

The same twelve, read in the model's unconstrained coordinates of the first row's draws (ad hoc): the
trade-off the data leave is between ρ² and τ_nm (τ_nm on ρ² linear, R² 0.56-0.90 per subject), much
more than between ρ² and σ_m² (R² 0.02-0.47, τ_nm free). ρ̃ changed sign 12-62 times in 600 draws
for S04, S14, S20, S22 and S42 (0-5 for the others); of those read closely (S04, S08, S20, S42), log
τ_nm, and often log σ_m and log θ1's mean, lie on ρ̃ along parabolas about ρ̃ = 0, with a dip there (ρ
= 0 less likely than their mode, not excluded); those whose ρ̃ kept its sign (S21, S23, S40) lie on a
straight ridge of ρ̃, log τ_nm and log σ_m (smallest eigenvalue of the correlation 0.015-0.023),
which the whitening takes out. So: polar coordinates (:mod:`scioc.models.bayes.noise_blocks`, k from
:mod:`scioc.pipelines.fit.noise_arcs`, 7 of the 12 in them) straighten less than their arcs promised, a
quarter fewer steps; ρ = u² removes the dip (no sign changes at all) and halves the steps, but its
density vanishes at u = 0 like |u|, and for S04, S14, S20 and S22, whose ρ reaches 0, the draw with
the smallest |u| was a divergent one; nutpie's low-rank mass matrix on the curved coordinates,
which learns the correlations the whitening leaves, cuts the kept draws' steps of the folded
centred and polar forms to about the squared form's (58.0 -> 33.2, 43.7 -> 31.6), at the price of
an expensive middle warm-up (tenths 5-6: 139-218 steps per draw). None of the three is a default:
``--rho-form polar`` and ``--rho-form squared`` are options, and the low-rank matrix
(``--adaptation curved_low_rank``) is measured at full size in README, "Speed".

The population of R (:func:`choose_R_population`). On the max-ent human the policy-scale population
with ρ centred (the form the estimates choose there; the full-size study of README "Speed", ``scioc
fit ... --R-population policy_scale --seed 2018`` at fdc832d, with two 12-subject fits beside it for
some minutes) ran at 64 leapfrog steps per draw and had 41 divergent transitions in its first 2793
of 8000 draws, when it was stopped; the lognormal population passes the verdict on the same study at
about 31 (README). On the ``kbl`` human the lognormal population's μ_R and σ_R do not mix in any
form tried. So the population follows the data: lognormal where the estimates fix the R of at least
half the subjects (on the max-ent human every subject's combined z is at least 4.4, median 23.6, at
full size), the policy scale where they leave more than half loose (on the ``kbl`` human 28 of 42
subjects, median z 2.15), since a subject whose R may be infinite (no policy noise, as the KBL
model's human) is then inside the population. By the median subject, as the other blocks' forms: a
few loose subjects among many whose data fix R leave σ_R held by the many, and the policy scale
failed where most subjects' R is fixed (a study of such a mixture has not been fitted). The two
populations are models of the same quantity that differ where the data say little about it; the
sidecar records which was used and why (``R_population_reason``), and ``--R-population`` chooses one
instead.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scioc.models.bayes.delayed_blocks import DelayedForm

#: τ_nm's and σ_m's blocks are centred when the median over units of (ML estimate / its SE) is at
#: least this: the data then pin each subject's value (models/bayes/delayed_model.py, "Geometry").
CENTRED_Z = 3.0
#: The form of τ_nm's and σ_m's blocks where the data do not pin them (module docstring, "Motor noise").
LOOSE_FORM = {"tau_nm": "noncentred", "sigma_m": "folded_centred"}
#: The forms the baseline log R blocks may take (``scioc fit --log-R-form``; default: :func:`log_R_form`).
LOG_R_FORMS = ("centred", "noncentred")
#: θ2's form in the delayed fit (:func:`scioc.models.bayes.blocks.theta2_block`: the recorded torque leaves θ2 at its prior,
#: which is a standard normal in this form; measured: :mod:`scioc.pipelines.fit.warmup`, "The pivot's tails").
THETA2_FORM = "quantile"


def choose_delayed_form(estimates: pd.DataFrame | None, subjects=None) -> tuple[DelayedForm, str]:
    """The forms of the lag, motor-noise and policy-scale blocks for these data, and why (recorded in the sidecar).

    Per block, z = ML estimate / SE per unit (0 where the estimate is at its bound 0 or has
    no SE); centred if the median z is at least :data:`CENTRED_Z` (a delayed human: the data
    fix each subject's value, and a non-centred scale would form a ridge with them), else
    :data:`LOOSE_FORM` (a human without lag or motor noise: the values sit at 0, where a centred
    half-normal forms a funnel with its scale): τ_nm non-centred, σ_m folded centred (module docstring,
    "Motor noise" and "The motor-noise scale's prior"). ρ = R^(-1/2) (``--R-population policy_scale``
    only) likewise, with z = ρ̂ / SE(ρ̂) = 2 / SE(log R̂) (0 where R is at its bound): centred where the data
    fix it, else folded centred; given ``subjects`` (the model's order), per subject (its units' z combined,
    :func:`rho_pinned`, recorded as ``rho_pinned`` for ``--rho-form mixed``): centred where the data fix every
    subject's ρ (module docstring, "The form of ρ"). Without estimates: τ_nm and σ_m non-centred, ρ folded.
    """
    if estimates is None or not {"tau_nm", "se_tau_nm", "sigma_m", "se_sigma_m"} <= set(estimates.columns):
        return DelayedForm("noncentred", "noncentred"), "non-centred (no delayed estimates to measure the data by)"
    forms, why = {}, []
    for name in ("tau_nm", "sigma_m"):
        v = pd.to_numeric(estimates[name], errors="coerce").to_numpy(dtype=float)
        se = pd.to_numeric(estimates[f"se_{name}"], errors="coerce").to_numpy(dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):  # an SE of 0 or NaN: not valid, z unused there
            z = v / se
        forms[name], reason = _form_by_z(name, z, se > 0)
        why.append(reason)
    if "se_log_R" in estimates.columns:
        if subjects is not None and "subject" in estimates.columns:
            forms["rho"], forms["rho_pinned"], reason = _rho_by_subject(estimates, subjects)
        else:
            se = pd.to_numeric(estimates["se_log_R"], errors="coerce").to_numpy(dtype=float)
            with np.errstate(divide="ignore"):
                z = 2.0 / se
            forms["rho"], reason = _form_by_z("rho", z, se > 0, loose="folded_centred")
        why.append(reason + " (with --R-population policy_scale)")
    return DelayedForm(**forms), "; ".join(why)


def rho_pinned(estimates: pd.DataFrame, subjects) -> tuple[bool, ...]:
    """Per subject of ``subjects`` (in their order): do its estimates fix ρ = R^(-1/2)? Its units' z = ρ̂/SE(ρ̂) =
    2/SE(log R̂) (0 where R is at its bound, without an SE) combined, sqrt(Σ z²) (the z of their inverse-variance
    mean, as if they shared one ρ), at least :data:`CENTRED_Z`. A subject without units in ``estimates``: no."""
    se = pd.to_numeric(estimates["se_log_R"], errors="coerce").to_numpy(dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(np.isfinite(2.0 / se) & (se > 0), 2.0 / se, 0.0)
    by_subject = np.sqrt((pd.Series(z) ** 2).groupby(estimates["subject"].astype(str).to_numpy()).sum())
    return tuple(bool(by_subject.get(str(s), 0.0) >= CENTRED_Z) for s in subjects)


def _rho_by_subject(estimates: pd.DataFrame, subjects) -> tuple[str, tuple, str]:
    """(ρ's form, rho_pinned, reason): centred if :func:`rho_pinned` flags every subject, else folded centred (not
    ``mixed``, which diverged where folded centred did not: module docstring, "Per subject")."""
    pinned = rho_pinned(estimates, subjects)
    form = "centred" if all(pinned) else "folded_centred"
    return form, pinned, (f"rho {form} ({sum(pinned)} of {len(pinned)} subjects with their units' estimate/SE "
                          f"combined at least the threshold {CENTRED_Z:g})")


def choose_R_population(estimates: pd.DataFrame | None, subjects) -> tuple[str, str]:
    """The population of the subjects' baseline R (:class:`scioc.models.bayes.delayed_blocks.DelayedPriors`'s
    ``R_population``) for these data, and why: ``lognormal`` (the max-ent model's) where the estimates fix the R of
    at least half the subjects (:func:`rho_pinned`; as the other blocks' forms, by the median subject), else
    ``policy_scale`` (module docstring, "The population of R"); lognormal without estimates with an SE of log R."""
    if estimates is None or not {"se_log_R", "subject"} <= set(estimates.columns):
        return "lognormal", "lognormal: no estimates of R with SEs to measure the data by"
    pinned = rho_pinned(estimates, subjects)
    n, fixed = len(pinned), sum(pinned)
    if 2 * fixed >= n:
        return "lognormal", (f"lognormal: the estimates fix the R of {fixed} of {n} subjects (their units' "
                             f"2/SE(log R) combined at least {CENTRED_Z:g}), at least half")
    return "policy_scale", (f"policy_scale: the estimates leave the R of {n - fixed} of {n} subjects loose (their "
                            f"units' 2/SE(log R) combined below {CENTRED_Z:g}; R may be infinite, no policy noise), "
                            "more than half, so R^(-1/2) has a half-normal population")


def _form_by_z(name: str, z: np.ndarray, valid: np.ndarray, loose: str | None = None) -> tuple[str, str]:
    """Centred if the median of ``z`` (0 where not ``valid`` or not finite) is at least :data:`CENTRED_Z`, else
    ``loose`` (default ``LOOSE_FORM[name]``); and the reason."""
    z = np.where(np.isfinite(z) & valid, z, 0.0)
    med = float(np.median(z))
    form = "centred" if med >= CENTRED_Z else (LOOSE_FORM[name] if loose is None else loose)
    return form, f"{name} {form} (median estimate/SE {med:.3g}, threshold {CENTRED_Z:g})"


def log_R_form(delayed_form: DelayedForm) -> tuple[str, str]:
    """The form of the baseline log R blocks (both levels) and why: centred where the motor noise's block is
    not centred (non-centred or folded: the estimates find no motor noise), else non-centred (module docstring)."""
    if delayed_form.sigma_m != "centred":
        return "centred", (f"log R centred: σ_m's block is {delayed_form.sigma_m} (no motor noise found), so the "
                           "policy noise alone fixes each unit's R")
    return "noncentred", ("log R non-centred: σ_m's block is centred (motor noise found), which the policy noise "
                          "trades off against, leaving R loose per unit")


__all__ = ["CENTRED_Z", "LOG_R_FORMS", "LOOSE_FORM", "THETA2_FORM", "choose_R_population", "choose_delayed_form",
           "log_R_form", "rho_pinned"]
