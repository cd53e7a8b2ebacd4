"""Lineage by content (issue 52): sidecars record the SHA-256 of what each artifact was made from, commands that
combine artifacts refuse ones that do not belong together (exit 3, naming both files), and no output replaces an
input (exit 2). One test per defect D1-D9 as the issue describes it, the minor items, and a matrix of every combining
command fed mismatched inputs."""

import json
import shutil
from dataclasses import replace
from pathlib import Path

import pandas as pd
import pytest

from scioc.models.design import STUDY
from scioc.pipelines.cli import EXIT_BAD_DATA, EXIT_FAILED_CHECK, EXIT_USAGE, main
from scioc.pipelines.fit.stage import default_inputs
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.lineage import LineageError, file_sha256, require_same, study_entry
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.simulate import simulate_to_dir
from scioc.pipelines.storage import write_table_atomic
from tests.pipelines.calibrate.test_execution import _fake_replications
from tests.pipelines.test_io import small_table

#: The smallest simulated study a fit runs on in seconds: 2 subjects, 4-s windows, a torque sensor (no reconstruction).
TINY = replace(STUDY, torque_sensor=True, run_seconds=8.0, window_start=2.0, window_seconds=4.0, preview=1.0,
               subjects=2)
SETTINGS = IdentifySettings.for_design(TINY, adequacy_boot=0)
#: A fit that only has to finish: nothing is judged on its draws.
QUICK_FIT = ["--chains", "1", "--draws", "25", "--tune", "25", "--cores", "1"]


def tiny_run(root, seed):
    """A run folder of a tiny simulated study: ``data/`` and ``identify/``."""
    sim = simulate_to_dir(root / "data", seed=seed, design=TINY)
    identify_to_dir(sim["study"], root / "identify", SETTINGS, show_progress=False,
                    experiment_file=str(root / "data" / "experiment.toml"))
    return Path(sim["study"])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two tiny run folders of two different simulated studies (seeds 1 and 2)."""
    base = tmp_path_factory.mktemp("lineage")
    return {seed: (base / f"run{seed}", tiny_run(base / f"run{seed}", seed)) for seed in (1, 2)}


def copy_run(small_fit, tmp_path) -> Path:
    """A copy of the shared small fit's run folder (data, identify, fit) that a test may change."""
    root, _, _ = small_fit
    run = tmp_path / "run"
    shutil.copytree(root, run)
    return run


def edit_json(path, **changes):
    side = json.loads(Path(path).read_text())
    side.update(changes)
    Path(path).write_text(json.dumps(side))
    return side


# The hashes themselves.

def test_a_study_of_several_files_is_hashed_by_its_names_and_contents(tmp_path):
    one = small_table(K=30)
    for name, part in one.groupby("subject"):
        write_table_atomic(part, tmp_path / "export" / f"{name}.csv")
    entry = study_entry(tmp_path / "export")
    assert [f["name"] for f in entry["files"]] == ["s1.csv", "s2.csv"]
    assert study_entry(str(tmp_path / "export" / "*.csv"))["sha256"] == entry["sha256"]  # a glob: the same study
    single = write_table_atomic(one, tmp_path / "one.parquet")
    assert study_entry(single) == {"path": str(single), "sha256": file_sha256(single)}
    # One file changed: the study's hash changes and the message says which file differs.
    write_table_atomic(one[one.subject == "s2"].assign(angle=0.0), tmp_path / "export" / "s2.csv")
    changed = study_entry(tmp_path / "export")
    assert changed["sha256"] != entry["sha256"]
    with pytest.raises(LineageError, match=r"export is not the study fit/posterior.json was made from: .*SHA-256 "
                                           r"[0-9a-f]{12}, this one [0-9a-f]{12}; s2.csv differs"):
        require_same("study", "fit/posterior.json", entry, tmp_path / "export", changed)


