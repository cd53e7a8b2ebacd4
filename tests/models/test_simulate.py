import numpy as np
import pytest

from scioc.models.assistant import design_assistant, human_feedback
from scioc.models.lq import lq_policy
from scioc.models.plant import discretize
from scioc.models.reference import reference_trajectory
from scioc.models.segment import planning_plant
from scioc.models.simulate import (
    ENCODER_STEP,
    Population,
    draw_subjects,
    quantize,
    simulate_run,
    simulate_study,
)


def test_population_defaults_follow_the_paper():
    p = Population()
    assert p.theta2 == 0.0 and p.beta < 0
    with pytest.raises(ValueError, match="sd_change"):
        Population(sd_change=-1.0)
    with pytest.raises(ValueError, match="finite"):
        Population(beta=np.nan)


def test_draws_are_reproducible_and_shift_theta1():
    a = draw_subjects(Population(), 30, np.random.default_rng(1))
    b = draw_subjects(Population(), 30, np.random.default_rng(1))
    assert all(np.array_equal(x.mc, y.mc) and np.array_equal(x.sc, y.sc) for x, y in zip(a, b))
    shift = np.array([np.log(s.sc[0] / s.sc[2]) - np.log(s.mc[0] / s.mc[2]) for s in a])
    assert np.all(shift < 0)  # β = -0.7 with SD 0.2: every subject moves the same way
    assert all(s.mc[1] == 0 and s.sc[1] == 0 for s in a)


def test_shared_run_is_the_max_ent_human_planning_with_the_assistant():
    # SC: u_H,k = -L_k x_k + f_k + eps_k with (L, f, S) the plan on the wheel closed by the
    # assistant's feedback and its feedforward as known input; the assistant reacts to x.
    plant, asst = discretize(0.01), design_assistant()
    ref = reference_trajectory(10.0).angle
    theta = [400.0, 0.0, 20.0]
    run = simulate_run(theta, "SC", ref, plant, asst, np.random.default_rng(4))
    fb = human_feedback(asst, ref)
    pol = lq_policy(planning_plant(plant, fb.gain), theta, ref, fb.feedforward)
    x = np.column_stack([run.true_angle, run.true_velocity])
    K = ref.shape[0] - 1
    eps = np.random.default_rng(4).standard_normal(K) / np.sqrt(2.0 * pol.S)
    np.testing.assert_allclose(run.u_H[:K], -np.sum(pol.L * x[:K], axis=1) + pol.f + eps, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(run.u_A[:K], -x[:K] @ fb.gain + fb.feedforward, rtol=1e-10, atol=1e-12)


def test_quantization_error_is_within_half_an_increment():
    x = np.random.default_rng(0).uniform(-1, 1, 1000)
    err = quantize(x) - x
    assert np.all(np.abs(err) <= ENCODER_STEP / 2 + 1e-15)
    assert np.allclose(quantize(x) / ENCODER_STEP, np.round(quantize(x) / ENCODER_STEP))


def test_manual_run_has_no_assistance_and_shared_run_has_some():
    plant, asst = discretize(0.01), design_assistant()
    ref = reference_trajectory(10.0).angle
    rng = np.random.default_rng(3)
    mc = simulate_run([400.0, 0.0, 20.0], "MC", ref, plant, asst, rng)
    sc = simulate_run([400.0, 0.0, 20.0], "SC", ref, plant, asst, rng)
    assert np.all(mc.u_A == 0.0)
    assert np.sqrt(np.mean(sc.u_A**2)) > 0.05
    with pytest.raises(ValueError, match="SC.*needs the assistant"):
        simulate_run([400.0, 0.0, 20.0], "SC", ref, plant, None, rng)
    # Another level is assisted by the assistant given, unassisted without one.
    other = simulate_run([400.0, 0.0, 20.0], "weak", ref, plant, None, np.random.default_rng(3))
    assert np.all(other.u_A == 0.0)


def test_study_is_seeded_and_a_subject_does_not_depend_on_the_next():
    t, two = simulate_study(2, np.random.default_rng(np.random.SeedSequence(5)), seconds=5.0)
    _, three = simulate_study(3, np.random.default_rng(np.random.SeedSequence(5)), seconds=5.0)
    _, again = simulate_study(2, np.random.default_rng(np.random.SeedSequence(5)), seconds=5.0)
    assert t.shape == (501,)
    for a, b in zip(two, again):
        assert np.array_equal(a.run.angle, b.run.angle) and np.array_equal(a.run.u_H, b.run.u_H)
    # Subjects are drawn first, then each simulated from its own child seed.
    assert [s.subject for s in two] == [s.subject for s in three][:4]
    conds = {(s.subject, s.condition) for s in two}
    assert conds == {("S01", "MC"), ("S01", "SC"), ("S02", "MC"), ("S02", "SC")}
