"""Which parts of a run folder the report combines: those made from the study its identification read.

The anchor is ``identify/``: its ``identify.json`` records the study's SHA-256 and the estimates it wrote (a
mismatch there, or a sidecar without these records, is a LineageError, exit 3: there is nothing to report on). Every
other part is checked against it by content; one that was made from another study, from other estimates or fits, or
that holds another human model's fit than its place in :data:`~scioc.pipelines.report.human_models.MODEL_ARTIFACTS`,
is left out, and the report says at its top which part and why (the report is still written, exit 0).
"""

from __future__ import annotations

from pathlib import Path

from scioc.pipelines import lineage
from scioc.pipelines.human_model.registry import PRIMARY
from scioc.pipelines.io import InputDataError
from scioc.pipelines.report.human_models import ANGLE_FIT, MODEL_ARTIFACTS
from scioc.pipelines.report.render import RunParts, read_artifact

#: The identifications a simulated run adds from the true torques (``scioc run``), checked like ``identify/``.
TRUE_TORQUE = ("identify_true_torque", "identify_true_torque_exogenous")


def _study_of(meta_path: Path) -> tuple:
    """``(identify.json, its study entry)`` of an identification folder's sidecar."""
    return meta_path, lineage.recorded(lineage.read_sidecar(meta_path), "study", meta_path)


def _check_data(root: Path, anchor: tuple) -> None:
    data = root / "data"
    if (data / "study.parquet").is_file():
        lineage.require_same("study", anchor[0], anchor[1], data / "study.parquet",
                             lineage.study_entry(data / "study.parquet"))
    if (data / "truth.parquet").is_file():
        lineage.require_one("study", anchor, lineage.simulated_study(data / "truth.parquet"))


def _check_tests(root: Path, tests: str, ident: str) -> None:
    """LineageError unless ``tests`` (compare.json) tested ``ident``'s estimates as they are."""
    where = root / tests
    estimates = root / ident / "estimates.parquet"
    lineage.require_same("estimates", where, lineage.recorded(read_artifact(where), "estimates", where), estimates,
                         lineage.entry(estimates))


def _check_fit(root: Path, fit: str, model: str, anchor: tuple) -> None:
    """LineageError unless ``fit`` fitted the anchor's study with ``model``, the model of its place in the folder."""
    where = root / fit / "posterior.json"
    side = lineage.read_sidecar(where)
    lineage.require_one("study", anchor, (where, lineage.recorded(side, "study", where)))
    theirs = side.get("human_model")
    if theirs != model:
        home = [f"{f}/" for m, (_, _, f) in MODEL_ARTIFACTS.items() if m == theirs]
        raise InputDataError(f"{where} is a fit of the {theirs} human model, where the report reads the {model} "
                             "model's fit" + (f"; it belongs in {home[0]}, beside its identification" if home else ""))


def _check_human_models(root: Path) -> None:
    where = root / "human_models.json"
    side = read_artifact(where)
    for model, (_, _, fit) in MODEL_ARTIFACTS.items():
        theirs = lineage.recorded(side, f"{model}_fit", where)
        if model == PRIMARY and theirs.get("path") == ANGLE_FIT:  # the max-ent fit of the angles (no torque sensor)
            fit = ANGLE_FIT
        lineage.require_same("fit", where, theirs, root / fit, lineage.entry(root / fit))


def check_run(root) -> RunParts:
    """The parts of the run folder ``root`` the report may combine (module docstring).

    Raises
    ------
    FileNotFoundError
        Without ``identify/estimates.parquet``.
    LineageError
        Where ``identify/`` itself does not hold the estimates its sidecar records.
    """
    root = Path(root)
    estimates = root / "identify" / "estimates.parquet"
    if not estimates.is_file():
        raise FileNotFoundError(f"{estimates}: no estimates; run `scioc identify` first")
    found = lineage.identification(estimates)
    if found is None:
        raise lineage.LineageError(f"{estimates}: no identify.json beside it, so which study it identified is not "
                                   "known; run `scioc identify` into this folder")
    anchor = (found[0], lineage.recorded(found[1], "study", found[0]))
    checks = {"data": lambda: _check_data(root, anchor)}
    for name in TRUE_TORQUE:
        checks[name] = lambda name=name: lineage.require_one("study", anchor, _study_of(root / name / "identify.json"))
    for model, (ident, tests, fit) in MODEL_ARTIFACTS.items():
        if ident != "identify":
            checks[ident] = lambda ident=ident: (lineage.identification(root / ident / "estimates.parquet"),
                                                 lineage.require_one("study", anchor,
                                                                     _study_of(root / ident / "identify.json")))
        checks[tests] = lambda tests=tests, ident=ident: _check_tests(root, tests, ident)
        checks[fit] = lambda fit=fit, model=model: _check_fit(root, fit, model, anchor)
    checks[ANGLE_FIT] = lambda: _check_fit(root, ANGLE_FIT, PRIMARY, anchor)
    checks["human_models.json"] = lambda: _check_human_models(root)
    left_out = {}
    for part, check in checks.items():
        if not (root / part).exists():
            continue
        try:
            check()
        except (ValueError, OSError, KeyError, TypeError) as exc:
            left_out[part] = str(exc)
    for model, (ident, tests, fit) in MODEL_ARTIFACTS.items():  # a part made from one left out goes with it
        for part in (tests, fit):
            if ident in left_out and (root / part).exists() and part not in left_out:
                left_out[part] = f"made from {ident}/, which is left out"
    if any(fit in left_out for fit in (ANGLE_FIT, *(f for _, _, f in MODEL_ARTIFACTS.values()))) and \
            (root / "human_models.json").exists():
        left_out.setdefault("human_models.json", "it compares fits of which one is left out")
    return RunParts(root, left_out)


__all__ = ["TRUE_TORQUE", "check_run"]
