import numpy as np

from scioc.models.sbc import central_coverage, ecdf_band, ess_basic, pit_from_rank, rank, thin, uniformity_test


def ar1(rng, phi, shape):
    x = np.zeros(shape)
    for t in range(1, shape[-1]):
        x[..., t] = phi * x[..., t - 1] + rng.standard_normal(shape[:-1])
    return x


def test_ess_of_independent_draws_is_about_n():
    x = np.random.default_rng(0).standard_normal((4, 1000))
    assert 3000 < ess_basic(x) < 5000


def test_ess_of_ar1_matches_theory():
    # AR(1) with φ: ESS ≈ N (1 - φ) / (1 + φ) = 10000 · 0.1 / 1.9 ≈ 526.
    x = ar1(np.random.default_rng(1), 0.9, (2, 5000))
    assert 350 < ess_basic(x) < 750


def test_rank_is_simuk_definition():
    assert rank(np.array([0.1, 0.5, 0.9]), 0.5) == 1
    assert rank(np.array([0.1, 0.5, 0.9]), 1.0) == 3


def test_thinned_ranks_of_a_calibrated_sampler_are_uniform():
    # Exact posterior sampled by an autocorrelated chain: the true value is a draw from the
    # same distribution, so thinned ranks are uniform. False-failure budget of the KS test:
    alpha = 1e-3
    rng = np.random.default_rng(2)
    L, reps = 49, 600
    r = np.empty(reps, dtype=int)
    for i in range(reps):
        true = rng.standard_normal()
        chain = ar1(rng, 0.8, (2, 1000)) * np.sqrt(1 - 0.8**2)  # stationary N(0, 1)
        kept, _ = thin(chain, L)
        r[i] = rank(kept, true)
    pit = pit_from_rank(r, L, rng.uniform(size=reps))
    assert uniformity_test(pit, alpha).passed


def test_uniformity_test_catches_an_overconfident_posterior():
    # Negative control: posterior draws 20 % too narrow must fail at the same size.
    alpha = 1e-3
    rng = np.random.default_rng(3)
    L, reps = 49, 600
    r = [rank(0.8 * rng.standard_normal(L), rng.standard_normal()) for _ in range(reps)]
    pit = pit_from_rank(np.array(r), L, rng.uniform(size=reps))
    assert not uniformity_test(pit, alpha).passed


def test_coverage_of_exact_intervals():
    rng = np.random.default_rng(4)
    cov = np.array([central_coverage(rng.standard_normal(400), rng.standard_normal()) for _ in range(2000)])
    # Binomial SE at 2000 draws is <= 0.011; 4 SE allows for the interval estimated from 400 draws.
    np.testing.assert_allclose(cov.mean(axis=0), [0.5, 0.8, 0.9, 0.95], atol=0.045)


def test_ecdf_band_holds_simultaneously_about_95_percent():
    n = 300
    z, lo, hi = ecdf_band(n, 0.05, seed=1)
    rng = np.random.default_rng(5)
    inside = 0
    for _ in range(1000):
        u = np.sort(rng.uniform(size=n))
        d = np.searchsorted(u, z, side="right") / n - z
        inside += bool(np.all((d >= lo - 1e-12) & (d <= hi + 1e-12)))
    # 1000 draws: binomial SE ≈ 0.007; the band is discrete, so allow 0.93..0.99.
    assert 0.93 <= inside / 1000 <= 0.99
