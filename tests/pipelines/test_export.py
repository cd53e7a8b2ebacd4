"""A lab's export read as it is: ``[columns]`` and ``[units]``, studies of many files, MATLAB files (issue 52,
item 3)."""

import dataclasses
import math
import re

import numpy as np
import pandas as pd
import pytest
from scipy.io import savemat

from scioc.models.design import STUDY
from scioc.pipelines.experiment import EXPERIMENT_FILE, find_experiment, write_experiment
from scioc.pipelines.export import ExportFormat, to_export, with_export
from scioc.pipelines.io import StudyFileError, load_study, study_files

from .test_io import small_table

#: The lab of data/examples/lab-export: German column names, degrees, N·cm and milliseconds.
LAB = ExportFormat(columns=(("subject", "Proband"), ("condition", "Bedingung"), ("t", "time_ms"),
                            ("angle", "wheel_deg"), ("angle_ref", "target_deg"), ("u_A", "assist_Ncm"),
                            ("velocity", "speed_deg_s"), ("u_H", "hand_Ncm")),
                   units=(("angle", "deg"), ("velocity", "deg/s"), ("torque", "N*cm"), ("time", "ms")))
LAB_DESIGN = with_export(STUDY, LAB)


def segments_equal(a, b) -> bool:
    """Whether two studies hold the same segments, bit for bit (labels and every array)."""
    def fields(s):
        return (s.subject, s.condition, s.trial, s.t, s.angle, s.angle_ref, s.u_A, s.velocity, s.u_H)

    return len(a.segments) == len(b.segments) and all(
        all(np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y for x, y in zip(fields(s), fields(r)))
        for s, r in zip(a.segments, b.segments))


def lab_table():
    """small_table in the lab's names and units, with whole milliseconds as a lab's clock prints them."""
    df = to_export(small_table(), LAB)
    return df.assign(time_ms=np.round(df["time_ms"]).astype(np.int64))


def per_subject(tmp_path, df, by="Proband", folder="exports"):
    """One CSV per subject, as the lab exports them; returns the folder."""
    out = tmp_path / folder
    out.mkdir()
    for subject, rows in df.groupby(by, sort=False):
        rows.to_csv(out / f"{subject}.csv", index=False)
    return out


# Each unit against a value worked by hand: (quantity, unit, scioc's column, value in the unit, value in scioc's).
HAND = [("angle", "deg", "angle", 180.0, math.pi), ("angle", "deg", "angle_ref", 90.0, math.pi / 2),
        ("velocity", "deg/s", "velocity", 360.0, 2 * math.pi), ("torque", "N*cm", "u_A", 250.0, 2.5),
        ("torque", "N·cm", "u_H", -12.5, -0.125), ("torque", "N*mm", "u_H", 1500.0, 1.5),
        ("torque", "Nmm", "u_A", 2.0, 0.002), ("time", "ms", "t", 2500.0, 2.5), ("time", "ms", "t", 10.0, 0.01)]


@pytest.mark.parametrize("quantity, unit, column, given, expected", HAND, ids=[f"{h[2]}-{h[3]:g}{h[1]}" for h in HAND])
def test_each_unit_converts_to_scioc_and_back_as_worked_by_hand(quantity, unit, column, given, expected):
    fmt = ExportFormat(units=((quantity, unit),))
    assert fmt.converts(column)
    assert fmt.to_scioc(column, np.array([given]))[0] == expected  # these values convert exactly
    assert fmt.from_scioc(column, np.array([expected]))[0] == given


def test_scioc_units_convert_nothing():
    fmt = ExportFormat(units=(("angle", "rad"), ("velocity", "rad/s"), ("torque", "N*m"), ("time", "s")))
    assert fmt.is_convention and not any(fmt.converts(c) for c in ("t", "angle", "u_A", "velocity", "u_H"))


def test_a_lab_table_loads_as_the_same_study_in_scioc_units(tmp_path):
    path = tmp_path / "lab.csv"
    lab_table().to_csv(path, index=False)
    study = load_study(path, LAB_DESIGN)
    small_table().to_parquet(tmp_path / "ref.parquet")
    ref = load_study(tmp_path / "ref.parquet")
    assert [(s.subject, s.condition) for s in study.segments] == [(s.subject, s.condition) for s in ref.segments]
    for s, r in zip(study.segments, ref.segments):
        # x·180/π·π/180, x·100/100 and round(1000·t)/1000 are x (t) to within their roundings: two ulps
        for name in ("t", "angle", "angle_ref", "u_A", "velocity", "u_H"):
            np.testing.assert_array_max_ulp(getattr(s, name), getattr(r, name), maxulp=2)


def test_a_file_column_named_like_a_scioc_column_that_is_renamed_is_ignored(tmp_path):
    df = lab_table().assign(angle=1e6)  # the lab's own "angle", not the wheel's (that is wheel_deg)
    df.to_csv(tmp_path / "lab.csv", index=False)
    assert np.abs(load_study(tmp_path / "lab.csv", LAB_DESIGN).segments[0].angle).max() < 1


