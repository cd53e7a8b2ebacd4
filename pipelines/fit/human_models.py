"""Which human model the data support, subject by subject: leave-one-subject-out of the max-ent and delayed fits.

:func:`compare_human_models` computes each subject's leave-one-subject-out ELPD under two fits of the same study by
integrated PSIS (:func:`scioc.pipelines.fit.loo.subject_elpd`): log densities of the same torques, so their difference
says which model predicts each subject, and its sum ± SE new subjects, better. Each fit's adequacy verdict goes
beside it: which model predicts better is never shown without whether each describes the data.
"""

from __future__ import annotations

import json
from pathlib import Path

import arviz as az
import numpy as np

from scioc.models.bayes.delayed_blocks import DelayedPriors
from scioc.models.bayes.hierarchical import Priors
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
from scioc.models.units import index_study
from scioc.pipelines import lineage
from scioc.pipelines.experiment import experiment_hash, parse_experiment
from scioc.pipelines.fit.artifacts import strict_json
from scioc.pipelines.fit.loo import LOSO_POINTS, comparison_reliability, reliability_words, subject_elpd
from scioc.pipelines.human_model.registry import ALTERNATIVE, PRIMARY, get
from scioc.pipelines.io import InputDataError, load_study, study_files
from scioc.pipelines.lineage import LineageError
from scioc.pipelines.prepare import IdentifySettings, PreparedStudy, prepare_study
from scioc.pipelines.storage import WRITTEN_BY, write_text_atomic

#: Human models compared, in the order of the difference (second minus first).
HUMAN_MODELS_COMPARED = (PRIMARY, ALTERNATIVE)
#: Importance-sampling points per subject for both models: twice the condition-vs-pooled comparison's, as the
#: delayed model's two further parameters per subject lower the importance-sampling ESS.
HUMAN_MODELS_POINTS = 2 * LOSO_POINTS
#: The comparison's file, in the delayed fit's folder (``--compare-to``) or the run folder.
HUMAN_MODELS_FILE = "human_models.json"
#: The command whose results these are (:data:`scioc.pipelines.storage.WRITTEN_BY`).
COMMAND = "scioc human-models"
_FIT_FILES = ("posterior.json", "posterior.nc", "contrasts.json")
_SIDECAR_KEYS = ("study", "identify_settings")


def fit_sidecar(folder) -> dict:
    """The ``posterior.json`` of a finished ``scioc fit`` folder (ValueError if it is none; InputDataError if its
    sidecar is unreadable or lacks a key the comparison reads)."""
    folder = Path(folder)
    missing = [f for f in _FIT_FILES if not (folder / f).is_file()]
    if missing:
        raise ValueError(f"{folder} is not a finished scioc fit folder (no {', '.join(missing)})")
    path = folder / "posterior.json"
    try:
        side = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise InputDataError(f"{path}: not readable as JSON ({exc})") from None
    for key in _SIDECAR_KEYS:
        if key not in side:
            raise InputDataError(f"{path}: no key {key!r}; was it written by scioc fit?")
    return side


#: Settings that do not change what is fitted (the adequacy bootstrap changes only the verdict beside it).
_NOT_THE_DATA = ("human_model", "adequacy_boot", "adequacy_seed")


def _same_settings(a: dict, b: dict) -> bool:
    keep = lambda d: {k: v for k, v in d.items() if k not in _NOT_THE_DATA}  # noqa: E731
    return keep(a) == keep(b)


def _study_sha256(side: dict, where) -> str:
    return lineage.recorded(side, "study", where)["sha256"]


def _differences(a: dict, b: dict, where=("first", "second")) -> list[str]:
    """What makes two fits (their sidecars' study hash, settings and experiment) not fits of the same data;
    ``where``: the sidecars' paths, for the messages."""
    out = []
    if _study_sha256(a, where[0]) != _study_sha256(b, where[1]):
        out.append(f"study {a['inputs']['study']['path']} (SHA-256 {lineage.short(_study_sha256(a, where[0]))}) "
                   f"against {b['inputs']['study']['path']} (SHA-256 {lineage.short(_study_sha256(b, where[1]))})")
    if not _same_settings(a["identify_settings"], b["identify_settings"]):
        diff = sorted(k for k in set(a["identify_settings"]) | set(b["identify_settings"])
                      if k not in _NOT_THE_DATA and a["identify_settings"].get(k) != b["identify_settings"].get(k))
        out.append("settings " + ", ".join(f"{k} {a['identify_settings'].get(k)!r} against "
                                           f"{b['identify_settings'].get(k)!r}" for k in diff))
    if a.get("experiment_sha256") != b.get("experiment_sha256"):
        out.append("experiment (its SHA-256 differs)")
    return out


