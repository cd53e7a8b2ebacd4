"""Human models, one seam each: the interface (:class:`HumanModel`), the registry (:func:`get`, :func:`register`)
and the built-in models.

- :mod:`.registry`: :class:`HumanModel`, :class:`FitContext`, :class:`FitOutcome`, the registry;
- :mod:`.maxent`: the paper's max-ent LQ human;
- :mod:`.delayed`: with a perceptual delay, a neuromuscular lag and motor noise.

A stage asks ``get(settings.human_model)`` and calls its methods; no stage compares a model's name.
"""

from scioc.pipelines.human_model.delayed import DELAYED
from scioc.pipelines.human_model.maxent import MAXENT
from scioc.pipelines.human_model.registry import (
    FitContext,
    FitOutcome,
    HumanModel,
    get,
    names,
    register,
    unregister,
)

register(MAXENT)
register(DELAYED)

__all__ = ["FitContext", "FitOutcome", "HumanModel", "get", "names", "register", "unregister"]
