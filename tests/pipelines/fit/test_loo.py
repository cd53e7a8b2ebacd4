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


def test_a_comparison_is_reliable_only_with_low_k_and_enough_importance_points():
    from pipelines.fit.loo import LOSO_ESS_MIN, comparison_reliability, reliability_words

    def summary(n_bad, ess=None):
        s = {"pareto_k": {"n_gt_threshold": n_bad}}
        return s if ess is None else {**s, "is_ess_loo_by_subject": dict(enumerate(ess))}

    seg = comparison_reliability(summary(0), summary(0))  # PSIS over segments: no importance sampling
    assert seg == {"reliable": True, "unreliable_because": [], "importance": None}
    ok = comparison_reliability(summary(0, [400.0, 100.0]), summary(0, [200.0, 400.0]))
    assert ok["reliable"] and ok["importance"]["is_ess_loo_min"] == 100.0 == LOSO_ESS_MIN
    assert ok["importance"]["mcse"] == pytest.approx(np.sqrt(2 / 400 + 1 / 100 + 1 / 200))
    few = comparison_reliability(summary(0, [400.0, 99.0]), summary(0, [400.0, 400.0]))
    assert not few["reliable"] and few["unreliable_because"] == ["importance-sampling ESS below 100"]
    both = comparison_reliability(summary(1, [400.0, 99.0]), summary(0, [400.0, 400.0]))
    assert reliability_words(both) == "UNRELIABLE (Pareto k above the threshold; importance-sampling ESS below 100)"
    assert reliability_words(ok) == "reliable"
