"""``scioc fit --compare-to``, ``scioc human-models`` and ``scioc run --human-models``: usage errors, the default,
and one end-to-end comparison of two tiny real fits."""

import json
from dataclasses import replace
from pathlib import Path

import pytest

from scioc.models.design import STUDY
from scioc.pipelines.cli import EXIT_BAD_DATA, EXIT_USAGE, main
from scioc.pipelines.cli.parser import build_parser
from scioc.pipelines.experiment import experiment_hash
from scioc.pipelines.fit.human_models import HUMAN_MODELS_POINTS
from scioc.pipelines.lineage import study_entry
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.run import default_human_models
from scioc.pipelines.simulate import simulate_to_dir
from scioc.pipelines.storage import write_table_atomic
from tests.pipelines.test_io import small_table


def study_file(path):
    """A small valid study at ``path`` (its content: the lineage checks read it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    return write_table_atomic(small_table(K=40), path)


def fake_fit(folder, *, human_model="maxent", study="study.parquet", settings=None, **extra):
    """The files of a finished fit folder, with a sidecar saying what was fitted (nothing is sampled); the study's
    SHA-256 is recorded where the study exists."""
    settings = settings or IdentifySettings()
    folder.mkdir(parents=True)
    recorded = study_entry(study) if Path(study).is_file() else {"path": str(study), "sha256": "0" * 64}
    side = {"study": str(study), "human_model": human_model, "identify_settings": settings.as_dict(),
            "experiment_sha256": experiment_hash(settings.design), "inputs": {"study": recorded}, **extra}
    (folder / "posterior.json").write_text(json.dumps(side))
    (folder / "posterior.nc").write_bytes(b"")
    (folder / "contrasts.json").write_text(json.dumps({"adequacy": {"verdict": "not checked"}}))
    return folder


def _fit(tmp_path, *options):
    if not (tmp_path / "study.parquet").exists():
        study_file(tmp_path / "study.parquet")
    return main(["fit", str(tmp_path / "study.parquet"), "--out", str(tmp_path / "out"), *options])


def test_compare_to_needs_the_delayed_human_model(tmp_path, capsys):
    fake_fit(tmp_path / "maxent", study=tmp_path / "study.parquet")
    assert _fit(tmp_path, "--compare-to", str(tmp_path / "maxent")) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err.startswith("scioc fit: error:") and "--human-model delayed" in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("config, model, needs", [
    ('R_population = "policy_scale"\n', "maxent", "unknown key(s) R_population for the maxent human model's fit"),
    ('rho_form = "folded_centred"\n', "delayed", 'under R_population = "policy_scale"'),
    ('log_R_form = "centred"\n', "maxent", "unknown key(s) log_R_form"),
    ('adaptation = "curved"\n', "delayed", "unknown key(s) adaptation for the delayed human model's fit"),
    ('R_population = "policy_scale"\nrho_form = "polar"\n', "delayed",
     "rho_form must be one of centred, noncentred, folded, folded_centred; got 'polar'"),
    ('adequacy_at = "mode"\n', "maxent", "adequacy_at must be one of draw, means"),
    ('[delayed]\ndelay = "sampled"\n', "delayed", "key 'delayed': the sampler settings are plain keys"),
    ('delay = \n', "delayed", "not a TOML file"),
])
def test_the_sampler_settings_are_checked_against_the_human_model(tmp_path, capsys, config, model, needs):
    # --sampler-config: the research settings of one human model's fit; a key the model does not know, or a value
    # it does not take, is refused before any work, naming the file (exit 3).
    path = tmp_path / "sampler.toml"
    path.write_text(config)
    assert _fit(tmp_path, "--human-model", model, "--sampler-config", str(path)) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert err.startswith("scioc fit: error:") and needs in err and str(path) in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("case, message, status", [
    ("missing", "is not a finished scioc fit folder (no posterior.json, posterior.nc, contrasts.json)", EXIT_USAGE),
    ("delayed", "is a delayed fit; compare with a max-ent fit", EXIT_USAGE),
    ("other study", "is not a fit of the same data as", EXIT_BAD_DATA),
    ("other window", "is not a fit of the same data as", EXIT_BAD_DATA),
    ("the output", "holds the input", EXIT_USAGE),
])
def test_compare_to_a_folder_it_cannot_be_compared_with_is_refused_before_fitting(tmp_path, capsys, case, message,
                                                                                   status):
    study = study_file(tmp_path / "study.parquet")
    target = tmp_path / "maxent"
    if case == "delayed":
        fake_fit(target, human_model="delayed", study=study)
    elif case == "other study":  # another study's content, though at this study's path
        fake_fit(target, study=study)
        side = json.loads((target / "posterior.json").read_text())
        side["inputs"]["study"]["sha256"] = "f" * 64
        (target / "posterior.json").write_text(json.dumps(side))
    elif case == "other window":
        fake_fit(target, study=study, settings=IdentifySettings(window_seconds=10.0))
    elif case == "the output":
        target = tmp_path / "out"
        fake_fit(target, study=study)
    options = ["--human-model", "delayed", "--compare-to", str(target)] + (["--force"] if case == "the output" else [])
    assert _fit(tmp_path, *options) == status
    err = capsys.readouterr().err
    assert err.startswith("scioc fit: error:") and message in err, err
    if case.startswith("other"):
        assert str(target / "posterior.json") in err and str(study) in err
        assert ("SHA-256 ffffffffffff" in err) == (case == "other study")
        assert ("window_seconds 10.0 against 15.0" in err) == (case == "other window")
    assert case == "the output" or not (tmp_path / "out").exists()


def test_compare_to_accepts_another_adequacy_bootstrap(tmp_path):
    """The adequacy bootstrap's size and seed do not make two fits different studies."""
    from scioc.pipelines.fit.human_models import check_maxent_fit

    study = study_file(tmp_path / "study.parquet")
    fake_fit(tmp_path / "maxent", study=study, settings=IdentifySettings(adequacy_boot=0, adequacy_seed=1))
    check_maxent_fit(tmp_path / "maxent", study, IdentifySettings(human_model="delayed"))


