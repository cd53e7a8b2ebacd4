"""The log-likelihood test quantity: the same number the kernel gives, per draw and summed over segments."""

import numpy as np

from scioc.models.maxent import loglik_grad
from scioc.models.segment import prepare_batch
from scioc.pipelines.calibrate.ranking import loglik_draws
from scioc.pipelines.calibrate.simulation import fit_plant, rest_segment, simulate_unit


def test_loglik_draws_is_the_kernels_loglik_summed_over_segments():
    rng = np.random.default_rng(3)
    segs = [simulate_unit(np.array([60.0, 0.0, 1.0]), c, 200, None, rng) for c in ("MC", "SC")]
    plant = fit_plant(None)
    batch = prepare_batch(plant, segs)
    thetas = rng.uniform([10.0, 0.0, 0.5], [100.0, 0.1, 2.0], (2, 3, 2, 3)).swapaxes(-1, -2)  # (2, 3, 3, n=2)
    ll = loglik_draws(thetas, batch, plant)
    assert ll.shape == (2, 3)
    assert ll[1, 2] == loglik_grad(thetas[1, 2], batch, plant).loglik.sum()
    assert rest_segment(200).K == 200


def test_thinning_is_arvizs_factor_then_evenly_spaced():
    from arviz_stats.base import array_stats

    from scioc.pipelines.calibrate.ranking import thin

    rng = np.random.default_rng(0)
    x = rng.normal(size=(2, 500))
    for t in range(1, 500):  # AR(1), φ = 0.8: about 110 effective draws of 1000
        x[:, t] += 0.8 * x[:, t - 1]
    kept, ess = thin(x, 39)
    factor = array_stats.thin_factor(x, chain_axis=0, draw_axis=1)
    assert factor > 1 and 39 < ess == min(array_stats.ess(x, method="bulk", chain_axis=0, draw_axis=1),
                                     array_stats.ess(x, method="tail", prob=0.95, chain_axis=0, draw_axis=1))
    pool = x[:, ::factor].reshape(-1)
    np.testing.assert_array_equal(kept, pool[np.round(np.linspace(0, pool.size - 1, 39)).astype(int)])
    assert factor == int(np.ceil(x.size / ess))  # ArviZ's factor: N over min(bulk, tail) ESS
