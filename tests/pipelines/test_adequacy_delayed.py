"""Model adequacy with the ``delayed`` human through the real pipeline: false alarms on the model's own
data within budget (angle only or measured torque, feedback or exogenous assistant), a wrong delay and
McRuer's crossover operator flagged, and the max-ent bootstrap unchanged."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats as sps

from scioc.models import adequacy as adq
from scioc.models.adequacy import SEGMENT_ALPHA, STATISTICS
from scioc.models.assistant import human_feedback
from scioc.models.bootstrap import bootstrap_records
from scioc.models.delayed import lag_coefficients, sample_delayed
from scioc.models.delayed.bootstrap import delayed_records
from scioc.models.delayed.lag import arm_torque
from scioc.models.delayed.sample import delayed_setup
from scioc.models.design import ENCODER_STEP, MANUAL, SHARED, STUDY
from scioc.models.plant import discretize
from scioc.models.population import Population, draw_subjects
from scioc.models.reconstruct import apply_reconstruction
from scioc.models.reference import reference_trajectory
from scioc.models.simulate import quantize, simulate_study
from scioc.pipelines.adequacy import CHECK_TEXT, assess_study, delayed_segment_chain, segment_chain
from scioc.pipelines.io import validate_table
from scioc.pipelines.prepare import IdentifySettings, assistant_law, prepare_study
from scioc.pipelines.simulate import study_table

#: False-failure budget of the seeded false-alarm tests below.
FALSE_FAILURE = 0.01
#: The `combined` human's magnitudes (models.humans): delay 0.12 s, lag 0.06 s, motor noise 0.25 N·m.
DELAY, TAU_NM, SIGMA_M = 12, 0.06, 0.25
PLANT = discretize(STUDY.dt, STUDY.wheel)


def _settings(exogenous=False, boot=49, window=(20.0, 10.0)):
    """A short design: 35-s runs, a 10-s window from 20 s (1-s reconstruction margins, 2-s preview)."""
    return IdentifySettings(window_start=window[0], window_seconds=window[1], adequacy_boot=boot,
                            assistant_model="exogenous" if exogenous else "feedback")


def delayed_study(n_subjects, seed, *, sensor=False, exogenous=False):
    """MC and SC runs of the delayed human itself (:func:`scioc.models.delayed.sample_delayed`, planning over the run,
    the arm at rest at its start), recorded by the study's encoder; θ from the paper's population. In SC the
    human plans with the assistant's law, or (``exogenous``) knows a given assistant torque (its feedforward)."""
    ref = reference_trajectory(35.0, STUDY.dt)
    fb = human_feedback(assistant_law(STUDY, SHARED), ref.angle)
    rng = np.random.default_rng(seed)
    frames, truth = [], []
    for i, sub in enumerate(draw_subjects(Population(beta=0.0), n_subjects, rng)):
        for j, cond in enumerate((MANUAL, SHARED)):
            kw = {} if cond == MANUAL else {"u_A": fb.feedforward} if exogenous else {"feedback": fb}
            draw = sample_delayed(sub.thetas[j], np.zeros(2), ref.angle, PLANT, rng, tau_nm=TAU_NM, sigma_m=SIGMA_M,
                                  delay=DELAY, params=STUDY.wheel, **kw)
            cols = {"subject": f"S{i:02d}", "condition": cond, "t": ref.t, "angle": quantize(draw.x[:, 0]),
                    "angle_ref": ref.angle, "u_A": np.append(draw.u_A, draw.u_A[-1])}
            if sensor:
                cols["u_H"] = np.append(draw.u_H, 0.0)
            frames.append(pd.DataFrame(cols))
            truth.append(np.asarray(sub.thetas[j]))
    return validate_table(pd.concat(frames, ignore_index=True), "<delayed>"), np.array(truth)


