"""The report's figures (matplotlib), each from stored artifacts; the sections put them on the page.

Colours follow the paper's Fig. 6: MC red, SC green.
"""

from __future__ import annotations

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import arviz_plots as azp  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import binom  # noqa: E402

from models.design import CONDITIONS, MANUAL, SHARED  # noqa: E402

MC_COLOR = "#c0392b"  # red, as in the paper's Fig. 6
SC_COLOR = "#27ae60"  # green
#: Colour of each condition.
COLORS = {MANUAL: MC_COLOR, SHARED: SC_COLOR}


def plain_log_axis(axis) -> None:
    """Label a log axis at 1, 2 and 5 times the powers of ten, as plain numbers, and leave minor ticks unlabelled.

    Matplotlib's default labels every minor tick when the data span less than a decade,
    and those labels run into each other.
    """
    axis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def reference(study: pd.DataFrame, start: float | None, length: float | None):
    """The reference angle of the first segment: in and after the analysis window, and the whole run (Fig. 4)."""
    key = study.iloc[0][["subject", "condition"]]
    seg = study[(study.subject == key.subject) & (study.condition == key.condition)]
    t, ref = seg["t"].to_numpy(), seg["angle_ref"].to_numpy()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), gridspec_kw={"width_ratios": [2, 1]})
    if start is not None:
        m = (t >= start) & (t <= start + 2 * length)
        axes[0].plot(t[m], ref[m], color="k")
        axes[0].axvspan(start, start + length, color="#ddd", label="analysis window")
        axes[0].legend(loc="upper right")
        axes[0].set_title("Reference in and after the analysis window (Fig. 4)")
    else:
        axes[0].plot(t, ref, color="k")
        axes[0].set_title("Reference (whole run is analysed)")
    axes[0].set_xlabel("time t (s)")
    axes[0].set_ylabel("reference angle φ_ref (rad)")
    axes[1].plot(t, ref, color="k", lw=0.6)
    axes[1].set_xlabel("time t (s)")
    axes[1].set_ylabel("φ_ref (rad)")
    axes[1].set_title("Whole run")
    return fig


def theta1_histogram(est: pd.DataFrame):
    """Histogram of the identified θ1 in MC and SC on a log axis (Fig. 5)."""
    fig, ax = plt.subplots(figsize=(7, 3.6))
    vals = est["theta1"].to_numpy()
    bins = np.geomspace(vals.min() / 1.2, vals.max() * 1.2, 25)
    for c in CONDITIONS:
        ax.hist(est.loc[est.condition == c, "theta1"], bins=bins, alpha=0.6, color=COLORS[c], label=c)
    ax.set_xscale("log")
    plain_log_axis(ax.xaxis)
    ax.set_xlabel("identified θ1 = q11/R (1/rad²)")
    ax.set_ylabel("subjects")
    ax.legend()
    return fig


def trajectories(d: pd.DataFrame, subject: str):
    """One subject's measured angle, velocity and torque beside forward optimal control with θ_MC and θ_SC (Fig. 6)."""
    fig, axes = plt.subplots(3, 2, figsize=(12, 7.5), sharex="col")
    for j, cond in enumerate(CONDITIONS):
        s = d[d.condition == cond]
        if s.empty:
            continue
        t = s["t"].to_numpy()
        for i, (q, label) in enumerate((("angle", "angle φ (rad)"), ("velocity", "velocity φ̇ (rad/s)"),
                                        ("u_H", "human torque u_H (N·m)"))):
            ax = axes[i, j]
            ax.plot(t, s[q], color=COLORS[cond], lw=0.9,
                    label=f"measured {cond}" + (" (reconstructed)" if q != "angle" else ""))
            ax.plot(t, s[f"pred_mc_{q}"], "--", color="#7f1d1d", lw=1.1, label="optimal control with θ_MC")
            ax.plot(t, s[f"pred_sc_{q}"], "--", color="#14532d", lw=1.1, label="optimal control with θ_SC")
            if q == "angle":
                ax.plot(t, s["angle_ref"], color="#999", lw=0.8, label="reference")
            ax.set_ylabel(label)
            if i == 0:
                ax.set_title(f"{subject}, {cond} data")
                ax.legend(fontsize=7, loc="upper right")
        axes[2, j].set_xlabel("time t (s)")
    return fig


