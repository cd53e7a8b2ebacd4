"""Units of a study: which subject × condition each segment belongs to, and the design check.

A *unit* is one subject in one condition level; several segments of a unit are its trials. The models that
compare levels (:mod:`scioc.models.bayes.hierarchical`) need every subject in every level, which
:func:`index_study` checks where the labels enter.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from scioc.models.design import CONDITIONS


class StudyIndex(NamedTuple):
    """Each segment's unit: ``subject_idx`` into ``subjects`` (labels in order of first appearance) and
    ``condition_idx`` into the levels (0: the baseline), int arrays of shape (n,)."""

    subjects: tuple[str, ...]
    subject_idx: np.ndarray
    condition_idx: np.ndarray


def index_study(subjects: Sequence, conditions: Sequence, levels: Sequence = CONDITIONS) -> StudyIndex:
    """Check the design and map each segment's subject and condition label (compared as strings) to its unit.

    ``levels``: baseline first (MC, SC). Raises ValueError, naming the segment or subjects, for unequal
    lengths, an unknown level, a level without any segment (its β is not identified), or a subject
    missing a level.
    """
    levels = tuple(str(v) for v in levels)
    if len(levels) < 2:
        raise ValueError(f"a comparison needs two or more levels; got {levels}")
    subj = [str(s) for s in subjects]
    cond = [str(c) for c in conditions]
    if len(subj) != len(cond):
        raise ValueError(f"subjects and conditions must have one entry per segment; got {len(subj)} and {len(cond)}")
    if not subj:
        raise ValueError("no segments given")
    for j, c in enumerate(cond):
        if c not in levels:
            raise ValueError(f"condition of segment {j} must be one of {', '.join(map(repr, levels))}; got {c!r}")
    for c in levels:
        if c not in cond:
            raise ValueError(
                f"no {c} segments at all: the change β (and β_R) of {c} is not identified. "
                "This model needs every subject in every condition; fit a single-condition "
                "model instead (none is provided here)."
            )
    labels = tuple(dict.fromkeys(subj))
    have = {s: set() for s in labels}
    for s, c in zip(subj, cond):
        have[s].add(c)
    missing = [(s, c) for s in labels for c in levels if c not in have[s]]
    if missing:
        listed = ", ".join(f"subject {s!r} has no {c} segment" for s, c in missing)
        both = f"both {levels[0]} and {levels[1]}" if len(levels) == 2 else f"every one of {', '.join(levels)}"
        raise ValueError(f"every subject needs segments in {both}: {listed}")
    pos = {s: i for i, s in enumerate(labels)}
    return StudyIndex(
        subjects=labels,
        subject_idx=np.array([pos[s] for s in subj], dtype=np.int64),
        condition_idx=np.array([levels.index(c) for c in cond], dtype=np.int64),
    )


__all__ = ["StudyIndex", "index_study"]
