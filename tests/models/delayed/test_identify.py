"""Maximum likelihood of the ``delayed`` human: recovery on its own data, near-zero delay terms on max-ent data,
the chained profile against fresh searches at every delay, the grid and the errors.

Seeded statistical tests. A parameter "within 3 SE" fails by chance with probability 0.27 % if its
standard error is right; the recovery cases check 3 parameters in 3 seeded cases (about a 2.5 % false-failure
budget in all, on these fixed seeds a fixed outcome), and each has a negative control that must fail.
"""

import numpy as np
import pytest

from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.identify import DELAY_GRID_S, START_SIGMA_M, START_TAU_NM, delay_grid, identify_unit_delayed
from scioc.models.delayed.lag import Warmup
from scioc.models.design import WheelParameters
from scioc.models.identify import identify_unit
from scioc.models.plant import discretize
from scioc.models.reference import reference_trajectory
from scioc.models.segment import Segment, prepare_batch
from scioc.models.simulate import simulate_windows

THETA = np.array([400.0, 0.0, 20.0])  # θ1 = 20 1/rad², the default population's median
TRUE = dict(tau_nm=0.06, sigma_m=0.25, delay_s=0.12)  # the literature humans' (models.humans)
#: Within this many standard errors (see the module docstring for the budget).
N_SE = 3.0


def unit(plant, rng, trials: int, *, seconds=15.0, preview=2.0, feedback=False, theta=THETA, **true):
    """``trials`` draws of one window of the study reference from the ``delayed`` human: one unit's batch.

    ``feedback``: in shared control with the paper's MPC assistant, whose law the human plans with.
    """
    dt = plant.dt
    K, M = round(seconds / dt), round(preview / dt)
    ref = reference_trajectory(seconds + preview + 1.0, dt).angle[: K + M + 1]
    kw = {"feedback": human_feedback(design_assistant(), ref).window(0, K + M)} if feedback else {}
    draw = sample_delayed(theta, [0.0, 0.0], ref, plant, rng, tau_nm=true["tau_nm"], sigma_m=true["sigma_m"],
                          delay=round(true["delay_s"] / dt), n_obs=K, size=trials, **kw)
    return prepare_batch(plant, draw.segments)


def test_the_grid_is_0_to_300_ms_in_whole_samples():
    assert DELAY_GRID_S[0] == 0.0 and DELAY_GRID_S[-1] == 0.3 and len(DELAY_GRID_S) == 31
    np.testing.assert_array_equal(delay_grid(0.01), np.arange(31))
    np.testing.assert_array_equal(delay_grid(0.005), np.arange(0, 61, 2))
    np.testing.assert_array_equal(delay_grid(0.02), np.arange(16))  # 10-ms steps rounded to 20-ms samples, once each


# In shared control the delay shows less (the assistant's spring takes over part of the correction): from
# 3 trials of 15 s it came out 9 instead of 12 samples in 2 of 6 units, from 8 trials within one sample in 6 of 6.
@pytest.mark.validation
@pytest.mark.parametrize("dt, feedback, trials, seed", [(0.01, False, 3, 0), (0.01, True, 8, 1), (0.005, False, 3, 2)],
                         ids=["100Hz-MC", "100Hz-SC", "200Hz-MC"])
def test_recovery_on_data_of_the_model(dt, feedback, trials, seed):
    plant = discretize(dt)
    theta = THETA * dt / 0.01  # θ per sample scales with dt (models.design), θ1 = 20 at any rate
    batch = unit(plant, np.random.default_rng([41, seed]), trials, feedback=feedback, theta=theta, **TRUE)
    est = identify_unit_delayed([batch], plant)
    d_true = round(TRUE["delay_s"] / dt)
    step = int(np.diff(delay_grid(dt))[0])
    assert abs(est.delay - d_true) <= step  # the delay to one grid step
    assert est.delay_s == est.delay * dt
    assert abs(est.tau_nm - TRUE["tau_nm"]) <= N_SE * est.se_tau_nm
    assert abs(est.sigma_m - TRUE["sigma_m"]) <= N_SE * est.se_sigma_m
    assert abs(np.log(est.theta1 / 20.0)) <= N_SE * est.se_log_theta1
    searched = np.isfinite(est.profile)  # the delays the profile's search visited
    assert est.converged and est.profile_converged[searched].all()
    assert est.loglik == pytest.approx(np.nanmax(est.profile), abs=1e-6)
    # negative control: the max-ent model on the same data is far from the truth in θ1
    me = identify_unit([batch], plant)
    assert abs(np.log(me.theta1 / 20.0)) > N_SE * me.se_log_theta1