def test_a_renamed_column_missing_is_named_as_the_file_names_it(tmp_path):
    lab_table().drop(columns=["wheel_deg"]).to_csv(tmp_path / "lab.csv", index=False)
    with pytest.raises(StudyFileError, match=r"lab.csv, column 'wheel_deg': required column is missing; the "
                                             r"experiment's \[columns\] angle names it \(columns present: Proband"):
        load_study(tmp_path / "lab.csv", LAB_DESIGN)
    lab_table().drop(columns=["hand_Ncm"]).to_csv(tmp_path / "lab.csv", index=False)  # optional, but named
    with pytest.raises(StudyFileError, match=r"column 'hand_Ncm': column is missing; the experiment's \[columns\] u_H"):
        load_study(tmp_path / "lab.csv", LAB_DESIGN)


def test_a_glob_a_folder_and_the_concatenated_table_load_bit_for_bit_alike(tmp_path):
    df = lab_table()
    folder = per_subject(tmp_path, df)
    (folder / EXPERIMENT_FILE).write_text("")  # not a study file: a folder's study is its data files
    df.to_csv(tmp_path / "all.csv", index=False)
    whole = load_study(tmp_path / "all.csv", LAB_DESIGN)
    for given in (folder / "*.csv", folder, str(folder / "s[12].csv")):
        study = load_study(given, LAB_DESIGN)
        assert segments_equal(study, whole), given
        assert study.path == str(given) and study.files == (str(folder / "s1.csv"), str(folder / "s2.csv"))
    study = load_study(folder / "*.csv", LAB_DESIGN)
    assert [(s.source, s.first_row) for s in study.segments] == [  # rows within each file
        (str(folder / "s1.csv"), 0), (str(folder / "s1.csv"), 21), (str(folder / "s2.csv"), 0),
        (str(folder / "s2.csv"), 21)]


def four_subjects():
    """lab_table twice over, as subjects P1..P4: P3.csv is the third file."""
    df = pd.concat([lab_table(), lab_table()], ignore_index=True)
    return df.assign(Proband=[f"P{i // 42 + 1}" for i in range(len(df))])


def test_a_bad_value_in_the_third_file_names_that_file_its_column_and_row(tmp_path):
    df = four_subjects()
    df.loc[df.index[df["Proband"] == "P3"][5], "wheel_deg"] = 900.0  # 15.7 rad: beyond one turn
    folder = per_subject(tmp_path, df)
    assert [p.name for p in study_files(folder / "*.csv")] == ["P1.csv", "P2.csv", "P3.csv", "P4.csv"]
    with pytest.raises(StudyFileError) as err:
        load_study(folder / "*.csv", LAB_DESIGN)
    assert str(err.value).startswith(f"{folder / 'P3.csv'}, column 'wheel_deg', row 5 (line 7): 900 deg (15.71 rad) "
                                     "is beyond the plausible ±6.283 rad")
    assert "is the column in deg, as the experiment's [units] angle says?" in str(err.value)
    assert (err.value.path, err.value.column, err.value.row) == (str(folder / "P3.csv"), "wheel_deg", 5)


@pytest.mark.parametrize("column, value, match", [
    ("assist_Ncm", "oops", "not a finite number: 'oops'"),
    ("time_ms", 75, "time step 0.005 s"),  # row 8 of a segment stepping by 10 ms: 70, 75
])
def test_other_bad_values_in_the_third_file_are_named_there(tmp_path, column, value, match):
    df = four_subjects().astype({column: object})
    df.loc[df.index[df["Proband"] == "P3"][8], column] = value
    folder = per_subject(tmp_path, df)
    with pytest.raises(StudyFileError, match=re.escape(match)) as err:
        load_study(folder, LAB_DESIGN)
    assert (err.value.path, err.value.column, err.value.row) == (str(folder / "P3.csv"), column, 8)
    assert "line 10" in str(err.value)


def test_files_that_differ_in_their_columns_are_refused_naming_the_file(tmp_path):
    folder = per_subject(tmp_path, lab_table())
    pd.read_csv(folder / "s2.csv").drop(columns=["hand_Ncm", "speed_deg_s"]).to_csv(folder / "s2.csv", index=False)
    with pytest.raises(StudyFileError, match=r"s2.csv, column 'speed_deg_s': column is missing here, but .*s1.csv "
                                             "has it"):
        load_study(folder, LAB_DESIGN)


