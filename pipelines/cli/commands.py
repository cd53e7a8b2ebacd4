"""The ``scioc`` commands: each turns its parsed options into typed settings, calls one pipeline function,
prints where the results went and returns the exit status.

Every pipeline module is imported inside its command: ``scioc --help`` and the light
commands then start in a fraction of a second, and only ``fit`` pays for PyMC.
"""

from __future__ import annotations

import dataclasses
import json
import sys
from pathlib import Path

from scioc.pipelines.cli.values import HUMAN_MODEL_NAMES


def cmd_loglik(args) -> int:
    from scioc.pipelines.experiment import find_experiment
    from scioc.pipelines.loglik import NonFiniteLoglik, parse_theta, study_loglik

    theta = parse_theta(args.theta)
    design, source = find_experiment(args.study, args.experiment)
    try:
        table = study_loglik(args.study, theta, args.assistant_model, design=design, experiment_file=source,
                             human_model=args.human_model, delay_s=args.delay_s, tau_nm=args.tau_nm,
                             sigma_m=args.sigma_m, likelihood=args.likelihood)
    except NonFiniteLoglik as exc:
        print(f"scioc loglik: error: {exc}", file=sys.stderr)
        return 1
    if args.format == "json":
        trial = "trial" in table.columns
        records = [
            {"subject": r.subject, "condition": r.condition, **({"trial": r.trial} if trial else {}),
             "loglik": float(r.loglik)}
            for r in table.itertuples(index=False)
        ]
        print(json.dumps(records, indent=2, allow_nan=False))
    else:
        print(table.to_string(index=False, float_format=lambda v: f"{v:.6f}"))
    return 0


def cmd_power(args) -> int:
    from scioc.pipelines.power import format_power, power_study

    humans = [h.strip() for h in args.humans.split(",") if h.strip()]
    summary = power_study(args.out, humans=humans, studies=args.studies, seed=args.seed, n_subjects=args.subjects,
                          beta=args.beta, n_boot=args.adequacy_boot, workers=args.workers,
                          log=lambda m: print(m, file=sys.stderr, flush=True))
    print(format_power(summary))
    print(f"wrote {Path(args.out) / 'power.json'}")
    return 0


def cmd_bench(args) -> int:
    from scioc.pipelines.bench import DEFAULT_PARTS, run_bench

    parts = DEFAULT_PARTS if args.parts is None else tuple(p.strip() for p in args.parts.split(",") if p.strip())
    run_bench(args.json, quick=args.quick, parts=parts, humans=args.humans, keep=args.keep, report=args.report)
    if args.json:
        print(f"wrote {args.json}")
    return 0


def cmd_bench_fit(args) -> int:
    from scioc.pipelines.human_model.registry import ALTERNATIVE

    if args.human_model == ALTERNATIVE:
        # imports PyMC (seconds): only for this command
        from scioc.models.bayes.delayed_model import DelayedForm, DelayedPriors
        from scioc.pipelines.bench.fit_delayed import bench_fit_delayed, format_fit_delayed

        res = bench_fit_delayed(n_subjects=args.subjects, seed=args.seed, chains=args.chains, draws=args.draws,
                                tune=args.tune, delayed_priors=DelayedPriors(R_population=args.R_population),
                                delayed_form=DelayedForm(rho=args.rho_form))
        print(format_fit_delayed(res))
    else:
        from scioc.models.bayes.hierarchical import Parameterization
        from scioc.pipelines.bench.fit import bench_parameterization, format_fit

        form = Parameterization(**{f.name: getattr(args, f.name) for f in dataclasses.fields(Parameterization)})
        res = bench_parameterization(form, study_seed=args.study_seed, window_seconds=args.window_seconds,
                                     seed=args.seed)
        print(format_fit(res))
    if args.json:
        from scioc.pipelines.storage import write_text_atomic

        write_text_atomic(args.json, json.dumps(res, indent=1) + "\n")
    return 0


def cmd_assistant(args) -> int:
    from scioc.pipelines.assistant_check import assistant_alone, format_assistant

    res = assistant_alone()
    print(json.dumps(res, indent=2) if args.format == "json" else format_assistant(res))
    return 0


