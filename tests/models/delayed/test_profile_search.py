"""The delay's profile searched without every grid delay (models.delayed.identify.profile_argmax), and the
identification from angles with the exact gradient against the central-difference search it replaces.

The synthetic profiles are seeded draws of the shapes the delayed human's profiles take (a floor where σ_m = 0
gives every delay the d = 0 likelihood, one bump, sometimes smaller ones); on them the argmax is compared with the
full grid's exactly.
"""

import numpy as np
import pytest

from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.delayed import sample_delayed
from scioc.models.delayed import identify as identify_module
from scioc.models.delayed import search as search_module
from scioc.models.delayed.angles import AngleWindow, window_loglik
from scioc.models.delayed.identify import COARSE_STRIDE, MAX_PEAKS, PROFILE_TIE, identify_unit_delayed, profile_argmax
from scioc.models.reference import reference_trajectory
from scioc.models.segment import prepare_batch

Q = 2 * np.pi / 40000  # the study's encoder step
SIGMA_Y = Q / np.sqrt(12)


def full_argmax(p):
    return int(np.flatnonzero(p >= p.max() - PROFILE_TIE)[0])


def search(p, **kw):
    calls = []
    best, vals = profile_argmax(p.size, lambda i: (calls.append(i), float(p[i]))[1], **kw)
    assert len(calls) == len(set(calls))  # each delay searched once
    np.testing.assert_array_equal(vals[calls], p[calls])
    return best, calls


def bump(rng, n, peak, width, height):
    """A strictly unimodal bump at ``peak`` (a smooth, skewed peak, as the profiles' main one)."""
    i = np.arange(n)
    skew = np.where(i < peak, 1.0, rng.uniform(0.5, 2.0))
    return height * np.exp(-0.5 * ((i - peak) / (width * skew)) ** 2)


@pytest.mark.parametrize("n", [31, 16, 61])
def test_a_unimodal_profile_has_the_full_grids_argmax_from_few_delays(n):
    rng = np.random.default_rng([71, n])
    counts = []
    for _ in range(200):
        peak = rng.uniform(0, n - 1)
        p = bump(rng, n, peak, rng.uniform(1.0, n / 3), rng.uniform(0.5, 20.0))
        p = p - 0.001 * np.abs(np.arange(n) - peak)  # strictly unimodal: no ties anywhere
        best, calls = search(p)
        assert best == full_argmax(p)
        counts.append(len(calls))
    # the coarse pass, then the gaps beside the one peak halved until closed: two delays per halving
    coarse = len(set(range(0, n, COARSE_STRIDE)) | {n - 1})
    assert max(counts) <= coarse + 2 * int(np.ceil(np.log2(COARSE_STRIDE)))
    assert max(counts) < n


def test_a_bump_over_the_floor_has_the_full_grids_argmax():
    # σ_m = 0 gives every delay the d = 0 likelihood: the profile is max(floor, bump), flat where the bump is below
    rng = np.random.default_rng(72)
    for _ in range(300):
        p = np.maximum(0.0, bump(rng, 31, rng.uniform(3, 28), rng.uniform(1.0, 4.0), rng.uniform(0.5, 10.0)) - 0.4)
        if p.max() <= PROFILE_TIE:
            continue
        best, calls = search(p)
        assert best == full_argmax(p)


def test_every_peak_the_coarse_pass_shows_is_refined():
    # bumps 8 delays apart, each with a coarse delay on its slopes: the coarse pass shows them all
    rng = np.random.default_rng(73)
    for _ in range(300):
        k = rng.integers(2, MAX_PEAKS + 1)
        peaks = rng.choice(np.arange(4, 29, 8), size=k, replace=False) + rng.uniform(-1.5, 1.5, k)
        p = sum(bump(rng, 31, c, rng.uniform(1.5, 2.5), rng.uniform(1.0, 10.0)) for c in peaks)
        best, calls = search(p)
        assert best == full_argmax(p)
        assert len(calls) < 31


def test_a_flat_or_ragged_profile_is_searched_at_every_delay():
    flat = np.zeros(31)  # no delay: every search ends at the d = 0 likelihood
    best, calls = search(flat)
    assert best == 0 and sorted(calls) == list(range(31))  # ties go to the smallest delay
    ragged = np.sin(np.pi * np.arange(31) / 4 + 0.3) + 0.01 * np.arange(31)  # a peak at every other coarse delay
    best, calls = search(ragged)
    assert best == full_argmax(ragged) and sorted(calls) == list(range(31))
    # negative control: a narrow peak on a stretch the coarse pass sees as monotone is not seen (the docstring's
    # limit), while the grid finds it
    hidden = np.linspace(0.0, 3.0, 31)
    hidden[13] = 10.0
    best, calls = search(hidden)
    assert full_argmax(hidden) == 13 and best == 30 and 13 not in calls


def test_a_tie_goes_to_the_smallest_delay():
    p = np.zeros(31)
    p[10:15] = 5.0  # a plateau at the top
    best, _ = search(p)
    assert best == 10 == full_argmax(p)