def window_tau0(p, tau_nm):
    """The arm torque at the window's start (:func:`scioc.models.delayed.lag.arm_torque`): over the measured torques
    from rest at the run's start (exact), or over the span's reconstructed torques from the arm torque of a
    held torque at the span's start (what :mod:`scioc.models.delayed.bootstrap` assumes of the recorded tau0)."""
    lag = lag_coefficients(tau_nm, STUDY.dt, STUDY.wheel)
    if not p.reconstructed:
        return float(arm_torque(p.data.u_H[: p.rows.start], lag.a, lag.alpha).tau[-1])
    r, j0, j1 = p.smoother, p.span.start, p.span.stop
    u = apply_reconstruction(r.F, r.b, r.A, r.Kg, r.Sv, r.C, np.ascontiguousarray(p.data.angle[j0:j1]),
                             np.ascontiguousarray(p.data.u_A[j0:j1]))[2]
    return float(arm_torque(u[: p.rows.start - j0], lag.a, lag.alpha, tau_start=u[0]).tau[-1])


def _delayed(prepared, *, tau_nm=TAU_NM, sigma_m=SIGMA_M, delay=DELAY):
    n = len(prepared)
    return {"tau_nm": np.full(n, tau_nm), "sigma_m": np.full(n, sigma_m), "delay": np.full(n, delay),
            "tau0": np.array([window_tau0(p, tau_nm) for p in prepared])}


def _limit(n):
    """Most flagged segments a 5 % per-segment rate exceeds with probability <= FALSE_FAILURE."""
    return int(sps.binom.isf(FALSE_FAILURE, n, SEGMENT_ALPHA))


@pytest.fixture(scope="module")
def encoder_only():
    """The default acquisition (angle only, the human plans with the assistant's law): 80 segments."""
    study, thetas = delayed_study(40, 11)
    prepared = prepare_study(study, _settings()).segments
    assert all(p.reconstructed for p in prepared)
    return prepared, thetas


def test_false_alarms_within_budget_on_the_models_own_data(encoder_only, measured):
    """Angle only, MC and SC, the true parameters as the fit: 3 of 80 flagged (200 segments of the default
    window length: :func:`test_false_alarm_rate_over_200_segments_of_15_s`)."""
    prepared, thetas = encoder_only
    cols, summary = assess_study(prepared, thetas, PLANT, _settings(), delayed=_delayed(prepared))
    measured("delayed human, angles only: segments flagged", cols["adequacy_flagged"].sum(),
             f"<= {_limit(len(prepared))} of {len(prepared)}")
    assert cols["adequacy_flagged"].sum() <= _limit(len(prepared))
    assert summary["verdict"] == "pass", summary["combined_p"]
    assert summary["bootstrap"]["human_model"] == "delayed"
    assert "innovations" in summary["checks"]["whiteness"]
    for k in STATISTICS:
        assert cols[f"adequacy_p_{k}"].mean() > 0.4  # valid or conservative: not piled up near 0


@pytest.mark.validation
def test_false_alarm_rate_over_200_segments_of_15_s():
    """The measurement behind the stated rate: 100 subjects × MC/SC, the default 15-s window (K = 1500), angle
    only, B = 49: 7 of 200 flagged, 3.5 % (Clopper-Pearson 95 %: 1.4-7.1 %); study verdict pass. The same
    measurement with an exogenous assistant (seed 1001) gave 4 of 200 (2.0 %, 0.6-5.0 %), with a torque sensor
    (1002) 9 of 200 (4.5 %, 2.1-8.4 %), with both (1003) 7 of 200 (3.5 %): 27 of 800 in all, 3.4 %
    (2.2-4.9 %). A false failure of this test (more than the binomial limit) has probability <= FALSE_FAILURE."""
    study, thetas = delayed_study(100, 1000)
    settings = _settings(window=(18.0, 15.0))
    prepared = prepare_study(study, settings).segments
    cols, summary = assess_study(prepared, thetas, PLANT, settings, delayed=_delayed(prepared))
    assert cols["adequacy_flagged"].sum() <= _limit(len(prepared))
    assert summary["verdict"] == "pass"


@pytest.mark.parametrize("sensor, exogenous", [(True, False), (False, True), (True, True)],
                         ids=["measured-feedback", "reconstructed-exogenous", "measured-exogenous"])