def window_settings(args):
    """The :class:`scioc.pipelines.prepare.IdentifySettings` of the experiment and the window options, and its source.

    The experiment (``--experiment``, or ``experiment.toml`` beside the study file, or the
    paper's study) gives the defaults; ``--window``, ``--whole-run`` and ``--preview``
    override its ``[analysis]``.

    Returns
    -------
    settings : IdentifySettings
    source : str or None
        The experiment file's path (None: the paper's study, no file).
    """
    from scioc.pipelines.experiment import find_experiment
    from scioc.pipelines.prepare import IdentifySettings

    design, source = find_experiment(args.study, getattr(args, "experiment", None))
    overrides = {}
    if args.whole_run:
        overrides.update(window_start=None, window_seconds=None)
    elif args.window is not None:
        try:
            start, seconds = (float(v) for v in args.window.split(","))
        except ValueError:
            raise ValueError(f"--window needs START,SECONDS in s (e.g. 210,15); got {args.window!r}") from None
        overrides.update(window_start=start, window_seconds=seconds)
    if args.preview is not None:
        overrides["preview"] = args.preview
    settings = IdentifySettings.for_design(design, reconstruct=args.reconstruct, assistant_model=args.assistant_model,
                                           adequacy_boot=args.adequacy_boot, adequacy_seed=args.adequacy_seed,
                                           **overrides)
    return settings, source


#: The simulated human each human model describes (``scioc simulate --human-model``): the delayed model's
#: structure (delay with prediction, a lag the human plans with, white motor noise before it) is ``kbl``'s.
HUMAN_OF_MODEL = dict(zip(HUMAN_MODEL_NAMES, ("maxent", "kbl")))


def simulated_human(args) -> str:
    """``--human``, or the human ``--human-model`` names (:data:`HUMAN_OF_MODEL`); maxent by default."""
    if getattr(args, "human_model", None):
        return HUMAN_OF_MODEL[args.human_model]
    return args.human or "maxent"


def cmd_simulate(args) -> int:
    from scioc.models.simulate import Population
    from scioc.pipelines.experiment import load_experiment
    from scioc.pipelines.simulate import simulate_to_dir

    design = load_experiment(args.experiment) if args.experiment else None
    paths = simulate_to_dir(args.out, n_subjects=args.subjects, seed=args.seed,
                            population=None if args.beta is None else Population(beta=args.beta),
                            seconds=args.run_seconds, human=simulated_human(args),
                            force=args.force, design=design, experiment_file=args.experiment)
    for k, v in paths.items():
        print(f"{k}: {v}")
    return 0


def cmd_identify(args) -> int:
    from scioc.pipelines.identify import format_identify, identify_to_dir

    settings, source = window_settings(args)
    settings = dataclasses.replace(settings, human_model=args.human_model)
    paths = identify_to_dir(args.study, args.out, settings, force=args.force, experiment_file=source)
    print(format_identify(args.out))
    for k, v in paths.items():
        print(f"{k}: {v}")
    # Exit 1 when the human model fails its adequacy checks: the estimates are written, but
    # no conclusion about costs should be drawn from them unexamined.
    return 1 if json.loads(Path(paths["meta"]).read_text())["adequacy"]["verdict"] == "fail" else 0


def cmd_compare(args) -> int:
    from scioc.pipelines.compare import compare_to_file, format_compare

    out = args.out or str(Path(args.estimates).parent / "compare.json")
    res = compare_to_file(args.estimates, out, alpha=args.alpha, include_nonconverged=args.include_nonconverged)
    print(format_compare(res))
    print(f"wrote {out}")
    # A human model that fails its adequacy checks, or nothing to test, is a failed check (exit 1).
    return 1 if res["adequacy"]["verdict"] == "fail" or res["nothing_to_test"] else 0


def cmd_recovery(args) -> int:
    from scioc.pipelines.recovery import format_recovery, recovery_of_files

    res = recovery_of_files(args.estimates, args.truth)
    print(json.dumps(res, indent=2) if args.format == "json" else format_recovery(res))
    return 0


def cmd_report(args) -> int:
    from scioc.pipelines.report import build_report

    print(build_report(args.run_dir, subject=args.subject))
    return 0