def reconstructed_torque(s: pd.DataFrame):
    """The true and the reconstructed torque of a stretch of one segment."""
    fig, ax = plt.subplots(figsize=(10, 3))
    ax.plot(s.t, s.true_u_H, color="#555", lw=0.8, label="true u_H")
    ax.plot(s.t, s.u_H, color=SC_COLOR, lw=1.2, label="reconstructed from the encoder angle")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("human torque u_H (N·m)")
    ax.legend(fontsize=8)
    return fig


def truth_scatter(sources):
    """True against estimated θ1 with ±1 SE, one panel per source of estimates (label, merged frame)."""
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, (label, d) in zip(axes, list(sources) + [(None, None)] * (2 - len(sources))):
        if d is None:
            ax.axis("off")
            continue
        for c in CONDITIONS:
            s = d[d.condition == c]
            ax.errorbar(s.theta1_true, s.theta1, yerr=[s.theta1 * (1 - np.exp(-s.se_log_theta1)),
                                                         s.theta1 * (np.exp(s.se_log_theta1) - 1)],
                        fmt="o", ms=3, color=COLORS[c], label=c, alpha=0.8)
        lo, hi = d[["theta1", "theta1_true"]].min().min() / 1.3, d[["theta1", "theta1_true"]].max().max() * 1.3
        ax.plot([lo, hi], [lo, hi], color="#888", lw=0.8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("true θ1 (1/rad²)")
        ax.set_ylabel("estimated θ1 (1/rad²)")
        ax.set_title(f"Estimates {label}")
        ax.legend()
    return fig


def forest(subjects: list, beta: dict, true_change: np.ndarray | None):
    """Per-subject MC→SC change of log θ1 (posterior mean and 94 % HDI from ``contrasts.json``) with β's band.

    Drawn here rather than by ``arviz_plots.plot_forest``: the report reads the stored
    contrasts (the same HDIs the text quotes, from :func:`pipelines.fit.contrasts.hdi`) and
    overlays β's HDI band and the simulated truth, which ``plot_forest`` does not draw. The
    diagnostics notebook shows ``plot_forest`` of the posterior itself.
    """
    n = len(subjects)
    fig, ax = plt.subplots(figsize=(7.5, 0.18 * n + 1.6))
    y = np.arange(n)[::-1]
    mean = np.array([s["mean"] for s in subjects])
    lo = np.array([s["hdi"][0] for s in subjects])
    hi = np.array([s["hdi"][1] for s in subjects])
    ax.axvspan(*beta["hdi"], color="#cfe3f3", label=f"β, 94 % HDI [{beta['hdi'][0]:.2f}, {beta['hdi'][1]:.2f}]")
    ax.axvline(beta["mean"], color="#1f77b4", lw=1)
    ax.axvline(0.0, color="#555", lw=0.8, ls=":")
    ax.hlines(y, lo, hi, color=SC_COLOR, lw=1.4)
    ax.plot(mean, y, "o", color=SC_COLOR, ms=3.5, label="subject: posterior mean, 94 % HDI")
    if true_change is not None:
        ax.plot(true_change, y, "x", color="k", ms=4, label="true change (simulation)")
    ax.set_yticks(y, [s["subject"] for s in subjects], fontsize=7)
    ax.set_xlabel("change of log θ1 from MC to SC: log(θ1[SC] / θ1[MC]) (dimensionless)")
    ax.set_ylabel("subject")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig


def predictive_bands(ppc: pd.DataFrame, subject: str):
    """Posterior predictive Fig. 6: angle, tracking error and torque with 5-95 % bands, per condition."""
    conds = [c for c in CONDITIONS if c in set(ppc.condition)]
    fig, axes = plt.subplots(3, len(conds), figsize=(6 * len(conds), 8.5), sharex="col", squeeze=False)
    for j, cond in enumerate(conds):
        s = ppc[ppc.condition == cond]
        t = s["t"].to_numpy()
        ref = s["angle_ref"].to_numpy()
        col = COLORS[cond]
        band = {"color": col, "alpha": 0.3, "lw": 0, "label": "posterior predictive 5-95 %"}
        ax = axes[0, j]
        ax.plot(t, ref, color="#999", lw=0.8, label="reference φ_ref")
        ax.fill_between(t, s.angle_q05, s.angle_q95, **band)
        ax.plot(t, s.angle, color="k", lw=0.7, label="measured angle")
        ax.set_ylabel("angle φ (rad)")
        ax.set_title(f"{subject}, {cond}")
        ax = axes[1, j]
        ax.fill_between(t, s.angle_q05 - ref, s.angle_q95 - ref, **band)
        ax.plot(t, s.angle_q50 - ref, color=col, lw=0.9, ls="--", label="predictive median")
        ax.plot(t, s.angle - ref, color="k", lw=0.7, label="measured")
        ax.axhline(0.0, color="#999", lw=0.6)
        ax.set_ylabel("tracking error φ − φ_ref (rad)")
        ax = axes[2, j]
        ax.plot(t, s.u_H, color="#777", lw=0.4, label="u_H (reconstructed from the angle)")
        ax.fill_between(t, s.u_H_q05, s.u_H_q95, **band)
        ax.plot(t, s.u_H_opt, color="k", lw=1.1, label="optimal control at the posterior median θ")
        ax.set_ylabel("human torque u_H (N·m)")
        ax.set_xlabel("time t (s)")
    for i in range(3):
        handles, labels = axes[i, -1].get_legend_handles_labels()
        axes[i, -1].legend(handles, labels, fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    return fig


def sbc_rank_histograms(pits: dict, names: list, n: int):
    """Rank histograms of the PIT, one panel per ranked quantity; grey: the 99 % band of a bin count.

    ``pits`` maps a fit ("correct", "negative control") to a Dataset of PIT values (dims
    chain, draw) per quantity; ``n`` is the number of replications.
    """
    fig, axes = plt.subplots(1, len(names), figsize=(3.6 * len(names), 3), squeeze=False)
    nb = 20
    for j, name in enumerate(names):
        ax = axes[0, j]
        for (tag, d), col in zip(pits.items(), ("#1f77b4", "#b02a37")):
            ax.hist(np.ravel(d[name].values), bins=nb, range=(0, 1), histtype="step", color=col, lw=1.4, label=tag)
        ax.axhspan(binom.ppf(0.005, n, 1 / nb), binom.ppf(0.995, n, 1 / nb), color="#ddd", zorder=0)
        ax.set_title(name)
        ax.set_xlabel("normalized rank (PIT)")
        ax.set_ylabel("replications per bin")
        if j == 0:
            ax.legend(fontsize=7)
    return fig


def sbc_ecdf(tree):
    """ECDF of the PIT minus the uniform CDF per ranked quantity, by ``arviz_plots.plot_ecdf_pit``.

    ``tree`` is a calibration's DataTree (:func:`pipelines.calibrate.summary.sbc_tree`); its
    ``pit`` group is plotted with ArviZ's default ``pot_c`` test: each panel shows the test's
    p-value and marks the PIT values that contribute most to a departure from uniformity.
    (ArviZ deprecates the simultaneous-envelope method, which assumes independent PIT values.)
    """
    pc = azp.plot_ecdf_pit(tree, group="pit", backend="matplotlib")
    return pc.viz["figure"].item()
