"""Units of a study: each segment mapped to its subject × condition, the design checked where labels enter."""

import numpy as np
import pytest

from scioc.models.units import index_study


def test_segments_map_to_subjects_in_order_of_appearance_and_conditions():
    index = index_study(["b", "a", "b", "a", 7, "7"], ["SC", "MC", "MC", "SC", "MC", "SC"])
    assert index.subjects == ("b", "a", "7")  # compared as strings: 7 and "7" are one subject
    np.testing.assert_array_equal(index.subject_idx, [0, 1, 0, 1, 2, 2])
    np.testing.assert_array_equal(index.condition_idx, [1, 0, 0, 1, 0, 1])


@pytest.mark.parametrize("subjects, conditions, message", [
    (["a", "a"], ["MC"], "one entry per segment"),
    ([], [], "no segments"),
    (["a", "a"], ["MC", "sc"], r"segment 1 must be one of 'MC', 'SC'"),
    (["a", "b"], ["MC", "MC"], "no SC segments at all"),
    (["a", "a", "b"], ["MC", "SC", "SC"], r"subject 'b' has no MC segment"),
])
def test_design_errors_name_the_segment_or_subject(subjects, conditions, message):
    with pytest.raises(ValueError, match=message):
        index_study(subjects, conditions)