def check_maxent_fit(folder, study_path, settings: IdentifySettings) -> dict:
    """Refuse, before a delayed fit of ``study_path`` starts, a ``folder`` it could not be compared with; return its
    sidecar. ``folder`` must be a finished max-ent fit (else ValueError) of the same study by content, settings and
    experiment (else LineageError naming what differs)."""
    side = fit_sidecar(folder)
    reference = HUMAN_MODELS_COMPARED[0]
    if side.get("human_model", reference) != reference:
        raise ValueError(f"{folder} is a {side['human_model']} fit; compare with a max-ent fit "
                         "(scioc fit without --human-model)")
    ours = {"inputs": {"study": lineage.study_entry(study_path)}, "identify_settings": settings.as_dict(),
            "experiment_sha256": experiment_hash(settings.design)}
    diff = _differences(side, ours, (Path(folder) / "posterior.json", study_path))
    if diff:
        raise LineageError(f"{Path(folder) / 'posterior.json'} is not a fit of the same data as {study_path}: "
                           f"{'; '.join(diff)}")
    return side


def fit_settings(side: dict, folder) -> IdentifySettings:
    """The :class:`scioc.pipelines.prepare.IdentifySettings` a fit used, from its sidecar (settings and experiment)."""
    path = Path(folder) / "posterior.json"
    if "experiment" not in side:
        raise InputDataError(f"{path}: no key 'experiment' (a fit written before experiment files); "
                             "give the settings")
    design = parse_experiment(side["experiment"], f"{path} (experiment)")
    try:
        return IdentifySettings(**side["identify_settings"], design=design)
    except (TypeError, ValueError) as exc:
        raise InputDataError(f"{path}: identify_settings: {exc}") from None


def _found(study) -> bool:
    """Whether a study (a file, a folder or a glob) has its files."""
    try:
        return all(f.is_file() for f in study_files(study))
    except InputDataError:
        return False


def located_study(side: dict, folder) -> str:
    """Where the study a fit read is now: the path as given, or else the one relative to the fit's folder
    (``study_relative``), which survives a run folder moved into place."""
    study, relative = str(side["study"]), side.get("study_relative")
    if not _found(study) and relative is not None and _found(Path(folder) / relative):
        return str(Path(folder) / relative)
    return study


def fit_study(side: dict, folder, study=None) -> Path:
    """The study a fit read: ``study`` if given, else :func:`located_study` (InputDataError if not there), checked by
    content against the fit's sidecar (LineageError naming both otherwise)."""
    folder = Path(folder)
    if study is None:
        study = located_study(side, folder)
    if not _found(study):
        raise InputDataError(f"{folder / 'posterior.json'}: its study {study} is not there "
                             "(moved, or the fit ran in another folder); give the study")
    where = folder / "posterior.json"
    lineage.require_same("study", where, lineage.recorded(side, "study", where), study, lineage.study_entry(study))
    return Path(study)


def sidecar_delays(side: dict, folder, prepared) -> np.ndarray:
    """The delay (samples) a delayed fit used for each segment of ``prepared``, from its sidecar's ``delay.by_unit``
    (InputDataError if it has none for a unit)."""
    path = Path(folder) / "posterior.json"
    by_unit = side.get("delay", {}).get("by_unit")
    if by_unit is None:
        raise InputDataError(f"{path}: no key 'delay' with 'by_unit' (the delays the delayed fit used)")
    try:
        return np.array([int(by_unit[f"{p.data.subject}/{p.data.condition}"]["delay_samples"])
                         for p in prepared.segments], dtype=np.int64)
    except KeyError as exc:
        raise InputDataError(f"{path}: delay.by_unit has no delay_samples for unit {exc.args[0]!r} of the "
                             "study") from None


def adequacy_brief(adequacy: dict | None, where: str) -> dict:
    """The adequacy verdict of a fit at its posterior θ, short: verdict, failed checks, flagged segments."""
    a = adequacy or {"verdict": "not checked", "reason": "no adequacy block"}
    keep = ("verdict", "failed_checks", "segments_flagged", "segments", "reason")
    return {**{k: a[k] for k in keep if k in a}, "where": where}


def unpooled_log_R_prior(side: dict, folder: Path):
    """(m, s) of the baseline log R's prior of a delayed fit with ``R_population = "unpooled"``, else None."""
    population = side.get("delayed_priors", {}).get("R_population", "lognormal")
    if population != "unpooled":
        return None
    try:
        centre, sd = side["priors"]["mu_log_R"]
        spread = side["priors"]["sigma_log_R"]
        return DelayedPriors.unpooled_log_R_prior(Priors(mu_log_R=(float(centre), float(sd)),
                                                         sigma_log_R=float(spread)))
    except (KeyError, TypeError, ValueError):
        raise InputDataError(f"{folder / 'posterior.json'}: an unpooled R population needs the priors "
                             "'mu_log_R' and 'sigma_log_R' it was fitted with") from None


