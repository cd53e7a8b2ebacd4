"""``scioc bench``: measured speed, one module per part.

:mod:`.likelihood`         dense Eq. 11-16 against the linear-time kernel, the study batch
:mod:`.delayed`            the ``delayed`` likelihood beside the max-ent kernel; its angle likelihood
:mod:`.identify`           identification of the default study, reconstruction, adequacy
:mod:`.fit`                the full hierarchical fit (and ``scioc bench-fit``)
:mod:`.fit_delayed`        the delayed human's fit on its own study (``scioc bench-fit``); the delay's profile
:mod:`.delayed_workflow`   the delayed fit as ``scioc fit`` runs it, against its speed goal
:mod:`.sbc`                calibration throughput with one and two Dask workers
:mod:`.example`            the second built-in example's identification and fit
:mod:`.common`             the timer, the machine, the default study prepared once
:mod:`.suite`              :func:`run_bench`, all parts in order
"""

from scioc.pipelines.bench.suite import DEFAULT_PARTS, PARTS, run_bench

__all__ = ["DEFAULT_PARTS", "PARTS", "run_bench"]
