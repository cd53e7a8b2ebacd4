"""DelayMetropolis samples each group's delay index from its exact conditional, alone and beside NUTS."""

import warnings

import numpy as np
import pymc as pm
import pytensor.tensor as pt
import pytest
from scipy import stats

from scioc.models.bayes.delay_step import DelayMetropolis

G = 7
# Per group, the log-likelihood of each grid index: one peaked group, one flat, one bimodal.
TABLE = np.array([[0.0, 1.0, 3.0, 4.5, 3.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
                  [2.0, 0.0, -3.0, -6.0, -3.0, 0.0, 2.5]])


def exact(table):
    p = np.exp(table - table.max(1, keepdims=True))
    return p / p.sum(1, keepdims=True)


def sample_indices(used_table, *, draws=3000, seed=0, extra_normal=False):
    with pm.Model() as model:
        idx = pm.DiscreteUniform("delay_index", 0, G - 1, shape=3)
        group = pt.as_tensor(used_table)[np.arange(3), idx]
        pm.Potential("loglik", pt.as_tensor(TABLE)[np.arange(3), idx].sum())
        if extra_normal:  # a continuous variable whose mean depends on the index: NUTS updates it
            pm.Normal("x", mu=pt.as_tensor(np.arange(G, dtype=float))[idx[0]], sigma=1.0)
        step = DelayMetropolis([idx], group, G)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            tr = pm.sample(draws=draws, tune=200, chains=1, cores=1, step=[step], random_seed=seed,
                           progressbar=False, quiet=True, compute_convergence_checks=False)
    return tr


def chi2_p(draws, p):
    """Chi-square p-value of draws of one group (every 4th, near independent) against probabilities p."""
    kept = draws[::4]
    counts = np.bincount(kept, minlength=G)
    expected = p * kept.shape[0]
    keep = expected >= 5  # the chi-square approximation; the rest pooled into one cell
    obs = np.append(counts[keep], counts[~keep].sum())
    exp = np.append(expected[keep], expected[~keep].sum())
    if exp[-1] == 0:
        obs, exp = obs[:-1], exp[:-1]
    return stats.chisquare(obs, exp).pvalue


def test_every_group_follows_its_exact_conditional():
    # False alarm: 3 chi-square tests at 0.001 each (about 0.3 % if the step is exact and thinned draws independent).
    tr = sample_indices(TABLE)
    idx = tr["posterior"]["delay_index"].values[0]
    p = exact(TABLE)
    for g in range(3):
        assert chi2_p(idx[:, g], p[g]) > 0.001, g
    acc = float(tr["sample_stats"]["delay_accept"].mean())
    assert 0.2 < acc < 0.95


def test_negative_control_a_wrong_likelihood_is_caught():
    # The step told the wrong log-likelihood (sign flipped) samples the wrong conditional; the same test fails.
    tr = sample_indices(-TABLE)
    idx = tr["posterior"]["delay_index"].values[0]
    p = exact(TABLE)
    assert min(chi2_p(idx[:, g], p[g]) for g in (0, 2)) < 1e-6


def test_beside_nuts_the_joint_posterior_is_sampled():
    # x | index ~ N(index, 1) integrates to 1, so the index's marginal is still exact(TABLE) and E[x] = E[index].
    tr = sample_indices(TABLE, extra_normal=True, draws=4000, seed=3)
    idx = tr["posterior"]["delay_index"].values[0]
    x = tr["posterior"]["x"].values[0]
    p = exact(TABLE)
    assert chi2_p(idx[:, 0], p[0]) > 0.001
    mean_idx = float((p[0] * np.arange(G)).sum())
    # E[x] = E[index] = 3.0 here; 4000 draws of sd ~1.3 with autocorrelation: SE about 0.05.
    assert abs(x.mean() - mean_idx) < 0.25


def test_refuses_more_than_one_variable_or_a_grid_of_one():
    with pm.Model():
        a = pm.DiscreteUniform("a", 0, 3)
        b = pm.DiscreteUniform("b", 0, 3)
        with pytest.raises(ValueError, match="exactly one"):
            DelayMetropolis([a, b], pt.stack([a, b]).astype("float64"), 4)
        with pytest.raises(ValueError, match="n_grid"):
            DelayMetropolis([a], a.astype("float64")[None], 1)
