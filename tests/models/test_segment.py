"""Segments and their θ-independent layout: shapes checked, states from the observed torques, the plan's wheel."""

import numpy as np
import pytest

from scioc.models.plant import propagate
from scioc.models.segment import Feedback, Segment, SegmentBatch, as_batch, plan_inputs, planning_plant, prepare_batch
from tests.conftest import random_segment


def test_empty_or_mismatched_segments_are_rejected(plant):
    with pytest.raises(ValueError, match="shape"):
        prepare_batch(plant, [Segment(np.zeros(2), np.zeros(5), np.zeros(5), np.zeros(5))])
    with pytest.raises(ValueError, match="no segments"):
        prepare_batch(plant, [])


def test_feedback_of_the_wrong_shape_is_rejected(plant):
    seg = Segment(np.zeros(2), np.zeros(11), np.zeros(10), np.zeros(10), Feedback(np.zeros(2), np.zeros(9)))
    with pytest.raises(ValueError, match="feedforward"):
        prepare_batch(plant, [seg])
    with pytest.raises(ValueError, match="gain"):
        prepare_batch(plant, [seg._replace(feedback=Feedback(np.zeros(3), np.zeros(10)))])


def test_batch_states_are_driven_by_the_observed_torques(plant):
    """x1, x2 follow Eq. 11 from x_0 with u_H + u_A over the K observed steps, the preview left out."""
    rng = np.random.default_rng(40)
    long = random_segment(rng, 80, True)
    seg = Segment(long.x0, long.angle_ref, long.u_H[:50], long.u_A)
    batch = prepare_batch(plant, [seg, seg])
    x = propagate(plant, seg.x0, seg.u_H + seg.u_A[:50])
    np.testing.assert_array_equal(batch.x1[1], x[:, 0])
    np.testing.assert_array_equal(batch.x2[1], x[:, 1])
    assert (batch.n, batch.K, batch.a.shape[1], batch.r.shape[1]) == (2, 50, 80, 81)
    np.testing.assert_array_equal(batch.fb, 0.0)


def test_feedback_plans_on_the_closed_wheel_with_the_feedforward(plant):
    rng = np.random.default_rng(41)
    seg = random_segment(rng, 30, True)
    gain = np.array([2.0, 0.3])
    fb = Feedback(gain, rng.normal(size=40))
    with_fb = seg._replace(feedback=fb.window(5, 30))
    closed, known = plan_inputs(with_fb, plant)
    np.testing.assert_array_equal(closed.A, plant.A - np.outer(plant.b, gain))
    np.testing.assert_array_equal(closed.b, plant.b)
    np.testing.assert_array_equal(known, fb.feedforward[5:35])
    assert planning_plant(plant, gain).dt == plant.dt
    open_plant, open_known = plan_inputs(seg, plant)
    assert open_plant is plant
    np.testing.assert_array_equal(open_known, seg.u_A)
    batch = prepare_batch(plant, [with_fb])
    np.testing.assert_array_equal(batch.fb[0], gain)
    np.testing.assert_array_equal(batch.a[0], fb.feedforward[5:35])


def test_repeat_and_as_batch(plant):
    rng = np.random.default_rng(42)
    segs = [random_segment(rng, 20, i == 1) for i in range(3)]
    batch = prepare_batch(plant, segs)
    rep = batch.repeat(1, 4)
    assert isinstance(rep, SegmentBatch) and rep.n == 4
    for name in SegmentBatch._fields:
        np.testing.assert_array_equal(getattr(rep, name), np.repeat(getattr(batch, name)[1:2], 4, axis=0))
    assert as_batch(batch, plant) is batch
    for name in SegmentBatch._fields:
        np.testing.assert_array_equal(getattr(as_batch(segs, plant), name), getattr(batch, name))
