"""Writing a fit's artifacts: strict JSON and NetCDF (atomically), checked before minutes of sampling."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from scioc.pipelines.storage import atomic_path


def strict_json(obj) -> str:
    """Strict JSON: non-finite numbers (an undefined k, a z of 0/0) become null."""

    def clean(x):
        if isinstance(x, float) and not np.isfinite(x):
            return None
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [clean(v) for v in x]
        return x

    return json.dumps(clean(obj), indent=2, allow_nan=False) + "\n"


def require_netcdf() -> None:
    """Fail before minutes of sampling, not after, if NetCDF cannot be written."""
    try:
        import h5netcdf  # noqa: F401
        import h5py  # noqa: F401
    except ImportError as exc:
        raise ImportError(f"writing posterior.nc needs the packages h5netcdf and h5py ({exc}); "
                          "install them with `pip install h5netcdf h5py`") from exc


def write_netcdf(idata, path: Path) -> Path:
    with atomic_path(path) as tmp:
        idata.to_netcdf(tmp, engine="h5netcdf")
    return path


__all__ = ["require_netcdf", "strict_json", "write_netcdf"]
