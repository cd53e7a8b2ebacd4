"""The mathematics of scioc: plant, costs, optimal control, max-ent likelihood, simulators.

Pure functions on arrays; no file I/O, no printing, no CLI. Never imports :mod:`scioc.pipelines`.
Importing it changes no process setting; :func:`scioc.configure` does (:mod:`scioc.models.runtime`).
"""
