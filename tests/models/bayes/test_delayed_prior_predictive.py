"""The prior predictive check of the delayed model: seeded, quantiles ordered, the motor noise's prior shows in the
torques (a prior scale near 0 gives smaller torques than the default's)."""

import numpy as np

from scioc.models.bayes.delayed_model import DelayedPriors
from scioc.models.bayes.delayed_windows import delayed_windows
from scioc.models.bayes.prior_predictive import delayed_prior_predictive_summary
from scioc.models.delayed.lag import Warmup
from scioc.models.design import CONDITIONS


def test_delayed_prior_predictive_is_seeded_ordered_and_sees_the_motor_noise(plant):
    w = delayed_windows(2, np.random.default_rng(3), K=150, preview=20)
    warm = [Warmup(np.full(30, 0.1 * i), 0.0) for i in range(len(w.segments))]
    kw = dict(delay=w.delay, tau0=warm, draws=15)
    a = delayed_prior_predictive_summary(w.subjects, w.conditions, w.segments, plant, np.random.default_rng(5), **kw)
    b = delayed_prior_predictive_summary(w.subjects, w.conditions, w.segments, plant, np.random.default_rng(5), **kw)
    for c in CONDITIONS:
        np.testing.assert_array_equal(a.summary.torque_rms[c], b.summary.torque_rms[c])
        assert np.all(np.diff(a.summary.error_rms[c]) >= 0) and np.all(a.summary.torque_rms[c] > 0)
    assert np.all(np.diff(a.tau_nm) >= 0) and 0.0 < a.tau_nm[0] and a.tau_nm[-1] < 2.0
    # The same draws of everything else with motor noise ~ 0 (s_m² ~ IG(100, 1e-10): s_m about 1e-6): smaller torques
    # (it adds variance).
    quiet_prior = DelayedPriors(sigma_m_variance_inverse_gamma=(100.0, 1e-10))
    quiet = delayed_prior_predictive_summary(w.subjects, w.conditions, w.segments, plant, np.random.default_rng(5),
                                             delayed_priors=quiet_prior, **kw)
    assert quiet.sigma_m[-1] < 1e-5
    assert quiet.summary.torque_rms["MC"][2] < a.summary.torque_rms["MC"][2]
