"""scioc: shared-control inverse optimal control.

Identify the cost function a human minimises when steering with and without a haptic assistant
(Inga et al., SMC 2018), and compare it between conditions in a Bayesian workflow.

- :mod:`scioc.models`: the mathematics (pure functions on arrays);
- :mod:`scioc.pipelines`: the workflow (I/O, validation, the CLI, reports);
- :func:`configure`: the process settings that bit-for-bit results need (the CLI calls it).

Importing :mod:`scioc` changes no process setting.
"""

from scioc.models.runtime import configure

__all__ = ["configure"]
__version__ = "0.1.0"
