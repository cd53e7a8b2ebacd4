import dataclasses
import time

import numpy as np
import pytest

from scioc.models.assistant import design_assistant
from scioc.models.humans import HUMANS, MOTOR_SD, HumanSpec, simulate_human
from scioc.models.lq import lq_policy
from scioc.models.plant import WheelParameters, propagate
from scioc.models.reference import reference_trajectory
from scioc.models.simulate import ENCODER_STEP, simulate_run

THETA = {"MC": np.array([400.0, 0.0, 20.0]), "SC": np.array([200.0, 0.0, 20.0])}  # the default population's median


@pytest.fixture(scope="module")
def assistant():
    return design_assistant()


@pytest.fixture(scope="module")
def ref60():
    return reference_trajectory(60.0).angle


def run(spec, cond, ref, plant, assistant, seed=3, **kw):
    return simulate_human(spec, THETA[cond], cond, ref, plant, assistant, np.random.default_rng(seed), **kw)


@pytest.mark.parametrize("cond", ["MC", "SC"])
@pytest.mark.parametrize("spec", [HUMANS["maxent"], HumanSpec("plain", "lq")])
def test_reduces_to_the_maxent_agent_of_simulate_run(spec, cond, plant, assistant, ref60):
    # Same seed, same draw order: the trajectory of models.simulate, up to rounding.
    cl = run(spec, cond, ref60, plant, assistant)
    ref_run = simulate_run(THETA[cond], cond, ref60, plant, assistant, np.random.default_rng(3))
    np.testing.assert_allclose(cl.x[:, 0], ref_run.true_angle, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cl.x[:, 1], ref_run.true_velocity, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cl.u_H, ref_run.u_H[:-1], rtol=0, atol=1e-10)
    np.testing.assert_allclose(cl.u_A, ref_run.u_A[:-1], rtol=0, atol=1e-10)


@pytest.mark.parametrize("cond", ["MC", "SC"])
@pytest.mark.parametrize("tau_nm", [0.0, 0.06])
def test_delay_is_invisible_without_unknown_noise(tau_nm, cond, plant, assistant, ref60):
    # Invariant: the internal model is exact, so predicting 0.12 s ahead from the old state
    # with the human's own commands recovers the present state, and the run is the no-delay run.
    base = run(HumanSpec("now", "lq", tau_nm=tau_nm), cond, ref60, plant, assistant)
    late = run(HumanSpec("late", "lq", tau_nm=tau_nm, delay_s=0.12), cond, ref60, plant, assistant)
    np.testing.assert_allclose(late.x, base.x, rtol=0, atol=1e-10)
    np.testing.assert_allclose(late.u_H, base.u_H, rtol=0, atol=1e-10)


@pytest.mark.parametrize("name", list(HUMANS))
def test_same_seed_same_bits(name, plant, assistant, ref60):
    spec = HUMANS[name].for_subject(np.random.default_rng(0))
    a = run(spec, "SC", ref60, plant, assistant, seed=11)
    b = run(spec, "SC", ref60, plant, assistant, seed=11)
    c = run(spec, "SC", ref60, plant, assistant, seed=12)
    for u, v in zip(a, b):
        assert np.array_equal(u, v)
    assert not np.array_equal(a.u_H, c.u_H)


# Tracking error RMS (rad) on the 60-s study reference after the 2-s fade-in, per human, MC and SC.
# The LQ humans measure 0.014-0.025 rad, the compensatory crossover operator 0.09 (MC) and 0.03 (SC):
# the ranges are wide enough for any seed, narrow enough to catch a broken loop.
TRACKING_RMS = {
    "maxent": (0.005, 0.04),
    "delay": (0.005, 0.05),
    "lag": (0.005, 0.04),
    "coloured": (0.005, 0.04),
    "combined": (0.005, 0.05),
    "kbl": (0.005, 0.05),
    "crossover": (0.01, 0.15),
}


