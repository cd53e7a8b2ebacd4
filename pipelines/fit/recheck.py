"""``scioc adequacy``: a finished fit's adequacy check again, at another point or seed, without refitting; it
writes nothing into the fit folder."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import arviz as az

from scioc.models.plant import discretize
from scioc.pipelines import lineage
from scioc.pipelines.fit.artifacts import strict_json
from scioc.pipelines.fit.human_models import fit_settings, fit_sidecar, fit_study
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.io import load_study
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.storage import WRITTEN_BY, write_text_atomic

#: The command whose results these are (:data:`scioc.pipelines.storage.WRITTEN_BY`).
COMMAND = "scioc adequacy"


def recheck_adequacy(fit_dir, *, at: str = "draw", seed: int | None = None, study=None) -> dict:
    """The adequacy verdict of a finished ``scioc fit`` folder at a posterior point.

    Parameters
    ----------
    fit_dir : str or Path
        A finished fit folder (max-ent or delayed human).
    at : {"draw", "means"}
        The posterior point (:data:`scioc.pipelines.fit.checks.ADEQUACY_POINTS`).
    seed : int, optional
        The adequacy seed (the draw and the bootstrap); default: the fit's.
    study : str or Path, optional
        The study (default: the path ``posterior.json`` records); it must be the one the fit read, by content
        (LineageError naming both files otherwise).

    Returns
    -------
    dict
        ``fit``, ``study``, ``human_model``, ``adequacy`` (as ``contrasts.json``'s) and ``inputs`` (their SHA-256).
    """
    folder = Path(fit_dir)
    side = fit_sidecar(folder)
    settings = fit_settings(side, folder)
    if seed is not None:
        settings = dataclasses.replace(settings, adequacy_seed=int(seed))
    study = fit_study(side, folder, study)
    prepared = prepare_study(load_study(study, settings.design), settings)
    plant = discretize(settings.design.dt, settings.design.wheel)
    idata = az.from_netcdf(folder / "posterior.nc")
    human_model = side.get("human_model", IdentifySettings.human_model)
    summary = get(human_model).posterior_adequacy(idata, prepared, plant, side, folder, at)
    return {"fit": str(folder), "study": str(study), "human_model": human_model, "adequacy": summary,
            "inputs": {"fit": lineage.entry(folder), "study": {**side["inputs"]["study"], "path": str(study)}},
            WRITTEN_BY: COMMAND}


def write_recheck(result: dict, path) -> Path:
    """Write a re-check as strict JSON, atomically (nothing half-written)."""
    return write_text_atomic(path, strict_json(result))


__all__ = ["recheck_adequacy", "write_recheck"]