@pytest.mark.validation
def test_on_max_ent_data_delay_lag_and_motor_noise_add_nothing(plant):
    # Measured on 40 max-ent windows (simulate_windows, seed 11): τ_nm <= 0.6 ms, σ_m <= 0.14 N·m, log-likelihood
    # gain over the max-ent fit <= 4.6 nats, θ1 within 1.2 max-ent SEs of the max-ent estimate. The bounds below
    # are about 1.5-3 times those.
    w = simulate_windows(2, np.random.default_rng(42))
    for seg in w.segments:
        batch = prepare_batch(plant, [seg])
        est, me = identify_unit_delayed([batch], plant), identify_unit([batch], plant)
        assert est.tau_nm < 0.002
        assert est.sigma_m < 0.2
        assert 0.0 <= est.loglik - me.loglik < 8.0  # the delayed model contains the max-ent one
        assert abs(np.log(est.theta1 / me.theta1)) < 2.0 * me.se_log_theta1
    # negative control: on data with a delay, lag and motor noise the same bounds fail
    batch = unit(plant, np.random.default_rng(43), 1, **TRUE)
    est, me = identify_unit_delayed([batch], plant), identify_unit([batch], plant)
    assert est.tau_nm > 0.002 and est.sigma_m > 0.2 and est.loglik - me.loglik > 8.0


@pytest.mark.validation
@pytest.mark.parametrize("source", ["delayed-MC", "delayed-SC", "maxent"])
def test_the_profile_is_the_best_of_other_searches(plant, source):
    """At every delay the profile (two searches: from the max-ent start and chained up from the previous delay)
    against two others: a fresh search at that delay alone, and the profile chained down from 300 ms."""
    if source == "maxent":
        batch = prepare_batch(plant, [simulate_windows(1, np.random.default_rng(45)).segments[0]])
    else:
        batch = unit(plant, np.random.default_rng([44, source == "delayed-SC"]), 1, seconds=8.0,
                     feedback=source == "delayed-SC", **TRUE)
    est = identify_unit_delayed([batch], plant, delay_search="grid")
    down = identify_unit_delayed([batch], plant, delays=est.delays[::-1], delay_search="grid").profile[::-1]
    alone = np.array([identify_unit_delayed([batch], plant, delays=[d]).loglik for d in est.delays])
    other = np.maximum(down, alone)
    # searches that reach the same maximum agree to the optimizer's tolerance (measured <= 4e-6 nats); a profile
    # value below another search's by more is a maximum missed
    assert np.all(est.profile >= other - 1e-4), np.flatnonzero(est.profile < other - 1e-4)
    assert est.delay == est.delays[int(np.argmax(np.maximum(est.profile, other)))]


def test_a_single_delay_and_the_bounds():
    plant = discretize(0.01)
    batch = unit(plant, np.random.default_rng(46), 1, seconds=5.0, **TRUE)
    est = identify_unit_delayed([batch], plant, delays=[0])
    assert est.delay == 0 and est.sigma_m == 0.0 and np.isnan(est.se_sigma_m)  # σ_m is R's at d = 0
    assert est.profile.shape == (1,) and est.loglik == pytest.approx(est.profile[0], abs=1e-6)
    est = identify_unit_delayed([batch], plant, delays=[12])
    assert est.delay == 12 and est.sigma_m > 0 and np.isfinite(est.se_sigma_m)
    assert 0 < START_TAU_NM < 0.06 and 0 < START_SIGMA_M < 0.25  # starts below the literature's values


def test_windows_inside_a_run_use_the_warm_up():
    plant = discretize(0.01)
    rng = np.random.default_rng(47)
    ref = reference_trajectory(12.0).angle
    draw = sample_delayed(THETA, [0.0, 0.0], ref, plant, rng, tau_nm=0.06, sigma_m=0.25, delay=12, n_obs=1100)
    seg = draw.segments[0]
    start = 300
    window = Segment(draw.x[start].copy(), seg.angle_ref[start:], seg.u_H[start:], seg.u_A[start:])
    batch = prepare_batch(plant, [window])
    warm = identify_unit_delayed([batch], plant, tau0=[[Warmup(seg.u_H[:start])]], delays=[12])
    rest = identify_unit_delayed([batch], plant, delays=[12])
    assert warm.loglik > rest.loglik + 1.0  # the arm is not at rest 3 s into the run
    assert abs(warm.tau_nm - 0.06) <= N_SE * warm.se_tau_nm


def test_invalid_arguments_are_refused():
    plant = discretize(0.01)
    batch = unit(plant, np.random.default_rng(48), 2, seconds=1.0, **TRUE)
    with pytest.raises(ValueError, match="delays"):
        identify_unit_delayed([batch], plant, delays=[-1, 2])
    with pytest.raises(ValueError, match="delays"):
        identify_unit_delayed([batch], plant, delays=[1.5])
    with pytest.raises(ValueError, match="tau0"):
        identify_unit_delayed([batch], plant, tau0=[[None]])  # two rows, one entry
    with pytest.raises(ValueError, match="at least one segment"):
        identify_unit_delayed([], plant)
    with pytest.raises(ValueError, match="params"):
        identify_unit_delayed([batch], plant, delays=[0], params=WheelParameters(0.05, 1.146, 0.286))
    with pytest.raises(ValueError, match="delay_search"):
        identify_unit_delayed([batch], plant, delay_search="golden")