def test_compare_to_finds_the_study_of_a_fit_made_by_scioc_run(tmp_path):
    """A fit of ``scioc run`` recorded its study inside the run's staging folder, since renamed: the comparison
    finds the study relative to the fit's folder (``study_relative``), as every other reader does."""
    from scioc.pipelines.fit.human_models import check_maxent_fit, fit_study
    from scioc.pipelines.lineage import LineageError

    study = study_file(tmp_path / "run" / "data" / "study.parquet")
    staged = tmp_path / ".run.staging" / "data" / "study.parquet"
    fake_fit(tmp_path / "run" / "fit", study=study, study_relative="../data/study.parquet")
    side = json.loads((tmp_path / "run" / "fit" / "posterior.json").read_text())
    (tmp_path / "run" / "fit" / "posterior.json").write_text(json.dumps({**side, "study": str(staged)}))
    check_maxent_fit(tmp_path / "run" / "fit", study, IdentifySettings(human_model="delayed"))
    assert fit_study(json.loads((tmp_path / "run" / "fit" / "posterior.json").read_text()),
                     tmp_path / "run" / "fit").resolve() == study.resolve()
    other = write_table_atomic(small_table(K=41), tmp_path / "other.parquet")
    with pytest.raises(LineageError, match="not a fit of the same data as .*other.parquet: study"):
        check_maxent_fit(tmp_path / "run" / "fit", other, IdentifySettings(human_model="delayed"))


def test_human_models_command_names_what_is_wrong(tmp_path, capsys):
    fake_fit(tmp_path / "a")
    assert main(["human-models", str(tmp_path / "a"), str(tmp_path / "nothing")]) == EXIT_USAGE
    assert "nothing is not a finished scioc fit folder" in capsys.readouterr().err
    assert main(["human-models", str(tmp_path / "a"), str(tmp_path / "a")]) == EXIT_USAGE
    assert "is a maxent fit, not a delayed fit" in capsys.readouterr().err
    fake_fit(tmp_path / "b", human_model="delayed")
    (tmp_path / "b" / "posterior.json").write_text("{not json")
    assert main(["human-models", str(tmp_path / "a"), str(tmp_path / "b")]) == EXIT_BAD_DATA
    err = capsys.readouterr().err
    assert err.startswith("scioc human-models: error:") and "posterior.json: not readable as JSON" in err
    # --out never replaces one of the fits' files.
    assert main(["human-models", str(tmp_path / "a"), str(tmp_path / "b"), "--out",
                 str(tmp_path / "a" / "contrasts.json")]) == EXIT_USAGE
    assert f"is contrasts.json of the fit {tmp_path / 'a'} itself, an input" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["human-models", str(tmp_path / "a"), str(tmp_path / "b"), "--points", "0"])
    assert exc.value.code == EXIT_USAGE and "--points: expected a positive integer" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["delayed", "maxent,kbl", "maxent,maxent", ""])
