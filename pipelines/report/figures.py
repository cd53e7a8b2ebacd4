"""The report's figures (matplotlib), each from stored artifacts; the sections put them on the page.

Colours follow the paper's Fig. 6: the baseline (MC) red, the next level (SC) green; further
levels take the next colours of :data:`PALETTE`. Every figure takes the levels in the
experiment's order, baseline first (:attr:`scioc.models.design.Design.ordered_levels`).
"""

from __future__ import annotations

import arviz_plots as azp
import matplotlib
import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import binom  # noqa: E402

from scioc.models.design import CONDITIONS  # noqa: E402

MC_COLOR = "#c0392b"  # red, as in the paper's Fig. 6
SC_COLOR = "#27ae60"  # green
#: Colours of the levels in order (baseline first): the paper's MC red and SC green, then others.
PALETTE = (MC_COLOR, SC_COLOR, "#2471a3", "#b9770e", "#7d3c98", "#17a589", "#566573", "#cb4335")
#: Darker shades of :data:`PALETTE`, for the predictions drawn over the data.
DARK = ("#7f1d1d", "#14532d", "#1b4f72", "#7e5109", "#4a235a", "#0e6251", "#212f3c", "#78281f")


def level_colors(levels) -> dict:
    """``{level: colour}`` for the levels in order, baseline first (cycling after 8 levels)."""
    return {v: PALETTE[i % len(PALETTE)] for i, v in enumerate(levels)}


def first_segment(d: pd.DataFrame) -> pd.DataFrame:
    """The rows of ``d``'s first subject × condition (× trial, when the table has trials)."""
    keys = [c for c in ("subject", "condition", "trial") if c in d.columns]
    first = d.iloc[0]
    mask = np.ones(len(d), bool)
    for c in keys:
        mask &= (d[c] == first[c]).to_numpy()
    return d[mask]


def plain_log_axis(axis) -> None:
    """Label a log axis at 1, 2 and 5 times the powers of ten as plain numbers, minor ticks unlabelled
    (matplotlib labels every minor tick of a span under a decade, and the labels collide)."""
    axis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    axis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def reference(study: pd.DataFrame, start: float | None, length: float | None):
    """The first segment's reference in and after the analysis window, and the whole run (Fig. 4); ``start`` None:
    the whole trial in one panel."""
    seg = first_segment(study)
    t, ref = seg["t"].to_numpy(), seg["angle_ref"].to_numpy()
    if start is None:
        fig, ax = plt.subplots(figsize=(11, 3.2))
        ax.plot(t, ref, color="k")
        ax.set_title("Reference over a whole trial (every trial is analysed whole)")
        ax.set_xlabel("time t (s)")
        ax.set_ylabel("reference angle φ_ref (rad)")
        return fig
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), gridspec_kw={"width_ratios": [2, 1]})
    m = (t >= start) & (t <= start + 2 * length)
    axes[0].plot(t[m], ref[m], color="k")
    axes[0].axvspan(start, start + length, color="#ddd", label="analysis window")
    axes[0].legend(loc="upper right")
    axes[0].set_title("Reference in and after the analysis window (Fig. 4)")
    axes[0].set_xlabel("time t (s)")
    axes[0].set_ylabel("reference angle φ_ref (rad)")
    axes[1].plot(t, ref, color="k", lw=0.6)
    axes[1].set_xlabel("time t (s)")
    axes[1].set_ylabel("φ_ref (rad)")
    axes[1].set_title("Whole run")
    return fig


def theta1_histogram(est: pd.DataFrame, levels=CONDITIONS):
    """Histogram of the identified θ1 per level (baseline first; default MC, SC) on a log axis (Fig. 5)."""
    fig, ax = plt.subplots(figsize=(7, 3.6))
    vals = est["theta1"].to_numpy()
    bins = np.geomspace(vals.min() / 1.2, vals.max() * 1.2, 25)
    colors = level_colors(levels)
    alpha = 0.6 if len(levels) <= 2 else 0.45
    for c in levels:
        ax.hist(est.loc[est.condition == c, "theta1"], bins=bins, alpha=alpha, color=colors[c], label=c)
    ax.set_xscale("log")
    plain_log_axis(ax.xaxis)
    ax.set_xlabel("identified θ1 = q11/R (1/rad²)")
    ax.set_ylabel("subjects")
    ax.legend()
    return fig


