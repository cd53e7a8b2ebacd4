"""The report's identification sections: details list what the console lists; the SC − MC row prints dashes."""

from html import unescape

import numpy as np
import pandas as pd

from scioc.pipelines.report.identify import section_identification
from scioc.pipelines.report.truth import section_truth


def _estimates(converged=(True, True, True, True), implausible=(False, False, False, False)):
    return pd.DataFrame({
        "subject": ["S01", "S01", "S02", "S02"], "condition": ["MC", "SC"] * 2,
        "theta1": [20.0, 10.0, 3e6, 12.0], "se_log_theta1": 0.05, "theta2": 0.0, "R": 20.0, "se_log_R": 0.02,
        "loglik": -100.0, "converged": list(converged), "implausible": list(implausible), "iterations": 12,
        "message": ["Optimization terminated successfully", "Iteration limit reached", "ok", "ok"]})


def test_the_segments_that_did_not_converge_or_hit_the_edge_are_listed():
    html = unescape(section_identification(_estimates((True, False, True, True), (False, False, True, False)), None))
    assert "3 of 4 optimizations converged" in html
    assert "Not converged (1):" in html and "S01 SC: Iteration limit reached" in html
    assert "At the edge of the search (1;" in html and "S02 MC: θ1 = 3e+06 1/rad²" in html


def test_when_every_segment_converged_the_details_say_so():
    html = unescape(section_identification(_estimates(), {"timing_s": {"reconstruct_s": 1.0, "optimize_s": 0.5,
                                                                       "segments": 4}}))
    assert "No segment failed to converge and none ended at the edge of the search" in html
    assert "Reconstruction took 1.00 s and the optimization 0.50 s for 4 segments." in html


def test_the_shift_row_prints_dashes_where_a_column_is_undefined():
    est = _estimates()
    truth = est[["subject", "condition", "theta1", "R"]].assign(theta1=[18.0, 9.0, 25.0, 13.0])
    html = unescape(section_truth(est, truth, None))
    tab = html[html.index("<table>"):html.index("</table>")]
    row = tab[tab.index("SC − MC"):].split("</tr>")[0]
    assert "nan" not in tab and row.count(">–<") == 3
    assert np.isfinite(float(row.split("</td>")[2].rsplit(">", 1)[1]))  # the shift itself is a number