@pytest.mark.parametrize("cond", ["MC", "SC"])
@pytest.mark.parametrize("name", list(HUMANS))
def test_every_human_is_stable_and_tracks(name, cond, plant, assistant, ref60):
    cl = run(HUMANS[name].for_subject(np.random.default_rng(0)), cond, ref60, plant, assistant)
    e = cl.x[200:, 0] - ref60[200:]
    lo, hi = TRACKING_RMS[name]
    assert lo < np.sqrt(np.mean(e**2)) < hi
    # No growth: the last 10 s track no worse than the whole run (a slow instability would).
    assert np.sqrt(np.mean(e[-1000:] ** 2)) < 2.0 * np.sqrt(np.mean(e**2))
    assert np.all(np.isfinite(cl.u_H)) and np.sqrt(np.mean(cl.u_H**2)) < 1.0  # N·m, study torques are ~0.1-0.4


@pytest.mark.parametrize("cond", ["MC", "SC"])
def test_crossover_operator_returns_to_rest(cond, plant, assistant):
    # Stability without noise: from a 0.2-rad offset with a zero reference the loop settles.
    spec = dataclasses.replace(HUMANS["crossover"], motor_sd=0.0)
    cl = simulate_human(spec, None, cond, np.zeros(6001), plant, assistant, np.random.default_rng(0), x0=(0.2, 0.0))
    assert np.max(np.abs(cl.x[-500:])) < 1e-4


@pytest.mark.parametrize("cond, wc_range, pm_min", [("MC", (2.0, 3.0), 50.0), ("SC", (0.8, 1.3), 80.0)])
def test_crossover_margins(cond, wc_range, pm_min, assistant):
    # The continuous loop Y_p Y_c of the module docstring: crossover frequency and margins.
    s = HUMANS["crossover"]
    J, c, d = WheelParameters()
    g = assistant.gain if cond == "SC" else np.zeros(2)
    w = np.logspace(-2, 2.3, 40000)  # rad/s
    jw = 1j * w
    loop = (s.crossover_gain * (s.lead_s * jw + 1) / ((s.lag_s * jw + 1) * (s.tau_nm * jw + 1))
            * np.exp(-s.delay_s * jw) / (J * jw**2 + (d + g[1]) * jw + c + g[0]))
    mag, phase = np.abs(loop), np.unwrap(np.angle(loop))
    i = np.nonzero((mag[:-1] >= 1) & (mag[1:] < 1))[0]
    assert i.size == 1
    assert wc_range[0] < w[i[0]] < wc_range[1]
    assert 180.0 + np.degrees(phase[i[0]]) > pm_min
    assert 1.0 / mag[np.nonzero(phase < -np.pi)[0][0]] > 1.5  # gain margin


def test_crossover_ignores_theta(plant, assistant, ref60):
    a = simulate_human(HUMANS["crossover"], None, "MC", ref60, plant, assistant, np.random.default_rng(5))
    b = simulate_human(HUMANS["crossover"], [1.0, 2.0, 3.0], "MC", ref60, plant, assistant, np.random.default_rng(5))
    assert np.array_equal(a.x, b.x)


def lag1_autocorrelation(v):
    return np.corrcoef(v[:-1], v[1:])[0, 1]


def test_lag_smooths_the_torque(plant, assistant, ref60):
    # White max-ent noise gives Δu a lag-1 autocorrelation of -0.5; through the 0.06-s lag it is positive
    # (measured -0.50 and +0.41 over 4 minutes).
    for cond in ("MC", "SC"):
        smooth = lag1_autocorrelation(np.diff(run(HUMANS["lag"], cond, ref60, plant, assistant).u_H))
        rough = lag1_autocorrelation(np.diff(run(HUMANS["maxent"], cond, ref60, plant, assistant).u_H))
        assert rough < -0.4 and smooth > 0.2


