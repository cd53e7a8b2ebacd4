"""``scioc identify`` and ``scioc loglik`` with ``--human-model delayed``: the warm-up of each window, the estimates'
columns and sidecar, agreement with the model functions called by hand, and the command line's errors."""

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest

from scioc.models.bayes.delayed_blocks import MOTOR_FORMS, R_POPULATIONS
from scioc.models.delayed import (
    DELAY_GRID_S,
    Warmup,
    forward_delayed,
    identify_unit_delayed,
    lag_coefficients,
    loglik_grad,
    window_loglik,
    window_tau0,
)
from scioc.models.design import STUDY
from scioc.models.maxent import forward_optimal_control
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.cli import main
from scioc.pipelines.cli.values import (
    HUMAN_MODEL_NAMES,
    LIKELIHOOD_NAMES,
    MAX_DELAY_S,
    R_POPULATION_NAMES,
    RHO_FORM_NAMES,
)
from scioc.pipelines.fit.delayed_forms import LOG_R_FORMS
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.io import load_study
from scioc.pipelines.loglik import LIKELIHOODS
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.simulate import simulate_to_dir

SENSOR = dataclasses.replace(STUDY, torque_sensor=True)
#: 12 s into 30-s runs: windows that start inside a run, as the paper's 210-225 s of 240 s do.
WINDOW = dict(window_start=12.0, window_seconds=10.0)


@pytest.fixture(scope="module")
def combined(tmp_path_factory):
    """Two subjects of the ``combined`` human (delay, lag, motor noise), 30-s runs, with a torque sensor."""
    root = tmp_path_factory.mktemp("delayed")
    return simulate_to_dir(root / "data", n_subjects=2, seed=4, seconds=30.0, human="combined", design=SENSOR)


def settings(human_model="delayed", **kw):
    return IdentifySettings.for_design(SENSOR, human_model=human_model, adequacy_boot=kw.pop("adequacy_boot", 0),
                                       **{**WINDOW, **kw})


def test_the_names_the_parser_spells_are_the_pipelines():
    from scioc.pipelines.human_model import names

    assert HUMAN_MODEL_NAMES == names()[:2]
    assert LIKELIHOOD_NAMES == LIKELIHOODS
    assert R_POPULATION_NAMES == R_POPULATIONS and RHO_FORM_NAMES == MOTOR_FORMS
    assert RHO_FORM_NAMES[:2] == LOG_R_FORMS  # scioc fit --log-R-form's choices
    assert MAX_DELAY_S == DELAY_GRID_S[-1]


def test_a_window_inside_a_run_keeps_the_torques_before_it(combined):
    study = load_study(combined["study"], SENSOR)
    measured = prepare_study(study, settings())
    for p in measured.segments:
        i0 = p.rows.start
        assert i0 == 1200 and p.warmup.tau_start == 0.0  # measured from the recording's start, at rest
        np.testing.assert_array_equal(p.warmup.u, p.data.u_H[:i0])
    whole = prepare_study(study, settings(window_start=None, window_seconds=None))
    assert all(p.warmup is None for p in whole.segments)  # a whole trial starts at rest
    rec = prepare_study(study, settings(reconstruct="always"))
    for p in rec.segments:  # reconstructed: only over the margin, from its first torque
        assert p.warmup.u.shape == (100,) and p.warmup.tau_start == p.warmup.u[0] != 0.0


def test_identify_delayed_writes_its_columns_and_sidecar(combined, tmp_path):
    paths = identify_to_dir(combined["study"], tmp_path / "id", settings(), show_progress=False)
    est = pd.read_parquet(paths["estimates"])
    meta = json.loads(open(paths["meta"]).read())
    assert set(est.human_model) == {"delayed"} and meta["human_model"] == meta["settings"]["human_model"] == "delayed"
    assert meta["delay_grid"] == {"nominal_s": list(DELAY_GRID_S), "samples": list(range(31)),
                                  "seconds": [0.01 * d for d in range(31)]}
    for col in ("delay_s", "tau_nm", "sigma_m", "se_tau_nm", "se_sigma_m", "lag_at_bound"):
        assert col in est.columns
    assert all(len(v) == 31 for v in est.profile_loglik)
    # the same as the model's function on the file's torques, each window's arm torque from all torques before it
    study = load_study(combined["study"], SENSOR)
    plant = discretize(SENSOR.dt, SENSOR.wheel)
    prepared = prepare_study(study, settings())
    for p in prepared.segments[:2]:
        row = est[(est.subject == p.data.subject) & (est.condition == p.data.condition)].iloc[0]
        seg = study.segments[[s.label for s in study.segments].index(p.data.label)]
        ref = identify_unit_delayed([prepare_batch(plant, [p.segment])], plant,
                                    tau0=[[Warmup(seg.u_H[: p.rows.start])]], delay_search="grid")
        assert (row.theta1, row.tau_nm, row.sigma_m, row.delay_s, row.loglik) == \
               (ref.theta1, ref.tau_nm, ref.sigma_m, ref.delay_s, ref.loglik)
        np.testing.assert_array_equal(row.profile_loglik, ref.profile)
    # the literature's human: delay 0.12 s, lag 0.06 s, motor noise 0.25 N·m (models.humans), from 10-s windows
    ok = ~est.implausible
    assert ok.all() and est.converged.all()
    assert np.median(est.delay_s) == pytest.approx(0.12, abs=0.02)
    assert np.median(est.tau_nm) == pytest.approx(0.06, abs=0.015)
    assert np.median(est.sigma_m) == pytest.approx(0.25, abs=0.05)