def test_sidecars_record_the_hash_of_every_input_and_output(runs):
    root, study = runs[1]
    sim = json.loads((root / "data" / "simulation.json").read_text())
    assert sim["outputs"]["study.parquet"] == file_sha256(study)
    assert sim["outputs"]["truth.parquet"] == file_sha256(root / "data" / "truth.parquet")
    meta = json.loads((root / "identify" / "identify.json").read_text())
    assert meta["inputs"]["study"] == {"path": str(study), "sha256": file_sha256(study)}
    assert meta["inputs"]["experiment"]["path"] == str(root / "data" / "experiment.toml")
    assert meta["outputs"]["estimates.parquet"] == file_sha256(root / "identify" / "estimates.parquet")


# D1: the fit's default estimates are matched to the study by content.

def test_d1_the_fit_identifies_itself_beside_another_studys_identification_and_says_so(runs, tmp_path, capsys):
    (root1, _), (root2, _) = runs[1], runs[2]
    run = tmp_path / "run"
    shutil.copytree(root2 / "data", run / "data")
    shutil.copytree(root1 / "identify", run / "identify")  # another study's identification beside this study
    assert main(["fit", str(run / "data" / "study.parquet"), "--out", str(run / "fit"), *QUICK_FIT]) in (0, 1)
    err = capsys.readouterr().err
    assert "scioc fit: note: the fit identifies every unit itself" in err
    assert f"{run / 'data' / 'study.parquet'} is not the study {run / 'identify' / 'identify.json'} was made from" \
        in err
    side = json.loads((run / "fit" / "posterior.json").read_text())
    assert side["inputs"]["estimates"] is None and "identifies every unit itself" in side["identified_itself"]
    assert side["inputs"]["study"]["sha256"] == file_sha256(run / "data" / "study.parquet")
    assert side["inputs"]["truth"]["sha256"] == file_sha256(run / "data" / "truth.parquet")
    assert json.loads((run / "fit" / "contrasts.json").read_text())["mixedlm"] is None
    # Given explicitly, another study's estimates are refused before any work.
    assert main(["fit", str(run / "data" / "study.parquet"), "--out", str(tmp_path / "x"), "--estimates",
                 str(root1 / "identify" / "estimates.parquet"), *QUICK_FIT]) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert str(run / "data" / "study.parquet") in err and str(root1 / "identify" / "identify.json") in err
    assert not (tmp_path / "x").exists()


def test_d1_after_simulate_force_replaces_the_data_the_old_identification_is_not_read(runs, tmp_path):
    root, _ = runs[1]
    run = tmp_path / "run"
    shutil.copytree(root, run)
    study = run / "data" / "study.parquet"
    assert default_inputs(study, None, None).estimates == run / "identify" / "estimates.parquet"
    assert main(["simulate", "--seed", "3", "--subjects", "2", "--run-seconds", "8", "--out", str(run / "data"),
                 "--force"]) == 0
    found = default_inputs(study, None, None)
    assert found.estimates is None and "identify.json was made from" in found.notes["estimates"]
    assert found.truth_dir == run / "data"  # the new simulation is this study's


def test_the_fit_finds_the_identification_beside_its_own_folder_when_it_is_of_this_study(runs, tmp_path):
    """The README's recipe: ``identify STUDY --out results/`` then ``fit STUDY --out results/fit``."""
    (root1, _), (root2, _) = runs[1], runs[2]
    study = tmp_path / "my" / "study.parquet"
    shutil.copytree(root1 / "data", study.parent)
    results = tmp_path / "results"
    shutil.copytree(root1 / "identify", results)
    assert default_inputs(study, None, None, out=results / "fit").estimates == results / "estimates.parquet"
    assert default_inputs(study, None, None, out=tmp_path / "elsewhere" / "fit").estimates is None
    other = tmp_path / "other" / "study.parquet"
    shutil.copytree(root2 / "data", other.parent)
    found = default_inputs(other, None, None, out=results / "fit")
    assert found.estimates is None and f"{results / 'identify.json'} was made from" in found.notes["estimates"]


