"""End-to-end runs of the ``scioc`` command (in-process and as a console script)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from models.maxent import loglik_grad
from models.maxent_dense import loglik_dense
from models.plant import discretize
from models.segment import prepare_batch
from pipelines.calibrate import DEFAULTS
from pipelines.cli import build_parser, main
from pipelines.identify import with_assistant_model
from pipelines.io import load_study, to_maxent_segment, write_table_atomic
from tests.pipelines.test_io import small_table


@pytest.fixture()
def study_file(tmp_path):
    return write_table_atomic(small_table(K=40), tmp_path / "study.parquet")


def test_loglik_json_matches_dense_reference(study_file, capsys):
    # The paper's model: the recorded u_A as a known input, against Eq. 11-16 literally.
    assert main(["loglik", str(study_file), "--theta", "60,0.1,1", "--format", "json",
                 "--assistant-model", "exogenous"]) == 0
    records = json.loads(capsys.readouterr().out)
    assert [set(r) for r in records] == [{"subject", "condition", "loglik"}] * 4
    study = load_study(study_file)
    plant = discretize(0.01)
    for rec, seg in zip(records, study.segments):
        assert (rec["subject"], rec["condition"]) == (seg.subject, seg.condition)
        ref = loglik_dense([60, 0.1, 1], to_maxent_segment(seg), plant, with_grad=False).loglik
        assert rec["loglik"] == pytest.approx(ref, rel=1e-10)
    # The default plans with the assistant's law in SC: MC unchanged, SC its own likelihood.
    assert main(["loglik", str(study_file), "--theta", "60,0.1,1", "--format", "json"]) == 0
    default = json.loads(capsys.readouterr().out)
    for rec, dflt, seg in zip(records, default, study.segments):
        if seg.condition == "MC":
            assert dflt["loglik"] == rec["loglik"]
        else:
            fb = with_assistant_model(to_maxent_segment(seg), "SC", seg.angle_ref, 0, "feedback")
            assert fb.feedback is not None
            ref = loglik_grad([60, 0.1, 1], prepare_batch(plant, [fb]), plant).loglik[0]
            assert dflt["loglik"] == pytest.approx(ref, rel=1e-12) and dflt["loglik"] != rec["loglik"]


def test_loglik_table_output(study_file, capsys):
    assert main(["loglik", str(study_file), "--theta", "60,0,1"]) == 0
    out = capsys.readouterr().out
    assert "subject" in out and "loglik" in out and "SC" in out


@pytest.mark.parametrize("theta", ["60,0", "60,0,-1", "a,b,c", "nan,0,1"])
def test_bad_theta_exits_nonzero(study_file, theta, capsys):
    assert main(["loglik", str(study_file), "--theta", theta]) == 2
    assert "error" in capsys.readouterr().err


def test_bad_file_exits_nonzero_naming_file_column_row(tmp_path, capsys):
    df = small_table()
    df.loc[5, "condition"] = "manual"
    path = tmp_path / "bad.csv"
    df.to_csv(path, index=False)
    assert main(["loglik", str(path), "--theta", "60,0,1"]) == 3  # bad input data
    err = capsys.readouterr().err
    assert str(path) in err and "column 'condition'" in err and "row 5" in err


def test_file_without_torque_is_refused(tmp_path, capsys):
    path = write_table_atomic(small_table(with_state=False), tmp_path / "angles.parquet")
    assert main(["loglik", str(path), "--theta", "60,0,1"]) == 3
    err = capsys.readouterr().err
    assert "column 'velocity'" in err


def test_console_script_runs(study_file):
    # The script installed beside this interpreter (the venv need not be on PATH).
    exe = Path(sys.executable).parent / "scioc"
    if not exe.exists():
        pytest.fail(f"the console script 'scioc' is not installed beside {sys.executable}")
    out = subprocess.run([exe, "loglik", str(study_file), "--theta", "60,0,1", "--format", "json"],
                         capture_output=True, text=True, check=True)
    assert len(json.loads(out.stdout)) == 4
    bad = subprocess.run([exe, "loglik", str(study_file), "--theta", "0,0,0"], capture_output=True, text=True)
    assert bad.returncode != 0 and "R must be > 0" in bad.stderr


def test_bench_quick_writes_json(tmp_path, capsys):
    path = tmp_path / "bench.json"
    assert main(["bench", "--quick", "--json", str(path)]) == 0
    res = json.loads(path.read_text())
    rows = res["likelihood"]["rows"]
    assert [r["K"] for r in rows] == [50, 100]
    assert all(r["ratio"] > 1 for r in rows)
    assert res["likelihood"]["long"]["dense"] == "infeasible"
    assert res["likelihood"]["batch"]["n"] == 4 and res["likelihood"]["batch"]["K"] == 1500
    assert res["likelihood"]["batch_preview"]["preview_steps"] == 200
    assert np.isfinite(res["likelihood"]["batch"]["linear_s"])
    assert res["identify"]["preview_2s"]["converged"] == 4


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
    (["simulate", "--out", "D", "--seconds", "inf"], "seconds > 0"),
    (["fit", "S", "--out", "D", "--cores", "-2"], "positive integer"),
    (["fit", "S", "--out", "D", "--chains", "0"], "positive integer"),
    (["compare", "E", "--alpha", "1.5"], "significance level"),
    (["calibrate", "--replications", "0"], "positive integer"),
    (["calibrate", "--seconds", "nan"], "seconds > 0"),
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
    assert f"default {DEFAULTS['unit']['K'] // 100} unit, {DEFAULTS['study']['K'] // 100} study" in helps["seconds"]


def test_broken_pipe_ends_quietly(study_file):
    exe = Path(sys.executable).parent / "scioc"
    proc = subprocess.Popen([exe, "loglik", str(study_file), "--theta", "60,0,1", "--format", "json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before scioc writes, as with `| head` on long output
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert err == ""


@pytest.mark.parametrize("theta", ["1e300,0,1e-300", "1e300,0,1", "1e-300,0,1e300"])
def test_non_finite_loglik_is_a_failed_check_not_infinity(study_file, theta, capsys):
    assert main(["loglik", str(study_file), f"--theta={theta}", "--format", "json"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "not finite" in captured.err and "segment (s1, MC)" in captured.err


def test_every_imported_third_party_package_is_declared():
    import ast
    import re
    import tomllib
    from importlib.metadata import packages_distributions

    root = Path(__file__).resolve().parents[2]
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    declared = {re.split(r"[\[<>=!~ ;]", d)[0].lower().replace("_", "-") for d in project["dependencies"]}
    imported = set()
    for path in [*(root / "models").glob("*.py"), *(root / "pipelines").glob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                imported.add(node.module.split(".")[0])
    dists = packages_distributions()
    third_party = {m for m in imported - set(sys.stdlib_module_names) - {"models", "pipelines", "__future__"}}
    missing = {m for m in third_party if not {d.lower() for d in dists.get(m, [m])} & declared}
    assert not missing, f"imported but not declared in pyproject.toml: {sorted(missing)}"