def test_false_alarms_within_budget_with_a_torque_sensor_or_an_exogenous_assistant(sensor, exogenous):
    study, thetas = delayed_study(15, 12 + 2 * sensor + exogenous, sensor=sensor, exogenous=exogenous)
    prepared = prepare_study(study, _settings(exogenous)).segments
    assert all(p.reconstructed != sensor for p in prepared)
    cols, summary = assess_study(prepared, thetas, PLANT, _settings(exogenous), delayed=_delayed(prepared))
    assert cols["adequacy_flagged"].sum() <= _limit(len(prepared))
    assert summary["verdict"] == "pass", summary["combined_p"]


def test_negative_control_the_wrong_delay_is_flagged(encoder_only, measured):
    """The same data (delay 12 samples) judged with d = 0: 61 of 80 flagged here (76 %); over 200 segments of
    15 s, 186 (93 %) angle only and 177 (89 %) with a torque sensor. The test asks for at least 40 % of 80: a
    76 % rate falls below with probability < 1e-9, a valid check at 5 % reaches it with probability < 1e-20."""
    prepared, thetas = encoder_only
    cols, summary = assess_study(prepared, thetas, PLANT, _settings(boot=19), delayed=_delayed(prepared, delay=0))
    measured("negative control, wrong delay: share of segments flagged", cols["adequacy_flagged"].mean(),
             ">= 0.4, verdict fail")
    assert cols["adequacy_flagged"].mean() >= 0.4
    assert summary["verdict"] == "fail" and "whiteness" in summary["failed_checks"]


def test_negative_control_mcruers_crossover_operator_is_flagged():
    """Not an LQ controller (models.humans), judged as a delayed human with its own delay (0.15 s), lag
    (0.1 s) and remnant scale (0.4 N·m), θ the population's median: 20 of 20 flagged here, 100 of 100 over 50
    subjects with 15-s windows. The test asks for 16 of 20 (a valid check at 5 %: probability 6e-18)."""
    t, segs = simulate_study(10, np.random.default_rng(np.random.SeedSequence(8)), Population(beta=0.0), 35.0,
                             human="crossover")
    prepared = prepare_study(validate_table(study_table(t, segs), "<crossover>"), _settings()).segments
    thetas = np.tile([400.0, 0.0, 20.0], (len(prepared), 1))
    cols, summary = assess_study(prepared, thetas, PLANT, _settings(boot=19),
                                 delayed=_delayed(prepared, tau_nm=0.1, sigma_m=0.4, delay=15))
    assert cols["adequacy_flagged"].sum() >= 16
    assert summary["verdict"] == "fail"


def test_the_reconstructions_noise_scale_would_break_exchangeability(encoder_only):
    """Why the delayed bootstrap does not rescale its max-ent noise to the reconstruction's σ_ε as the
    max-ent one does (models.delayed.bootstrap): on the delayed model's own data that makes the replicates
    far too smooth: 17 of 20 flagged (3 of these 80 segments without the rescaling). The test asks for at least
    8 of 20 (a valid check at 5 % reaches that with probability 3e-6)."""
    prepared, thetas = encoder_only
    prepared, thetas = prepared[:20], thetas[:20]
    flagged = 0
    for i, (p, th, tau0) in enumerate(zip(prepared, thetas, _delayed(prepared)["tau0"])):
        law = assistant_law(STUDY, p.data.condition)
        chain = delayed_segment_chain(p, th, PLANT, tau_nm=TAU_NM, sigma_m=SIGMA_M, delay=DELAY, tau0=tau0,
                                      resolution=ENCODER_STEP, assistant=law)
        kw = {"feedback": p.segment.feedback} if p.segment.feedback is not None else {"u_A": p.segment.u_A}
        S = delayed_setup(th, p.segment.angle_ref, PLANT, tau_nm=TAU_NM, **kw).policy.S
        chain = chain._replace(noise_scale=p.sigma_eps * np.sqrt(2.0 * S[0]))
        flagged += adq.segment_adequacy(delayed_records(chain, 19, np.random.default_rng(i)), STUDY.dt).p_segment \
            <= SEGMENT_ALPHA
    assert flagged >= 8


