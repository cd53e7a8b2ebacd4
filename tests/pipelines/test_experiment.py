"""The experiment file: reading, validating, writing and hashing ``experiment.toml`` (issue 12, item 1)."""

import dataclasses
import json
import re

import pytest

import scioc.pipelines.experiment as experiment
from scioc.models.design import PAPER_ASSISTANT, STUDY, AssistantSpec, Design, WheelParameters
from scioc.pipelines.experiment import (
    EXPERIMENT_FILE,
    ExperimentFileError,
    experiment_hash,
    find_experiment,
    load_experiment,
    parse_experiment,
    resolved,
    sidecar,
    to_toml,
    write_experiment,
)
from scioc.pipelines.export import COLUMNS, UNITS, ExportDesign, ExportFormat, convention, export_of, with_export
from scioc.pipelines.io import InputDataError

#: The example of issue 12, verbatim: the paper's study written out.
EXAMPLE = '''\
[sampling]
rate_hz = 100.0            # the t column must step by 1/rate_hz within a trial

[wheel]                    # paper Eq. 18
inertia = 0.04             # kg·m²
spring = 1.146             # N·m/rad
damper = 0.286             # N·m·s/rad

[encoder]
counts_per_rev = 40000     # 0: the angle is not quantized

[conditions]
baseline = "MC"            # every contrast is taken against this level
levels = ["MC", "SC"]      # all levels in the data, baseline included

[conditions.assistant]     # one entry per assisted level; levels without an entry have u_A = 0
SC = { kind = "mpc", theta = [5.0, 0.0, 1.0], horizon = 50, step_s = 0.02, period_s = 0.01 }
# kind = "linear": u_A = -gain[0]·angle - gain[1]·velocity + reference_gain·angle_ref
#   e.g. strong = { kind = "linear", gain = [6.0, 0.3], reference_gain = 6.0 }

[analysis]
window_start_s = 210.0     # on the trial's own t axis
window_s = 15.0
# whole = true             # analyse every trial whole instead of one window
preview_s = 2.0            # 0: the paper's horizon

[simulation]               # used by `scioc simulate` / `scioc run` only
run_s = 240.0
subjects = 42
trials = 1
torque_sensor = false      # true: the simulated rig also records u_H
'''

WEAK = AssistantSpec(kind="linear", gain=(2.0, 0.1), reference_gain=2.0)
STRONG = AssistantSpec(kind="linear", gain=(6.0, 0.3), reference_gain=6.0)
#: A design different from the paper's in every respect.
OTHER = Design(wheel=WheelParameters(0.06, 2.0, 0.4), dt=1 / 200, encoder_counts=0, levels=("none", "weak", "strong"),
               baseline="none", assistants=(("weak", WEAK), ("strong", STRONG)), run_seconds=60.0, subjects=16,
               trials=3, torque_sensor=True, whole=True, preview=0.0)


def write(tmp_path, text, name=EXPERIMENT_FILE):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("text", ["", EXAMPLE], ids=["empty", "issue-example"])
def test_an_empty_file_and_the_issue_example_give_the_paper_study(tmp_path, text):
    design = load_experiment(write(tmp_path, text))
    assert design == STUDY
    assert experiment_hash(design) == experiment_hash(STUDY)


@pytest.mark.parametrize("design", [STUDY, OTHER], ids=["paper", "other"])
def test_to_toml_round_trips_to_an_equal_design_and_hash(tmp_path, design):
    text = to_toml(design)
    assert text.isascii()
    path = tmp_path / "out" / EXPERIMENT_FILE
    write_experiment(design, path)
    assert path.read_text() == text and [p.name for p in path.parent.iterdir()] == [EXPERIMENT_FILE]
    back = load_experiment(path)
    assert back == design
    assert experiment_hash(back) == experiment_hash(design)
    assert parse_experiment(resolved(design)) == design  # a sidecar's resolved form reads back too


def test_other_differs_from_the_paper_in_every_section():
    a, b = resolved(STUDY), resolved(OTHER)
    for section in a:
        for key in set(a[section]) & set(b[section]):
            assert a[section][key] != b[section][key], (section, key)


