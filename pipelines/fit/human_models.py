"""Which human model the data support, subject by subject: leave-one-subject-out of the max-ent and delayed fits.

:func:`compare_human_models` takes two ``scioc fit`` folders of the same study and settings,
one fitted with the ``maxent`` human and one with the ``delayed`` human, and computes for
each the leave-one-subject-out ELPD of every subject by integrated PSIS
(:func:`pipelines.fit.loo.subject_elpd`: the subject's unit parameters integrated out by
importance sampling, :mod:`models.bayes.subject_loo`; for the delayed model with its lag
and motor noise, :mod:`models.bayes.delayed_loo`). Both are log densities of the same
observed torques, so their difference per subject says which model predicts that subject
better, and the sum over subjects ± its SE (``sqrt(n) sd``, as
:func:`pipelines.fit.loo.elpd_difference`) which predicts new subjects better.

It runs after the two fits (they are minutes each); ``scioc fit`` can report it by
calling it with the two folders. The delayed fit's plug-in delays are read from its
``posterior.json``, its arm torques follow the prepared segments' warm-ups, as in the fit.
"""

from __future__ import annotations

import json
from pathlib import Path

import arviz as az
import numpy as np

from models.bayes.delayed_loo import DelayedSubjectTerms
from models.plant import discretize
from models.segment import prepare_batch
from models.units import index_study
from pipelines.fit.artifacts import strict_json
from pipelines.fit.loo import subject_elpd
from pipelines.io import load_study
from pipelines.prepare import IdentifySettings, PreparedStudy, prepare_study
from pipelines.storage import write_text_atomic

#: Human models compared, in the order of the difference (second minus first).
HUMAN_MODELS_COMPARED = ("maxent", "delayed")


def _sidecar(folder: Path) -> dict:
    return json.loads((folder / "posterior.json").read_text())


#: Settings that do not change what is fitted (the human model is what is compared; the adequacy
#: bootstrap's size and seed change only the verdict beside the posterior).
_NOT_THE_DATA = ("human_model", "adequacy_boot", "adequacy_seed")


def _same_settings(a: dict, b: dict) -> bool:
    keep = lambda d: {k: v for k, v in d.items() if k not in _NOT_THE_DATA}  # noqa: E731
    return keep(a) == keep(b)


