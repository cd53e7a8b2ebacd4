"""Provenance for JSON sidecars: package versions and the machine."""

from __future__ import annotations

import platform
from importlib import metadata

PACKAGES = ("scioc", "numpy", "scipy", "numba", "pandas", "pyarrow", "pymc", "pytensor", "nutpie", "arviz",
            "statsmodels", "matplotlib", "dask", "distributed")


def versions() -> dict:
    """Installed versions of the packages scioc's results depend on, and the Python/machine."""
    out = {"python": platform.python_version(), "machine": platform.machine()}
    for name in PACKAGES:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out