@pytest.mark.parametrize("name", list(HUMANS))
def test_motor_noise_where_specified(name, plant, assistant, ref60):
    # The same seed without motor noise gives the same max-ent draws: the difference is the motor noise's doing.
    spec = HUMANS[name].for_subject(np.random.default_rng(0))
    a = run(spec, "MC", ref60, plant, assistant)
    b = run(dataclasses.replace(spec, motor_sd=0.0), "MC", ref60, plant, assistant)
    sd = np.std(a.u_H - b.u_H)
    if spec.motor_sd > 0:
        assert sd > 0.03  # N·m; white 0.25 low-passed by a 0.06-s lag is still about 0.07
    else:
        assert sd == 0.0


def test_coloured_noise_is_the_filtered_draw(plant, assistant, ref60):
    # Exact: without delay and lag, u_H + L x - f = ε + m with m the AR(1)-filtered second draw.
    spec = HUMANS["coloured"]
    cl = run(spec, "MC", ref60, plant, assistant, seed=9)
    K = ref60.shape[0] - 1
    pol = lq_policy(plant, THETA["MC"], ref60, np.zeros(K))
    rng = np.random.default_rng(9)
    eps = rng.standard_normal(K) / np.sqrt(2.0 * pol.S)
    w = rng.standard_normal(K) * MOTOR_SD
    a = np.exp(-plant.dt / spec.motor_tau)
    m = np.empty(K)
    prev = 0.0
    for k in range(K):
        prev = a * prev + (1.0 - a) * w[k]
        m[k] = prev
    v = cl.u_H + np.sum(pol.L * cl.x[:-1], axis=1) - pol.f
    np.testing.assert_allclose(v, eps + m, rtol=0, atol=1e-10)


def test_delayed_human_acts_on_the_prediction_from_the_old_state(plant, assistant):
    # Exact: the command is the max-ent law at the state predicted from x_{k-d} with the commands
    # c_j = u_H,j - m_j (the human knows c, not m), d = 12; before k = d it predicts from x_0.
    spec = HUMANS["delay"]
    ref = reference_trajectory(20.0).angle
    K, d = ref.shape[0] - 1, 12
    cl = run(spec, "MC", ref, plant, assistant, seed=4)
    pol = lq_policy(plant, THETA["MC"], ref, np.zeros(K))
    rng = np.random.default_rng(4)
    eps = rng.standard_normal(K) / np.sqrt(2.0 * pol.S)
    c = cl.u_H - rng.standard_normal(K) * spec.motor_sd
    for k in range(K):
        z = cl.x[max(k - d, 0)]
        for j in range(max(k - d, 0), k):
            z = plant.A @ z + plant.b * c[j]
        assert c[k] == pytest.approx(-pol.L[k] @ z + pol.f[k] + eps[k], abs=1e-10)


@pytest.mark.parametrize("name", ["lag", "combined", "crossover"])
def test_lagged_torque_keeps_the_data_convention(name, plant, assistant, ref60):
    # u_H is the ZOH-equivalent of the lagged torque: the velocity step is exact, the angle step is off by
    # the within-sample change of the torque (about 1e-5 rad), and it does not accumulate.
    cl = run(HUMANS[name].for_subject(np.random.default_rng(0)), "SC", ref60, plant, assistant)
    step = cl.x[1:] - (cl.x[:-1] @ plant.A.T + np.outer(cl.u_H + cl.u_A, plant.b))
    assert np.max(np.abs(step[:, 1])) < 1e-12
    assert np.max(np.abs(step[:, 0])) < 1e-4
    drift = propagate(plant, cl.x[0], cl.u_H + cl.u_A) - cl.x
    assert np.max(np.abs(drift[:, 0])) < ENCODER_STEP


