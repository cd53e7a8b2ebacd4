"""``scioc bench --quick``: every quick part runs and writes its JSON (the numbers are not quotable)."""

import json

import numpy as np
import pytest

from scioc.pipelines.cli import main


@pytest.mark.validation
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
    # The delayed likelihood of the torques, and of the encoder's angles beside its dense reference.
    assert {r["delay"] for r in res["delayed"]["rows"]} == {0, 10, 30}
    assert all(0 < r["value_min_s"] for r in res["delayed"]["rows"])  # the log-likelihood alone, beside it
    ang = res["delayed_angles"]
    assert ang["n"] == 4 and ang["K"] == 1500 and [r["delay"] for r in ang["rows"]] == [0, 10, 30]
    assert all(r["dense_s"] > r["filter_s"] > 0 for r in ang["dense"])
    ident = ang["identify"]  # every unit from angles and torques; the goal is for the paper's 84, not these 4
    assert len(ident["angles"]) == len(ident["torques"]) == 4 and ident["within_goal"] is None
    assert ident["angles_total_s"] == pytest.approx(sum(ident["angles"]))
    # The second example's identification (its fit is left out of --quick).
    ex = res["example"]
    assert ex["units"] == 48 and ex["segments"] == 144 and ex["samples_per_segment"] == 2400
    assert ex["identify_s"] > 0 and "fit_s" not in ex


@pytest.mark.validation
def test_bench_fit_of_the_delayed_human_records_its_settings(tmp_path, capsys):
    """``scioc bench-fit --human-model delayed``: the variant asked for is the one fitted, and the JSON says which."""
    path = tmp_path / "fit.json"
    argv = ["bench-fit", "--human-model", "delayed", "--subjects", "2", "--chains", "1", "--draws", "20", "--tune",
            "20", "--R-population", "policy_scale", "--rho-form", "folded", "--json", str(path)]
    assert main(argv) == 0
    res = json.loads(path.read_text())
    st = res["settings"]
    assert st["segments"] == 4 and (st["chains"], st["draws"], st["tune"]) == (1, 20, 20)
    assert st["delayed_priors"]["R_population"] == "policy_scale" and st["delayed_form"]["rho"] == "folded"
    assert st["nuts"] == {"adaptation": "low_rank"}
    assert "rho_scale" in res["diagnostics"]["population"] and "mu_log_R" not in res["diagnostics"]["population"]
    assert "baseline R population: policy_scale (ρ folded); mass matrix: low_rank" in capsys.readouterr().out
