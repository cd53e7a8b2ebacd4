"""A calibration's summary and its simuk-layout DataTree, from a small run: ranks, re-ranking, ArviZ's PIT test."""

import json

import numpy as np
import pytest
import xarray as xr
from arviz_stats.base import array_stats

from scioc.models.sbc import pit_from_rank, rank
from scioc.pipelines.calibrate import CalibrationConfig, calibrate, format_summary, rep_path
from scioc.pipelines.calibrate.ranking import LOGLIK

SMALL = dict(level="unit", replications=4, K=200, chains=2, tune=100, draws=100, L=19, batch_size=2, seed=7)


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sbc")
    return out, calibrate(CalibrationConfig(**SMALL), out, n_workers=1, show_progress=False)


@pytest.mark.validation
def test_the_log_likelihood_is_ranked_beside_the_parameters(small_run):
    _, summary = small_run
    assert list(summary["parameters"]) == ["theta1", "theta2", "R", LOGLIK]
    assert summary["parameters"][LOGLIK]["contraction"] is None  # no prior variance to contract
    assert summary["parameters"]["theta1"]["alpha"] == pytest.approx(0.01 / 4)  # Bonferroni over all four
    assert "contraction -" in format_summary({**summary, "wall_seconds_this_run": 1.0, "wall_seconds_total": 1.0})


def test_the_tree_holds_every_replication_in_simuks_layout_and_can_be_reranked(small_run):
    out, summary = small_run
    tree = xr.open_datatree(out / "sbc.nc", engine="h5netcdf")
    reps = [json.loads(rep_path(out, i).read_text()) for i in range(SMALL["replications"])]
    ranks = tree["prior_sbc"].to_dataset()
    assert set(ranks.data_vars) == {"theta1", "theta2", "R", LOGLIK}
    assert ranks["theta1"].dims == ("chain", "draw") and ranks.sizes == {"chain": 1, "draw": 4}
    thinned, truth = tree["thinned_posterior"].to_dataset(), tree["prior"].to_dataset()
    assert thinned.sizes["thinned"] == SMALL["L"]
    for name in ranks.data_vars:
        np.testing.assert_array_equal(ranks[name].values[0], [r["ranks"][name] for r in reps])
        # Re-ranking from the stored thinned draws and truths gives the stored ranks.
        again = [rank(thinned[name].values[0, i], truth[name].values[0, i]) for i in range(4)]
        np.testing.assert_array_equal(again, ranks[name].values[0])
        pit = pit_from_rank(ranks[name].values[0], SMALL["L"], [r["pit_u"][name] for r in reps])
        np.testing.assert_allclose(tree["pit"][name].values[0], pit)
        # The pot_c p-value reported beside the KS test is ArviZ's, on the same PIT values.
        assert summary["parameters"][name]["pot_c_p_value"] == pytest.approx(
            float(array_stats.uniformity_test(pit, axis=-1, method="pot_c")[0]))