@pytest.mark.validation
def test_a_run_with_its_fit_combines_every_part_by_content(tmp_path, monkeypatch):
    """``scioc run`` records its experiment relative to the run folder; its fit reads the identification it made and
    the report leaves nothing out."""
    import scioc.pipelines.fit as fit
    from scioc.pipelines.run import run_all

    real = fit.fit_to_dir
    monkeypatch.setattr(fit, "fit_to_dir", lambda *a, **k: real(*a, **{**k, "chains": 1, "draws": 25, "tune": 25,
                                                                       "cores": 1}))
    report = run_all(tmp_path, n_subjects=2, seed=5, design=TINY, settings=SETTINGS, human_models=("maxent",))
    run = report.parent
    side = json.loads((run / "fit" / "posterior.json").read_text())
    assert side["identified_itself"] is None and side["inputs"]["experiment"]["path"] == "data/experiment.toml"
    assert side["inputs"]["estimates"]["sha256"] == file_sha256(run / "identify" / "estimates.parquet")
    assert side["inputs"]["study"]["sha256"] == file_sha256(run / "data" / "study.parquet")
    html = report.read_text()
    assert "Left out of this report" not in html and "Sampler convergence" in html


# D2: adequacy checks the study it reads against the fit's.

def test_d2_adequacy_refuses_another_study_a_replaced_one_and_an_angles_only_one(small_fit, tmp_path, capsys):
    run = copy_run(small_fit, tmp_path)
    other = write_table_atomic(small_table(K=40), tmp_path / "other.parquet")
    assert main(["adequacy", str(run / "fit"), "--study", str(other)]) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert f"{other} is not the study {run / 'fit' / 'posterior.json'} was made from" in err
    # The study at the path the fit records, replaced since.
    edit_json(run / "fit" / "posterior.json", study=str(run / "data" / "study.parquet"))
    pd.read_parquet(other).to_parquet(run / "data" / "study.parquet")
    assert main(["adequacy", str(run / "fit")]) == EXIT_BAD_DATA
    assert "is not the study" in capsys.readouterr().err
    # A delayed fit against a study of angles only.
    edit_json(run / "fit" / "posterior.json", human_model="delayed")
    angles = write_table_atomic(small_table(K=40, with_state=False), tmp_path / "angles.parquet")
    assert main(["adequacy", str(run / "fit"), "--study", str(angles)]) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert str(angles) in err and str(run / "fit" / "posterior.json") in err


# D3: recovery checks that the truth is of the identified study.

def test_d3_recovery_refuses_another_studys_truth(runs, capsys):
    (root1, _), (root2, _) = runs[1], runs[2]
    assert main(["recovery", str(root1 / "identify" / "estimates.parquet"), "--truth",
                 str(root2 / "data" / "truth.parquet")]) == EXIT_BAD_DATA
    out, err = capsys.readouterr()
    assert f"{root1 / 'identify' / 'identify.json'} and {root2 / 'data' / 'simulation.json'} are not of the " \
           "same study" in err and "bias" not in out
    assert main(["recovery", str(root1 / "identify" / "estimates.parquet"), "--truth",
                 str(root1 / "data" / "truth.parquet")]) == 0


# D4: a calibration's replication files are checked, not only read.

@pytest.mark.parametrize("damage, names", [
    (lambda rep: {**rep, "ranks": {**rep["ranks"], "theta1": 500}}, ("key 'ranks.theta1' is 500", "0 to 99")),
    (lambda rep: {**rep, "index": 3}, ("key 'index' is 3", "another replication than 7")),
    (lambda rep: {**rep, "fingerprint": "0123456789abcdef"}, ("key 'fingerprint' is '0123456789abcdef'",
                                                               "config.json")),
], ids=["rank-beyond-L", "copied-under-another-index", "another-configuration"])
def test_d4_a_replication_out_of_range_or_of_another_place_is_refused(tmp_path, capsys, damage, names):
    out = tmp_path / "cal"
    _fake_replications(out / "unit", 10, 99)
    path = out / "unit" / "reps" / "rep_00007.json"
    if "another replication" in names[1]:  # replication 3, copied over replication 7
        path.write_text((out / "unit" / "reps" / "rep_00003.json").read_text())
    else:
        path.write_text(json.dumps(damage(json.loads(path.read_text()))))
    assert main(["calibrate", "--replications", "10", "--negative-control", "none", "--out", str(out)]) \
        == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert str(path) in err and all(n in err for n in names), err
    assert not (out / "unit" / "summary.json").exists()


# D5, D6: no output replaces an input.

