"""The prior predictive check of the hierarchical model: seeded, quantiles ordered."""

import numpy as np

from scioc.models.bayes.prior_predictive import prior_predictive_summary
from scioc.models.design import CONDITIONS
from tests.models.bayes.test_hierarchical import small_study


def test_prior_predictive_summary_is_seeded_and_ordered(plant):
    subjects, conditions, segs = small_study(plant, K=100, M=30)
    a = prior_predictive_summary(subjects, conditions, segs, plant, np.random.default_rng(35), draws=20)
    b = prior_predictive_summary(subjects, conditions, segs, plant, np.random.default_rng(35), draws=20)
    for c in CONDITIONS:
        np.testing.assert_array_equal(a.torque_rms[c], b.torque_rms[c])
        assert np.all(np.diff(a.error_rms[c]) >= 0) and np.all(a.torque_rms[c] > 0)
