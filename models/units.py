"""Units of a study: which subject × condition each segment belongs to, and the design check.

A *unit* is one subject in one condition level (by default MC, manual, and SC, shared
control; an experiment file may name two or more levels with a baseline). Several
segments (trials) of one unit are replicates of it. The models that compare the
conditions (:mod:`scioc.models.bayes.hierarchical`) need every subject in every level;
:func:`index_study` checks that where the labels enter and maps each segment to its unit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from scioc.models.design import CONDITIONS


class StudyIndex(NamedTuple):
    """Which unit each segment belongs to.

    Attributes
    ----------
    subjects : tuple of str
        Subject labels in order of first appearance (the ``subject`` coordinate).
    subject_idx : ndarray of int, shape (n,)
    condition_idx : ndarray of int, shape (n,)
        Position of the segment's level in ``levels`` (0: the baseline; by default 0 for
        MC, 1 for SC).
    """

    subjects: tuple[str, ...]
    subject_idx: np.ndarray
    condition_idx: np.ndarray


def index_study(subjects: Sequence, conditions: Sequence, levels: Sequence = CONDITIONS) -> StudyIndex:
    """Check the design and map each segment to its (subject, condition) unit.

    Parameters
    ----------
    subjects : sequence, length n
        Subject label of each segment (compared as strings).
    conditions : sequence of str, length n
        Condition level of each segment (several segments of one unit are its trials).
    levels : sequence of str
        The levels, baseline first (default MC, SC).

    Returns
    -------
    StudyIndex

    Raises
    ------
    ValueError
        If the lengths differ, a condition is not MC or SC (naming the first such
        segment), there are no SC (or no MC) segments at all (β would not be
        identified; no fallback model is offered), or a subject lacks one condition
        (naming the subjects).
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