def test_d5_adequacy_and_human_models_never_write_onto_an_input(small_fit, tmp_path, capsys):
    run = copy_run(small_fit, tmp_path)
    study = run / "data" / "study.parquet"
    before = study.read_bytes()
    assert main(["adequacy", str(run / "fit"), "--out", str(run / "fit" / ".." / "data" / "study.parquet")]) \
        == EXIT_USAGE
    assert f"--out {run / 'fit' / '..' / 'data' / 'study.parquet'} exists and is not an earlier result of scioc " \
           "adequacy" in capsys.readouterr().err
    assert main(["human-models", str(run / "fit"), str(run / "fit"), "--out", str(study)]) == EXIT_USAGE
    assert "is not an earlier result of scioc human-models" in capsys.readouterr().err
    assert main(["human-models", str(run / "fit"), str(run / "fit"), "--study", str(study), "--out",
                 str(study)]) == EXIT_USAGE
    assert f"--out {study} is the study itself, an input of this command" in capsys.readouterr().err
    assert study.read_bytes() == before


def test_d6_compare_never_writes_onto_the_study_or_the_identifications_sidecar(runs, tmp_path, capsys,
                                                                               monkeypatch):
    root, _ = runs[1]
    run = tmp_path / "run"
    shutil.copytree(root, run)
    estimates = run / "identify" / "estimates.parquet"
    before = {p: p.read_bytes() for p in (run / "data" / "study.parquet", run / "identify" / "identify.json")}
    assert main(["compare", str(estimates), "--out", str(run / "data" / "study.parquet")]) == EXIT_USAGE
    assert f"--out {run / 'data' / 'study.parquet'} exists and is not an earlier result of scioc compare" \
        in capsys.readouterr().err
    monkeypatch.chdir(run / "identify")
    assert main(["compare", "estimates.parquet", "--out", "identify.json"]) == EXIT_USAGE
    assert "--out identify.json is the identification's sidecar itself" in capsys.readouterr().err
    assert all(p.read_bytes() == b for p, b in before.items())
    # An earlier result of compare itself may be replaced.
    assert main(["compare", "estimates.parquet", "--out", "c.json"]) in (0, 1)
    assert main(["compare", "estimates.parquet", "--out", "c.json"]) in (0, 1)
    assert json.loads(Path("c.json").read_text())["written_by"] == "scioc compare"


# D7: the report combines only the parts of one study.

def test_d7_the_report_leaves_out_another_studys_parts_and_says_why(small_fit, runs, tmp_path, capsys):
    run = copy_run(small_fit, tmp_path)
    other, _ = runs[2]
    assert main(["compare", str(other / "identify" / "estimates.parquet"), "--out", str(run / "compare.json")]) \
        in (0, 1)
    edit_json(run / "fit" / "posterior.json",
              inputs={**json.loads((run / "fit" / "posterior.json").read_text())["inputs"],
                      "study": {"path": "another/study.parquet", "sha256": "e" * 64}})
    capsys.readouterr()
    assert main(["report", str(run)]) == 0
    err = capsys.readouterr().err
    assert "scioc report: note: compare.json is left out of the report" in err
    assert f"{run / 'identify' / 'estimates.parquet'} is not the estimates {run / 'compare.json'} was made from" in err
    assert f"{run / 'identify' / 'identify.json'} and {run / 'fit' / 'posterior.json'} are not of the same study" \
        in err
    html = (run / "index.html").read_text()
    assert "Left out of this report" in html and "<code>compare.json</code>" in html and "<code>fit</code>" in html
    assert "No compare.json" in html and "The Bayesian fit in" in html and "is not shown" in html
    # The identification itself not holding the estimates its sidecar records: nothing to report on.
    write_table_atomic(pd.read_parquet(other / "identify" / "estimates.parquet"),
                       run / "identify" / "estimates.parquet")
    assert main(["report", str(run)]) == EXIT_BAD_DATA
    assert f"{run / 'identify' / 'estimates.parquet'} is not the estimates {run / 'identify' / 'identify.json'} " \
           "records" in capsys.readouterr().err


# D8: an absurd preview is a clear error, not an OverflowError.