VARIANTS = {
    "rate": dict(dt=0.005), "inertia": dict(wheel=WheelParameters(0.05, 1.146, 0.286)),
    "spring": dict(wheel=WheelParameters(0.04, 1.2, 0.286)), "damper": dict(wheel=WheelParameters(0.04, 1.146, 0.3)),
    "counts": dict(encoder_counts=4096), "levels": dict(levels=("MC", "SC", "SC2"), effects=()),
    "effects": dict(effects=(-0.3,)),
    "baseline": dict(baseline="SC", assistants=()), "no-assistant": dict(assistants=()),
    "theta": dict(assistants=(("SC", dataclasses.replace(PAPER_ASSISTANT, theta=(5.0, 0.1, 1.0))),)),
    "horizon": dict(assistants=(("SC", dataclasses.replace(PAPER_ASSISTANT, horizon=49)),)),
    "step": dict(assistants=(("SC", dataclasses.replace(PAPER_ASSISTANT, step_s=0.03)),)),
    "period": dict(assistants=(("SC", dataclasses.replace(PAPER_ASSISTANT, period_s=0.02)),)),
    "linear": dict(assistants=(("SC", STRONG),)), "run": dict(run_seconds=241.0), "subjects": dict(subjects=41),
    "trials": dict(trials=2), "sensor": dict(torque_sensor=True), "start": dict(window_start=200.0),
    "window": dict(window_seconds=16.0), "whole": dict(whole=True), "preview": dict(preview=1.5),
}
OTHER_VARIANTS = {"gain": dict(assistants=(("weak", dataclasses.replace(WEAK, gain=(2.0, 0.2))), ("strong", STRONG))),
                  "reference_gain": dict(assistants=(("weak", dataclasses.replace(WEAK, reference_gain=2.5)),
                                                     ("strong", STRONG)))}


def test_the_hash_changes_with_any_one_value_and_every_variant_round_trips():
    designs = {"paper": STUDY, "other": OTHER}
    designs |= {name: dataclasses.replace(STUDY, **change) for name, change in VARIANTS.items()}
    designs |= {name: dataclasses.replace(OTHER, **change) for name, change in OTHER_VARIANTS.items()}
    hashes = {name: experiment_hash(d) for name, d in designs.items()}
    assert len(set(hashes.values())) == len(hashes)
    assert all(re.fullmatch("[0-9a-f]{64}", h) for h in hashes.values())
    for name, design in designs.items():
        assert parse_experiment(resolved(design)) == design, name
        assert parse_experiment(experiment.tomllib.loads(to_toml(design))) == design, name


def test_the_hash_ignores_how_a_value_is_written(tmp_path):
    a = load_experiment(write(tmp_path, "[sampling]\nrate_hz = 200\n[simulation]\nrun_s = 240\n", "a.toml"))
    b = load_experiment(write(tmp_path, "[simulation]\nrun_s = 240.0\n[sampling]\nrate_hz = 200.0\n", "b.toml"))
    assert a == b and experiment_hash(a) == experiment_hash(b)
    # the assistants' order in the file does not matter, nor unused fields of another kind
    c = dataclasses.replace(OTHER, assistants=(("strong", dataclasses.replace(STRONG, theta=(1.0, 1.0, 1.0))),
                                               ("weak", WEAK)))
    assert experiment_hash(c) == experiment_hash(OTHER)
    # with whole = true the window is not used
    assert experiment_hash(dataclasses.replace(OTHER, window_start=5.0)) == experiment_hash(OTHER)
    assert experiment_hash(STUDY) == experiment_hash(dataclasses.replace(STUDY, window_start=210))


@pytest.mark.parametrize("rate", [100.0, 128.0, 200.0, 300.0, 333.0, 1000.0, 1024.0, 2500.0])
def test_any_rate_round_trips_exactly(rate):
    design = dataclasses.replace(STUDY, dt=1.0 / rate, assistants=())
    assert resolved(design)["sampling"]["rate_hz"] == rate
    assert load_back(design) == design


