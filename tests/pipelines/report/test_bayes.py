"""The report's Bayesian section reads the fit's artifacts (and says so when there is none)."""

from html import unescape

import pytest

from scioc.pipelines.report.bayes import section_bayes


@pytest.mark.validation
def test_report_section_reads_the_fit(small_fit, tmp_path):
    root, _, _ = small_fit
    html = unescape(section_bayes(root))
    for phrase in ("paper's test (Wilcoxon)", "Bayesian contrast", "mixed model", "Sampler convergence", "PSIS-LOO",
                   "Posterior predictive check", "Ground truth check", "true β = -0.7"):
        assert phrase in html, phrase
    assert html.count("<img") == 2  # the forest plot and the predictive bands
    assert "No Bayesian fit" in section_bayes(tmp_path)


def test_the_diagnostics_section_advises_only_a_fit_whose_verdict_fails():
    from scioc.pipelines.report.bayes import section_diagnostics

    def diag(div, ess):
        p = {"rhat": 1.001, "ess_bulk": ess, "ess_tail": ess, "ess_bulk_per_s": 1.0}
        return {"sampler": {"divergences": div, "ebfmi": [1.0], "max_tree_depth": 5, "mean_steps_per_draw": 31.0},
                "population": {"beta": p}, "units": {}, "worst": {"rhat": 1.001, "ess": ess, "ess_parameter": "beta",
                                                                   "min_ess_bulk_per_s": 1.0},
                "passed": not div and ess >= 400}

    side = {"criteria": {"rhat_max": 1.01, "ess_bulk_and_tail_min": 400}, "seed": 1,
            "sampler": {"chains": 4, "draws": 1000, "tune": 1000, "target_accept": 0.8},
            "seconds": {m: {"sample_s": 1.0, "compile_and_sample_s": 2.0} for m in ("condition", "pooled")},
            "diagnostics": {"condition": diag(2, 900.0), "pooled": diag(0, 900.0)}}
    html = unescape(section_diagnostics(side))
    assert "What to try" in html and "condition: 2 divergent transitions: refit with --target-accept 0.9" in html
    assert "pooled:" not in html.split("What to try")[1]
    side["diagnostics"]["condition"] = diag(0, 900.0)
    assert "What to try" not in unescape(section_diagnostics(side))
