"""Demonstrations in the data convention and their θ-independent layout for the likelihood.

Besides θ, the max-ent likelihood needs only the states driven from x_0 by the observed torques (Eq. 11),
which :func:`prepare_batch` computes once per data set.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from scioc.models.plant import DiscretePlant, propagate


class Feedback(NamedTuple):
    """The assistant's law ``u_A,k = -gain @ x_k + feedforward[k]`` as the human knows it.

    ``gain`` (2,), N·m per (rad, rad/s), closes the wheel (an added spring and damper); ``feedforward``
    (K + M,), N·m, is a known input. Built by :func:`scioc.models.assistant.human_feedback`.
    """

    gain: np.ndarray
    feedforward: np.ndarray

    def window(self, start: int, n: int) -> "Feedback":
        """The same law over samples ``start .. start + n - 1`` of the run it was built for."""
        return Feedback(self.gain, self.feedforward[start : start + n])


def planning_plant(plant: DiscretePlant, gain) -> DiscretePlant:
    """The wheel closed by the assistant's state feedback: ``A - b gainᵀ``, same b and dt."""
    g = np.asarray(gain, dtype=float).reshape(2)
    return DiscretePlant(plant.A - np.outer(plant.b, g), plant.b, plant.dt)


class Segment(NamedTuple):
    """One demonstration (a subject × condition window) in the data convention.

    ``x0`` (2,), rad and rad/s; ``angle_ref`` (K + M + 1,), rad; ``u_H`` (K,) and the recorded ``u_A``
    (K + M,), N·m. ``feedback`` None is the paper's model (Eq. 15-16: u_A a known sequence); a
    :class:`Feedback` human plans with the assistant's law. M >= 0 preview steps extend the plan.
    """

    x0: np.ndarray
    angle_ref: np.ndarray
    u_H: np.ndarray
    u_A: np.ndarray
    feedback: Feedback | None = None

    @property
    def K(self) -> int:
        return int(self.u_H.shape[0])

    @property
    def preview(self) -> int:
        return int(self.u_A.shape[0] - self.u_H.shape[0])


class SegmentBatch(NamedTuple):
    """n segments of equal K and M, one row each, for the kernel.

    ``x1``, ``x2`` (n, K + 1): angle (rad) and velocity (rad/s) driven by the observed torques; ``r``
    (n, K + M + 1), rad; ``u`` (n, K), N·m; ``a`` (n, K + M), the plan's known input (u_A or the
    feedforward), N·m; ``fb`` (n, 2), the feedback the plan closes the wheel with, ``A - b fbᵀ``.
    """

    x1: np.ndarray
    x2: np.ndarray
    r: np.ndarray
    u: np.ndarray
    a: np.ndarray
    fb: np.ndarray

    @property
    def n(self) -> int:
        return int(self.u.shape[0])

    def repeat(self, j: int, n: int) -> "SegmentBatch":
        """A batch of ``n`` copies of segment ``j`` (to evaluate it under n θ in one call)."""
        return SegmentBatch(*(np.repeat(arr[j : j + 1], n, axis=0) for arr in self))

    @property
    def K(self) -> int:
        return int(self.u.shape[1])


def check_segment(seg: Segment) -> Segment:
    """A segment with float arrays of consistent shapes (K >= 1, preview M >= 0), or ValueError naming the shapes."""
    x0 = np.asarray(seg.x0, dtype=float).reshape(2)
    r = np.asarray(seg.angle_ref, dtype=float)
    u = np.asarray(seg.u_H, dtype=float)
    a = np.asarray(seg.u_A, dtype=float)
    if u.ndim != 1 or a.ndim != 1 or a.shape[0] < u.shape[0] or r.shape != (a.shape[0] + 1,):
        raise ValueError(
            f"a segment needs u_H of shape (K,), u_A of shape (K + M,) and angle_ref of shape (K + M + 1,) "
            f"with M >= 0; got {u.shape}, {a.shape}, {r.shape}"
        )
    if u.shape[0] < 1:
        raise ValueError("a segment needs at least two samples (K >= 1)")
    fb = seg.feedback
    if fb is not None:
        gain = np.asarray(fb.gain, dtype=float)
        ff = np.asarray(fb.feedforward, dtype=float)
        if gain.shape != (2,) or ff.shape != a.shape:
            raise ValueError(
                f"a segment's feedback needs gain of shape (2,) and feedforward of the shape of u_A {a.shape}; "
                f"got {gain.shape}, {ff.shape}"
            )
        fb = Feedback(gain, ff)
    return Segment(x0, r, u, a, fb)


def plan_inputs(segment: Segment, plant: DiscretePlant) -> tuple[DiscretePlant, np.ndarray]:
    """``(plant, u_known)`` the human plans with: ``plant`` and u_A, or the closed wheel and the feedforward."""
    seg = check_segment(segment)
    if seg.feedback is None:
        return plant, seg.u_A
    return planning_plant(plant, seg.feedback.gain), seg.feedback.feedforward


def prepare_batch(plant: DiscretePlant, segments) -> SegmentBatch:
    """Lay out segments of equal K and M for :func:`scioc.models.maxent.loglik_grad` (θ-independent, once)."""
    segs = [check_segment(s) for s in segments]
    if not segs:
        raise ValueError("no segments given")
    K, M = segs[0].K, segs[0].preview
    if any(s.K != K or s.preview != M for s in segs):
        raise ValueError(
            "prepare_batch needs segments of equal length and preview; use loglik_segments for mixed lengths"
        )
    n = len(segs)
    x1 = np.empty((n, K + 1))
    x2 = np.empty((n, K + 1))
    r = np.empty((n, K + M + 1))
    u = np.empty((n, K))
    a = np.empty((n, K + M))
    fb = np.zeros((n, 2))
    for i, s in enumerate(segs):
        x = propagate(plant, s.x0, s.u_H + s.u_A[:K])
        x1[i] = x[:, 0]
        x2[i] = x[:, 1]
        r[i] = s.angle_ref
        u[i] = s.u_H
        if s.feedback is None:
            a[i] = s.u_A
        else:
            a[i] = s.feedback.feedforward
            fb[i] = s.feedback.gain
    return SegmentBatch(x1, x2, r, u, a, fb)


def as_batch(segments, plant: DiscretePlant) -> SegmentBatch:
    """``segments`` itself if it is a :class:`SegmentBatch`, else :func:`prepare_batch` of them."""
    if isinstance(segments, SegmentBatch):
        return segments
    return prepare_batch(plant, list(segments))


__all__ = [
    "as_batch",
    "Feedback",
    "Segment",
    "SegmentBatch",
    "check_segment",
    "planning_plant",
    "plan_inputs",
    "prepare_batch",
]
