"""The LOO difference against ArviZ's ``compare``: the same ELPD difference; the SE with n − 1, as R's loo."""

import numpy as np
import pytest
import xarray as xr
from arviz_stats import compare

from pipelines.fit.loo import elpd_difference, psis_summary


def _tree(rng, shift):
    ll = rng.normal(-1.0 + shift, 0.3, (2, 200, 30)) + rng.normal(0, 0.5, 30)
    return xr.DataTree.from_dict({
        "posterior": xr.Dataset({"mu": (("chain", "draw"), rng.normal(size=(2, 200)))}),
        "log_likelihood": xr.Dataset({"y": (("chain", "draw", "unit"), ll)}, coords={"unit": np.arange(30)})})


def test_the_difference_is_compares_and_its_se_is_compares_with_n_minus_1():
    rng = np.random.default_rng(4)
    trees = {"condition": _tree(rng, 0.2), "pooled": _tree(rng, 0.0)}
    out, pointwise = {}, {}
    for name, t in trees.items():
        out[name], pointwise[name] = psis_summary(t, "y", "unit")
    d = elpd_difference(out, pointwise)
    table = compare(trees, var_name="y", round_to="none")
    other = [m for m in table.index if m != table.index[0]][0]
    assert d["elpd_diff"] == pytest.approx(abs(table.loc[other, "elpd_diff"]), rel=1e-12)
    assert d["se"] == pytest.approx(table.loc[other, "dse"] * np.sqrt(30 / 29), rel=1e-12)
    assert d["n"] == 30 and out["condition"]["pareto_k"]["n"] == 30
