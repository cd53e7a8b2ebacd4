"""The report's HTML layer: values are escaped, undefined numbers print as a dash, figures are embedded."""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from scioc.pipelines.report.render import MISSING, figure, number, render, table


def test_values_are_escaped_and_the_templates_markup_is_not():
    html = table(pd.DataFrame({"subject": ["<script>alert(1)</script>"], "x": [1.5]}), left=("subject",))
    assert "<script>" not in html and "&lt;script&gt;" in html
    assert html.startswith("<table><tr><th class=\"l\">subject</th>")
    assert "&lt;" not in render("note.html.j2", text="a")  # a template's own markup stays markup


def test_nan_and_none_print_as_a_dash_not_nan():
    html = table(pd.DataFrame({"a": [np.nan, 0.123456], "b": [None, "x"]}))
    assert "nan" not in html and "None" not in html and html.count(f">{MISSING}<") == 2 and ">0.1235<" in html
    assert number(float("nan")) == MISSING and number(None, ".1f", "n/a") == "n/a" and number(2.0, "g") == "2"


def test_a_figure_is_an_embedded_png_with_its_caption_escaped():
    fig, ax = plt.subplots()
    ax.plot([0, 1])
    html = figure(fig, "a < b")
    assert "data:image/png;base64," in html and html.count("a &lt; b") == 2
    assert not plt.fignum_exists(fig.number)  # closed


def test_the_headline_says_at_which_posterior_point_the_fit_was_checked():
    from scioc.pipelines.report.adequacy import headline

    a = {"verdict": "pass", "combined_p": {"variance": 0.5}, "study_alpha": 0.01}
    at_draw = {"verdict": "fail", "point": {"at": "draw", "what": "one joint posterior draw"}}
    html = headline(a, at_draw)
    assert "posterior θ (one joint posterior draw) the verdict is <b>fail</b>" in html
    assert "posterior θ the verdict is <b>fail</b>" in headline(a, {"verdict": "fail"})  # a fit from before