def load_back(design):
    return parse_experiment(experiment.tomllib.loads(to_toml(design)))


def test_labels_that_need_quoting_round_trip():
    design = Design(levels=("ohne Hilfe", 'stärker "x"', "a.b", "tab\there"), baseline="ohne Hilfe",
                    assistants=(('stärker "x"', PAPER_ASSISTANT), ("a.b", STRONG)))  # in the levels' order
    assert to_toml(design).isascii()
    assert load_back(design) == design


def assisted(text, tmp_path):
    return dict(load_experiment(write(tmp_path, text)).assistants)


def test_the_default_assistant_table(tmp_path):
    paper = {"SC": PAPER_ASSISTANT}
    assert assisted('[conditions]\nlevels = ["MC", "SC"]\nbaseline = "MC"\n', tmp_path) == paper
    assert assisted('[conditions]\nlevels = ["MC", "SC", "SC2"]\n', tmp_path) == paper
    assert assisted('[conditions]\nlevels = ["none", "SC"]\nbaseline = "none"\n', tmp_path) == paper
    assert assisted('[conditions]\nlevels = ["none", "weak"]\nbaseline = "none"\n', tmp_path) == {}
    assert assisted("[conditions.assistant]\n", tmp_path) == {}  # an empty table: no assistant
    text = '[conditions]\nlevels = ["MC", "SC", "SC2"]\n[conditions.assistant]\nSC2 = { kind = "mpc", horizon = 20 }\n'
    assert assisted(text, tmp_path) == {"SC2": dataclasses.replace(PAPER_ASSISTANT, horizon=20)}  # replaces the default
    text = '[conditions.assistant]\nSC = { kind = "linear", gain = [6, 0.3], reference_gain = 6 }\n'
    assert assisted(text, tmp_path) == {"SC": STRONG}


def test_the_baseline_defaults_to_mc(tmp_path):
    design = load_experiment(write(tmp_path, '[conditions]\nlevels = ["SC", "MC", "X"]\n'))
    assert design.baseline == "MC" and design.levels == ("SC", "MC", "X")
    assert design.contrasts == ("SC", "X")


def test_find_experiment(tmp_path):
    study = tmp_path / "study.parquet"
    assert find_experiment(study) == (STUDY, None)
    assert find_experiment(None) == (STUDY, None)
    other = tmp_path / "elsewhere" / "mine.toml"
    write_experiment(OTHER, other)
    assert find_experiment(study, explicit=other) == (OTHER, str(other))
    beside = write(tmp_path, "[simulation]\nsubjects = 7\n")
    expected = (dataclasses.replace(STUDY, subjects=7), str(beside))
    assert find_experiment(study) == expected
    assert find_experiment(tmp_path) == expected  # a folder: the file inside it
    assert find_experiment(study, explicit=other) == (OTHER, str(other))  # explicit wins over beside
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(ExperimentFileError, match=re.escape(str(missing))) as err:
        find_experiment(study, explicit=missing)
    assert isinstance(err.value, InputDataError) and err.value.path == str(missing)


def test_sidecar():
    out = sidecar(OTHER, "data/x/experiment.toml")
    assert out == {"experiment": resolved(OTHER), "experiment_sha256": experiment_hash(OTHER),
                   "experiment_file": "data/x/experiment.toml"}
    assert json.loads(json.dumps(sidecar(STUDY, None))) == sidecar(STUDY, None)
    assert sidecar(STUDY, None)["experiment_file"] is None


def test_the_docstring_describes_every_key():
    doc = experiment.__doc__
    res = resolved(STUDY)
    assert list(res) == [s for s in experiment.SECTIONS if s not in ("columns", "units")]  # the convention's
    for section, table in res.items():
        assert tuple(table) == experiment.SECTIONS[section]
    assert list(resolved(LAB)) == list(experiment.SECTIONS)
    for section, keys in experiment.SECTIONS.items():
        for key in keys:
            assert f"``{section}.{key}``" in doc, f"{section}.{key}"
    for kind, keys in experiment.ASSISTANT_KEYS.items():
        assert kind in doc
        for key in keys:
            assert f"``{key}``" in doc, key
    for unit in ("Hz", "kg·m²", "N·m/rad", "N·m·s/rad", "per revolution"):
        assert unit in doc