def compare_human_models(maxent_dir, delayed_dir, *, settings: IdentifySettings | None = None,
                         prepared: PreparedStudy | None = None, seed: int = 2018, out=None) -> dict:
    """Leave-one-subject-out ELPD per subject under the max-ent and the delayed human, and their difference.

    Parameters
    ----------
    maxent_dir, delayed_dir : str or Path
        ``scioc fit`` folders of the same study with ``human_model`` maxent and delayed.
    settings : IdentifySettings, optional
        The settings both fits used (window, preview, reconstruction, experiment); needed
        unless ``prepared`` is given. Checked against both sidecars.
    prepared : PreparedStudy, optional
        The study as the fits prepared it (default: loaded from the sidecar's study path and
        prepared with ``settings``).
    seed : int
        Seeds the importance sampling (``SeedSequence(seed).spawn(2)``: max-ent, delayed).
    out : str or Path, optional
        Write the result as ``human_models.json`` there (atomically).

    Returns
    -------
    dict
        ``by_subject``: per subject ``elpd_maxent``, ``elpd_delayed``, ``difference``
        (delayed - maxent) and ``preferred``; ``difference``: ``elpd_diff`` ± ``se``, ``z``,
        ``preferred``, ``n_preferring_delayed``, ``n``, ``reliable`` (every Pareto k of both
        below the threshold); ``maxent`` and ``delayed``: each model's PSIS summary with the
        importance-sampling ESS.

    Raises
    ------
    ValueError
        If the folders are not one max-ent and one delayed fit of the same study and settings.
    """
    folders = {"maxent": Path(maxent_dir), "delayed": Path(delayed_dir)}
    sides = {k: _sidecar(v) for k, v in folders.items()}
    for k, side in sides.items():
        if side.get("human_model", "maxent") != k:
            raise ValueError(f"{folders[k]} is a {side.get('human_model', 'maxent')} fit, not a {k} fit")
    if sides["maxent"]["study"] != sides["delayed"]["study"] or not _same_settings(
            sides["maxent"]["identify_settings"], sides["delayed"]["identify_settings"]) or \
            sides["maxent"].get("experiment_sha256") != sides["delayed"].get("experiment_sha256"):
        raise ValueError("the two fits are not of the same study file with the same settings and experiment")
    if prepared is None:
        if settings is None:
            raise ValueError("give the settings both fits used (or the prepared study)")
        if not _same_settings(settings.as_dict(), sides["maxent"]["identify_settings"]):
            raise ValueError("these settings are not the ones the fits used")
        prepared = prepare_study(load_study(sides["maxent"]["study"], settings.design), settings)
    design = prepared.settings.design
    plant = discretize(design.dt, design.wheel)
    levels = design.ordered_levels
    batch = prepare_batch(plant, [p.segment for p in prepared.segments])
    index = index_study(prepared.subjects, prepared.conditions, levels)
    by_unit = sides["delayed"]["delay"]["by_unit"]
    delay = np.array([by_unit[f"{p.data.subject}/{p.data.condition}"]["delay_samples"] for p in prepared.segments])
    warm = [p.warmup for p in prepared.segments]
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(2)]
    summaries, pointwise = {}, {}
    for (name, folder), rng in zip(folders.items(), rngs):
        idata = az.from_netcdf(folder / "posterior.nc")
        extra = None if name == "maxent" else (
            lambda flat: DelayedSubjectTerms(flat, batch, plant, delay, warm, params=design.wheel))
        summaries[name], pointwise[name] = subject_elpd(idata, batch, index, plant, rng, levels, extra=extra)
    diff_i = pointwise["delayed"] - pointwise["maxent"]
    n = diff_i.shape[0]
    se = float(np.sqrt(n * diff_i.var(ddof=1))) if n > 1 else float("nan")
    total = float(diff_i.sum())
    bad = sum(summaries[k]["pareto_k"]["n_gt_threshold"] for k in summaries)
    result = {
        "maxent": summaries["maxent"], "delayed": summaries["delayed"],
        "by_subject": {str(s): {"elpd_maxent": float(a), "elpd_delayed": float(b), "difference": float(b - a),
                                "preferred": "delayed" if b > a else "maxent"}
                       for s, a, b in zip(index.subjects, pointwise["maxent"], pointwise["delayed"])},
        "difference": {"elpd_diff": total, "se": se, "z": total / se if se > 0 else float("nan"),
                       "what": "elpd(delayed) - elpd(maxent), summed over subjects",
                       "preferred": "delayed" if total > 0 else "maxent",
                       "n_preferring_delayed": int((diff_i > 0).sum()), "n": int(n), "reliable": bad == 0},
        "seed": int(seed), "fits": {k: str(v) for k, v in folders.items()},
    }
    if out is not None:
        write_text_atomic(Path(out) / "human_models.json", strict_json(result))
    return result


def format_human_models(res: dict) -> str:
    """Two lines: the total difference and how many subjects prefer each model."""
    d = res["difference"]
    return (f"leave-one-subject-out, human models: elpd(delayed) - elpd(maxent) = {d['elpd_diff']:.1f} ± {d['se']:.1f} "
            f"({'reliable' if d['reliable'] else 'Pareto k high: unreliable'}); preferred: {d['preferred']}\n"
            f"subjects better predicted by the delayed human: {d['n_preferring_delayed']} of {d['n']}")


__all__ = ["HUMAN_MODELS_COMPARED", "compare_human_models", "format_human_models"]
