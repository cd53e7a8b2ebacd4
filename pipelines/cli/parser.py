"""The ``scioc`` argument parser: every command's options and their defaults (the values' checks and names:
:mod:`scioc.pipelines.cli.values`)."""

from __future__ import annotations

import argparse
from importlib.metadata import PackageNotFoundError, version

import scioc.pipelines.cli.commands as commands
from scioc.pipelines.cli.values import (
    ADEQUACY_AT_HELP,
    ADEQUACY_AT_NAMES,
    HUMAN_MODEL_NAMES,
    HUMAN_NAMES,
    LIKELIHOOD_NAMES,
    MAX_DELAY_S,
    PARAMETERIZATION_BLOCKS,
    PREVIEW,
    R_POPULATION_NAMES,
    RHO_FORM_NAMES,
    RUN_SECONDS,
    WINDOW_TEXT,
    acceptance,
    finite_float,
    human_models_list,
    humans_list,
    nonnegative_float,
    nonnegative_int,
    nonnegative_seconds,
    positive_int,
    positive_seconds,
    preview_seconds,
    significance_level,
    window_spec,
)

#: The study argument of the commands that read one.
STUDY_HELP = ("study: a file (Parquet, CSV, .mat), a folder of them or a quoted glob, in the experiment's "
              "[columns] and [units] (default: the data convention)")


def _add_force_option(p):
    p.add_argument("--force", action="store_true",
                   help="replace an existing non-empty --out folder as a whole (default: refuse)")


def _add_assistant_model_option(p):
    # The choices of pipelines.prepare.ASSISTANT_MODELS, spelled out so parsing imports no model code.
    p.add_argument("--assistant-model", choices=("feedback", "exogenous"), default="feedback",
                   help="in SC the human plans with the assistant's feedback law (default) or takes the recorded "
                   "u_A as a known input sequence (exogenous: the paper's Eq. 15-16)")


def _add_human_model_option(p):
    """``--human-model``: the model of the human whose data are analysed (shared by the commands that take it)."""
    p.add_argument("--human-model", choices=HUMAN_MODEL_NAMES, default="maxent",
                   help="the human model: maxent (the paper's max-ent LQ human, default) or delayed (with a "
                        "perceptual delay, a neuromuscular lag and motor noise; docs/methods.md)")


def _add_experiment_option(p):
    p.add_argument("--experiment", metavar="PATH",
                   help="the experiment file (rig, assistants, design; README 'Experiment file'); default: "
                        "experiment.toml beside the study file if there, else the paper's study")


def _add_window_options(p):
    _add_experiment_option(p)
    p.add_argument("--window", type=window_spec, default=None, metavar="START,SECONDS",
                   help=f"analysis window on each trial's time axis, s (default: the experiment's [analysis], "
                        f"without one the paper's {WINDOW_TEXT})")
    p.add_argument("--whole-run", action="store_true", help="analyse each segment whole")
    p.add_argument("--preview", type=preview_seconds, default=None,
                   help=f"seconds the human's plan looks past the window (default: the experiment's; without one "
                        f"{PREVIEW:g}; 0 = the paper's horizon)")
    _add_assistant_model_option(p)
    p.add_argument("--reconstruct", choices=("auto", "always"), default="auto",
                   help="reconstruct velocity and u_H from the angle when missing (auto, the default) or always")
    p.add_argument("--adequacy-boot", type=nonnegative_int, default=49, metavar="B",
                   help="bootstrap data sets per segment for the model-adequacy checks (default 49; 0 skips them)")
    p.add_argument("--adequacy-seed", type=nonnegative_int, default=2018, help="seed of the adequacy bootstrap (default 2018)")



def _add_human_options(p, *, by_model: bool = False):
    group = p.add_mutually_exclusive_group() if by_model else p
    group.add_argument("--human", choices=HUMAN_NAMES, default=None if by_model else "maxent",
                       help="the simulated human: maxent (the paper's agent, default) or a negative control the "
                            "max-ent likelihood does not describe (see models/humans.py)")
    if by_model:
        group.add_argument("--human-model", choices=HUMAN_MODEL_NAMES, default=None,
                           help="simulate the human a human model describes: maxent (as --human maxent) or delayed "
                                "(as --human kbl: each subject's delay 0.10-0.20 s and lag 0.05-0.10 s, white motor "
                                "noise before the lag)")
    p.add_argument("--beta", type=finite_float, default=None,
                   help="mean shift of log θ1 from the baseline to every other level in the simulated population "
                        "(default: the experiment's [simulation] beta, -0.7 for the paper's; 0: no change)")