#: A lab's export: every [units] quantity in another unit, some columns renamed, the trial from the file name.
LAB_TEXT = '''\
[columns]
subject = "Proband"
condition = "Bedingung"
t = "time_ms"
angle = "wheel_deg"
angle_ref = "target_deg"
u_A = "assist_Ncm"
velocity = "Geschwindigkeit"
u_H = "hand torque"
from_file_name = '[^_]+_(?P<trial>\\d+)'

[units]
angle = "deg"
velocity = "deg/s"
torque = "N·cm"
time = "ms"
'''
LAB = with_export(STUDY, ExportFormat(
    columns=(("subject", "Proband"), ("condition", "Bedingung"), ("t", "time_ms"), ("angle", "wheel_deg"),
             ("angle_ref", "target_deg"), ("u_A", "assist_Ncm"), ("velocity", "Geschwindigkeit"),
             ("u_H", "hand torque")),
    units=(("angle", "deg"), ("velocity", "deg/s"), ("torque", "N*cm"), ("time", "ms")),
    from_file_name=r"[^_]+_(?P<trial>\d+)"))


def test_columns_and_units_read_into_an_export_design(tmp_path):
    design = load_experiment(write(tmp_path, LAB_TEXT))
    assert isinstance(design, ExportDesign) and design == LAB
    assert experiment_hash(design) != experiment_hash(STUDY)  # the format enters the hash
    assert convention(design) == STUDY and type(convention(design)) is Design
    fmt = export_of(design)
    assert fmt.name("angle") == "wheel_deg" and fmt.name("trial") == "trial" and fmt.file_columns == ("trial",)
    assert fmt.unit("u_H") == "N*cm" and fmt.file_labels("P03_2") == {"trial": "2"} and fmt.file_labels("P03") is None
    assert resolved(design)["units"] == {"angle": "deg", "velocity": "deg/s", "torque": "N*cm", "time": "ms"}


def test_an_export_design_round_trips_through_toml_and_its_sidecar(tmp_path):
    text = to_toml(LAB)
    assert text.isascii() and "[columns]" in text and "[units]" in text
    assert load_back(LAB) == LAB and parse_experiment(resolved(LAB)) == LAB
    write_experiment(LAB, tmp_path / EXPERIMENT_FILE)
    assert load_experiment(tmp_path / EXPERIMENT_FILE) == LAB
    assert json.loads(json.dumps(sidecar(LAB, None)))["experiment"] == resolved(LAB)


@pytest.mark.parametrize("text", [
    '[columns]\nsubject = "subject"\nt = "t"\n[units]\nangle = "rad"\ntorque = "Nm"\ntime = "s"\n',
    "[columns]\n[units]\n"], ids=["the convention written out", "empty tables"])
def test_the_convention_written_out_is_the_plain_design_with_its_hash(tmp_path, text):
    design = load_experiment(write(tmp_path, text))
    assert type(design) is Design and design == STUDY and experiment_hash(design) == experiment_hash(STUDY)


def test_each_export_key_changes_the_hash_and_spellings_do_not():
    one = {f"columns.{c}": ExportFormat(columns=((c, "x"),)) for c in COLUMNS}
    one |= {f"units.{q}": ExportFormat(units=((q, list(u)[1]),)) for q, u in UNITS.items()}
    one |= {"units.torque N*mm": ExportFormat(units=(("torque", "N*mm"),)),
            "from_file_name": ExportFormat(from_file_name="(?P<subject>.+)"),
            "another from_file_name": ExportFormat(from_file_name="(?P<subject>.+)_x")}
    hashes = {name: experiment_hash(with_export(STUDY, fmt)) for name, fmt in one.items()}
    assert len(set(hashes.values()) | {experiment_hash(STUDY)}) == len(hashes) + 1
    for name, fmt in one.items():
        assert load_back(with_export(STUDY, fmt)) == with_export(STUDY, fmt), name
    spelled = [ExportFormat(units=(("torque", u),)) for u in ("N*cm", "N·cm", "Ncm")]
    assert len({experiment_hash(with_export(STUDY, f)) for f in spelled}) == 1