def test_d8_a_preview_beyond_a_minute_is_refused(runs, tmp_path, capsys):
    _, study = runs[1]
    with pytest.raises(SystemExit) as exc:
        main(["identify", str(study), "--out", str(tmp_path / "id"), "--preview", "1e308"])
    assert exc.value.code == EXIT_USAGE
    assert "--preview: expected a number of seconds >= 0 and at most 60; got '1e308'" in capsys.readouterr().err
    experiment = tmp_path / "experiment.toml"
    experiment.write_text("[analysis]\npreview_s = 1e308\n")
    assert main(["identify", str(study), "--out", str(tmp_path / "id"), "--experiment", str(experiment)]) \
        == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert f"{experiment}, key 'analysis.preview_s'" in err and "at most 60 s" in err and "Traceback" not in err
    with pytest.raises(ValueError, match="preview must be at most 60 s"):
        IdentifySettings(preview=1e308)
    from scioc.models.design import MAX_PREVIEW
    from scioc.pipelines.cli import values

    assert values.MAX_PREVIEW == MAX_PREVIEW  # spelled out so that parsing imports no model code


# D9: a delayed fit in RUN/fit.

def test_d9_the_report_says_why_a_delayed_fit_in_the_max_ent_place_is_not_shown(small_fit, tmp_path, capsys):
    run = copy_run(small_fit, tmp_path)
    side = json.loads((run / "fit" / "posterior.json").read_text())
    side["diagnostics"].pop("pooled")  # as a delayed fit's sidecar: one model
    edit_json(run / "fit" / "posterior.json", human_model="delayed", diagnostics=side["diagnostics"])
    assert main(["report", str(run)]) == 0
    err = capsys.readouterr().err
    assert f"{run / 'fit' / 'posterior.json'} is a fit of the delayed human model, where the report reads the maxent " \
           "model's fit; it belongs in fit_delayed/" in err
    html = (run / "index.html").read_text()
    assert "is a fit of the delayed human model" in html and "Traceback" not in html
    # Without the place check (the section read directly), the section still says why rather than failing.
    from scioc.pipelines.report.bayes import section_bayes

    assert "without the pooled model this section compares with" in section_bayes(run)


# Every combining command, fed artifacts that do not belong together: exit 3, naming both files.

def test_every_combining_command_refuses_mismatched_inputs_naming_both_files(small_fit, runs, tmp_path, capsys):
    run = copy_run(small_fit, tmp_path)
    (root1, _), (root2, study2) = runs[1], runs[2]
    estimates = run / "identify" / "estimates.parquet"
    other_fit = tmp_path / "other_fit"
    shutil.copytree(run / "fit", other_fit)
    edit_json(other_fit / "posterior.json", human_model="delayed",
              inputs={"study": {"path": str(study2), "sha256": file_sha256(study2)}})
    replaced = tmp_path / "replaced" / "identify"
    shutil.copytree(run / "identify", replaced)
    write_table_atomic(pd.read_parquet(root1 / "identify" / "estimates.parquet"), replaced / "estimates.parquet")
    bad_report = tmp_path / "bad_report"
    shutil.copytree(run, bad_report)
    shutil.copy(replaced / "estimates.parquet", bad_report / "identify" / "estimates.parquet")
    cal = tmp_path / "cal"
    _fake_replications(cal / "unit", 4, 99, fingerprint="0123456789abcdef")
    cases = {
        "fit": (["fit", str(study2), "--out", str(tmp_path / "f"), "--estimates", str(estimates)],
                (study2, run / "identify" / "identify.json")),
        "compare": (["compare", str(replaced / "estimates.parquet"), "--out", str(tmp_path / "c.json")],
                    (replaced / "estimates.parquet", replaced / "identify.json")),
        "adequacy": (["adequacy", str(run / "fit"), "--study", str(study2)], (study2, run / "fit" / "posterior.json")),
        "human-models": (["human-models", str(run / "fit"), str(other_fit)],
                         (run / "fit" / "posterior.json", other_fit / "posterior.json")),
        "recovery": (["recovery", str(estimates), "--truth", str(root2 / "data" / "truth.parquet")],
                     (run / "identify" / "identify.json", root2 / "data" / "simulation.json")),
        "report": (["report", str(bad_report)], (bad_report / "identify" / "estimates.parquet",
                                                 bad_report / "identify" / "identify.json")),
        "calibrate": (["calibrate", "--replications", "4", "--negative-control", "none", "--out", str(cal)],
                      (cal / "unit" / "reps" / "rep_00000.json", cal / "unit" / "config.json")),
    }
    for command, (argv, files) in cases.items():
        assert main(argv) == EXIT_BAD_DATA, command
        err = capsys.readouterr().err
        assert err.startswith(f"scioc {command}: error:"), (command, err)
        for f in files:
            assert str(f) in err, (command, f, err)


