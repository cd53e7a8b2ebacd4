"""A run folder as Python objects, for notebooks: ``scioc.open_run(DIR)``.

It reads what ``scioc run``, ``scioc analyse`` or the stages alone wrote into one folder (never refits), with
the report's check (:func:`scioc.pipelines.report.parts.check_run`): a part made from another study, other
estimates or other fits is left out, and :attr:`Run.left_out` says which and why.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

from scioc.pipelines.report.human_models import MODEL_ARTIFACTS, RUN_FILE
from scioc.pipelines.report.parts import check_run


class ModelResults(NamedTuple):
    """One human model's artifacts in a run folder (None where one is missing)."""

    name: str
    estimates: object  # DataFrame: identify/estimates.parquet, one row per subject × condition
    identify: dict | None  # identify.json: settings, adequacy verdict, lineage
    tests: dict | None  # compare.json: the Wilcoxon tests
    contrasts: dict | None  # fit/contrasts.json: β, per-subject contrasts, LOO, adequacy at the posterior
    sidecar: dict | None  # fit/posterior.json: sampler, diagnostics, convergence verdict, lineage
    fit_dir: Path | None  # the fit folder, where there is one

    def posterior(self):
        """The fit's posterior DataTree (``posterior.nc``), or None without a fit."""
        if self.fit_dir is None:
            return None
        import arviz as az

        return az.from_netcdf(self.fit_dir / "posterior.nc")

    @property
    def verdicts(self) -> dict:
        """Model adequacy at the estimates and at the posterior, and sampler convergence: separate claims."""
        return {"adequacy": ((self.identify or {}).get("adequacy") or {}).get("verdict"),
                "adequacy_at_posterior": ((self.contrasts or {}).get("adequacy") or {}).get("verdict"),
                "convergence": ((self.sidecar or {}).get("convergence_verdict") or {}).get("condition")}


class Run(NamedTuple):
    """A run folder: its human models' results, the comparison between them, and what each part was made from."""

    root: Path
    models: dict  # name -> ModelResults, for the models the folder holds
    human_models: dict | None  # human_models.json: leave-one-subject-out between the two fits
    choice: dict | None  # run.json: which human models ran and why
    lineage: dict  # artifact (relative path) -> the inputs its sidecar records, with their SHA-256
    left_out: dict  # part -> why it was not made from this run's study (as the report leaves it out)

    @property
    def verdicts(self) -> dict:
        """Per human model: its adequacy verdicts and its sampler-convergence verdict."""
        return {name: m.verdicts for name, m in self.models.items()}


def open_run(root) -> Run:
    """Read a run folder (``scioc run``, ``scioc analyse``, or stages run alone into it), as the report does.

    Raises
    ------
    FileNotFoundError
        Where the folder holds no identification (``identify/estimates.parquet``).
    LineageError
        Where ``identify/`` does not hold the estimates its sidecar records.
    """
    run = check_run(root)
    models = {}
    for name, (ident, tests, fit) in MODEL_ARTIFACTS.items():
        estimates = run.read(f"{ident}/estimates.parquet")
        if estimates is None:
            continue
        fit_dir = run.root / fit if run.kept(fit) and (run.root / fit / "posterior.nc").exists() else None
        models[name] = ModelResults(name, estimates, run.read(f"{ident}/identify.json"), run.read(tests),
                                    run.read(f"{fit}/contrasts.json"), run.read(f"{fit}/posterior.json"), fit_dir)
    lineage = {}
    for path in sorted(run.root.glob("*/*.json")) + sorted(run.root.glob("*.json")):
        rel = path.relative_to(run.root).as_posix()
        side = run.read(rel)
        if isinstance(side, dict) and "inputs" in side:
            lineage[rel] = side["inputs"]
    return Run(run.root, models, run.read("human_models.json"), run.read(RUN_FILE), lineage, dict(run.left_out))


__all__ = ["ModelResults", "Run", "open_run"]