# ---- on data: angles drawn from the delayed human, quantized by the study's encoder

def angle_unit(plant, seed, K, *, feedback=False, M=200):
    """One window of the study reference, drawn from the delayed human (τ_nm 0.06 s, σ_m 0.25 N·m, 120 ms):
    the start's batch (the true torques) and its quantized angles."""
    rng = np.random.default_rng([75, seed])
    ref = reference_trajectory((K + M) * plant.dt + 1.0, plant.dt).angle[: K + M + 1]
    kw = {"feedback": human_feedback(design_assistant(), ref).window(0, K + M)} if feedback else {}
    draw = sample_delayed([400.0, 0.0, 20.0], [0.0, 0.0], ref, plant, rng, tau_nm=0.06, sigma_m=0.25, delay=12,
                          n_obs=K, **kw)
    y = Q * np.round(draw.x[:, 0] / Q)
    return prepare_batch(plant, draw.segments), AngleWindow(y, ref, None, kw.get("feedback"), 0.0, None)


def central_difference_grad_z(z, d, unit):
    """The gradient in z by central differences of the angle likelihood (one-sided at a lower bound, 0 where
    held): the search before the exact gradient."""
    lo, hi = search_module.limits(d)

    def f(zz):
        th = search_module.theta_from_z(zz, unit.R0)
        return sum(window_loglik(th, max(zz[3], 0.0), max(zz[4], 0.0), d, w, unit.plant, sigma_y=unit.sigma_y,
                                 params=unit.params).loglik for w in unit.angles)

    ll = f(z)
    g = np.zeros(5)
    for j in range(5):
        if hi[j] == lo[j]:
            continue
        h = 1e-5 * max(abs(z[j]), search_module.STEP_FLOOR[j])
        zp, zm = z.copy(), z.copy()
        if z[j] - h < lo[j]:
            zp[j] += h
            zm[j] += 2 * h
            g[j] = (-3 * ll + 4 * f(zp) - f(zm)) / (2 * h)
        else:
            zp[j] += h
            zm[j] -= h
            g[j] = (f(zp) - f(zm)) / (2 * h)
    return ll, g


def test_estimates_from_angles_agree_with_the_central_difference_search(plant, monkeypatch, measured):
    batch, w = angle_unit(plant, 0, 500)
    new = identify_unit_delayed([batch], plant, angles=[w], sigma_y=SIGMA_Y)
    grid = identify_unit_delayed([batch], plant, angles=[w], sigma_y=SIGMA_Y, delay_search="grid")
    exact = search_module.loglik_grad_z

    def by_differences(z, d, unit):
        return central_difference_grad_z(np.asarray(z, dtype=float), d, unit) if unit.angles else exact(z, d, unit)

    monkeypatch.setattr(search_module, "loglik_grad_z", by_differences)
    monkeypatch.setattr(identify_module, "loglik_grad_z", by_differences)
    old = identify_unit_delayed([batch], plant, angles=[w], sigma_y=SIGMA_Y, delay_search="grid")
    assert new.delay == grid.delay == old.delay
    assert np.isfinite(new.profile).sum() < new.profile.size  # the bracket searched fewer delays
    est = lambda e: np.array([np.log(e.theta1), e.theta2, np.log(e.theta[2]), e.tau_nm, e.sigma_m])  # noqa: E731
    se = np.array([old.se_log_theta1, old.se_theta2, old.se_log_R, old.se_tau_nm, old.se_sigma_m])
    free = np.isfinite(se)  # θ2 and R sit on their bounds here (θ2 = 0 is the truth), in both searches
    assert free.sum() >= 3
    np.testing.assert_allclose(est(new)[~free], est(old)[~free], rtol=1e-6, atol=1e-9)
    shift = np.abs(est(new) - est(old))[free] / se[free]
    measured("largest |exact - central differences| / SE", shift.max(), "<= 1")
    assert np.all(shift <= 1.0), shift
    assert new.loglik >= old.loglik - 1e-4  # the same maximum, to the optimizer's tolerance


@pytest.mark.validation
def test_the_bracket_finds_the_grids_delay_on_data_of_the_model(plant, measured):
    # 6 units in MC and 6 in SC at the study's length; the profiles have a floor, one bump, and on some a smaller
    # second one (measured: 13 to 18 of 31 delays searched)
    searched = []
    for seed in range(6):
        for feedback in (False, True):
            batch, w = angle_unit(plant, seed, 1500, feedback=feedback)
            grid = identify_unit_delayed([batch], plant, angles=[w], sigma_y=SIGMA_Y, delay_search="grid")
            new = identify_unit_delayed([batch], plant, angles=[w], sigma_y=SIGMA_Y)
            assert new.delay == grid.delay
            assert new.loglik == pytest.approx(grid.loglik, abs=1e-4)
            searched.append(int(np.isfinite(new.profile).sum()))
    measured("delays searched per unit (of 31), largest", max(searched), "< 31")
    assert max(searched) < 31
