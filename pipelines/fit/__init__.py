"""``scioc fit``: the hierarchical Bayesian fit of a study (:mod:`scioc.pipelines.fit.stage`) and its parts.

=========================  ===========================================================
module                     what it holds
=========================  ===========================================================
:mod:`.sampling`           nutpie through ``pm.sample``: seeds, clean stdout, Ctrl-C, log lines
:mod:`.start`              where the chains start: near the ML estimates
:mod:`.whiten`             sampling on each subject's whitened coordinates (and after a pilot run)
:mod:`.warmup`             how long the warm-up is: the default, and the delayed fit's pilot run
:mod:`.diagnostics`        R-hat, ESS, E-BFMI, divergences and the sampler's verdict
:mod:`.contrasts`          β, exp(β), P(β < 0), HDIs, per-subject contrasts
:mod:`.loo`                PSIS-LOO over segments and leave-one-subject-out
:mod:`.ppc`                posterior predictive draws and ``constant_data``
:mod:`.checks`             mixed model, truth check, adequacy at a posterior point
:mod:`.delayed`            the delayed human's fit: delays, sampling, results, adequacy
:mod:`.human_models`       leave-one-subject-out between a max-ent and a delayed fit
:mod:`.recheck`            ``scioc adequacy``: a finished fit's adequacy, again
:mod:`.stage`              :func:`fit_to_dir` (the artifacts)
:mod:`.summary`            :func:`format_fit`: the lines ``scioc fit`` prints
=========================  ===========================================================

Importing this package imports PyMC (seconds): the CLI imports it only to fit.
"""

from scioc.pipelines.fit.checks import mixedlm_check, truth_check
from scioc.pipelines.fit.diagnostics import ESS_MIN, RHAT_MAX, diagnostics
from scioc.pipelines.fit.stage import fit_to_dir
from scioc.pipelines.fit.summary import format_fit

__all__ = ["fit_to_dir", "format_fit", "diagnostics", "mixedlm_check", "truth_check", "ESS_MIN", "RHAT_MAX"]
