"""models.bayes.noise_blocks, polar: the law of ρ and σ_m is the half-normal populations' in polar coordinates too."""

import numpy as np
import pymc as pm
import pytest
from scipy import stats

from scioc.models.bayes.noise_blocks import NOISE_A, NOISE_B, draw_a, draw_b, log_envelope, polar_noise_block

S_RHO, S_M = 0.3, 0.2


def _block_model(k, **start):
    with pm.Model(coords={"subject": np.arange(len(k))}) as model:
        polar_noise_block(S_RHO, S_M, np.asarray(k, dtype=float), start_rho=start.get("rho", 0.3),
                          start_sigma=start.get("sigma", 0.1))
    return model


def _elementwise_logp(model):
    """(a, b) -> log p per subject (b's log-density holds the joint one; a's is 0)."""
    f = model.compile_fn(model.logp(sum=False, vars=[model[NOISE_B]])[0], inputs=model.value_vars,
                         on_unused_input="ignore")
    return lambda a, b: f({NOISE_A: a, NOISE_B: b})


def _rho_sigma(model):
    """(a, b) -> (ρ, σ_m) per subject."""
    f = model.compile_fn(model.replace_rvs_by_values([model["rho"], model["sigma_m"]]), inputs=model.value_vars)
    return lambda a, b: f({NOISE_A: a, NOISE_B: b})


def test_the_envelope_is_a_partition_of_unity_over_the_copies_of_phi():
    """Σ_n w(φ + nπ) = 1 to rounding; without Poisson's correction term it is not (negative control)."""
    phi = np.linspace(-4.0, 4.0, 41)
    n = np.arange(-30, 31)[:, None]
    total = np.exp(log_envelope(phi + np.pi * n)).sum(axis=0)
    assert np.abs(total - 1.0).max() < 1e-14
    plain = (np.exp(-(phi + np.pi * n) ** 2 / (2 * np.pi**2)) / np.sqrt(2 * np.pi)).sum(axis=0)
    assert np.abs(plain - 1.0).max() > 1e-9


def test_polar_density_integrates_to_one_and_gives_rho_and_sigma_m_their_half_normal_laws():
    """Quadrature of exp(log p(a, b)) over a grid: mass 1, and the moments of ρ = |r cos φ| and σ_m = |r sin φ| / √k
    are the half-normal ones (E x = s √(2/π), E x² = s², E x⁴ = 3 s⁴). Negative control: the same density without its
    Jacobian (2a - ½ log k) has not mass 1."""
    k = 2.5
    a = np.linspace(-12.0, 2.5, 700)
    b = np.linspace(-9.0 * np.pi, 9.0 * np.pi, 2700)
    A, B = np.meshgrid(a, b, indexing="ij")
    model = _block_model(np.full(A.size, k))
    lp = _elementwise_logp(model)(A.ravel(), B.ravel()).reshape(A.shape)
    cell = (a[1] - a[0]) * (b[1] - b[0])
    w = np.exp(lp) * cell
    assert w.sum() == pytest.approx(1.0, rel=1e-8)
    r = np.exp(A)
    for x, s in ((np.abs(r * np.cos(B)), S_RHO), (np.abs(r * np.sin(B) / np.sqrt(k)), S_M)):
        assert (w * x).sum() == pytest.approx(s * np.sqrt(2.0 / np.pi), rel=1e-4)  # |cos φ|'s kinks: coarser
        assert (w * x**2).sum() == pytest.approx(s**2, rel=1e-8)
        assert (w * x**4).sum() == pytest.approx(3.0 * s**4, rel=1e-8)
    no_jacobian = np.exp(lp - (2.0 * A - 0.5 * np.log(k))) * cell
    assert abs(no_jacobian.sum() - 1.0) > 0.1


def test_a_subject_without_k_keeps_the_folded_centred_coordinates():
    """k NaN: a = ρ̃ ~ N(0, s_ρ), b = σ̃ ~ N(0, s_m), and ρ = |a|, σ_m = |b|."""
    model = _block_model([np.nan, np.nan, 3.0])
    a, b = np.array([0.4, -0.1, -1.2]), np.array([-0.2, 0.05, 0.9])
    lp = _elementwise_logp(model)(a, b)
    expect = stats.norm.logpdf(a[:2], scale=S_RHO) + stats.norm.logpdf(b[:2], scale=S_M)
    np.testing.assert_allclose(lp[:2], expect, rtol=1e-12)
    rho, sigma = _rho_sigma(model)(a, b)
    np.testing.assert_allclose(rho, [0.4, 0.1, np.exp(-1.2) * abs(np.cos(0.9))], rtol=1e-12)
    np.testing.assert_allclose(sigma, [0.2, 0.05, np.exp(-1.2) * abs(np.sin(0.9)) / np.sqrt(3.0)], rtol=1e-12)