def test_a_four_minute_run_is_fast(plant, assistant):
    ref = reference_trajectory().angle
    spec = HUMANS["combined"]  # the slowest: lag, delay and motor noise
    run(spec, "SC", ref, plant, assistant)  # compile
    best = np.inf
    for seed in range(3):
        t0 = time.perf_counter()
        run(spec, "SC", ref, plant, assistant, seed=seed)
        best = min(best, time.perf_counter() - t0)
    assert best < 0.1  # s; measured about 0.008 s


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(name="", kind="lq"), "name"),
        (dict(name="x", kind="pid"), "kind"),
        (dict(name="x", kind="lq", delay_s=-0.1), "delay_s"),
        (dict(name="x", kind="lq", tau_nm=np.nan), "tau_nm"),
        (dict(name="x", kind="lq", motor_sd=-1.0), "motor_sd"),
        (dict(name="x", kind="lq", motor_tau=np.inf), "motor_tau"),
        (dict(name="x", kind="lq", lead_s=0.1), "lead_s"),
        (dict(name="x", kind="crossover"), "crossover_gain"),
        (dict(name="x", kind="crossover", crossover_gain=1.0, lag_s=-1.0), "lag_s"),
    ],
)
def test_bad_specs_are_rejected(kwargs, field):
    with pytest.raises(ValueError, match=field):
        HumanSpec(**kwargs)


def test_bad_calls_are_rejected(plant, assistant, ref60):
    with pytest.raises(ValueError, match="SC.*needs the assistant"):
        simulate_human(HUMANS["maxent"], THETA["SC"], "SC", ref60, plant, None, np.random.default_rng(0))
    with pytest.raises(ValueError, match="params"):
        run(HUMANS["lag"], "MC", ref60, plant, assistant, params=WheelParameters(inertia=0.05))
    with pytest.raises(ValueError, match="re-solves every sample"):
        run(HUMANS["maxent"], "SC", ref60, plant, design_assistant(period=0.02))
    with pytest.raises(ValueError, match="R must be > 0"):
        simulate_human(HUMANS["maxent"], [1.0, 0.0, 0.0], "MC", ref60, plant, assistant, np.random.default_rng(0))


def test_kbl_subjects_draw_delay_and_lag_within_their_ranges(plant, assistant, ref60):
    kbl = HUMANS["kbl"]
    assert kbl.varies and not HUMANS["combined"].varies
    draws = [kbl.for_subject(np.random.default_rng(s)) for s in range(200)]
    delays = np.array([h.delay_s for h in draws])
    lags = np.array([h.tau_nm for h in draws])
    assert delays.min() >= 0.10 and delays.max() < 0.20 and lags.min() >= 0.05 and lags.max() < 0.10
    assert np.ptp(delays) > 0.08 and np.ptp(lags) > 0.04  # they do vary
    assert not any(h.varies for h in draws)
    with pytest.raises(ValueError, match="varies between subjects"):
        run(kbl, "MC", ref60, plant, assistant)
    # A human that does not vary is returned as it is, and the generator is not touched.
    rng = np.random.default_rng(5)
    assert HUMANS["combined"].for_subject(rng) is HUMANS["combined"]
    assert rng.random() == np.random.default_rng(5).random()


def test_kbl_study_keeps_each_subjects_delay_and_lag_across_levels():
    from scioc.models.simulate import simulate_study

    _, segs = simulate_study(4, np.random.default_rng(7), seconds=3.0, human="kbl")
    by_subject = {}
    for s in segs:
        by_subject.setdefault(s.subject, set()).add((s.human.delay_s, s.human.tau_nm))
    assert all(len(v) == 1 for v in by_subject.values())  # the human does not change between MC and SC
    assert len({next(iter(v)) for v in by_subject.values()}) == 4  # subjects differ
    # Other humans' runs are unchanged by the extra draw: the same seed gives the same combined study.
    _, a = simulate_study(2, np.random.default_rng(7), seconds=3.0, human="combined")
    _, b = simulate_study(2, np.random.default_rng(7), seconds=3.0, human="combined")
    assert all(np.array_equal(x.run.angle, y.run.angle) for x, y in zip(a, b))
