"""Model adequacy through the real pipeline: angle-only acquisition, false alarms within budget, misfit flagged."""

import json

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from scioc.models.adequacy import SEGMENT_ALPHA, STATISTICS
from scioc.models.simulate import Population, simulate_study
from scioc.pipelines.cli import main
from scioc.pipelines.identify import identify_study
from scioc.pipelines.io import validate_table
from scioc.pipelines.prepare import IdentifySettings
from scioc.pipelines.simulate import study_table

#: False-failure budget of the seeded statistical tests below.
FALSE_FAILURE = 0.01
#: A short design: 35-s runs, a 10-s window from 20 s (1-s reconstruction margins, 2-s preview).
SETTINGS = IdentifySettings(window_start=20.0, window_seconds=10.0, adequacy_boot=19)


def _study(human: str, n_subjects: int, seed: int):
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    t, segs = simulate_study(n_subjects, rng, Population(beta=0.0), 35.0, human=human)
    return validate_table(study_table(t, segs), f"<{human}>")


@pytest.fixture(scope="module")
def correct():
    return identify_study(_study("maxent", 30, 7), SETTINGS, show_progress=False)


@pytest.mark.validation
def test_false_alarms_within_budget_on_the_models_own_humans(correct, measured):
    """Angle-only acquisition, MC and SC, plug-in θ: flagged segments stay within the per-segment
    budget (binomial bound at FALSE_FAILURE), and the study verdict passes (family-wise 1 %)."""
    est = correct.estimates
    n = len(est)
    assert n == 60 and est["reconstructed"].all()
    limit = int(sps.binom.isf(FALSE_FAILURE, n, SEGMENT_ALPHA))  # P(count > limit) <= FALSE_FAILURE
    measured("max-ent human, angles only: segments flagged of 60", est["adequacy_flagged"].sum(), f"<= {limit}")
    assert est["adequacy_flagged"].sum() <= limit
    assert correct.adequacy["verdict"] == "pass", correct.adequacy["combined_p"]
    for k in STATISTICS:
        p = est[f"adequacy_p_{k}"]
        assert p.between(1 / 20, 1).all()
        assert p.mean() > 0.4  # valid or conservative: not piled up near 0


@pytest.mark.validation
def test_a_misspecified_human_is_flagged(measured):
    res = identify_study(_study("lag", 10, 8), SETTINGS, show_progress=False)
    measured("negative control, lagged human: share of segments flagged", res.estimates["adequacy_flagged"].mean(),
             "> 0.5, verdict fail")
    assert res.adequacy["verdict"] == "fail"
    assert res.adequacy["failed_checks"]
    assert res.estimates["adequacy_flagged"].mean() > 0.5
    assert {"subject", "condition", "p", "checks_at_5_percent"} <= set(res.adequacy["flagged_segments"][0])


@pytest.mark.validation
def test_same_seed_same_adequacy(correct):
    again = identify_study(_study("maxent", 30, 7), SETTINGS, show_progress=False)
    cols = [c for c in correct.estimates if c.startswith("adequacy")]
    pd.testing.assert_frame_equal(correct.estimates[cols], again.estimates[cols], check_exact=True)


def test_cli_prints_the_verdict_and_exits_1_when_it_fails(tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["simulate", "--subjects", "3", "--run-seconds", "35", "--human", "combined", "--beta", "0",
                 "--out", str(data)]) == 0
    sim = json.loads((data / "simulation.json").read_text())
    assert sim["human"]["name"] == "combined" and sim["population"]["beta"] == 0.0
    capsys.readouterr()
    code = main(["identify", str(data / "study.parquet"), "--out", str(tmp_path / "id"), "--window", "20,10",
                 "--adequacy-boot", "19"])
    out = capsys.readouterr().out
    assert code == 1
    assert "model adequacy: FAIL" in out
    meta = json.loads((tmp_path / "id" / "identify.json").read_text())
    assert meta["adequacy"]["verdict"] == "fail" and meta["adequacy"]["bootstrap"]["replicates_per_segment"] == 19
    est = pd.read_parquet(tmp_path / "id" / "estimates.parquet")
    assert {"adequacy_p", "adequacy_flagged", *(f"adequacy_p_{k}" for k in STATISTICS)} <= set(est.columns)


def test_adequacy_can_be_switched_off(tmp_path, capsys):
    data = tmp_path / "data"
    assert main(["simulate", "--subjects", "2", "--run-seconds", "35", "--out", str(data)]) == 0
    capsys.readouterr()
    assert main(["identify", str(data / "study.parquet"), "--out", str(tmp_path / "id"), "--window", "20,10",
                 "--adequacy-boot", "0"]) == 0
    assert "NOT CHECKED" in capsys.readouterr().out
    assert json.loads((tmp_path / "id" / "identify.json").read_text())["adequacy"]["verdict"] == "not checked"


def test_cli_human_names_are_the_models():
    from scioc.models.humans import HUMANS
    from scioc.pipelines.cli import HUMAN_NAMES

    assert tuple(HUMANS) == HUMAN_NAMES