MPC = '[conditions.assistant]\nSC = { kind = "mpc", %s }\n'
LINEAR = '[conditions.assistant]\nSC = { kind = "linear", %s }\n'
THREE = '[conditions]\nlevels = ["none", "weak", "strong"]\nbaseline = "none"\n'
#: (file text, the dotted key the error must name, a fragment of what is allowed or given)
MALFORMED = [
    ("[sampling]\nrate_hz = 0\n", "sampling.rate_hz", "> 0"),
    ("[sampling]\nrate_hz = -100.0\n", "sampling.rate_hz", "got -100.0"),
    ("[sampling]\nrate_hz = nan\n", "sampling.rate_hz", "finite"),
    ("[sampling]\nrate_hz = inf\n", "sampling.rate_hz", "finite"),
    ('[sampling]\nrate_hz = "100"\n', "sampling.rate_hz", 'got "100"'),
    ("[sampling]\nrate_hz = true\n", "sampling.rate_hz", "got true"),
    ("[sampling]\nrate = 100\n", "sampling.rate", "allowed: rate_hz"),
    ("[sample]\nrate_hz = 100\n", "sample", "allowed: sampling, wheel, encoder"),
    ("rate_hz = 100\n", "rate_hz", "unknown section"),
    ("sampling = 100\n", "sampling", "must be a table"),
    ("[wheel]\ninertia = 0\n", "wheel.inertia", "> 0"),
    ("[wheel]\ndamper = -0.2\n", "wheel.damper", "> 0"),
    ("[wheel]\nmass = 1.0\n", "wheel.mass", "allowed: inertia, spring, damper"),
    ("[encoder]\ncounts_per_rev = 40000.0\n", "encoder.counts_per_rev", "integer"),
    ("[encoder]\ncounts_per_rev = -1\n", "encoder.counts_per_rev", ">= 0"),
    ('[conditions]\nlevels = ["MC"]\n', "conditions.levels", "two or more"),
    ('[conditions]\nlevels = ["MC", "MC"]\n', "conditions.levels", "distinct"),
    ('[conditions]\nlevels = ["MC", ""]\n', "conditions.levels", "non-empty"),
    ('[conditions]\nlevels = "MC, SC"\n', "conditions.levels", "list"),
    ('[conditions]\nlevels = ["MC", 2]\n', "conditions.levels", 'got ["MC", 2]'),
    ('[conditions]\nbaseline = "XX"\n', "conditions.baseline", '["MC", "SC"]'),
    ('[conditions]\nlevels = ["a", "b"]\n', "conditions.baseline", "not given"),
    ('[conditions]\nbaseline = "SC"\n', "conditions.baseline", "[conditions.assistant]"),
    ('[conditions]\ncontrol = "MC"\n', "conditions.control", "allowed: baseline, levels, assistant"),
    ('[conditions]\nassistant = "mpc"\n', "conditions.assistant", "must be a table"),
    ('[conditions.assistant]\nXX = { kind = "mpc" }\n', "conditions.assistant.XX", '["MC", "SC"]'),
    ('[conditions.assistant]\nMC = { kind = "mpc" }\n', "conditions.assistant.MC", "baseline"),
    ('[conditions.assistant]\nSC = "mpc"\n', "conditions.assistant.SC", 'kind = "linear"'),
    ("[conditions.assistant]\nSC = { horizon = 50 }\n", "conditions.assistant.SC.kind", "required"),
    ('[conditions.assistant]\nSC = { kind = "pid" }\n', "conditions.assistant.SC.kind", '"mpc", "linear"'),
    (MPC % "theta = [5.0, 0.0]", "conditions.assistant.SC.theta", "three"),
    (MPC % "theta = [5.0, 0.0, 0.0]", "conditions.assistant.SC.theta", "R"),
    (MPC % "theta = [-1.0, 0.0, 1.0]", "conditions.assistant.SC.theta", ">= 0"),
    (MPC % "horizon = 0", "conditions.assistant.SC.horizon", ">= 1"),
    (MPC % "horizon = 50.0", "conditions.assistant.SC.horizon", "integer"),
    (MPC % "step_s = 0.015", "conditions.assistant.SC.step_s", "multiple of the sample time"),
    (MPC % "period_s = 0", "conditions.assistant.SC.period_s", "> 0"),
    (MPC % "gain = [1.0, 0.0]", "conditions.assistant.SC.gain", 'for kind = "mpc"'),
    ("[sampling]\nrate_hz = 150\n", "conditions.assistant.SC.period_s", "default entry"),
    (LINEAR % "gain = [1.0], reference_gain = 1.0", "conditions.assistant.SC.gain", "two"),
    (LINEAR % "gain = [1.0, nan], reference_gain = 1.0", "conditions.assistant.SC.gain", "finite"),
    (LINEAR % "gain = [1.0, 0.1]", "conditions.assistant.SC.reference_gain", "required"),
    (LINEAR % "reference_gain = 1.0", "conditions.assistant.SC.gain", "required"),
    (LINEAR % "gain = [1, 0], reference_gain = true", "conditions.assistant.SC.reference_gain", "got true"),
    (LINEAR % "gain = [1, 0], reference_gain = 1, horizon = 5", "conditions.assistant.SC.horizon",
     "allowed: kind, gain, reference_gain"),
    (THREE + '[conditions.assistant]\nstrong = { kind = "linear", gain = "6, 0.3", reference_gain = 6.0 }\n',
     "conditions.assistant.strong.gain", 'got "6, 0.3"'),
    ('[conditions]\nlevels = ["MC", "a.b"]\n[conditions.assistant]\n"a.b" = { kind = "x" }\n',
     'conditions.assistant."a.b".kind', "got \"x\""),
    ("[analysis]\nwindow_s = 0\n", "analysis.window_s", "> 0"),
    ("[analysis]\nwindow_start_s = -1\n", "analysis.window_start_s", ">= 0"),
    ("[analysis]\npreview_s = -0.5\n", "analysis.preview_s", ">= 0"),
    ('[analysis]\nwhole = "yes"\n', "analysis.whole", "true or false"),
    ("[analysis]\nwhole = 1\n", "analysis.whole", "got 1"),
    ("[analysis]\nwhole = true\nwindow_s = 10.0\n", "analysis.whole", "analysis.window_s"),
    ("[analysis]\nwindow = [210, 15]\n", "analysis.window", "allowed: window_start_s, window_s, whole, preview_s"),
    ("[simulation]\nsubjects = 0\n", "simulation.subjects", ">= 1"),
    ("[simulation]\ntrials = 1.5\n", "simulation.trials", "integer"),
    ("[simulation]\nsubjects = true\n", "simulation.subjects", "got true"),
    ("[simulation]\ntorque_sensor = 1\n", "simulation.torque_sensor", "true or false"),
    ("[simulation]\nrun_s = 0.0\n", "simulation.run_s", "> 0"),
    ('columns = "Proband"\n', "columns", "must be a table"),
    ('[columns]\nProband = "subject"\n', "columns.Proband", 'a key is scioc\'s column name, its value the file\'s'),
    ('[columns]\nangle = 3\n', "columns.angle", "non-empty string; got 3"),
    ('[columns]\nangle = ""\n', "columns.angle", "non-empty string"),
    ('[columns]\nangle = "deg"\nangle_ref = "deg"\n', "columns.angle", "columns.angle_ref names it too"),
    ('[columns]\nangle = "angle_ref"\n', "columns.angle", "scioc reads angle_ref from a column of that name"),
    ('[columns]\nfrom_file_name = "(?P<subj>.+)"\n', "columns.from_file_name", "named groups among subject"),
    ('[columns]\nfrom_file_name = ".+"\n', "columns.from_file_name", "(?P<subject>.+)"),
    ('[columns]\nfrom_file_name = "(?P<subject>.+"\n', "columns.from_file_name", "not a regular expression"),
    ('[columns]\nsubject = "P"\nfrom_file_name = "(?P<subject>.+)"\n', "columns.from_file_name", "drop one"),
    ('[units]\nangle = "grad"\n', "units.angle", 'angle, angle_ref must be one of "rad", "deg"; got "grad"'),
    ('[units]\ntorque = "kg"\n', "units.torque", '"N*m", "N*cm", "N*mm"'),
    ('[units]\ntime = 1000\n', "units.time", '"s", "ms"; got 1000'),
    ('[units]\nlength = "m"\n', "units.length", "allowed: angle, velocity, torque, time"),
]


