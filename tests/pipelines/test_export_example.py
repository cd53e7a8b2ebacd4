"""The worked example of a lab's export, ``data/examples/lab-export`` (issue 52, item 4): ``scioc identify`` reads the
lab's CSV files through their ``experiment.toml`` and gives the estimates of the simulated study they were made from.
"""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from scioc.pipelines.cli import main
from scioc.pipelines.experiment import EXPERIMENT_FILE, find_experiment, load_experiment
from scioc.pipelines.export import ExportDesign
from scioc.pipelines.io import load_study, study_files
from scioc.pipelines.prepare import IdentifySettings

EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "examples" / "lab-export"
#: The estimates' columns compared to a tolerance, with it. The export's t, angle_ref and u_A convert back to within
#: one or two ulps of the simulated values (ms/1000, deg·π/180, N·cm/100; the angles exactly, on the encoder grid).
#: Measured, that moves θ and the log-likelihood by about 1e-14 relative and the standard errors, from a
#: finite-difference Hessian, by about 3e-11: the tolerances leave a margin of about a thousand.
RTOL = {"q11": 1e-11, "q22": 1e-11, "R": 1e-11, "theta1": 1e-11, "theta2": 1e-11, "loglik": 1e-11,
        "se_log_theta1": 1e-8, "se_theta2": 1e-8, "se_log_R": 1e-8}
#: Columns that differ by the optimizer's rounding and say nothing about the estimate: the gradient's norm at it.
UNCOMPARED = ("grad_norm",)


def _make_export():
    """``make_export.py`` of the example, the script that wrote its files."""
    spec = importlib.util.spec_from_file_location("make_export", EXAMPLE / "make_export.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """The simulated study the example's files were made from, simulated again in scioc's convention."""
    return _make_export().simulate(tmp_path_factory.mktemp("lab-export") / "study")


def test_the_example_is_a_lab_export_of_four_subjects():
    design, source = find_experiment(EXAMPLE)
    assert isinstance(design, ExportDesign) and source == str(EXAMPLE / EXPERIMENT_FILE)
    files = study_files(EXAMPLE)
    assert [f.name for f in files] == ["S01.csv", "S02.csv", "S03.csv", "S04.csv"]
    for f in files:
        assert f.read_text().split("\n", 1)[0] == "Proband,Bedingung,time_ms,wheel_deg,target_deg,assist_Ncm"
        assert f.stat().st_size < 400_000
    assert sorted({(s.subject, s.condition) for s in load_study(EXAMPLE, design).segments}) == [
        (f"S0{i}", c) for i in range(1, 5) for c in ("MC", "SC")]


def test_the_analysis_window_with_its_margin_and_preview_lies_within_the_runs():
    design = load_experiment(EXAMPLE / EXPERIMENT_FILE)
    margin = IdentifySettings().margin  # the reconstruction sees this much on each side of the window
    end = design.window_start + design.window_seconds + design.preview
    assert design.window_start >= margin and end + margin <= design.run_seconds
    for s in load_study(EXAMPLE / "*.csv", design).segments:
        assert s.t[0] == 0.0 and s.t[-1] == design.run_seconds, s.label


def test_the_export_is_the_simulated_study_in_the_labs_names_and_units(simulated):
    lab = load_study(EXAMPLE / "*.csv", load_experiment(EXAMPLE / EXPERIMENT_FILE))
    own = load_study(simulated["study"])
    assert [s.label for s in lab.segments] == [s.label for s in own.segments]
    for s, r in zip(lab.segments, own.segments):
        assert np.array_equal(s.angle, r.angle), f"{s.label}: regenerate with data/examples/lab-export/make_export.py"
        for name in ("t", "angle_ref", "u_A"):
            np.testing.assert_array_max_ulp(getattr(s, name), getattr(r, name), maxulp=2)


def test_identify_on_the_export_gives_the_simulated_studys_estimates(simulated, tmp_path):
    assert main(["identify", str(EXAMPLE / "*.csv"), "--out", str(tmp_path / "lab")]) == 0
    assert main(["identify", simulated["study"], "--out", str(tmp_path / "own")]) == 0
    lab = pd.read_parquet(tmp_path / "lab" / "estimates.parquet")
    own = pd.read_parquet(tmp_path / "own" / "estimates.parquet")
    assert list(lab.columns) == list(own.columns) and len(lab) == 8
    for column in lab.columns:
        if column in RTOL:
            np.testing.assert_allclose(lab[column], own[column], rtol=RTOL[column], atol=0, err_msg=column)
        elif column not in UNCOMPARED:  # labels, convergence, the window, every adequacy p-value: bit for bit
            pd.testing.assert_series_equal(lab[column], own[column], check_exact=True, obj=column)
    meta = json.loads((tmp_path / "lab" / "identify.json").read_text())
    assert meta["experiment"]["units"] == {"angle": "deg", "torque": "N*cm", "time": "ms"}
    assert meta["experiment"]["columns"]["angle"] == "wheel_deg"
    assert meta["adequacy"] == json.loads((tmp_path / "own" / "identify.json").read_text())["adequacy"]