# The minor items.

def test_an_error_after_a_progress_bar_starts_a_line_of_its_own(runs, tmp_path, capsys, monkeypatch):
    from scioc.pipelines import identify

    def fail(*args, **kwargs):
        raise LineageError("stopped")

    _, study = runs[1]
    monkeypatch.setattr(identify, "identify_prepared", fail)  # after the reconstruction's bar
    code = main(["identify", str(study), "--out", str(tmp_path / "id"), "--reconstruct", "always"])
    err = capsys.readouterr().err
    assert code == EXIT_BAD_DATA and "\nscioc identify: error: stopped\n" in err


def test_a_non_finite_number_is_named_without_numpys_repr(tmp_path, capsys):
    table = small_table()
    table.loc[3, "angle"] = float("nan")
    path = write_table_atomic(table, tmp_path / "study.parquet")
    assert main(["loglik", str(path), "--theta", "60,0,1"]) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert "not a finite number: nan" in err and "np.float64" not in err


def test_the_current_folder_and_a_file_are_refused_as_output_folders(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "keep.txt").write_text("mine")
    assert main(["simulate", "--subjects", "1", "--run-seconds", "8", "--out", ".", "--force"]) == EXIT_USAGE
    assert "the output folder . is the current folder" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]  # no ..*.old folder left
    for command in ("calibrate", "power"):
        assert main([command, "--out", "keep.txt"]) == EXIT_USAGE
        assert "keep.txt exists and is not a folder" in capsys.readouterr().err


def test_compare_with_nothing_to_test_says_so_and_exits_1(tmp_path, capsys):
    estimates = pd.DataFrame({"subject": ["S1", "S1", "S2", "S2"], "condition": ["MC", "SC"] * 2,
                              "theta1": [10.0, 12.0, 9.0, 8.0], "theta2": 0.1, "converged": False})
    path = write_table_atomic(estimates, tmp_path / "estimates.parquet")
    assert main(["compare", str(path)]) == EXIT_FAILED_CHECK
    out = capsys.readouterr().out
    assert "NOTHING TO TEST against SC: no subject has usable estimates of both MC and SC" in out
    res = json.loads((tmp_path / "compare.json").read_text())
    assert res["theta1"]["n_pairs"] == 0 and res["theta1"]["p_value"] is None and res["nothing_to_test"]
    # With three levels, one contrast without a pair: Holm's family is the contrasts with a test.
    from scioc.pipelines.compare import compare_estimates

    three = pd.concat([estimates.assign(converged=True), estimates.assign(condition=["MC", "WEAK"] * 2)])
    three = three.drop_duplicates(["subject", "condition"]).assign(converged=lambda d: d.condition != "WEAK")
    res = compare_estimates(three, levels=("MC", "SC", "WEAK"))
    assert list(res["nothing_to_test"]) == ["WEAK"] and res["contrasts"]["WEAK"]["theta1"]["p_holm"] is None
    assert res["contrasts"]["SC"]["theta1"]["p_holm"] == res["contrasts"]["SC"]["theta1"]["p_value"]


def test_a_run_shorter_than_the_window_is_simulated_to_be_analysed_whole(tmp_path, capsys):
    assert main(["simulate", "--subjects", "1", "--run-seconds", "20", "--out", str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err
    assert "analysis window 210-225 s lies outside the 20-s runs" in err and "whole = true" in err
    assert "whole = true" in (tmp_path / "d" / "experiment.toml").read_text()
    assert "outside the 20-s runs" in json.loads((tmp_path / "d" / "simulation.json").read_text())["analysis_window"]
