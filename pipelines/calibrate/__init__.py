"""``scioc calibrate``: simulation-based calibration (Talts et al. 2018), locally or on Dask, resumable.

:mod:`.config`         :class:`CalibrationConfig`, the level defaults, seeds
:mod:`.simulation`     the fitted wheel, the window, the exact demonstration, caches
:mod:`.ranking`        the one loop: sample, thin, rank, PIT, keep the thinned draws
:mod:`.unit`           the unit-level replication (:mod:`.unit_delayed`: of the ``delayed`` human)
:mod:`.study`          the study-level replication
:mod:`.store`          replication files, configuration, resume rules
:mod:`.execution`      Dask: tasks, the scheduler check, :func:`calibrate`
:mod:`.summary`        uniformity tests, coverage, contraction, the simuk-layout tree
"""

from scioc.pipelines.calibrate.config import DEFAULTS, CalibrationConfig, level_configs
from scioc.pipelines.calibrate.execution import calibrate, calibrate_runs, check_scheduler
from scioc.pipelines.calibrate.store import rep_path
from scioc.pipelines.calibrate.summary import FAMILY_ALPHA, as_expected, format_summary

__all__ = ["DEFAULTS", "CalibrationConfig", "level_configs", "calibrate", "calibrate_runs", "check_scheduler",
           "rep_path", "FAMILY_ALPHA", "as_expected", "format_summary"]
