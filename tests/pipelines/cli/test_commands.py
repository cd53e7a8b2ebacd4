"""End-to-end runs of the ``scioc`` command (in-process and as a console script)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scioc.models.maxent import loglik_grad
from scioc.models.maxent_dense import loglik_dense
from scioc.models.plant import discretize
from scioc.models.segment import Segment, prepare_batch
from scioc.pipelines.cli import main
from scioc.pipelines.io import load_study
from scioc.pipelines.prepare import with_assistant_model
from scioc.pipelines.storage import write_table_atomic
from tests.pipelines.test_io import small_table


@pytest.fixture()
def study_file(tmp_path):
    return write_table_atomic(small_table(K=40), tmp_path / "study.parquet")


def to_maxent_segment(seg):
    """The likelihood's view of a recorded segment with velocity and u_H, built here by hand: x_0, whole run."""
    return Segment(np.array([seg.angle[0], seg.velocity[0]]), seg.angle_ref, seg.u_H[:-1], seg.u_A[:-1])


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
    assert "column 'u_H'" in err


def test_a_measured_torque_without_velocity_is_used_as_measured(tmp_path, capsys):
    # The velocity follows from the plant (the initial state fitted to the angles with the
    # measured torques); the torque is not reconstructed.
    from scioc.models.assistant import design_assistant, feedforward
    from scioc.models.plant import discretize, propagate

    plant = discretize(0.01)
    K = 300
    t = np.arange(K + 1) * 0.01
    ref = 0.1 * np.sin(t)
    u_H = 0.2 * np.sin(3 * t)
    x = propagate(plant, np.array([0.05, -0.1]), u_H[:-1])
    df = pd.DataFrame({"subject": "s1", "condition": "MC", "t": t, "angle": x[:, 0], "angle_ref": ref,
                       "u_A": 0.0, "u_H": u_H})
    a = design_assistant()
    xs = propagate(plant, np.array([0.05, -0.1]), np.zeros(K))
    sc = df.assign(condition="SC", angle=xs[:, 0], u_H=0.0)
    sc["u_A"] = 0.0
    # SC with the assistant alone acting: its torque follows its law on the true states.
    x_sc = np.zeros((K + 1, 2))
    x_sc[0] = (0.05, -0.1)
    ff = feedforward(a, ref)
    u_A = np.zeros(K + 1)
    for k in range(K):
        u_A[k] = -a.gain @ x_sc[k] + ff[k]
        x_sc[k + 1] = plant.A @ x_sc[k] + plant.b * u_A[k]
    u_A[K] = u_A[K - 1]
    sc = sc.assign(angle=x_sc[:, 0], u_A=u_A)
    path = write_table_atomic(pd.concat([df, sc], ignore_index=True), tmp_path / "torque.parquet")
    with_velocity = write_table_atomic(pd.concat([df.assign(velocity=x[:, 1]), sc.assign(velocity=x_sc[:, 1])],
                                                 ignore_index=True), tmp_path / "full.parquet")
    assert main(["loglik", str(path), "--theta", "60,0,1", "--format", "json"]) == 0
    derived = json.loads(capsys.readouterr().out)
    assert main(["loglik", str(with_velocity), "--theta", "60,0,1", "--format", "json"]) == 0
    recorded = json.loads(capsys.readouterr().out)
    for a_, b_ in zip(derived, recorded):
        assert a_["loglik"] == pytest.approx(b_["loglik"], rel=1e-8)


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


def test_broken_pipe_ends_quietly(study_file):
    exe = Path(sys.executable).parent / "scioc"
    proc = subprocess.Popen([exe, "loglik", str(study_file), "--theta", "60,0,1", "--format", "json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # the reader is gone before scioc writes, as with `| head` on long output
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141
    assert err == ""


@pytest.mark.parametrize("theta", ["1e308,0,1e308", "1.7e308,1e308,1.7e308"])
def test_non_finite_loglik_is_a_failed_check_not_infinity(study_file, theta, capsys):
    # log p scales with θ (degree-1 homogeneity of the cost): at q11 = R = 1e308 the kernel overflows (nan)
    assert main(["loglik", str(study_file), f"--theta={theta}", "--format", "json"]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "not finite" in captured.err and "segment (s1, MC)" in captured.err


@pytest.mark.parametrize("theta", ["1e300,0,1", "1e-300,0,1e300"])
def test_an_extreme_but_finite_loglik_is_reported(study_file, theta, capsys):
    # These gave +inf before the kernel logged its running product of S_k before overflow; the
    # density there is a huge negative number (the scaled one, tests/models/test_maxent.py).
    assert main(["loglik", str(study_file), f"--theta={theta}", "--format", "json"]) == 0
    values = [row["loglik"] for row in json.loads(capsys.readouterr().out)]
    assert all(np.isfinite(v) and v < -1e200 for v in values)


def test_simulate_human_model_names_the_human_it_describes(tmp_path, capsys):
    out = tmp_path / "d"
    assert main(["simulate", "--subjects", "2", "--run-seconds", "3", "--human-model", "delayed", "--beta", "0",
                     "--out", str(out)]) == 0
    assert json.loads((out / "simulation.json").read_text())["human"]["name"] == "kbl"
    assert main(["simulate", "--subjects", "2", "--run-seconds", "3", "--human-model", "maxent",
                     "--out", str(tmp_path / "m")]) == 0
    assert json.loads((tmp_path / "m" / "simulation.json").read_text())["human"]["name"] == "maxent"
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:  # --human and --human-model together: a usage error
        main(["simulate", "--human", "kbl", "--human-model", "delayed", "--out", str(tmp_path / "x")])
    assert exc.value.code == 2
    assert "not allowed with" in capsys.readouterr().err
