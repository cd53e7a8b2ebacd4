"""``scioc report``: the HTML report of a run folder (:func:`build_report`), one module per part.

:mod:`.build`          :func:`build_report`: reads the artifacts, orders the sections
:mod:`.render`         the HTML layer: jinja2 templates (``templates/``), tables, figures
:mod:`.figures`        every matplotlib figure
:mod:`.levels`         the run's experiment and the words for it (levels, assistants, rig)
:mod:`.design`         study design and reference trajectory
:mod:`.identify`       θ1 histogram, Wilcoxon tests, Fig. 6, cross-prediction, details
:mod:`.truth`          reconstruction error, truth vs estimates (simulated studies)
:mod:`.bayes`          the hierarchical fit: diagnostics, LOO, PPC
:mod:`.contrasts`      per contrast: three methods side by side, forest plot, truth check
:mod:`.adequacy`       the model-adequacy verdict, caveats and section
:mod:`.human_models`   the max-ent and delayed human models side by side, which the data support
:mod:`.calibration`    simulation-based calibration
"""

from scioc.pipelines.report.build import build_report

__all__ = ["build_report"]
