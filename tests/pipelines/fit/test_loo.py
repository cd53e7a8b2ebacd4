"""The LOO difference against ArviZ's ``compare``: the same ELPD difference; the SE with n − 1, as R's loo."""

import numpy as np
import pytest
import xarray as xr
from arviz_stats import compare

from scioc.pipelines.fit.loo import elpd_difference, psis_summary


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
    from scioc.pipelines.fit.loo import LOSO_ESS_MIN, comparison_reliability, reliability_words

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


def _tree_of(ll, rng):
    chains, draws = ll.shape[:2]
    return xr.DataTree.from_dict({
        "posterior": xr.Dataset({"a": (("chain", "draw"), rng.normal(size=(chains, draws))),
                                 "b": (("chain", "draw", "s"), rng.normal(size=(chains, draws, 3)))}),
        "log_likelihood": xr.Dataset({"y": (("chain", "draw", "segment"), ll)})})


@pytest.mark.parametrize("chains", [1, 2, 4])
def test_psis_summary_is_arviz_loo_bit_for_bit(chains):
    import arviz as az

    rng = np.random.default_rng(chains)
    tree = _tree_of(rng.normal(size=(chains, 40, 5)) * rng.uniform(0.5, 3.0, size=5), rng)
    summary, pointwise = psis_summary(tree, "y", "segment")
    ref = az.loo(tree, pointwise=True, var_name="y")
    assert summary["elpd_loo"] == float(ref.elpd) and summary["se"] == float(ref.se)
    np.testing.assert_array_equal(pointwise, np.asarray(ref.elpd_i))
    np.testing.assert_array_equal(list(summary["pareto_k"]["by_segment"].values()), np.asarray(ref.pareto_k))


def test_a_stuck_chain_makes_the_psis_summary_unreliable_not_a_crash():
    # One chain repeats one value for a segment (a stuck chain): its largest ratios are all equal and ArviZ's loo
    # raises for the whole data set. The summary gives that segment a NaN k, counted above the threshold.
    import arviz as az

    rng = np.random.default_rng(3)
    ll = rng.normal(size=(1, 30, 4))
    ll[0, :, 1] = -3.0
    tree = _tree_of(ll, rng)
    with pytest.raises(ValueError, match="tail"):
        az.loo(tree, pointwise=True, var_name="y")
    summary, pointwise = psis_summary(tree, "y", "segment")
    k = summary["pareto_k"]
    assert np.isnan(k["by_segment"]["1"]) and k["n_nan"] == 1 and k["n_gt_threshold"] >= 1
    assert np.all(np.isfinite(pointwise)) and pointwise[1] == pytest.approx(-3.0)  # raw weights: the constant
    assert all(np.isfinite(k["by_segment"][s]) for s in ("0", "2", "3"))
