"""``scioc fit``: the hierarchical Bayesian fit of a study (:func:`fit_to_dir`, in :mod:`.stage`) and its parts.

* :mod:`.sampling`: nutpie through ``pm.sample``; :mod:`.start`: where the chains start, near the ML estimates;
  :mod:`.whiten`: sampling on each subject's whitened coordinates; :mod:`.warmup`: how long the warm-up is.
* :mod:`.diagnostics`: R-hat, ESS, E-BFMI, divergences and the sampler's verdict.
* :mod:`.contrasts`: β, exp(β), P(β < 0), HDIs; :mod:`.loo`: PSIS-LOO over segments and leaving subjects out;
  :mod:`.ppc`: posterior predictive draws; :mod:`.checks`: mixed model, truth check, adequacy at a posterior point.
* :mod:`.delayed`, :mod:`.delayed_forms`: the delayed human's fit and its blocks' forms.
* :mod:`.human_models`: max-ent against delayed by leaving subjects out; :mod:`.recheck`: ``scioc adequacy``;
  :mod:`.summary`: the lines ``scioc fit`` prints.

Importing this package imports PyMC, which is slow: the CLI imports it only to fit.
"""

from scioc.pipelines.fit.checks import mixedlm_check, truth_check
from scioc.pipelines.fit.diagnostics import ESS_MIN, RHAT_MAX, diagnostics
from scioc.pipelines.fit.stage import fit_to_dir
from scioc.pipelines.fit.summary import format_fit

__all__ = ["fit_to_dir", "format_fit", "diagnostics", "mixedlm_check", "truth_check", "ESS_MIN", "RHAT_MAX"]