def _shown_path(path, relative_to) -> str:
    """``path`` as a comparison records it: as given, or relative to ``relative_to`` when inside it."""
    if relative_to is not None:
        try:
            return Path(path).resolve().relative_to(Path(relative_to).resolve()).as_posix()
        except ValueError:
            pass
    return str(path)


def compare_human_models(maxent_dir, delayed_dir, *, settings: IdentifySettings | None = None,
                         prepared: PreparedStudy | None = None, seed: int = 2018, out=None, study=None,
                         points: int = HUMAN_MODELS_POINTS, relative_to=None) -> dict:
    """Leave-one-subject-out ELPD per subject under the max-ent and the delayed human, and their difference.

    Parameters
    ----------
    maxent_dir, delayed_dir : str or Path
        Finished ``scioc fit`` folders of the same study and settings, one per human model (else ValueError).
    settings : IdentifySettings, optional
        The settings both fits used, checked against both sidecars (default: the max-ent fit's).
    prepared : PreparedStudy, optional
        The study as the fits prepared it (default: the study file prepared with ``settings``).
    seed : int
        Seeds the importance sampling (``SeedSequence(seed).spawn(2)``: max-ent, delayed).
    points : int
        Importance-sampling points per subject, for both models.
    out, study, relative_to : str or Path, optional
        Where to write :data:`HUMAN_MODELS_FILE`; the study file (default: :func:`located_study`); a folder to record
        the fit folders relative to (``scioc run``'s, renamed at its end).

    Returns
    -------
    dict
        ``by_subject`` (each model's ELPD, the difference delayed - maxent, ``preferred``); ``difference`` (the sum
        ± ``se``, ``z``, ``preferred``, ``n_preferring_delayed``, ``n`` and
        :func:`scioc.pipelines.fit.loo.comparison_reliability`); ``maxent`` and ``delayed`` (PSIS summaries);
        ``adequacy`` (:func:`adequacy_brief`) and ``convergence`` (verdict) of each fit.
    """
    folders = {"maxent": Path(maxent_dir), "delayed": Path(delayed_dir)}
    sides = {k: fit_sidecar(v) for k, v in folders.items()}
    for k, side in sides.items():
        if side.get("human_model", HUMAN_MODELS_COMPARED[0]) != k:
            raise ValueError(f"{folders[k]} is a {side.get('human_model', HUMAN_MODELS_COMPARED[0])} fit, not a {k} "
                             "fit")
    where = tuple(folders[k] / "posterior.json" for k in ("maxent", "delayed"))
    scored = {k: side.get("likelihood", "torques") for k, side in sides.items()}
    if scored["maxent"] != scored["delayed"]:
        raise LineageError(f"{where[0]} and {where[1]} score different data (the max-ent fit the {scored['maxent']}, "
                           f"the delayed fit the {scored['delayed']}): leave-one-subject-out compares fits of the same "
                           "recordings")
    diff = _differences(sides["maxent"], sides["delayed"], where)
    if diff:
        raise LineageError(f"{where[0]} and {where[1]} are not fits of the same data: {'; '.join(diff)}")
    if prepared is None:
        settings = fit_settings(sides["maxent"], folders["maxent"]) if settings is None else settings
        if not _same_settings(settings.as_dict(), sides["maxent"]["identify_settings"]):
            raise ValueError("these settings are not the ones the fits used")
        study = fit_study(sides["maxent"], folders["maxent"], study)
        prepared = prepare_study(load_study(study, settings.design), settings)
    design = prepared.settings.design
    plant = discretize(design.dt, design.wheel)
    levels = design.ordered_levels
    batch = prepare_batch(plant, [p.segment for p in prepared.segments])
    index = index_study(prepared.subjects, prepared.conditions, levels)
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(2)]
    summaries, pointwise = {}, {}
    for (name, folder), rng in zip(folders.items(), rngs):
        idata = az.from_netcdf(folder / "posterior.nc")
        extra = get(name).subject_loo_terms(sides[name], folder, prepared, batch, plant)
        summaries[name], pointwise[name] = subject_elpd(idata, batch, index, plant, rng, levels, extra=extra,
                                                        points=points)
    diff_i = pointwise["delayed"] - pointwise["maxent"]
    n = diff_i.shape[0]
    se = float(np.sqrt(n * diff_i.var(ddof=1))) if n > 1 else float("nan")
    total = float(diff_i.sum())
    result = {
        "maxent": summaries["maxent"], "delayed": summaries["delayed"],
        "by_subject": {str(s): {"elpd_maxent": float(a), "elpd_delayed": float(b), "difference": float(b - a),
                                "preferred": "delayed" if b > a else "maxent"}
                       for s, a, b in zip(index.subjects, pointwise["maxent"], pointwise["delayed"])},
        "difference": {"elpd_diff": total, "se": se, "z": total / se if se > 0 else float("nan"),
                       "what": "elpd(delayed) - elpd(maxent), summed over subjects",
                       "preferred": "delayed" if total > 0 else "maxent",
                       "n_preferring_delayed": int((diff_i > 0).sum()), "n": int(n),
                       **comparison_reliability(summaries["maxent"], summaries["delayed"])},
        "seed": int(seed), "fits": {k: _shown_path(v, relative_to) for k, v in folders.items()},
        "inputs": {**{f"{k}_fit": lineage.entry(_shown_path(v, relative_to), lineage.artifact_sha256(v))
                      for k, v in folders.items()}, "study": sides["maxent"]["inputs"]["study"]},
        "adequacy": {k: adequacy_brief(json.loads((v / "contrasts.json").read_text()).get("adequacy"),
                                       f"at the posterior θ ({_shown_path(v / 'contrasts.json', relative_to)})")
                     for k, v in folders.items()},
        # Each fit's draws feed the ELPD, so whether its sampler converged goes beside it.
        "convergence": {k: (side.get("convergence_verdict") or {}).get("condition") for k, side in sides.items()},
        WRITTEN_BY: COMMAND,
    }
    if out is not None:
        write_human_models(result, Path(out) / HUMAN_MODELS_FILE)
    return result