def test_the_subject_can_come_from_the_file_name(tmp_path):
    fmt = ExportFormat(columns=tuple((c, n) for c, n in LAB.columns if c != "subject"), units=LAB.units,
                       from_file_name=r"VP_(?P<subject>\w+)")
    df = lab_table()
    folder = per_subject(tmp_path, df)
    for f in folder.iterdir():
        pd.read_csv(f).drop(columns=["Proband"]).to_csv(folder / f"VP_{f.name}", index=False)
        f.unlink()
    df.to_csv(tmp_path / "all.csv", index=False)
    assert segments_equal(load_study(folder, with_export(STUDY, fmt)), load_study(tmp_path / "all.csv", LAB_DESIGN))
    (folder / "notes.csv").write_text("x\n1\n")
    with pytest.raises(StudyFileError, match=r"notes.csv: the file name 'notes' does not match the experiment's "
                                             r"\[columns\] from_file_name = 'VP_\(\?P<subject>\\w\+\)'"):
        load_study(folder, with_export(STUDY, fmt))
    (folder / "notes.csv").unlink()
    pd.read_csv(folder / "VP_s1.csv").assign(subject="x").to_csv(folder / "VP_s1.csv", index=False)
    with pytest.raises(StudyFileError, match="VP_s1.csv, column 'subject': the file has this column, and"):
        load_study(folder, with_export(STUDY, fmt))


def test_matlab_files_of_variables_or_of_one_struct(tmp_path):
    df = lab_table()
    df.to_csv(tmp_path / "all.csv", index=False)
    whole = load_study(tmp_path / "all.csv", LAB_DESIGN)
    # the labels as cell arrays of text, the numbers as vectors
    columns = {c: df[c].to_numpy(dtype=object if c in ("Proband", "Bedingung") else None) for c in df.columns}
    savemat(tmp_path / "vars.mat", columns)
    savemat(tmp_path / "struct.mat", {"export": columns})
    for name in ("vars.mat", "struct.mat"):
        assert segments_equal(load_study(tmp_path / name, LAB_DESIGN), whole), name
    savemat(tmp_path / "short.mat", {**columns, "wheel_deg": columns["wheel_deg"][:-1]})
    with pytest.raises(StudyFileError, match=r"short.mat: the variables differ in length \(.*wheel_deg: 83"):
        load_study(tmp_path / "short.mat", LAB_DESIGN)
    savemat(tmp_path / "matrix.mat", {**columns, "wheel_deg": np.ones((84, 2))})
    with pytest.raises(StudyFileError, match=r"matrix.mat: variable 'wheel_deg' has shape \(84, 2\)"):
        load_study(tmp_path / "matrix.mat", LAB_DESIGN)


def test_a_study_without_files_is_refused(tmp_path):
    with pytest.raises(StudyFileError, match=r"exports/\*.csv: no file matches this pattern"):
        load_study(tmp_path / "exports" / "*.csv")
    (tmp_path / "empty").mkdir()
    with pytest.raises(StudyFileError, match=r"empty: is a directory without study files"):
        load_study(tmp_path / "empty")


def test_time_in_milliseconds_suggests_the_units_table(tmp_path):
    path = tmp_path / "ms.csv"
    small_table().assign(t=lambda d: d["t"] * 1000).to_csv(path, index=False)
    with pytest.raises(StudyFileError, match=r'is t in milliseconds\? t must be in seconds, or say \[units\] time = '
                                             r'"ms" in the experiment file'):
        load_study(path)


def test_the_experiment_beside_a_glob_or_inside_a_folder_is_found(tmp_path):
    folder = per_subject(tmp_path, lab_table())
    write_experiment(LAB_DESIGN, folder / EXPERIMENT_FILE)
    for given in (folder / "*.csv", folder):
        design, source = find_experiment(given)
        assert design == LAB_DESIGN and source == str(folder / EXPERIMENT_FILE)
        assert len(load_study(given, design).segments) == 4


def test_encoder_counts_in_degrees_load_exactly_on_scioc_encoder_grid(tmp_path):
    from scioc.models.simulate import quantize

    df = lab_table()
    counts = np.round(df["wheel_deg"] / 0.009) + np.arange(len(df)) % 7 - 3  # whole counts of 0.009°
    df["wheel_deg"] = np.round(counts * 0.009, 3)  # as the rig prints them
    df.to_csv(tmp_path / "lab.csv", index=False)
    angle = np.concatenate([s.angle for s in load_study(tmp_path / "lab.csv", LAB_DESIGN).segments])
    step = STUDY.encoder_step
    assert np.array_equal(angle, counts.to_numpy() * step) and np.array_equal(angle, quantize(angle, step))
    assert not np.array_equal(angle, df["wheel_deg"].to_numpy() * math.pi / 180)  # the conversion alone is off it
    df.loc[3, "wheel_deg"] += 0.001  # one value between counts: the column is not the encoder's, and kept as given
    df.to_csv(tmp_path / "lab.csv", index=False)
    angle = np.concatenate([s.angle for s in load_study(tmp_path / "lab.csv", LAB_DESIGN).segments])
    assert np.array_equal(angle, df["wheel_deg"].to_numpy() * math.pi / 180)
    unquantized = with_export(dataclasses.replace(STUDY, encoder_counts=0), LAB)
    df.loc[3, "wheel_deg"] -= 0.001
    df.to_csv(tmp_path / "lab.csv", index=False)
    angle = np.concatenate([s.angle for s in load_study(tmp_path / "lab.csv", unquantized).segments])
    assert np.array_equal(angle, df["wheel_deg"].to_numpy() * math.pi / 180)  # no encoder: no grid