@pytest.mark.parametrize("text, key, fragment", MALFORMED, ids=[f"{i:02d}-{m[1]}" for i, m in enumerate(MALFORMED)])
def test_a_malformed_file_is_refused_naming_the_file_and_the_key(tmp_path, text, key, fragment):
    path = write(tmp_path, text)
    with pytest.raises(ExperimentFileError) as err:
        load_experiment(path)
    message = str(err.value)
    assert isinstance(err.value, InputDataError)  # the CLI exits with status 3
    assert str(path) in message and err.value.path == str(path)
    assert f"key '{key}'" in message and err.value.key == key
    assert fragment in message, message


def test_a_toml_syntax_error_names_the_file_line_and_column(tmp_path):
    path = write(tmp_path, "[sampling]\nrate_hz = 100.0\n[wheel\ninertia = 0.04\n")
    with pytest.raises(ExperimentFileError, match=r"line 3, column \d+") as err:
        load_experiment(path)
    assert str(path) in str(err.value) and err.value.key is None


def test_unreadable_files_are_refused(tmp_path):
    bad = tmp_path / "latin1.toml"
    bad.write_bytes('[conditions]\nlevels = ["MC", "Stärke"]\n'.encode("latin-1"))
    with pytest.raises(ExperimentFileError, match="UTF-8"):
        load_experiment(bad)
    with pytest.raises(ExperimentFileError, match=re.escape(str(tmp_path))):
        load_experiment(tmp_path)  # a folder


