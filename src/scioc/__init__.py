"""scioc: shared-control inverse optimal control.

Identify the cost function a human minimises when steering with and without a haptic assistant
(Inga et al., SMC 2018), and compare it between conditions in a Bayesian workflow.

- :mod:`scioc.models`: the mathematics (pure functions on arrays);
- :mod:`scioc.pipelines`: the workflow (I/O, validation, the CLI, reports);
- :func:`configure`: the process settings that bit-for-bit results need (the CLI calls it);
- :func:`open_run`: a run folder's tables, posteriors, verdicts and lineage, for notebooks.

Importing :mod:`scioc` changes no process setting.
"""

from scioc.models.runtime import configure

__all__ = ["configure", "open_run"]
__version__ = "0.1.0"


def __getattr__(name):
    if name == "open_run":  # imported on first use: it reads tables (pandas) and posteriors (ArviZ)
        from scioc.pipelines.run_folder import open_run

        return open_run
    raise AttributeError(f"module 'scioc' has no attribute {name!r}")