def test_run_human_models_must_be_known_names_with_maxent(text, capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["run", "--human-model", text])
    assert exc.value.code == EXIT_USAGE and "--human-model" in capsys.readouterr().err


def test_run_human_models_default_follows_the_torque_sensor_and_the_maxent_adequacy():
    args = build_parser().parse_args(["run"])
    assert args.human_models is None  # the run decides from its experiment and the max-ent adequacy verdict
    sensor = replace(STUDY, torque_sensor=True)
    for design in (STUDY, sensor):  # angle only: the delayed model from the angles, without a fit (its reason says)
        for verdict in ("pass", "fail", "not checked"):
            models, why = default_human_models(design, verdict)
            assert models == (("maxent",) if verdict == "pass" else ("maxent", "delayed"))
            assert ("encoder's angles" in why) == (models == ("maxent", "delayed") and design is STUDY)
        assert default_human_models(design, None)[0] == ("maxent", "delayed")  # no verdict: not shown to fit
    assert build_parser().parse_args(["run", "--human-model", "delayed, maxent"]).human_models == ("maxent",
                                                                                                   "delayed")


#: The smallest study the two fits and the comparison run on: 3 subjects, 4-s windows, a torque sensor.
TINY = replace(STUDY, torque_sensor=True, run_seconds=8.0, window_start=2.0, window_seconds=4.0, preview=1.0,
               subjects=3)
#: Tiny samplers: the numbers are checked for consistency, not quality (they do not converge).
SAMPLER = ["--chains", "2", "--draws", "20", "--tune", "30", "--seed", "4"]


@pytest.mark.validation
def test_fit_compare_to_and_the_human_models_command_agree(tmp_path, capsys):
    sim = simulate_to_dir(tmp_path / "data", seed=7, human="kbl", design=TINY)
    study = str(sim["study"])
    maxent, delayed = str(tmp_path / "fit_maxent"), str(tmp_path / "fit_delayed")
    assert main(["fit", study, "--out", maxent, *SAMPLER]) in (0, 1)  # 1: tiny chains do not converge
    capsys.readouterr()
    assert main(["fit", study, "--out", delayed, "--human-model", "delayed", "--compare-to", maxent, *SAMPLER]) in (0, 1)
    out = capsys.readouterr().out
    written = json.loads((tmp_path / "fit_delayed" / "human_models.json").read_text())
    assert "human models, leave-one-subject-out over 3 subjects:" in out
    for line in ("  maxent   adequacy at the posterior:", "  delayed  adequacy at the posterior:",
                 "elpd(delayed) - elpd(maxent) =", "(z = ", "subjects better predicted: delayed",
                 "importance sampling: smallest ESS", f"human_models: {delayed}/human_models.json"):
        assert line in out, line
    assert set(written["adequacy"]) == {"maxent", "delayed"}
    d = written["difference"]
    assert d["reliable"] == (not d["unreliable_because"]) and d["importance"]["threshold"] == 100
    assert set(written["maxent"]["is_ess_loo_by_subject"]) == set(written["by_subject"])
    assert written["adequacy"]["delayed"]["verdict"] in ("pass", "fail")
    assert not [p for p in (tmp_path / "fit_delayed").iterdir() if p.name.startswith(".")]  # nothing half-written
    # The command reads the two folders and prints the same, writing nothing without --out.
    before = sorted(p.name for p in tmp_path.rglob("*"))
    assert main(["human-models", maxent, delayed, "--seed", "4", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out) == written and written["written_by"] == "scioc human-models"
    assert sorted(p.name for p in tmp_path.rglob("*")) == before
    assert main(["human-models", maxent, delayed, "--seed", "4", "--out", str(tmp_path / "hm.json")]) == 0
    assert json.loads((tmp_path / "hm.json").read_text()) == written
    assert written["maxent"]["proposal_points_per_subject"] == HUMAN_MODELS_POINTS
    capsys.readouterr()
    assert main(["human-models", maxent, delayed, "--points", "300", "--format", "json"]) == 0
    fewer = json.loads(capsys.readouterr().out)
    assert fewer["maxent"]["proposal_points_per_subject"] == fewer["delayed"]["proposal_points_per_subject"] == 300
