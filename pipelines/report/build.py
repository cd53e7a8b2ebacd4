"""``scioc report``: a self-contained HTML report (figures embedded) from stored artifacts; it never refits.

It reads under a run folder ``data/``, ``identify/``, ``identify_true_torque/`` and
``identify_true_torque_exogenous/`` (simulated studies), ``compare.json``, ``fit/``, the delayed model's
``identify_delayed/``, ``compare_delayed.json``, ``fit_delayed/`` and ``human_models.json``, and beside
it ``../calibration/`` and ``../power/``. A section whose artifacts are missing is left out with a note; a part
not made from the study ``identify/`` identified is left out too, named at the top with why
(:mod:`scioc.pipelines.report.parts`).
The words follow the run's experiment (:func:`scioc.pipelines.report.levels.run_experiment`); with the
paper's study the report reads as the paper's analysis.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib
from markupsafe import Markup

from scioc.pipelines.report import adequacy as report_adequacy
from scioc.pipelines.report import human_models as report_human_models
from scioc.pipelines.report.bayes import section_bayes
from scioc.pipelines.report.calibration import section_calibration
from scioc.pipelines.report.design import section_design, section_reference
from scioc.pipelines.report.identify import (
    section_cross_prediction,
    section_fig6,
    section_histogram,
    section_identification,
    section_wilcoxon,
)
from scioc.pipelines.report.levels import acquisition, joined, paper_labels, run_experiment
from scioc.pipelines.report.parts import check_run
from scioc.pipelines.report.render import read_artifact, render
from scioc.pipelines.report.truth import section_reconstruction, section_truth
from scioc.pipelines.storage import write_text_atomic


def _h2(text: str) -> Markup:
    return render("heading.html.j2", text=text)


def _torque_measured(est) -> bool:
    """Whether every unit's u_H was recorded (a torque sensor) rather than reconstructed from the angle."""
    return "reconstructed" in est and not est["reconstructed"].astype(bool).any()


def build_report(root, *, subject: str | None = None, out=None, calibration=None, title: str | None = None) -> Path:
    """Assemble ``index.html`` (or ``out``) from the artifacts under the run folder ``root``; returns its path.

    ``subject``: for the Fig. 6 trajectories (default the third, as in the paper); ``calibration``:
    ``scioc calibrate``'s folder (default ``root/../calibration``); ``title``: default the folder's name.
    """
    matplotlib.use("Agg")  # figures are rendered to PNG, never shown: the report is built without a display
    root = Path(root)
    run = check_run(root)
    for part, why in run.left_out.items():
        print(f"scioc report: note: {part} is left out of the report: {why}", file=sys.stderr, flush=True)
    sim = run.read("data/simulation.json")
    study = run.read("data/study.parquet")
    truth = run.read("data/truth.parquet")
    truth_traj = run.read("data/truth_trajectories.parquet")
    est = run.read("identify/estimates.parquet")
    traj = run.read("identify/trajectories.parquet")
    val = run.read("identify/validation.parquet")
    meta = run.read("identify/identify.json")
    est_true = run.read("identify_true_torque/estimates.parquet")
    est_paper = run.read("identify_true_torque_exogenous/estimates.parquet")
    cmp = run.read("compare.json")
    fit_res = run.read("fit/contrasts.json")
    adequacy = (meta or {}).get("adequacy")
    fit_adequacy = (fit_res or {}).get("adequacy")
    power = read_artifact(root.parent / "power" / "power.json")
    subjects = sorted(est.subject.unique())
    subject = subject or (subjects[2] if len(subjects) > 2 else subjects[0])
    exp = run_experiment(meta, sim)
    design = exp.design
    measured = _torque_measured(est)
    trials = int(est["trials"].max()) if "trials" in est else 1
    chain = acquisition(design, not measured)

    body = [report_adequacy.headline(adequacy, fit_adequacy, chain[0]),
            render("left_out.html.j2", parts=list(run.left_out.items())) if run.left_out else Markup(""),
            report_human_models.headline(run, design),
            section_design(sim, meta, exp, trials=trials, torque_measured=measured)]
    if study is not None:
        body.append(section_reference(study, meta, design))
    tests = "the paper's test" if len(design.levels) == 2 else f"the paper's test against {design.baseline}"
    body += [_h2(f"Identified parameters and {tests}"), section_histogram(est, design),
             report_adequacy.caveat(adequacy),
             section_wilcoxon(cmp, design) if cmp else
             render("note.html.j2", text="No compare.json: run `scioc compare`.")]
    if (root / "fit").exists():
        body += [_h2("Hierarchical Bayesian model"), report_adequacy.caveat(fit_adequacy if fit_adequacy else adequacy),
                 section_bayes(run, design, not measured, trials > 1)]
    body.append(report_human_models.section(run, design))
    body += [report_adequacy.section(est, adequacy, power, chain[1]), _h2("Model validation (Fig. 6)")]
    if traj is not None:
        body.append(section_fig6(traj, subject, design, not measured))
    if val is not None:
        body.append(section_cross_prediction(val, design))
    body.append(_h2("Data acquisition: " + ("the recorded torque" if measured else "reconstruction from the angle")))
    if traj is not None:
        body.append(section_reconstruction(traj, truth_traj, design, measured))
    if truth is not None and truth["theta1"].notna().any():  # the crossover operator has no cost θ
        body += [_h2("Ground truth vs estimates"),
                 section_truth(est, truth, est_true, est_paper, design, measured)]
    body += [_h2("Identification details"), section_identification(est, meta),
             _h2("Simulation-based calibration"),
             section_calibration(Path(calibration) if calibration else root.parent / "calibration")]
    if sim and "versions" in sim:
        body.append(render("provenance.html.j2", versions={k: v for k, v in sim["versions"].items() if v}))
    path = Path(out) if out else root / "index.html"
    what = ("in manual and shared control" if paper_labels(design) else
            f"in the conditions {joined(design.ordered_levels)} (baseline {design.baseline})")
    write_text_atomic(path, render("page.html.j2", title=title or root.name, sections=body, what=what) + "\n")
    return path