@pytest.fixture(scope="module")
def maxent_study():
    t, segs = simulate_study(2, np.random.default_rng(np.random.SeedSequence(7)), Population(beta=0.0), 35.0)
    tab = study_table(t, segs)
    sensor = tab.assign(u_H=np.concatenate([s.run.u_H for s in segs]))
    return [prepare_study(validate_table(x, "<maxent>"), _settings()).segments for x in (tab, sensor)], \
        np.array([s.theta for s in segs])


def test_without_delay_lag_and_motor_noise_it_is_the_maxent_bootstrap(maxent_study):
    """Pipeline chains, angle only and measured torque, MC and SC: the same records to rounding on the same
    draws, and the same p-values. The max-ent chain's recorded row starts its residuals at the encoder angle
    where the torque is measured, the delayed one at the likelihood's fitted state; that start is aligned here."""
    studies, thetas = maxent_study
    for prepared in studies:
        for p, th in zip(prepared, thetas):
            law = assistant_law(STUDY, p.data.condition)
            mc = segment_chain(p, th, PLANT, resolution=ENCODER_STEP, assistant=law)
            dc = delayed_segment_chain(p, th, PLANT, tau_nm=0.0, sigma_m=0.0, delay=0, tau0=0.0,
                                       resolution=ENCODER_STEP, assistant=law)
            dc = dc._replace(noise_scale=mc.noise_scale, x0_window=np.array([mc.angle[mc.w0], mc.velocity[mc.w0]])
                             if mc.recon is None else dc.x0_window)
            a = bootstrap_records(mc, 19, np.random.default_rng(3))
            b = delayed_records(dc, 19, np.random.default_rng(3))
            for name, x, y in zip(a._fields, a, b):
                np.testing.assert_allclose(y, x, rtol=1e-9, atol=1e-9 * np.max(np.abs(x)), err_msg=name)
            sa, sb = adq.segment_adequacy(a, STUDY.dt), adq.segment_adequacy(b, STUDY.dt)
            assert sa.p == sb.p and sa.p_segment == sb.p_segment


def test_maxent_is_the_default_and_recorded(maxent_study):
    (prepared, _), thetas = maxent_study
    a = assess_study(prepared, thetas, PLANT, _settings(boot=9))
    b = assess_study(prepared, thetas, PLANT, _settings(boot=9), delayed=None)
    pd.testing.assert_frame_equal(a[0], b[0], check_exact=True)
    assert a[1] == b[1] and a[1]["bootstrap"]["human_model"] == "maxent" and a[1]["checks"] == CHECK_TEXT


def test_same_seed_same_adequacy(maxent_study):
    (prepared, _), thetas = maxent_study
    delayed = _delayed(prepared)
    a = assess_study(prepared, thetas, PLANT, _settings(boot=9), delayed=delayed)
    b = assess_study(prepared, thetas, PLANT, _settings(boot=9), delayed=delayed)
    pd.testing.assert_frame_equal(a[0], b[0], check_exact=True)
    assert a[1] == b[1]


@pytest.mark.parametrize("change, message", [
    (lambda d: {k: v for k, v in d.items() if k != "tau0"}, "exactly the keys"),
    (lambda d: d | {"delay": d["delay"][:-1]}, r"delayed\['delay'\] must hold 4"),
    (lambda d: d | {"sigma_m": -d["sigma_m"] - 1}, "must be >= 0"),
    (lambda d: d | {"delay": d["delay"] + 0.5}, "whole samples"),
    (lambda d: d | {"tau_nm": d["tau_nm"] * np.nan}, "finite"),
])
def test_the_delayed_parameters_are_validated(maxent_study, change, message):
    (prepared, _), thetas = maxent_study
    with pytest.raises(ValueError, match=message):
        assess_study(prepared, thetas, PLANT, _settings(boot=9), delayed=change(_delayed(prepared)))