def test_prior_draws_have_the_half_normal_laws_and_a_uniform_angle_would_not():
    """pm.draw (a from its marginal, φ given r by rejection, its copy by the envelope): KS against the half-normals
    for polar and folded centred subjects (false-alarm rate 0.001 per test). Negative control: φ uniform instead of its
    law given r (the same a) fails the KS of σ_m."""
    k = np.array([2.5, np.nan, 0.5, 8.0])
    model = _block_model(k)
    rho, sigma = pm.draw([model["rho"], model["sigma_m"]], draws=3000, random_seed=11)
    for j in range(k.size):
        assert stats.kstest(rho[:, j], stats.halfnorm(scale=S_RHO).cdf).pvalue > 1e-3
        assert stats.kstest(sigma[:, j], stats.halfnorm(scale=S_M).cdf).pvalue > 1e-3
    rng = np.random.default_rng(3)
    a = draw_a(S_RHO, S_M, np.full(3000, 8.0), rng, (3000,))
    b = draw_b(a, S_RHO, S_M, np.full(3000, 8.0), rng)
    sig_ok = np.abs(np.exp(a) * np.sin(b)) / np.sqrt(8.0)
    assert stats.kstest(sig_ok, stats.halfnorm(scale=S_M).cdf).pvalue > 1e-3
    sig_bad = np.abs(np.exp(a) * np.sin(rng.uniform(0, np.pi, 3000))) / np.sqrt(8.0)
    assert stats.kstest(sig_bad, stats.halfnorm(scale=S_M).cdf).pvalue < 1e-6


def test_the_block_starts_at_the_given_rho_and_sigma_m_and_refuses_bad_k():
    model = _block_model([2.0, np.nan], rho=0.25, sigma=0.15)
    point = model.initial_point()
    rho, sigma = _rho_sigma(model)(point[NOISE_A], point[NOISE_B])
    np.testing.assert_allclose(rho, [0.25, 0.25], rtol=1e-12)
    np.testing.assert_allclose(sigma, [0.15, 0.15], rtol=1e-12)
    with pytest.raises(ValueError, match="2 subjects"):
        with pm.Model(coords={"subject": [0, 1]}):
            polar_noise_block(S_RHO, S_M, [1.0], start_rho=0.3, start_sigma=0.1)
    for bad in ([0.0, 1.0], [-1.0, 1.0], [np.inf, 1.0]):
        with pytest.raises(ValueError, match="k must be > 0"):
            with pm.Model(coords={"subject": [0, 1]}):
                polar_noise_block(S_RHO, S_M, bad, start_rho=0.3, start_sigma=0.1)


def test_the_squared_form_gives_rho_the_half_normal_law_with_u_at_a_finite_step_from_rho_zero():
    """models.bayes.noise_blocks.squared_half_normal_block: ρ = u², u's density |u| p(u²) (p the half-normal's):
    by quadrature its mass is 1 and E ρ², E ρ⁴ are the half-normal's; its draws pass the KS test (false alarm 1e-3).
    Negative controls: without the Jacobian |u| the mass is not 1; u itself is not half-normal (KS fails)."""
    from scioc.models.bayes.noise_blocks import squared_half_normal_block

    u = np.linspace(-3.0, 3.0, 6001)
    with pm.Model(coords={"subject": np.arange(u.size)}) as model:
        squared_half_normal_block("rho", S_RHO, start=0.2)
    np.testing.assert_allclose(model.initial_point()["rho_root"], np.sqrt(0.2))
    f = model.compile_fn(model.logp(sum=False)[0], inputs=model.value_vars, on_unused_input="ignore")
    lp = f({"rho_root": u})
    w = np.exp(lp) * (u[1] - u[0])
    assert w.sum() == pytest.approx(1.0, abs=1e-6)
    assert (w * u**4).sum() == pytest.approx(S_RHO**2, rel=1e-6)
    assert (w * u**8).sum() == pytest.approx(3.0 * S_RHO**4, rel=1e-6)
    assert abs((np.exp(lp - np.log(np.abs(u) + 1e-300)) * (u[1] - u[0])).sum() - 1.0) > 0.1
    with pm.Model(coords={"subject": [0, 1]}) as small:
        squared_half_normal_block("rho", S_RHO, start=0.2)
    rho, root = pm.draw([small["rho"], small["rho_root"]], draws=4000, random_seed=5)
    for j in range(2):
        assert stats.kstest(rho[:, j], stats.halfnorm(scale=S_RHO).cdf).pvalue > 1e-3
    assert stats.kstest(np.abs(root[:, 0]), stats.halfnorm(scale=S_RHO).cdf).pvalue < 1e-3
    assert (root < 0).mean() == pytest.approx(0.5, abs=0.05)  # both copies
