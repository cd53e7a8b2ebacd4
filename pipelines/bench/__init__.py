"""``scioc bench``: measured speed, one module per part.

=========================  ===========================================================
module                     what it measures
=========================  ===========================================================
:mod:`.likelihood`         dense Eq. 11-16 against the linear-time kernel, the study batch
:mod:`.identify`           identification of the default study, reconstruction, adequacy
:mod:`.fit`                the full hierarchical fit (and ``scioc bench-fit``)
:mod:`.fit_delayed`        the delayed human's fit on its own study (``scioc bench-fit``); the delay's profile
:mod:`.delayed_workflow`   the delayed fit as ``scioc fit`` runs it: issue 13's 15-minute goal
:mod:`.sbc`                calibration throughput with one and two Dask workers
:mod:`.common`             the timer, the machine, the default study prepared once
:mod:`.suite`              :func:`run_bench`, all parts in order
=========================  ===========================================================
"""

from scioc.pipelines.bench.suite import PARTS, run_bench

__all__ = ["PARTS", "run_bench"]
