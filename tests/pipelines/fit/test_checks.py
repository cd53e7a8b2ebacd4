"""Checks of the fit against other evidence: the mixed model against its closed form."""

import numpy as np
import pandas as pd
import pytest

from pipelines.fit import mixedlm_check


def test_mixedlm_of_a_balanced_paired_design_is_the_paired_mean_difference():
    """Closed form: with two observations per subject, the REML fixed effect of SC is the mean
    paired difference of log θ1 and its SE is SD(d)/√n (the paired t-test), when the subject
    variance is not at its boundary."""
    rng = np.random.default_rng(7)
    n = 30
    a = rng.normal(3.0, 0.5, n)
    d = rng.normal(-0.7, 0.2, n)
    est = pd.DataFrame({"subject": np.repeat([f"S{i}" for i in range(n)], 2), "condition": ["MC", "SC"] * n,
                        "theta1": np.exp(np.column_stack([a, a + d]).ravel())})
    mm = mixedlm_check(est)
    assert mm["coef"] == pytest.approx(d.mean(), rel=1e-6)
    # The optimizer stops at a tolerance of its own: agreement to 1e-4 relative.
    assert mm["se"] == pytest.approx(d.std(ddof=1) / np.sqrt(n), rel=1e-4)
    assert mm["ratio"] == pytest.approx(np.exp(d.mean()), rel=1e-6)
