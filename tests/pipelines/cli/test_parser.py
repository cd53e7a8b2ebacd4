"""The ``scioc`` parser: option checks are usage errors (exit 2), every option says its default, and the
literal defaults the parser spells out (to import no model code) equal the models' own."""

import dataclasses

import pytest

from scioc.models.design import STUDY
from scioc.pipelines.calibrate import DEFAULTS
from scioc.pipelines.cli import build_parser, main
from scioc.pipelines.cli.commands import window_settings
from scioc.pipelines.cli.values import PARAMETERIZATION_BLOCKS, PREVIEW, RUN_SECONDS, SAMPLE_TIME, WINDOW


def _exit_code(argv, capsys):
    """Exit status and stderr of ``scioc argv``, whether argparse or main() ends it."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err


@pytest.mark.parametrize("argv, match", [
    (["identify", "S", "--out", "D", "--window", "5,inf"], "finite"),
    (["identify", "S", "--out", "D", "--window", "5,0.01"], "too short"),
    (["identify", "S", "--out", "D", "--window", "5"], "START,SECONDS"),
    (["identify", "S", "--out", "D", "--preview", "inf"], "seconds >= 0"),
    (["identify", "S", "--out", "D", "--preview", "-1"], "seconds >= 0"),
    (["simulate", "--out", "D", "--run-seconds", "inf"], "seconds > 0"),
    (["fit", "S", "--out", "D", "--cores", "-2"], "positive integer"),
    (["fit", "S", "--out", "D", "--chains", "0"], "positive integer"),
    (["compare", "E", "--alpha", "1.5"], "significance level"),
    (["calibrate", "--replications", "0"], "positive integer"),
    (["calibrate", "--window-seconds", "nan"], "seconds > 0"),
    (["loglik"], "required"),
    (["nonsense"], "invalid choice"),
])
def test_bad_option_values_are_usage_errors(argv, match, capsys):
    code, err = _exit_code(argv, capsys)
    assert code == 2
    assert match in err and "Traceback" not in err
    assert "theta must be finite" not in err


def test_data_errors_exit_3_and_usage_errors_exit_2(tmp_path, capsys):
    code, err = _exit_code(["loglik", str(tmp_path / "missing.parquet"), "--theta", "60,0,1"], capsys)
    assert code == 3 and "no such file" in err
    code, err = _exit_code(["loglik", str(tmp_path / "missing.parquet"), "--theta", "60,0"], capsys)
    assert code == 2 and "three comma-separated numbers" in err


def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    from importlib.metadata import version

    assert capsys.readouterr().out.strip() == f"scioc {version('scioc')}"


def _options(parser):
    for sub in parser._subparsers._group_actions[0].choices.values():
        for action in sub._actions:
            if action.option_strings and action.dest != "help":
                yield sub.prog, action


# simulate's and identify's own options are edited by another engineer; they are checked there.
_NOT_HERE = {("scioc simulate", "subjects"), ("scioc simulate", "seed"), ("scioc simulate", "out"),
             ("scioc identify", "out")}


def test_every_option_has_help_with_its_default():
    for prog, action in _options(build_parser()):
        if (prog, action.dest) in _NOT_HERE:
            continue
        assert action.help, f"{prog} {action.option_strings[0]} has no help text"
        if action.default not in (None, False) and not action.required:
            assert "default" in action.help, (prog, action.dest, action.help)
            if isinstance(action.default, (int, float)):
                assert f"{action.default:g}" in action.help, (prog, action.dest, action.help)


def test_calibrate_help_states_the_true_defaults():
    helps = {a.dest: a.help for prog, a in _options(build_parser()) if prog == "scioc calibrate"}
    assert f"default {DEFAULTS['study']['n_subjects']})" in helps["subjects"]
    assert f"default {DEFAULTS['unit']['batch_size']} unit, {DEFAULTS['study']['batch_size']} study" \
        in helps["batch_size"]
    assert f"default {DEFAULTS['unit']['replications']} unit, {DEFAULTS['study']['replications']} study" \
        in helps["replications"]
    assert f"default {DEFAULTS['unit']['K'] // 100} unit, {DEFAULTS['study']['K'] // 100} study" in helps["window_seconds"]


def test_the_parsers_design_defaults_are_the_studys():
    assert (SAMPLE_TIME, WINDOW, PREVIEW, RUN_SECONDS) == (STUDY.dt, (STUDY.window_start, STUDY.window_seconds),
                                                          STUDY.preview, STUDY.run_seconds)
    # The window and preview come from the experiment; without an experiment file they are the paper's.
    args = build_parser().parse_args(["identify", "S", "--out", "D"])
    assert args.window is None and args.preview is None and args.experiment is None
    settings, source = window_settings(args)
    assert source is None and settings.design == STUDY
    assert (settings.window_start, settings.window_seconds, settings.preview) == (210.0, 15.0, 2.0)
    args = build_parser().parse_args(["identify", "S", "--out", "D", "--window", "1,2", "--preview", "0"])
    settings, _ = window_settings(args)
    assert (settings.window_start, settings.window_seconds, settings.preview) == (1.0, 2.0, 0.0)


def test_the_parameterization_options_are_the_models():
    from scioc.models.bayes.hierarchical import Parameterization

    assert PARAMETERIZATION_BLOCKS == {f.name: f.default for f in dataclasses.fields(Parameterization)}
    args = build_parser().parse_args(["bench-fit"])
    assert {k: getattr(args, k) for k in PARAMETERIZATION_BLOCKS} == PARAMETERIZATION_BLOCKS


def test_the_adequacy_points_are_the_checks():
    from scioc.pipelines.cli.values import ADEQUACY_AT_NAMES
    from scioc.pipelines.fit.checks import ADEQUACY_POINTS

    assert ADEQUACY_AT_NAMES == ADEQUACY_POINTS
    assert build_parser().parse_args(["adequacy", "F"]).at == "draw"


@pytest.mark.parametrize("text", ["0", "1", "1.2", "-0.5", "nan", "x"])
def test_fit_target_accept_is_a_rate_between_0_and_1(text, capsys):
    from scioc.pipelines.cli.parser import build_parser

    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["fit", "s.parquet", "--out", "o", "--target-accept", text])
    assert exc.value.code == 2 and "--target-accept: expected a target acceptance rate between 0 and 1" in \
        capsys.readouterr().err
    assert build_parser().parse_args(["fit", "s.parquet", "--out", "o", "--target-accept", "0.95"]).target_accept == 0.95
    assert build_parser().parse_args(["fit", "s.parquet", "--out", "o"]).target_accept is None