def cmd_analyse(args) -> int:
    from scioc.pipelines.run import analyse_to_dir, run_verdicts

    report = analyse_to_dir(args.study, args.out, experiment_file=args.experiment, seed=args.seed,
                            fit=not args.skip_fit, human_models=args.human_models, force=args.force)
    verdicts = run_verdicts(report.parent)
    print("adequacy at identify: " + ", ".join(f"{m} {v.upper()}" for m, v in verdicts.items()))
    # The analysis ran; when every human model it ran fails its adequacy checks, that is a failed check (exit 1).
    return 1 if all(v == "fail" for v in verdicts.values()) else 0


def cmd_run(args) -> int:
    from scioc.models.simulate import Population
    from scioc.pipelines.experiment import load_experiment
    from scioc.pipelines.run import run_all, run_verdicts

    design = load_experiment(args.experiment) if args.experiment else None
    name = args.name or (Path(args.experiment).resolve().parent.name if args.experiment else "default-study")
    report = run_all(args.out, n_subjects=args.subjects, seed=args.seed, fit=not args.skip_fit, human=args.human,
                     population=None if args.beta is None else Population(beta=args.beta), name=name,
                     design=design, human_models=args.human_models)
    # The workflow ran; when every human model it ran fails its adequacy checks, that is a failed check (exit 1).
    return 1 if all(v == "fail" for v in run_verdicts(report.parent).values()) else 0


def sampler_config(path) -> dict:
    """The research settings of ``--sampler-config FILE.toml`` (a flat table of keys; the human model checks them)."""
    import tomllib

    from scioc.pipelines.io import InputDataError

    if path is None:
        return {}
    try:
        with open(path, "rb") as fh:
            options = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise InputDataError(f"{path}: not a TOML file ({exc})") from None
    nested = [k for k, v in options.items() if isinstance(v, dict)]
    if nested:
        raise InputDataError(f"{path}: key {nested[0]!r}: the sampler settings are plain keys, not tables")
    return options


def cmd_fit(args) -> int:
    from scioc.pipelines.human_model.registry import ALTERNATIVE, PRIMARY

    if args.compare_to is not None and args.human_model != ALTERNATIVE:
        raise ValueError(f"--compare-to compares a {ALTERNATIVE} fit with a {PRIMARY} one: it needs --human-model "
                         f"{ALTERNATIVE}")
    if args.out is None and not args.plan:
        raise ValueError("--out DIR is required (or --plan, which writes nothing)")
    from scioc.pipelines.fit import fit_to_dir, format_fit  # imports PyMC (seconds): only when fitting
    from scioc.pipelines.io import InputDataError

    options = sampler_config(args.sampler_config)
    common = dict(seed=args.seed, chains=args.chains, draws=args.draws, tune=args.tune, experiment_file=args.experiment,
                  estimates_path=args.estimates, truth_dir=args.truth, cores=args.cores, subject=args.subject,
                  human_model=args.human_model, target_accept=args.target_accept, likelihood=args.likelihood)
    try:
        if args.plan:
            plan = fit_to_dir(args.study, args.out or ".", plan_only=True, sampler_options=options, show_progress=True,
                              **common)
            print(format_plan(plan))
            return 0
        if args.compare_to is not None:
            from scioc.pipelines.fit.human_models import check_maxent_fit
            from scioc.pipelines.fit.stage import default_inputs, resolve_settings
            from scioc.pipelines.storage import refuse_inputs_inside

            refuse_inputs_inside(args.out, args.compare_to)
            est = default_inputs(Path(args.study), args.estimates, args.truth, args.experiment, out=args.out).estimates
            settings, _, _ = resolve_settings(Path(args.study), est, None, args.experiment, args.human_model)
            check_maxent_fit(args.compare_to, args.study, settings)  # before minutes of sampling, not after
        paths = fit_to_dir(args.study, args.out, show_progress=True, force=args.force, sampler_options=options,
                           **common)
    except ValueError as exc:
        if args.sampler_config and not isinstance(exc, InputDataError) and "sampler options" in str(exc):
            raise InputDataError(str(exc).replace("sampler options", str(args.sampler_config))) from None
        raise
    print(format_fit(args.out))
    for k, v in paths.items():
        print(f"{k}: {v}")
    if args.compare_to is not None:
        from scioc.pipelines.fit.human_models import HUMAN_MODELS_FILE, compare_human_models, format_human_models

        res = compare_human_models(args.compare_to, args.out, seed=args.seed, out=args.out, study=args.study)
        print(format_human_models(res))
        print(f"human_models: {Path(args.out) / HUMAN_MODELS_FILE}")
    # Exit 1 when the sampler did not converge or the human model fails its adequacy checks.
    side = json.loads(Path(paths["sidecar"]).read_text())
    res = json.loads(Path(paths["contrasts"]).read_text())
    converged = all(v == "pass" for v in side["convergence_verdict"].values())
    return 0 if converged and res["adequacy"]["verdict"] != "fail" else 1