def build_parser() -> argparse.ArgumentParser:
    """The ``scioc`` parser with every command; each command's ``func`` is its :mod:`scioc.pipelines.cli.commands` function."""
    parser = argparse.ArgumentParser(
        prog="scioc", description="Shared-control inverse optimal control: identify human steering cost functions "
        "in manual and shared control (Inga et al., SMC 2018).",
        epilog="exit status: 0 success, 1 a failing verdict or check, 2 a usage error, 3 bad input data, "
        "130 interrupted (README: Errors and exit codes)",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("loglik", help="log-likelihood of every segment of a study file under one θ")
    p.add_argument("study", help=STUDY_HELP)
    p.add_argument("--theta", required=True, help="q11,q22,R (e.g. 60,0,1)")
    _add_assistant_model_option(p)
    _add_human_model_option(p)
    p.add_argument("--delay-s", type=nonnegative_seconds, default=None, metavar="S",
                   help=f"delayed human: perceptual delay, s, a whole number of samples up to {MAX_DELAY_S:g}")
    p.add_argument("--tau-nm", type=nonnegative_seconds, default=None, metavar="T",
                   help="delayed human: neuromuscular time constant, s (0 to 1)")
    p.add_argument("--sigma-m", type=nonnegative_float, default=None, metavar="M",
                   help="delayed human: motor-noise SD per sample, N·m")
    p.add_argument("--likelihood", choices=LIKELIHOOD_NAMES, default="torques",
                   help="the likelihood of the human torques u_H (default), or the delayed human's of the encoder's "
                   "angles (no u_H needed; what identify uses where no torque was recorded)")
    _add_experiment_option(p)
    p.add_argument("--format", choices=("table", "json"), default="table", help="output format (default table)")
    p.set_defaults(func=commands.cmd_loglik)

    p = sub.add_parser("simulate", help="simulate the experiment: study table (angles only) + ground truth")
    p.add_argument("--experiment", metavar="PATH",
                   help="the experiment to simulate (default: the paper's study); written beside the study")
    p.add_argument("--subjects", type=positive_int, default=None,
                   help="simulated subjects (default: the experiment's [simulation] subjects, 42 for the paper's)")
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="root seed (default 2018)")
    p.add_argument("--run-seconds", type=positive_seconds, default=None,
                   help=f"length of each run, s (default: the experiment's [simulation] run_s, {RUN_SECONDS:g} for "
                        "the paper's)")
    _add_human_options(p, by_model=True)
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (study.parquet, truth, simulation.json)")
    _add_force_option(p)
    p.set_defaults(func=commands.cmd_simulate)

    p = sub.add_parser("identify", help="maximum-likelihood θ per subject × condition, like the paper")
    p.add_argument("study", help=STUDY_HELP)
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (estimates, trajectories, identify.json)")
    _add_window_options(p)
    _add_human_model_option(p)
    _add_force_option(p)
    p.set_defaults(func=commands.cmd_identify)

    p = sub.add_parser("fit", help="hierarchical Bayesian fit (nutpie): β with HDI, diagnostics, LOO")
    p.add_argument("study", help=STUDY_HELP)
    p.add_argument("--out", metavar="DIR", help="output folder (required unless --plan)")
    p.add_argument("--human-model", choices=HUMAN_MODEL_NAMES, default="maxent", help="the human model: maxent "
                   "(the paper's, default) or delayed (perceptual delay, neuromuscular lag, motor noise)")
    p.add_argument("--likelihood", choices=LIKELIHOOD_NAMES, default=None,
                   help="what the fit scores: the torques u_H (recorded or reconstructed), or the encoder's angles "
                   "(default: the torques; the delayed model scores the angles where no torque was recorded)")
    p.add_argument("--estimates", metavar="PATH", help="estimates.parquet of scioc identify: its settings (window, "
                   "preview, assistant model, experiment) and the mixed-model check (default: the run folder's "
                   "identify/, when it identified this study)")
    p.add_argument("--truth", metavar="DIR",
                   help="folder with simulation.json and truth.parquet (default: the study's folder, if there)")
    p.add_argument("--compare-to", metavar="MAXENT_FIT", help="with --human-model delayed: a finished max-ent fit of "
                   "the same study; then leave-one-subject-out between the two (OUT/human_models.json)")
    _add_experiment_option(p)
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="sampler seed (default 2018)")
    p.add_argument("--chains", type=positive_int, default=4, help="Markov chains (default 4)")
    p.add_argument("--draws", type=positive_int, default=1000, help="draws kept per chain (default 1000)")
    p.add_argument("--tune", type=nonnegative_int, default=None,
                   help="warm-up draws per chain (default: the human model's; --plan shows it)")
    p.add_argument("--cores", type=positive_int, help="chains sampled in parallel (default: all CPUs)")
    p.add_argument("--target-accept", type=acceptance,
                   help="the sampler's target acceptance rate (default: the human model's; raise it where "
                        "transitions diverge)")
    p.add_argument("--subject", help="subject of the posterior predictive bands (default: the third)")
    p.add_argument("--sampler-config", metavar="FILE.toml", help="research settings of the sampler and the model's "
                   "forms (docs/guide.md, 'Sampler settings'); default: none, the defaults --plan shows")
    p.add_argument("--plan", action="store_true",
                   help="print the parameterization, populations, warm-up and rate the fit would use, and why; "
                        "then exit without sampling")
    _add_force_option(p)
    p.set_defaults(func=commands.cmd_fit)

    p = sub.add_parser("adequacy", help="the adequacy check of a finished fit again, at another posterior point or "
                                        "seed, without refitting (writes nothing without --out)")
    p.add_argument("fit", metavar="FIT", help="folder of `scioc fit` (either human model)")
    p.add_argument("--at", choices=ADEQUACY_AT_NAMES, default="draw", help=ADEQUACY_AT_HELP)
    p.add_argument("--seed", type=nonnegative_int, default=None,
                   help="adequacy seed: the draw and the bootstrap (default: the one the fit used)")
    p.add_argument("--study", metavar="PATH", help="the study file the fit read (default: the path its "
                                                   "posterior.json records)")
    p.add_argument("--format", choices=("text", "json"), default="text", help="output format (default text)")
    p.add_argument("--out", metavar="FILE", help="also write the result as JSON to FILE (atomically)")
    p.set_defaults(func=commands.cmd_adequacy)

    p = sub.add_parser("human-models", help="leave-one-subject-out between a max-ent and a delayed fit of the same "
                                            "study, beside each one's adequacy verdict (writes nothing without --out)")
    p.add_argument("maxent_fit", metavar="MAXENT_FIT", help="folder of `scioc fit` (max-ent human)")
    p.add_argument("delayed_fit", metavar="DELAYED_FIT", help="folder of `scioc fit --human-model delayed`")
    p.add_argument("--study", metavar="PATH",
                   help="the study file both fitted (default: the path their posterior.json records)")
    p.add_argument("--seed", type=nonnegative_int, default=2018,
                   help="seed of the importance sampling (default 2018)")
    p.add_argument("--points", type=positive_int, default=None,
                   help="importance-sampling points per subject, both models (default: HUMAN_MODELS_POINTS of "
                        "pipelines/fit/human_models.py; time grows in proportion)")
    p.add_argument("--format", choices=("text", "json"), default="text", help="output format (default text)")
    p.add_argument("--out", metavar="FILE", help="also write the result as JSON to FILE (atomically)")
    p.set_defaults(func=commands.cmd_human_models)

    p = sub.add_parser("compare", help="Wilcoxon matched-pairs signed-rank test of θ1 and θ2, MC vs SC")
    p.add_argument("estimates", help="estimates.parquet written by `scioc identify`")
    p.add_argument("--alpha", type=significance_level, default=0.001, help="two-sided significance level (default 0.001)")
    p.add_argument("--out", help="JSON path (default: compare.json beside ESTIMATES); never ESTIMATES itself")
    p.add_argument("--include-nonconverged", action="store_true",
                   help="test units whose identification did not converge too (default: leave them out, listed)")
    p.set_defaults(func=commands.cmd_compare)

    p = sub.add_parser("recovery", help="estimates against a simulated study's truth: θ1, its condition effects and "
                                        "(delayed) the delay, lag and motor noise")
    p.add_argument("estimates", help="estimates.parquet written by `scioc identify`")
    p.add_argument("--truth", required=True, help="truth.parquet written by `scioc simulate`")
    p.add_argument("--format", choices=("text", "json"), default="text", help="output format (default text)")
    p.set_defaults(func=commands.cmd_recovery)

    p = sub.add_parser("report", help="self-contained HTML report from a run folder's artifacts")
    p.add_argument("run_dir", help="folder with data/, identify/, compare.json (as `scioc run` writes)")
    p.add_argument("--subject", help="subject for the Fig. 6 trajectories (default: the third)")
    p.set_defaults(func=commands.cmd_report)

    p = sub.add_parser("analyse", help="the whole workflow on a lab's recordings, ending with the report: identify, "
                       "compare, the fits, the human models")
    p.add_argument("study", help=STUDY_HELP)
    p.add_argument("--out", required=True, metavar="DIR", help="the run folder (identify/, compare.json, fit/, ..., "
                   "index.html)")
    _add_experiment_option(p)
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="seed of the fits and checks (default 2018)")
    p.add_argument("--skip-fit", action="store_true", help="leave out the hierarchical Bayesian fits (minutes)")
    p.add_argument("--human-model", dest="human_models", type=human_models_list, default=None, metavar="LIST",
                   help="comma-separated human models, maxent among them (default: chosen by the data: maxent, and "
                        "delayed too when maxent fails its adequacy checks)")
    _add_force_option(p)
    p.set_defaults(func=commands.cmd_analyse)

    p = sub.add_parser("run", help="the whole workflow on the built-in simulated study, ending with the report")
    p.add_argument("--out", default="reports", metavar="DIR", help="where everything goes (default reports/)")
    p.add_argument("--experiment", metavar="PATH",
                   help="simulate and analyse this experiment instead of the paper's (e.g. "
                        "data/examples/three-assistants/experiment.toml)")
    p.add_argument("--subjects", type=positive_int, default=None,
                   help="simulated subjects (default: the experiment's, 42 for the paper's)")
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="seed of the whole workflow (default 2018)")
    p.add_argument("--skip-fit", action="store_true", help="leave out the hierarchical Bayesian fits (minutes)")
    p.add_argument("--human-model", dest="human_models", type=human_models_list, default=None, metavar="LIST",
                   help="comma-separated human models to analyse the study with, maxent among them (default: "
                        "chosen by the data: maxent, and delayed too when maxent fails its adequacy checks; "
                        "docs/decisions/run-human-models.md)")
    _add_human_options(p)
    p.add_argument("--name", default=None,
                   help="subfolder of --out for this run (default default-study, or the experiment file's folder "
                        "name)")
    p.set_defaults(func=commands.cmd_run)

    p = sub.add_parser("calibrate", help="simulation-based calibration (unit or study level), locally or on Dask")
    p.add_argument("--level", choices=("unit", "study"), default="unit",
                   help="one subject × condition per replication, or a whole study (default unit)")
    p.add_argument("--replications", type=positive_int, help="replications (default 1000 unit, 200 study)")
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="seed of the replications (default 2018)")
    p.add_argument("--out", default="reports/calibration", metavar="DIR",
                   help="results go to DIR/LEVEL and DIR/LEVEL-negative (default reports/calibration)")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="an existing Dask scheduler (default: a local cluster)")
    p.add_argument("--workers", type=positive_int, default=2, help="workers of the local cluster (default 2)")
    p.add_argument("--batch-size", type=positive_int, help="replications per Dask task (default 10 unit, 3 study)")
    p.add_argument("--negative-control", choices=("inertia", "ignore-uA", "no-delay", "none"),
                   help="also run this wrong fit at the same size (default: inertia at the unit level, ignore-uA "
                        "at the study level, no-delay for --human-model delayed; 'none' to skip)")
    p.add_argument("--subjects", type=positive_int, help="subjects per simulated study (study level; default 6)")
    p.add_argument("--window-seconds", type=positive_seconds,
                   help="window length in s (default 15 unit, 2 study; with --experiment, the unit level takes its "
                        "analysis window, or its run when analysed whole)")
    p.add_argument("--experiment", metavar="PATH",
                   help="calibrate this experiment's rate, wheel, levels, assistants and window (default: the "
                        "paper's study)")
    p.add_argument("--likelihood", choices=LIKELIHOOD_NAMES, default="torques",
                   help="what each replication records and fits: the human's torques (default), or the encoder's "
                        "angles (--human-model delayed: the unit level, and the study level's only one)")
    _add_human_model_option(p)
    p.set_defaults(func=commands.cmd_calibrate)

    p = sub.add_parser("assistant", help="the MPC assistant alone on the study reference: tracking and torques")
    p.add_argument("--format", choices=("table", "json"), default="table", help="output format (default table)")
    p.set_defaults(func=commands.cmd_assistant)

    p = sub.add_parser("power", help="how often the adequacy verdict fails per simulated human (false alarms on "
                       "maxent, power on the others), beside the paper's Wilcoxon test; resumable")
    p.add_argument("--humans", default=",".join(HUMAN_NAMES),
                   help=f"comma-separated simulated humans (default: all, {','.join(HUMAN_NAMES)})")
    p.add_argument("--studies", type=positive_int, default=20, help="simulated studies per human (default 20)")
    p.add_argument("--subjects", type=positive_int, default=42, help="subjects per study (default 42)")
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="root seed (default 2018)")
    p.add_argument("--beta", type=finite_float, default=0.0,
                   help="true mean SC shift of log θ1 (default 0: the cost does not change)")
    p.add_argument("--adequacy-boot", type=nonnegative_int, default=49, metavar="B",
                   help="bootstrap data sets per segment (default 49)")
    p.add_argument("--workers", type=positive_int, default=1, help="studies run in parallel processes (default 1)")
    p.add_argument("--out", default="reports/power", metavar="DIR", help="results folder (default reports/power)")
    p.set_defaults(func=commands.cmd_power)

    p = sub.add_parser("bench", help="measured speed of the kernels, the identification, the full fit and SBC")
    p.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    p.add_argument("--report", metavar="PATH", help="also write the tables as a speed section of this Markdown "
                   "report, stamped with the commit: the default parts' section, or one of its own for other parts "
                   "(make bench: docs/validation.md)")
    p.add_argument("--quick", action="store_true", help="small sizes, to check the command (numbers not quotable)")
    p.add_argument("--parts", default=None, metavar="LIST", help="subset "
                   "of likelihood, delayed (its likelihood), identify, fit (the default study's, about 3 min), sbc "
                   "and example (the second example's identify and fit; default: all but the two below); "
                   "fit_delayed: the delay's profile, and the delayed human's fit as scioc fit runs it on the paper's "
                   "study with a torque sensor, against its goal of 15 minutes (15-35 minutes per human); "
                   "fit_angles: the paper's design, angles only: the delayed fit with its identification against "
                   "30 minutes and the max-ent fit through the same likelihood against 15 "
                   "(pipelines/bench/delayed_workflow.py)")
    p.add_argument("--humans", type=humans_list, default=None, metavar="LIST",
                   help="simulated humans of the fit_delayed and fit_angles parts (default: pipelines/bench/"
                   "delayed_workflow.py's WORKFLOW_HUMANS, maxent and kbl, and ANGLE_WORKFLOW_HUMANS, kbl and "
                   "combined, each with a true shift of log θ1 of -0.7 and 0)")
    p.add_argument("--keep", metavar="DIR", default=None, help="keep the study, estimates and fits of those parts "
                   "in DIR/<human>/ and DIR/angles-<human>-<shift>/ (default: removed)")
    p.set_defaults(func=commands.cmd_bench)

    # A developer tool: not in `scioc --help`'s list of commands.
    p = sub.add_parser("bench-fit", description="one fit of the default simulated study in a chosen "
                       "parameterization (docs/decisions/maxent-parameterization.md)")
    p.add_argument("--study-seed", type=nonnegative_int, default=2018,
                   help="seed of the simulated study (default 2018, scioc run's)")
    p.add_argument("--seed", type=nonnegative_int, default=2018, help="sampler seed (default 2018)")
    p.add_argument("--window-seconds", type=positive_seconds, default=15.0,
                   help="analysis window, s (default the paper's 15; shorter gives less data per unit)")
    for name, default in PARAMETERIZATION_BLOCKS.items():
        p.add_argument(f"--{name.replace('_', '-')}", choices=["centred", "noncentred", "mean"], default=default,
                       help=f"form of the {name} block (default {default})")
    g = p.add_argument_group("--human-model delayed (docs/decisions/delayed-R-population.md)")
    g.add_argument("--human-model", choices=HUMAN_MODEL_NAMES, default="maxent",
                   help="maxent (default): the forms above on the default study; delayed: one fit of a study drawn "
                   "from the delayed human (pipelines/bench/fit_delayed.py; --seed seeds study and sampler)")
    g.add_argument("--subjects", type=positive_int, default=42, help="subjects of the delayed study (default 42)")
    g.add_argument("--chains", type=positive_int, default=4, help="chains (default 4)")
    g.add_argument("--draws", type=positive_int, default=1000, help="draws per chain (default 1000)")
    g.add_argument("--tune", type=positive_int, default=1000, help="tuning draws per chain (default 1000)")
    g.add_argument("--R-population", dest="R_population", choices=R_POPULATION_NAMES, default="lognormal", help="the "
                   "baseline R's population (default lognormal; policy_scale: R^(-1/2) half-normal; unpooled: none)")
    g.add_argument("--rho-form", choices=RHO_FORM_NAMES, default="folded",
                   help="form of ρ = R^(-1/2) with --R-population policy_scale (default folded)")
    p.add_argument("--json", metavar="PATH", help="also write the result as JSON")
    p.set_defaults(func=commands.cmd_bench_fit)
    return parser


def _version() -> str:
    try:
        return version("scioc")
    except PackageNotFoundError:  # run from a source tree that was never installed
        return "unknown (not installed)"
