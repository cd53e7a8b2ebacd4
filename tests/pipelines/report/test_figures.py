"""The report's figures: the θ1 histogram's log axis carries few, plain labels that cannot overlap."""

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from scioc.pipelines.report import figures


def test_the_theta1_histogram_labels_its_log_axis_at_1_2_5_only():
    rng = np.random.default_rng(0)
    est = pd.DataFrame({"theta1": np.exp(rng.normal(2.8, 0.5, 84)), "condition": ["MC", "SC"] * 42})
    fig = figures.theta1_histogram(est)
    ax = fig.axes[0]
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_xticklabels() if t.get_text() and t.get_visible()]
    assert 3 <= len(labels) and all(float(s) / 10 ** np.floor(np.log10(float(s))) in (1, 2, 5) for s in labels)
    assert not [t.get_text() for t in ax.get_xticklabels(minor=True) if t.get_text()]
    # No two labels overlap on the drawn figure.
    boxes = sorted((t.get_window_extent() for t in ax.get_xticklabels() if t.get_text()), key=lambda b: b.x0)
    assert all(a.x1 < b.x0 for a, b in zip(boxes, boxes[1:]))
    plt.close(fig)