def format_plan(plan: dict) -> str:
    """``scioc fit --plan``: each choice, its value and why."""
    lines = [f"plan of the {plan['human_model']} fit (nothing sampled):"]
    for key, item in plan.items():
        if key != "human_model":
            lines.append(f"  {key.replace('_', ' ')}: {item['value']}  ({item['reason']})")
    return "\n".join(lines)


def fit_files(folder) -> dict:
    """``{what: path}`` of a fit folder's files, the inputs an ``--out`` never replaces."""
    return {f"{name} of the fit {folder}": Path(folder) / name for name in ("posterior.json", "posterior.nc",
                                                                            "contrasts.json")}


def cmd_adequacy(args) -> int:
    from scioc.pipelines.adequacy import format_adequacy
    from scioc.pipelines.fit.artifacts import strict_json
    from scioc.pipelines.fit.recheck import COMMAND, recheck_adequacy, write_recheck
    from scioc.pipelines.storage import check_output_file

    if args.out is not None:  # never onto an input (before the work)
        check_output_file(args.out, COMMAND, {"the study": args.study, **fit_files(args.fit)})
    res = recheck_adequacy(args.fit, at=args.at, seed=args.seed, study=args.study)
    if args.format == "json":
        print(strict_json(res), end="")
    else:
        point = res["adequacy"].get("point", {})
        print(f"{res['fit']} ({res['human_model']} human), adequacy at {point.get('what', 'the posterior')}"
              + (f": chain {point['chain']}, draw {point['draw']}" if point.get("at") == "draw" else ""))
        print(format_adequacy(res["adequacy"]))
    if args.out is not None:
        write_recheck(res, args.out)
        print(f"wrote {args.out}", file=sys.stderr if args.format == "json" else sys.stdout)
    # Exit 1 when the human model fails its adequacy checks, as scioc fit.
    return 1 if res["adequacy"]["verdict"] == "fail" else 0


def cmd_human_models(args) -> int:
    from scioc.pipelines.fit.artifacts import strict_json
    from scioc.pipelines.fit.human_models import (
        COMMAND,
        HUMAN_MODELS_POINTS,
        compare_human_models,
        format_human_models,
        write_human_models,
    )
    from scioc.pipelines.storage import check_output_file

    if args.out is not None:  # never onto an input (before the work)
        check_output_file(args.out, COMMAND, {"the study": args.study, **fit_files(args.maxent_fit),
                                              **fit_files(args.delayed_fit)})
    res = compare_human_models(args.maxent_fit, args.delayed_fit, seed=args.seed, study=args.study,
                               points=args.points or HUMAN_MODELS_POINTS)
    if args.format == "json":
        print(strict_json(res), end="")
    else:
        print(format_human_models(res))
    if args.out is not None:
        write_human_models(res, args.out)
        print(f"wrote {args.out}", file=sys.stderr if args.format == "json" else sys.stdout)
    return 0


def cmd_calibrate(args) -> int:
    from scioc.pipelines.calibrate import as_expected, calibrate_runs, format_summary, level_configs
    from scioc.pipelines.experiment import load_experiment

    design = load_experiment(args.experiment) if args.experiment else None
    runs = level_configs(args.level, seed=args.seed, replications=args.replications, batch_size=args.batch_size,
                         n_subjects=args.subjects, seconds=args.window_seconds, negative_control=args.negative_control,
                         design=design, human_model=args.human_model, likelihood=args.likelihood)
    summaries = calibrate_runs(runs, args.out, scheduler=args.scheduler, n_workers=args.workers)
    for summary in summaries:
        print(format_summary(summary))
    return 0 if all(as_expected(s) for s in summaries) else 1