def trajectories(d: pd.DataFrame, subject: str, levels=CONDITIONS, reconstructed: bool = True):
    """One subject's measured angle, velocity and torque beside forward optimal control with each level's θ (Fig. 6).

    One column per level, the first trial of each; dashed: the ``pred_{level}_*`` columns of
    ``trajectories.parquet``. ``reconstructed``: velocity and torque come from the angle.
    """
    levels = list(levels)
    colors = dict(zip(levels, DARK))
    fig, axes = plt.subplots(3, len(levels), figsize=(6 * len(levels), 7.5), sharex="col", squeeze=False)
    for j, cond in enumerate(levels):
        s = d[d.condition == cond]
        if s.empty:
            continue
        s = first_segment(s)
        t = s["t"].to_numpy()
        for i, (q, label) in enumerate((("angle", "angle φ (rad)"), ("velocity", "velocity φ̇ (rad/s)"),
                                        ("u_H", "human torque u_H (N·m)"))):
            ax = axes[i, j]
            how = "" if q == "angle" else " (reconstructed)" if reconstructed else \
                " (derived)" if q == "velocity" else " (recorded)"
            ax.plot(t, s[q], color=level_colors(levels)[cond], lw=0.9, label=f"measured {cond}{how}")
            for other in levels:
                column = f"pred_{other.lower()}_{q}"
                if column in s:
                    ax.plot(t, s[column], "--", color=colors.get(other, "#333"), lw=1.1,
                            label=f"optimal control with θ_{other}")
            if q == "angle":
                ax.plot(t, s["angle_ref"], color="#999", lw=0.8, label="reference")
            ax.set_ylabel(label)
            if i == 0:
                trial = f", trial {s['trial'].iloc[0]}" if "trial" in s and s["trial"].notna().any() else ""
                ax.set_title(f"{subject}, {cond} data{trial}")
                ax.legend(fontsize=7, loc="upper right")
        axes[2, j].set_xlabel("time t (s)")
    return fig


def reconstructed_torque(s: pd.DataFrame, source: str = "the encoder angle", color: str = SC_COLOR):
    """The true and the reconstructed torque of a stretch of one segment (reconstructed from ``source``)."""
    fig, ax = plt.subplots(figsize=(10, 3))
    ax.plot(s.t, s.true_u_H, color="#555", lw=0.8, label="true u_H")
    ax.plot(s.t, s.u_H, color=color, lw=1.2, label=f"reconstructed from {source}")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("human torque u_H (N·m)")
    ax.legend(fontsize=8)
    return fig


def truth_scatter(sources, levels=CONDITIONS):
    """True against estimated θ1 with ±1 SE, one panel per source of estimates (label, merged frame), per level."""
    colors = level_colors(levels)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, (label, d) in zip(axes, list(sources) + [(None, None)] * (2 - len(sources))):
        if d is None:
            ax.axis("off")
            continue
        for c in levels:
            s = d[d.condition == c]
            ax.errorbar(s.theta1_true, s.theta1, yerr=[s.theta1 * (1 - np.exp(-s.se_log_theta1)),
                                                         s.theta1 * (np.exp(s.se_log_theta1) - 1)],
                        fmt="o", ms=3, color=colors[c], label=c, alpha=0.8)
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


def forest(subjects: list, beta: dict, true_change: np.ndarray | None, pair: tuple = CONDITIONS,
           color: str = SC_COLOR):
    """Per-subject change of log θ1 from ``pair[0]`` to ``pair[1]`` (posterior mean, 94 % HDI) with β's band.

    Drawn here, not by ``arviz_plots.plot_forest``, to show the stored HDIs the text quotes with β's
    band and the simulated truth over them.
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
    ax.hlines(y, lo, hi, color=color, lw=1.4)
    ax.plot(mean, y, "o", color=color, ms=3.5, label="subject: posterior mean, 94 % HDI")
    if true_change is not None:
        ax.plot(true_change, y, "x", color="k", ms=4, label="true change (simulation)")
    ax.set_yticks(y, [s["subject"] for s in subjects], fontsize=7)
    base, level = pair
    ax.set_xlabel(f"change of log θ1 from {base} to {level}: log(θ1[{level}] / θ1[{base}]) (dimensionless)")
    ax.set_ylabel("subject")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return fig


def predictive_bands(ppc: pd.DataFrame, subject: str, levels=CONDITIONS, reconstructed: bool = True):
    """Posterior predictive Fig. 6: angle, tracking error and torque with 5-95 % bands, per level (its first trial)."""
    conds = [c for c in levels if c in set(ppc.condition)]
    colors = level_colors(levels)
    fig, axes = plt.subplots(3, len(conds), figsize=(6 * len(conds), 8.5), sharex="col", squeeze=False)
    for j, cond in enumerate(conds):
        s = first_segment(ppc[ppc.condition == cond])
        t = s["t"].to_numpy()
        ref = s["angle_ref"].to_numpy()
        col = colors[cond]
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
        ax.plot(t, s.u_H, color="#777", lw=0.4,
                label="u_H (reconstructed from the angle)" if reconstructed else "u_H (recorded)")
        ax.fill_between(t, s.u_H_q05, s.u_H_q95, **band)
        ax.plot(t, s.u_H_opt, color="k", lw=1.1, label="optimal control at the posterior median θ")
        ax.set_ylabel("human torque u_H (N·m)")
        ax.set_xlabel("time t (s)")
    for i in range(3):
        handles, labels = axes[i, -1].get_legend_handles_labels()
        axes[i, -1].legend(handles, labels, fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    return fig


def sbc_rank_histograms(pits: dict, names: list, n: int):
    """Rank histograms of the PIT per quantity for each fit of ``pits`` (name: Dataset), with the 99 % band of a
    bin count over ``n`` replications in grey."""
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
    """ECDF of the PIT minus the uniform CDF per quantity of a calibration's DataTree, by
    ``arviz_plots.plot_ecdf_pit`` with its ``pot_c`` test (p-value, and the points that depart most)."""
    pc = azp.plot_ecdf_pit(tree, group="pit", backend="matplotlib")
    return pc.viz["figure"].item()
