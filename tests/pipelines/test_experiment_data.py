"""A study file read against its experiment file: rate, levels, trials, windows, assistant laws, and recovery.

The second built-in example (``data/examples/three-assistants``: 200 Hz, another wheel, an
unquantized angle with a torque sensor, three levels with two linear assistants, three
trials per subject × condition, 16 subjects) is simulated and identified from its files
alone here, as issue 12 asks.
"""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import spearmanr

from scioc.pipelines.cli import main
from scioc.pipelines.compare import compare_to_file
from scioc.pipelines.experiment import EXPERIMENT_FILE, load_experiment
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.io import StudyFileError, load_study
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.simulate import simulate_to_dir
from scioc.pipelines.storage import write_table_atomic

EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "examples" / "three-assistants" / EXPERIMENT_FILE


@pytest.fixture(scope="module")
def example():
    return load_experiment(EXAMPLE)


def test_the_example_differs_from_the_paper_in_every_respect(example):
    from scioc.models.design import STUDY

    assert example.rate_hz == 200.0 and example.wheel != STUDY.wheel and example.encoder_counts == 0
    assert example.torque_sensor and example.trials == 3 and example.subjects == 16
    assert example.levels == ("none", "weak", "strong") and example.baseline == "none"
    assert [example.assistant(v).kind for v in example.contrasts] == ["linear", "linear"]
    assert example.whole and example.preview == 0.0


@pytest.fixture(scope="module")
def example_study(tmp_path_factory, example):
    root = tmp_path_factory.mktemp("example")
    sim = simulate_to_dir(root / "data", design=example, seed=2018)
    return root, sim


def test_the_simulated_example_is_written_with_its_experiment(example_study, example):
    root, sim = example_study
    assert load_experiment(sim["experiment"]) == example
    df = pd.read_parquet(sim["study"])
    assert {"trial", "u_H"} <= set(df.columns) and "velocity" not in df.columns
    study = load_study(sim["study"], example)
    assert len(study.segments) == 16 * 3 * 3
    assert {s.trial for s in study.segments} == {"1", "2", "3"}
    assert np.allclose(np.diff(study.segments[0].t), 0.005)


@pytest.fixture(scope="module")
def example_identified(example_study, example):
    root, sim = example_study
    settings = IdentifySettings.for_design(example)
    paths = identify_to_dir(sim["study"], root / "identify", settings, show_progress=False,
                            experiment_file=sim["experiment"])
    return root, sim, paths


def test_the_example_is_recovered_from_its_files_alone(example_identified):
    root, sim, paths = example_identified
    est = pd.read_parquet(paths["estimates"])
    truth = pd.read_parquet(sim["truth"]).groupby(["subject", "condition"], as_index=False).first()
    assert len(est) == 16 * 3 and set(est["trials"]) == {3}  # one estimate per unit, from its three trials
    m = est.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))
    for level, g in m.groupby("condition"):
        rho = spearmanr(g["theta1"], g["theta1_true"]).statistic
        err = np.abs(np.log(g["theta1"] / g["theta1_true"])).mean()
        assert rho >= 0.95 and err <= 0.1, (level, rho, err)
    meta = json.loads(Path(paths["meta"]).read_text())
    assert meta["experiment"]["sampling"]["rate_hz"] == 200.0 and len(meta["experiment_sha256"]) == 64
    assert meta["adequacy"]["verdict"] == "pass"


def test_the_example_is_compared_per_level_against_its_baseline(example_identified):
    root, sim, paths = example_identified
    res = compare_to_file(paths["estimates"], root / "compare.json")
    assert res["baseline"] == "none" and list(res["contrasts"]) == ["weak", "strong"]
    for level in ("weak", "strong"):
        t = res["contrasts"][level]["theta1"]
        assert t["n_pairs"] == 16 and t["p_holm"] >= t["p_value"]
        assert t["median_difference"] < 0  # the simulated shifts are -0.35 and -0.7
    assert "Holm" in res["multiplicity"]
    assert res["experiment"]["conditions"]["baseline"] == "none"