def test_the_delayed_trajectories_are_its_own_mean_behaviour(combined, tmp_path):
    # Fig. 6 and the cross-prediction of a delayed identification plan on the lagged wheel with each level's
    # (θ, τ_nm), not with the max-ent human's plan for the command cost.
    paths = identify_to_dir(combined["study"], tmp_path / "id", settings(), show_progress=False)
    est = pd.read_parquet(paths["estimates"])
    traj = pd.read_parquet(paths["trajectories"])
    plant = discretize(SENSOR.dt, SENSOR.wheel)
    p = prepare_study(load_study(combined["study"], SENSOR), settings()).segments[0]
    s, K = p.segment, p.segment.K
    rows = traj[(traj.subject == p.data.subject) & (traj.condition == p.data.condition)]
    for level in STUDY.levels:
        e = est[(est.subject == p.data.subject) & (est.condition == level)].iloc[0]
        lag = lag_coefficients(e.tau_nm, plant.dt, SENSOR.wheel)
        ref = forward_delayed([e.q11, e.q22, e.R], s.x0, s.angle_ref, plant, u_A=s.u_A, tau_nm=e.tau_nm,
                              tau0=window_tau0([p.warmup], lag.a, lag.alpha)[0][0], params=SENSOR.wheel)
        np.testing.assert_array_equal(rows[f"pred_{level.lower()}_u_H"].to_numpy()[:K], ref.u_H[:K])
        np.testing.assert_array_equal(rows[f"pred_{level.lower()}_angle"].to_numpy(), ref.x[: K + 1, 0])
        maxent = forward_optimal_control([e.q11, e.q22, e.R], s.x0, s.angle_ref, s.u_A, plant)
        assert np.abs(maxent.u_H[:K] - ref.u_H[:K]).max() > 1e-3  # measured: 6e-3 N·m at the start, where τ_0 acts


def test_maxent_identify_says_so_and_has_no_delayed_columns(combined, tmp_path):
    paths = identify_to_dir(combined["study"], tmp_path / "id", settings("maxent"), show_progress=False)
    est = pd.read_parquet(paths["estimates"])
    meta = json.loads(open(paths["meta"]).read())
    assert set(est.human_model) == {"maxent"} and meta["human_model"] == "maxent" and meta["delay_grid"] is None
    assert "tau_nm" not in est.columns and "profile_loglik" not in est.columns


def test_the_adequacy_bootstrap_draws_from_the_delayed_model(combined, tmp_path):
    paths = identify_to_dir(combined["study"], tmp_path / "id", settings(adequacy_boot=4), show_progress=False)
    meta = json.loads(open(paths["meta"]).read())
    assert meta["adequacy"]["bootstrap"]["human_model"] == "delayed"
    assert "adequacy_p" in pd.read_parquet(paths["estimates"]).columns


def test_cli_identify_with_the_delayed_human(combined, tmp_path, capsys):
    exp = tmp_path / "experiment.toml"
    exp.write_text("[simulation]\ntorque_sensor = true\n")
    code = main(["identify", combined["study"], "--out", str(tmp_path / "id"), "--window", "12,10",
                 "--human-model", "delayed", "--adequacy-boot", "0", "--experiment", str(exp)])
    assert code == 0
    assert "(human model: delayed)" in capsys.readouterr().out
    assert set(pd.read_parquet(tmp_path / "id" / "estimates.parquet").human_model) == {"delayed"}


