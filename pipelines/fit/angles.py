"""Fits scored by the encoder's angles: the study's windows as the angle likelihood's Op."""

from __future__ import annotations

from scioc.models.bayes.angle_op import AngleLoglikOp
from scioc.pipelines.prepare import angle_windows


def angle_op(prepared, plant, delay) -> AngleLoglikOp:
    """The angle likelihood of every prepared window at its ``delay`` (samples), through the study's encoder."""
    design = prepared.settings.design
    return AngleLoglikOp(angle_windows(prepared.segments, range(len(prepared.segments))), plant, delay=delay,
                         sigma_y=design.encoder_sd, params=design.wheel)


__all__ = ["angle_op"]