def test_parse_names_the_given_path_and_backs_up_design_errors(monkeypatch):
    with pytest.raises(ExperimentFileError, match=r"^<experiment>, key 'wheel.spring'"):
        parse_experiment({"wheel": {"spring": 0}})
    with pytest.raises(ExperimentFileError, match=r"^mine.toml: must be a table"):
        parse_experiment([], path="mine.toml")

    def refuse(**fields):
        raise ValueError("Design.preview must be a finite number >= 0; got 2.0")

    monkeypatch.setattr(experiment, "Design", refuse)  # a check only Design makes still names the section
    with pytest.raises(ExperimentFileError, match=r"key 'analysis': Design.preview") as err:
        parse_experiment({})
    assert err.value.key == "analysis"


def test_the_simulated_effects_are_one_number_or_one_per_level(tmp_path):
    three = '[conditions]\nbaseline = "none"\nlevels = ["none", "weak", "strong"]\n'
    assert load_experiment(write(tmp_path, three, "a.toml")).effects == (-0.7, -0.7)
    d = load_experiment(write(tmp_path, three + "[simulation]\nbeta = -0.2\n", "b.toml"))
    assert d.effects == (-0.2, -0.2)
    d = load_experiment(write(tmp_path, three + "[simulation]\nbeta = [-0.35, -0.7]\n", "c.toml"))
    assert d.effects == (-0.35, -0.7)
    with pytest.raises(ExperimentFileError, match="simulation.beta"):
        load_experiment(write(tmp_path, three + "[simulation]\nbeta = [-0.35]\n", "d.toml"))