def _loglik_json(study, capsys, *extra):
    assert main(["loglik", study, "--theta", "400,0,20", "--format", "json", *extra]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.fixture()
def no_analysis(tmp_path):
    """An experiment file without [analysis]: scioc loglik then evaluates whole trials."""
    exp = tmp_path / "whole.toml"
    exp.write_text("[simulation]\ntorque_sensor = true\n")
    return ["--experiment", str(exp)]


def test_cli_loglik_delayed_is_the_models(combined, capsys, no_analysis):
    got = _loglik_json(combined["study"], capsys, "--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "0.06",
                       "--sigma-m", "0.25", *no_analysis)
    study = load_study(combined["study"])
    plant = discretize(0.01)
    prepared = prepare_study(study, IdentifySettings(window_start=None, window_seconds=None, preview=0.0,
                                                     adequacy_boot=0))
    for rec, p in zip(got, prepared.segments):
        ref = loglik_grad([400.0, 0.0, 20.0], prepare_batch(plant, [p.segment]), plant, tau_nm=0.06, sigma_m=0.25,
                          delay=12).loglik[0]  # whole trials: at rest at their start
        assert rec["loglik"] == ref
    # zero delay, lag and motor noise is the max-ent likelihood
    zero = _loglik_json(combined["study"], capsys, "--human-model", "delayed", "--delay-s", "0", "--tau-nm", "0",
                        "--sigma-m", "0", *no_analysis)
    maxent = _loglik_json(combined["study"], capsys, *no_analysis)
    for a, b in zip(zero, maxent):
        assert a["loglik"] == pytest.approx(b["loglik"], rel=1e-12)


def test_cli_loglik_delayed_in_a_window_starts_from_the_warm_up(combined, tmp_path, capsys):
    exp = tmp_path / "experiment.toml"
    exp.write_text("[analysis]\nwindow_start_s = 12.0\nwindow_s = 10.0\npreview_s = 2.0\n")
    got = _loglik_json(combined["study"], capsys, "--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "0.06",
                       "--sigma-m", "0.25", "--experiment", str(exp))
    study = load_study(combined["study"])
    plant = discretize(0.01)
    prepared = prepare_study(study, IdentifySettings(**WINDOW, adequacy_boot=0))
    lag = lag_coefficients(0.06)
    for rec, p, seg in zip(got, prepared.segments, study.segments):
        tau0 = window_tau0([Warmup(seg.u_H[: p.rows.start])], lag.a, lag.alpha)[0]
        ref = loglik_grad([400.0, 0.0, 20.0], prepare_batch(plant, [p.segment]), plant, tau_nm=0.06, sigma_m=0.25,
                          delay=12, tau0=tau0).loglik[0]
        assert tau0[0] != 0.0 and rec["loglik"] == ref


@pytest.mark.parametrize("extra, message", [
    (["--human-model", "delayed", "--delay-s", "0.35", "--tau-nm", "0.06", "--sigma-m", "0.25"], "between 0 and 0.3"),
    (["--human-model", "delayed", "--delay-s", "0.125", "--tau-nm", "0.06", "--sigma-m", "0.25"], "whole number"),
    (["--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "2", "--sigma-m", "0.25"], "--tau-nm"),
    (["--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "0.06"], "needs --delay-s, --tau-nm and --sigma-m"),
    (["--tau-nm", "0.06"], "apply to --human-model delayed"),
    (["--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "-0.06", "--sigma-m", "0.25"], "--tau-nm"),
    (["--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "0.06", "--sigma-m", "nan"], "--sigma-m"),
    (["--human-model", "lagged"], "--human-model"),
])
def test_cli_loglik_refuses_bad_parameters_as_usage_errors(combined, capsys, no_analysis, extra, message):
    assert _status(["loglik", combined["study"], "--theta", "400,0,20", *extra, *no_analysis]) == 2
    assert message in capsys.readouterr().err


def _status(argv) -> int:
    """The exit status of ``scioc argv``, whether argparse exits or the command returns it."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def test_identify_says_which_units_it_identified_from_their_angles(tmp_path):
    import json

    from scioc.pipelines.adequacy import not_checked
    from scioc.pipelines.identify import format_identify

    meta = {"segments": 4, "converged": 4, "human_model": "delayed", "reconstructed_units": 4,
            "adequacy": not_checked("test")}
    (tmp_path / "identify.json").write_text(json.dumps(meta))
    assert "4 of 4 units have no recorded torque: the delayed model identified them from their encoder angles" in \
        format_identify(tmp_path)
    for other in ({"human_model": "delayed", "reconstructed_units": 0}, {"human_model": "maxent"}):
        (tmp_path / "identify.json").write_text(json.dumps({**meta, **other}))
        assert "encoder angles" not in format_identify(tmp_path)


def test_without_a_torque_sensor_the_delayed_model_is_identified_from_the_angles(combined, tmp_path):
    # The same recordings with the torque reconstructed from the encoder: the delayed model is fitted to the
    # angles themselves (models.delayed.angles), as identify_unit_delayed does with the unit's AngleWindows.
    # Before, the torque likelihood of the reconstructed torque put τ_nm at its 1-s bound (README "Human models").
    from scioc.pipelines.prepare import angle_windows

    s_rec = settings(reconstruct="always")
    paths = identify_to_dir(combined["study"], tmp_path / "id", s_rec, show_progress=False)
    est = pd.read_parquet(paths["estimates"])
    assert set(est.likelihood) == {"angles"}
    plant = discretize(SENSOR.dt, SENSOR.wheel)
    prepared = prepare_study(load_study(combined["study"], SENSOR), s_rec)
    p = prepared.segments[0]
    row = est[(est.subject == p.data.subject) & (est.condition == p.data.condition)].iloc[0]
    ref = identify_unit_delayed([prepare_batch(plant, [p.segment])], plant, params=SENSOR.wheel,
                                tau0=[[p.warmup]], angles=angle_windows(prepared.segments, [0]),
                                sigma_y=SENSOR.encoder_sd, delay_search="grid")  # scioc identify's search
    assert (row.theta1, row.tau_nm, row.sigma_m, row.delay_s) == (ref.theta1, ref.tau_nm, ref.sigma_m, ref.delay_s)
    # the literature's human (delay 0.12 s, lag 0.06 s, motor noise 0.25 N·m) from 10-s windows of angles
    assert est.converged.all() and not est.lag_at_bound.any()
    assert np.median(est.tau_nm) == pytest.approx(0.06, abs=0.03)
    assert np.median(est.sigma_m) == pytest.approx(0.25, abs=0.08)
    # the torques' path on the same files is unchanged
    assert set(pd.read_parquet(identify_to_dir(combined["study"], tmp_path / "t", settings(),
                                               show_progress=False)["estimates"]).likelihood) == {"torques"}


def test_cli_loglik_of_the_angles_is_the_models(combined, tmp_path, capsys):
    # --likelihood angles: the delayed human's likelihood of the encoder's angles, window by window, as identify
    # evaluates it (models.delayed.window_loglik on the prepared windows); on a file without u_H too (the torques
    # before each window then reconstructed), where the torque likelihood is refused and says what to use instead.
    from scioc.pipelines.prepare import angle_windows

    exp = tmp_path / "experiment.toml"
    exp.write_text("[analysis]\nwindow_start_s = 12.0\nwindow_s = 10.0\npreview_s = 2.0\n")
    angle_only = tmp_path / "angles.parquet"
    pd.read_parquet(combined["study"]).drop(columns=["u_H"]).to_parquet(angle_only)
    plant = discretize(0.01)
    human = ["--human-model", "delayed", "--delay-s", "0.12", "--tau-nm", "0.06", "--sigma-m", "0.25"]
    for path in (combined["study"], str(angle_only)):
        got = _loglik_json(path, capsys, *human, "--likelihood", "angles", "--experiment", str(exp))
        prepared = prepare_study(load_study(path), IdentifySettings(**WINDOW, adequacy_boot=0))
        wins = angle_windows(prepared.segments, range(len(prepared.segments)))
        assert len(got) == len(wins) == 4
        for rec, w in zip(got, wins):
            ref = window_loglik([400.0, 0.0, 20.0], 0.06, 0.25, 12, w, plant, sigma_y=STUDY.encoder_sd)
            assert np.isfinite(ref.loglik) and rec["loglik"] == ref.loglik
    torques = _loglik_json(combined["study"], capsys, *human, "--experiment", str(exp))
    assert all(a["loglik"] != t["loglik"] for a, t in zip(got, torques))  # another likelihood, not a relabelling
    assert _status(["loglik", str(angle_only), "--theta", "400,0,20", *human, "--experiment", str(exp)]) == 3
    assert "use --likelihood angles" in capsys.readouterr().err
    # the max-ent human's likelihood of the angles: the delayed human's with no delay, lag or motor noise
    maxent = _loglik_json(str(angle_only), capsys, "--likelihood", "angles", "--experiment", str(exp))
    for rec, w in zip(maxent, wins):
        assert rec["loglik"] == window_loglik([400.0, 0.0, 20.0], 0.0, 0.0, 0, w, plant, sigma_y=STUDY.encoder_sd).loglik
