"""The report's Bayesian section reads the fit's artifacts (and says so when there is none)."""

from html import unescape

import pytest

from pipelines.report.bayes import section_bayes


@pytest.mark.slow
def test_report_section_reads_the_fit(small_fit, tmp_path):
    root, _, _ = small_fit
    html = unescape(section_bayes(root))
    for phrase in ("paper's test (Wilcoxon)", "Bayesian contrast", "mixed model", "Sampler convergence", "PSIS-LOO",
                   "Posterior predictive check", "Ground truth check", "true β = -0.7"):
        assert phrase in html, phrase
    assert html.count("<img") == 2  # the forest plot and the predictive bands
    assert "No Bayesian fit" in section_bayes(tmp_path)
