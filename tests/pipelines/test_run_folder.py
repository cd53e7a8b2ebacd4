"""``scioc.open_run``: a run folder's tables, verdicts and lineage, read as the report reads them."""

import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def analysed(tmp_path_factory):
    from scioc.pipelines.run import analyse_to_dir

    return analyse_to_dir(ROOT / "data" / "examples" / "lab-export", tmp_path_factory.mktemp("lab") / "run",
                          fit=False).parent


def test_open_run_gives_the_tables_verdicts_and_lineage(analysed):
    import scioc

    run = scioc.open_run(analysed)
    assert list(run.models) == ["maxent"] and run.left_out == {}
    m = run.models["maxent"]
    assert len(m.estimates) == 8 and m.tests["adequacy"]["human_model"] == "maxent" and m.posterior() is None
    assert run.verdicts == {"maxent": {"adequacy": m.identify["adequacy"]["verdict"], "adequacy_at_posterior": None,
                                       "convergence": None}}
    assert run.choice["human_models"] == ["maxent"]
    assert run.lineage["identify/identify.json"]["study"]["sha256"]


def test_a_part_made_from_other_estimates_is_left_out_and_said_why(analysed, tmp_path):
    import shutil

    import scioc

    copy = tmp_path / "run"
    shutil.copytree(analysed, copy)
    side = json.loads((copy / "compare.json").read_text())
    side["inputs"]["estimates"]["sha256"] = "0" * 64  # as if it tested another identification's estimates
    (copy / "compare.json").write_text(json.dumps(side))
    run = scioc.open_run(copy)
    assert set(run.left_out) == {"compare.json"} and run.models["maxent"].tests is None
    assert "compare.json" in run.left_out["compare.json"]


def test_a_folder_without_an_identification_is_refused(tmp_path):
    import scioc

    with pytest.raises(FileNotFoundError, match="no estimates"):
        scioc.open_run(tmp_path)


def test_the_stage_counter_counts_every_stage_once_in_order(tmp_path, capsys):
    # The delayed model's stages are counted before the data decide; where they are not needed they say so, in
    # their place, so the log reads [1/N], [2/N], ..., [N/N].
    import re

    from scioc.pipelines.run import analyse_to_dir

    analyse_to_dir(ROOT / "data" / "examples" / "lab-export", tmp_path / "run", fit=False)
    counts = re.findall(r"^\[(\d+)/(\d+)\]", capsys.readouterr().out, flags=re.M)
    n = int(counts[0][1])
    assert [(int(k), int(t)) for k, t in counts] == [(k, n) for k in range(1, n + 1)]
