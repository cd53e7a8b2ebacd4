"""scioc recovery: estimates against the simulator's truth."""

import json

import numpy as np
import pandas as pd
import pytest

from scioc.pipelines.cli import main
from scioc.pipelines.lineage import file_sha256
from scioc.pipelines.recovery import format_recovery, recovery


def _tables(shift_est, shift_true, delayed=False):
    subjects = [f"S{i}" for i in range(6)]
    rng = np.random.default_rng(0)
    base = np.exp(rng.normal(3.0, 0.5, 6))
    truth = pd.DataFrame({"subject": subjects * 2, "condition": ["MC"] * 6 + ["SC"] * 6,
                          "theta1": np.concatenate([base, base * np.exp(shift_true)])})
    est = truth.assign(theta1=np.concatenate([base * 1.1, base * 1.1 * np.exp(shift_est)]))
    if delayed:
        truth = truth.assign(delay_s=0.12, tau_nm=0.06, motor_sd=0.25)
        est = est.assign(human_model="delayed", delay_s=[0.12] * 10 + [0.15, 0.09], tau_nm=0.065, sigma_m=0.3)
    return est, truth


def test_recovery_measures_the_bias_of_the_condition_effect():
    est, truth = _tables(-0.5, -0.2)
    res = recovery(est, truth, ["MC", "SC"], "MC")
    assert res["contrasts"]["SC"]["bias"] == pytest.approx(-0.3)
    assert res["levels"]["MC"]["mean_error_log_theta1"] == pytest.approx(np.log(1.1))
    assert res["levels"]["MC"]["spearman_theta1"] == pytest.approx(1.0)
    assert "delayed" not in res and res["human_model"] == "maxent"


def test_recovery_of_delay_lag_and_motor_noise():
    est, truth = _tables(0.0, 0.0, delayed=True)
    d = recovery(est, truth, ["MC", "SC"], "MC")["delayed"]
    assert d["delay_exact"] == 10 and d["delay_mean_abs_error_s"] == pytest.approx(0.06 / 12)
    assert d["tau_nm_mean_error_s"] == pytest.approx(0.005) and d["sigma_m_mean"] == pytest.approx(0.3)
    assert "delay exact in 10 of 12 units" in format_recovery(recovery(est, truth, ["MC", "SC"], "MC"))


def _write(folder, est, truth, simulation=None):
    """The estimates and the truth with the sidecars that say which study each is of (one study, hashed "1" * 64)."""
    est.to_parquet(folder / "estimates.parquet")
    truth.to_parquet(folder / "truth.parquet")
    study = {"path": "study.parquet", "sha256": "1" * 64}
    (folder / "identify.json").write_text(json.dumps({"inputs": {"study": study}, "outputs": {
        "estimates.parquet": file_sha256(folder / "estimates.parquet")}}))
    (folder / "simulation.json").write_text(json.dumps({**(simulation or {}), "outputs": {
        "study.parquet": study["sha256"], "truth.parquet": file_sha256(folder / "truth.parquet")}}))


def test_cli(tmp_path, capsys):
    est, truth = _tables(-0.5, -0.2)
    _write(tmp_path, est, truth)
    assert main(["recovery", str(tmp_path / "estimates.parquet"), "--truth", str(tmp_path / "truth.parquet"),
                 "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["contrasts"]["SC"]["bias"] == pytest.approx(-0.3)
    assert main(["recovery", str(tmp_path / "none.parquet"), "--truth", str(tmp_path / "truth.parquet")]) == 3


def test_delay_profile_spread_counts_each_subjects_summed_profile():
    from scioc.pipelines.human_model.delayed import delay_profile_spread

    flat, peaked = np.zeros(5), np.array([0.0, -2.0, -20.0, -5.0, -11.0])
    est = pd.DataFrame({"subject": ["A", "A", "B", "B"], "condition": ["MC", "SC"] * 2,
                        "profile_loglik": [peaked, peaked, flat, np.full(5, np.nan)]})
    res = delay_profile_spread(est)
    # A sums to [0, -4, -40, -10, -22]: 1 delay within 3 nats, 2 within 6 and 3 within 10. B has a unit without any
    # profile value: left out.
    assert res["grid_delays"] == 5 and res["subjects"] == 1
    assert [res["within"][k]["median"] for k in ("3", "6", "10")] == [1.0, 2.0, 3.0]
    both = delay_profile_spread(est.assign(profile_loglik=[peaked, peaked, flat, flat]))
    assert both["subjects"] == 2 and both["within"]["3"] == {"median": 3.0, "min": 1, "max": 5}


def test_the_paper_agents_truth_has_no_delay_lag_or_motor_noise(tmp_path, capsys):
    """A truth file written before the body columns were recorded for the paper's agent reads them as 0."""
    est, truth = _tables(0.0, 0.0, delayed=True)
    truth = truth.drop(columns=["delay_s", "tau_nm", "motor_sd"])
    args = ["recovery", str(tmp_path / "estimates.parquet"), "--truth", str(tmp_path / "truth.parquet"),
            "--format", "json"]
    _write(tmp_path, est, truth)  # a simulation.json without the human: unknown
    assert main(args) == 0 and "delayed" not in json.loads(capsys.readouterr().out)
    _write(tmp_path, est, truth, {"human": {"name": "kbl"}})
    assert main(args) == 0 and "delayed" not in json.loads(capsys.readouterr().out)  # another human: not assumed
    _write(tmp_path, est, truth, {"human": {"name": "maxent"}})
    assert main(args) == 0
    d = json.loads(capsys.readouterr().out)["delayed"]
    assert d["delay_exact"] == 0 and d["delay_mean_error_s"] == pytest.approx((0.12 * 10 + 0.15 + 0.09) / 12)
    assert d["tau_nm_mean_error_s"] == pytest.approx(0.065) and d["motor_sd_true_mean"] == 0.0