def write_human_models(result: dict, path) -> Path:
    """Write a comparison as strict JSON, atomically (nothing half-written)."""
    return write_text_atomic(path, strict_json(result))


def _adequacy_line(name: str, a: dict | None) -> str:
    if not a:
        return f"  {name:8s} adequacy at the posterior: not recorded"
    v = a.get("verdict", "not checked")
    if v == "not checked":
        return f"  {name:8s} adequacy at the posterior: NOT CHECKED ({a.get('reason', '')})"
    flagged = (f"{a['segments_flagged']} of {a['segments']} segments flagged" if "segments" in a else "")
    failed = f"failed: {', '.join(a['failed_checks'])}; " if a.get("failed_checks") else ""
    return f"  {name:8s} adequacy at the posterior: {'PASS' if v == 'pass' else 'FAIL'} ({failed}{flagged})"


def format_human_models(res: dict) -> str:
    """The comparison in a few lines, each model's adequacy verdict beside it, with a caveat when a fit did not
    converge or the preferred model fails its adequacy checks."""
    d = res["difference"]
    n, k = d["n"], d["n_preferring_delayed"]
    se = "n/a" if d.get("se") is None or not np.isfinite(d["se"]) else f"{d['se']:.1f}"
    z = "n/a" if d.get("z") is None or not np.isfinite(d["z"]) else f"{d['z']:.2f}"
    adequacy = res.get("adequacy", {})
    lines = [f"human models, leave-one-subject-out over {n} subjects:",
             *(_adequacy_line(m, adequacy.get(m)) for m in HUMAN_MODELS_COMPARED),
             f"  elpd(delayed) - elpd(maxent) = {d['elpd_diff']:.1f} ± {se} (z = {z}); " + reliability_words(d)
             + (f"; importance sampling: smallest ESS {imp['is_ess_loo_min']:.0f}, Monte Carlo SE of the difference "
                f"{imp['mcse']:.2f}" if (imp := d.get("importance")) else ""),
             f"  subjects better predicted: delayed {k} of {n}, maxent {n - k} of {n}",
             f"  preferred by the ELPD: {d['preferred']}"]
    for m, v in (res.get("convergence") or {}).items():
        if v is not None and v != "pass":
            lines.append(f"  CAVEAT: the {m} fit's sampler did not converge ({v}): its ELPD rests on unconverged draws")
    if (adequacy.get(d["preferred"]) or {}).get("verdict") == "fail":
        lines.append(f"  CAVEAT: {d['preferred']}, which predicts better, fails its adequacy checks: neither its costs "
                     "nor this preference say that it describes the data")
    return "\n".join(lines)


__all__ = ["HUMAN_MODELS_COMPARED", "HUMAN_MODELS_FILE", "HUMAN_MODELS_POINTS", "adequacy_brief", "check_maxent_fit",
           "compare_human_models", "fit_settings", "fit_sidecar", "fit_study", "format_human_models", "located_study",
           "sidecar_delays", "write_human_models"]