def test_loglik_rows_carry_the_trial(example_study, capsys):
    _, sim = example_study
    assert main(["loglik", sim["study"], "--theta", "60,0,1", "--format", "json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 144 and rows[0]["trial"] == "1" and set(rows[0]) == {"subject", "condition", "trial", "loglik"}


# --- a data file that disagrees with its experiment file: a clear error naming file, column and row, exit 3


def _example_table(example_study):
    _, sim = example_study
    return pd.read_parquet(sim["study"])


def _cli_error(tmp_path, df, capsys, *, experiment=EXAMPLE, command=("loglik", "--theta", "60,0,1")):
    path = write_table_atomic(df, tmp_path / "study.parquet")
    code = main([command[0], str(path), *command[1:], "--experiment", str(experiment)])
    return code, capsys.readouterr().err


def test_a_wrong_rate_is_named(example_study, tmp_path, capsys):
    df = _example_table(example_study)
    df = df[df["trial"] == 1]
    code, err = _cli_error(tmp_path, df.assign(t=df["t"] * 2), capsys)
    assert code == 3 and "column 't'" in err and "200 Hz" in err and "rate_hz" in err


def test_an_unknown_level_is_named(example_study, tmp_path, capsys):
    df = _example_table(example_study)
    code, err = _cli_error(tmp_path, df.replace({"condition": {"weak": "medium"}}), capsys)
    assert code == 3 and "column 'condition'" in err and "medium" in err and "none, weak, strong" in err


def test_a_missing_level_is_named(example_study, tmp_path, capsys):
    df = _example_table(example_study)
    code, err = _cli_error(tmp_path, df[df["condition"] != "strong"], capsys)
    assert code == 3 and "no strong segments at all" in err


def test_assistance_on_an_unassisted_level_is_named(example_study, tmp_path, capsys):
    df = _example_table(example_study)
    df.loc[df["condition"] == "none", "u_A"] = 0.1
    code, err = _cli_error(tmp_path, df, capsys)
    assert code == 3 and "column 'u_A'" in err and "unassisted" in err


def test_a_window_outside_a_trial_is_named(example_study, tmp_path, capsys):
    df = _example_table(example_study)
    code, err = _cli_error(tmp_path, df, capsys, command=("identify", "--out", str(tmp_path / "o"), "--window",
                                                         "20,5", "--adequacy-boot", "0"))
    assert code == 3 and "does not contain the window 20..25 s" in err and "row 0" in err


def test_u_A_that_violates_the_declared_law_is_named(example_study, tmp_path, capsys):
    # The recording's strong assistant declared as the weak one's law: the recorded u_A
    # does not follow it; the error suggests the exogenous model, which then runs.
    text = EXAMPLE.read_text().replace("strong = { kind = \"linear\", gain = [6.0, 0.3], reference_gain = 6.0 }",
                                       "strong = { kind = \"linear\", gain = [2.0, 0.1], reference_gain = 2.0 }")
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(text)
    df = _example_table(example_study)
    code, err = _cli_error(tmp_path, df, capsys, experiment=wrong)
    assert code == 3 and "does not follow the assistant law" in err and "level strong" in err
    assert "--assistant-model exogenous" in err
    path = tmp_path / "study.parquet"
    assert main(["loglik", str(path), "--theta", "60,0,1", "--experiment", str(wrong),
                 "--assistant-model", "exogenous"]) == 0


def test_a_malformed_experiment_file_exits_3_naming_the_key(example_study, tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[sampling]\nrate_hz = -5\n")
    code, err = _cli_error(tmp_path, _example_table(example_study), capsys, experiment=bad)
    assert code == 3 and str(bad) in err and "sampling.rate_hz" in err


def test_trials_are_found_and_validated_per_trial(example_study, example):
    df = _example_table(example_study)
    # A time step broken inside one trial is named at its row.
    i = int(np.flatnonzero((df["subject"] == "S02") & (df["trial"] == 2))[5])
    bad = df.copy()
    bad.loc[i, "t"] += 0.001
    with pytest.raises(StudyFileError, match=r"segment \(S02, .*, 2\).*time step"):
        from scioc.pipelines.io import validate_table

        validate_table(bad, "x.parquet", design=example)
