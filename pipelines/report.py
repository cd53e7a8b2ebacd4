"""``scioc report``: a self-contained HTML report (figures embedded) from stored artifacts.

Reads what the stages wrote under a run folder and never refits:

* ``data/`` — ``study.parquet``, ``simulation.json`` and, for simulated studies, ``truth*.parquet``
* ``identify/`` — ``estimates.parquet``, ``trajectories.parquet``, ``validation.parquet``, ``identify.json``
* ``identify_true_torque/`` — the same from the true torques (simulated studies only)
* ``identify_true_torque_exogenous/`` — the same with the paper's exogenous-u_A likelihood
* ``compare.json`` — the Wilcoxon tests

Sections whose artifacts are missing are left out with a note.
"""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from pipelines import report_adequacy  # noqa: E402
from pipelines.io import write_text_atomic  # noqa: E402

MC_COLOR = "#c0392b"  # red, as in the paper's Fig. 6
SC_COLOR = "#27ae60"  # green

CSS = """
body { font-family: system-ui, sans-serif; max-width: 1100px; margin: 2em auto; color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; } h2 { border-bottom: 1px solid #ccc; padding-bottom: .2em; margin-top: 2em; }
table { border-collapse: collapse; margin: .8em 0; font-size: .92em; }
th, td { border: 1px solid #ccc; padding: .25em .6em; text-align: right; }
th { background: #f3f3f3; } td.l, th.l { text-align: left; }
.note { color: #666; font-size: .9em; } figure { margin: 1em 0; } figcaption { color: #444; font-size: .9em; }
.ok { color: #1e7e34; font-weight: bold; } .bad { color: #b02a37; font-weight: bold; }
div.verdict { padding: .8em 1em; border-radius: 4px; margin: 1em 0; font-size: 1.05em; }
div.verdict.ok { background: #e8f5e9; border: 1px solid #1e7e34; font-weight: normal; color: #222; }
div.verdict.bad { background: #fdecea; border: 2px solid #b02a37; font-weight: normal; color: #222; }
div.verdict.warn { background: #fff8e1; border: 1px solid #b08900; }
"""


def _fig_html(fig, caption: str) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    return (f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}" style="max-width:100%">'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def _table(df: pd.DataFrame, fmt: dict | None = None, left: tuple = ()) -> str:
    fmt = fmt or {}
    head = "".join(f'<th class="{"l" if c in left else ""}">{html.escape(str(c))}</th>' for c in df.columns)
    rows = []
    for _, r in df.iterrows():
        cells = []
        for c in df.columns:
            v = r[c]
            f = fmt.get(c)
            s = f(v) if f else (f"{v:.4g}" if isinstance(v, (float, np.floating)) else str(v))
            cells.append(f'<td class="{"l" if c in left else ""}">{html.escape(s)}</td>')
        rows.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>"


def _read(path: Path):
    if not path.exists():
        return None
    if path.suffix == ".json":
        return json.loads(path.read_text())
    return pd.read_parquet(path)


# --------------------------------------------------------------------------- sections


def section_design(root: Path, sim: dict | None, ident_meta: dict | None) -> str:
    parts = ["<h2>Study design</h2>"]
    if sim:
        pop = sim["population"]
        parts.append(
            f"<p>Simulated experiment: {sim['n_subjects']} subjects, each a {sim['run_seconds'] / 60:g}-minute run in "
            "manual control (MC) and one in shared control (SC) in random order, sampled at 100 Hz; encoder "
            f"{sim['encoder_counts_per_revolution']} increments per revolution; seed {sim['seed']}. "
            + _human_text(sim.get("human", {}).get("name", "maxent")) + "</p>"
        )
        rows = [
            ("median θ1 = q11/R in MC (1/rad²)", np.exp(pop["log_theta1_mc"])),
            ("between-subject SD of log θ1", pop["sd_log_theta1"]),
            ("mean SC shift β of log θ1", pop["beta"]),
            ("between-subject SD of the shift", pop["sd_change"]),
            ("median R in MC (1/(N·m)²)", np.exp(pop["log_R"])),
            ("between-subject SD of log R", pop["sd_log_R"]),
            ("mean SC shift of log R", pop["gamma"]),
            ("θ2 = q22/R", pop["theta2"]),
        ]
        parts.append("<p>Population of the simulated subjects:</p>")
        parts.append(_table(pd.DataFrame(rows, columns=["parameter", "value"]), left=("parameter",)))
        if "assistant_alone" in sim:
            a = sim["assistant_alone"]
            parts.append(
                "<p>The MPC assistant (θ_A = [5, 0, 1], N_P = 50 × 0.02 s) alone, nobody steering, over a whole run: "
                f"tracking error RMS {a['run']['error_rms_rad']:.3f} rad (peak {a['run']['error_peak_rad']:.3f}) "
                f"against a reference of RMS {a['run']['reference_rms_rad']:.3f} rad, with torque RMS "
                f"{a['run']['u_A_rms_Nm']:.3f} N·m (peak {a['run']['u_A_peak_Nm']:.3f}): it tracks, but not "
                "perfectly — the paper's “slight assistance”.</p>"
            )
    if ident_meta:
        s = ident_meta["settings"]
        win = ("the whole run" if s["window_start"] is None
               else f"{s['window_start']:g} s to {s['window_start'] + s['window_seconds']:g} s")
        parts.append(
            f"<p>Identification window: {win}; the human's plan looks {s['preview']:g} s past the window "
            "(0 would be the paper's horizon exactly; see the README); in SC the human "
            + ("plans with the assistant's feedback law (the simulated humans' own model)"
               if s.get("assistant_model", "exogenous") == "feedback"
               else "takes the recorded u_A as a known input (the paper's Eq. 15-16)")
            + f"; velocity and torque reconstructed from the angle where missing (margin {s['margin']:g} s).</p>"
        )
    return "".join(parts)


def _human_text(name: str) -> str:
    """What the simulated human is, in words (models/humans.py has the details and sources)."""
    if name == "maxent":
        return ("The simulated human is the max-ent LQ agent; in SC it knows the assistant's law and plans on the "
                "wheel the assistant's state feedback closes, with its reference feedforward as a known input, while "
                "the assistant (re-solved every 10 ms) reacts to the actual state.")
    return (f"<b>The simulated human is <code>{html.escape(name)}</code>, a negative control that is not the max-ent "
            "LQ agent the likelihood assumes</b> (<code>models/humans.py</code>: perceptual delay, neuromuscular lag, "
            "motor noise or a crossover-model operator, with magnitudes from the manual-control literature). "
            + ("Its cost parameters below are those of its LQ planner." if name != "crossover" else
               "It is not an LQ controller: it has no cost θ, so the population below is unused."))


def section_reference(study: pd.DataFrame, ident_meta: dict | None) -> str:
    first = study.groupby(["subject", "condition"], sort=False).head(10**9)
    key = study.iloc[0][["subject", "condition"]]
    seg = first[(first.subject == key.subject) & (first.condition == key.condition)]
    t, ref = seg["t"].to_numpy(), seg["angle_ref"].to_numpy()
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.2), gridspec_kw={"width_ratios": [2, 1]})
    start = ident_meta["settings"]["window_start"] if ident_meta else None
    length = ident_meta["settings"]["window_seconds"] if ident_meta else None
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
    return "<h2>Reference trajectory</h2>" + _fig_html(
        fig, "Reference angle shown to every subject in both conditions; grey: the 15-s analysis window.")


def section_histogram(est: pd.DataFrame) -> str:
    fig, ax = plt.subplots(figsize=(7, 3.6))
    vals = est["theta1"].to_numpy()
    bins = np.geomspace(vals.min() / 1.2, vals.max() * 1.2, 25)
    for c, col in (("MC", MC_COLOR), ("SC", SC_COLOR)):
        ax.hist(est.loc[est.condition == c, "theta1"], bins=bins, alpha=0.6, color=col, label=c)
    ax.set_xscale("log")
    ax.set_xlabel("identified θ1 = q11/R (1/rad²)")
    ax.set_ylabel("subjects")
    ax.legend()
    return _fig_html(fig, "Histogram of the identified normalized angle weight θ1 in MC and SC (Fig. 5).")


def section_wilcoxon(cmp: dict) -> str:
    rows = []
    for col in ("theta1", "theta2"):
        r = cmp[col]
        rows.append({
            "parameter": {"theta1": "θ1 = q11/R", "theta2": "θ2 = q22/R"}[col],
            "pairs": r["n_pairs"], "N (non-zero)": r["n"], "W+": r["w_plus"], "W−": r["w_minus"], "T": r["T"],
            "exact p (two-sided)": r["p_value"],
            f"critical T at α = {r['alpha']:g}": "–" if r["critical_value"] is None else r["critical_value"],
            "reject H0": "yes" if r["reject"] else "no",
            "rank-biserial r": r["rank_biserial"],
            "median SC − MC": r["median_difference"],
        })
    df = pd.DataFrame(rows)
    txt = ("<p>Wilcoxon matched-pairs signed-rank test of SC against MC (the paper's test). The paper reports "
           "T = 3 &lt; 195 = P(0.1; 42) for θ1.</p>")
    if cmp.get("unpaired_subjects"):
        txt += f"<p class='note'>Left out (one condition only): {', '.join(cmp['unpaired_subjects'])}</p>"
    return txt + _table(df, fmt={"exact p (two-sided)": lambda v: f"{v:.3g}"}, left=("parameter",))


def section_fig6(traj: pd.DataFrame, subject: str) -> str:
    d = traj[traj.subject == subject]
    if d.empty:
        return f"<p class='note'>Subject {html.escape(subject)} is not in the study.</p>"
    fig, axes = plt.subplots(3, 2, figsize=(12, 7.5), sharex="col")
    for j, (cond, col) in enumerate((("MC", MC_COLOR), ("SC", SC_COLOR))):
        s = d[d.condition == cond]
        if s.empty:
            continue
        t = s["t"].to_numpy()
        for i, (q, label) in enumerate((("angle", "angle φ (rad)"), ("velocity", "velocity φ̇ (rad/s)"),
                                        ("u_H", "human torque u_H (N·m)"))):
            ax = axes[i, j]
            ax.plot(t, s[q], color=col, lw=0.9, label=f"measured {cond}" + (" (reconstructed)" if q != "angle" else ""))
            ax.plot(t, s[f"pred_mc_{q}"], "--", color="#7f1d1d", lw=1.1, label="optimal control with θ_MC")
            ax.plot(t, s[f"pred_sc_{q}"], "--", color="#14532d", lw=1.1, label="optimal control with θ_SC")
            if q == "angle":
                ax.plot(t, s["angle_ref"], color="#999", lw=0.8, label="reference")
            ax.set_ylabel(label)
            if i == 0:
                ax.set_title(f"{subject}, {cond} data")
                ax.legend(fontsize=7, loc="upper right")
        axes[2, j].set_xlabel("time t (s)")
    return _fig_html(fig, f"Subject {subject}: measured trajectories beside those that forward optimal control "
                          "generates with θ_MC and θ_SC (Fig. 6).")


def section_cross_prediction(val: pd.DataFrame) -> str:
    sc = val[val.condition == "SC"].dropna()
    mc = val[val.condition == "MC"].dropna()
    worse_u = float((sc.rmse_uH_theta_mc > sc.rmse_uH_theta_sc).mean()) if len(sc) else float("nan")
    worse_a = float((sc.rmse_angle_theta_mc > sc.rmse_angle_theta_sc).mean()) if len(sc) else float("nan")
    summary = pd.DataFrame([
        {"data": "SC", "prediction": "θ_MC", "angle RMSE (rad)": sc.rmse_angle_theta_mc.mean(),
         "u_H RMSE (N·m)": sc.rmse_uH_theta_mc.mean()},
        {"data": "SC", "prediction": "θ_SC", "angle RMSE (rad)": sc.rmse_angle_theta_sc.mean(),
         "u_H RMSE (N·m)": sc.rmse_uH_theta_sc.mean()},
        {"data": "MC", "prediction": "θ_MC", "angle RMSE (rad)": mc.rmse_angle_theta_mc.mean(),
         "u_H RMSE (N·m)": mc.rmse_uH_theta_mc.mean()},
        {"data": "MC", "prediction": "θ_SC", "angle RMSE (rad)": mc.rmse_angle_theta_sc.mean(),
         "u_H RMSE (N·m)": mc.rmse_uH_theta_sc.mean()},
    ])
    txt = (f"<p>Mean over subjects of the RMSE between forward optimal control and the data. For {worse_u:.0%} of "
           f"the subjects θ_MC predicts the SC torque worse than θ_SC does (angle: {worse_a:.0%}). The torque "
           "RMSE includes the human's max-ent variability, which no deterministic prediction explains.</p>")
    per = sc[["subject", "rmse_angle_theta_mc", "rmse_angle_theta_sc", "rmse_uH_theta_mc", "rmse_uH_theta_sc"]]
    per = per.rename(columns={"rmse_angle_theta_mc": "SC angle, θ_MC (rad)", "rmse_angle_theta_sc": "SC angle, θ_SC (rad)",
                              "rmse_uH_theta_mc": "SC u_H, θ_MC (N·m)", "rmse_uH_theta_sc": "SC u_H, θ_SC (N·m)"})
    return (txt + _table(summary, left=("data", "prediction"))
            + "<details><summary>Per subject (SC data)</summary>" + _table(per, left=("subject",)) + "</details>")


def section_reconstruction(traj: pd.DataFrame, truth_traj: pd.DataFrame | None) -> str:
    if truth_traj is None:
        return "<p class='note'>No ground truth: reconstruction error not available for recorded data.</p>"
    m = traj.merge(truth_traj.rename(columns={"angle": "true_angle", "velocity": "true_velocity", "u_H": "true_u_H"}),
                   on=["subject", "condition", "t"], how="left")
    rows = []
    for c in ("MC", "SC"):
        s = m[m.condition == c]
        per = s.groupby("subject")
        e_v = per.apply(lambda g: np.sqrt(np.mean((g.velocity - g.true_velocity) ** 2)), include_groups=False)
        e_u = per.apply(lambda g: np.sqrt(np.mean((g.u_H.iloc[:-1] - g.true_u_H.iloc[:-1]) ** 2)), include_groups=False)
        sd_u = per.apply(lambda g: g.true_u_H.iloc[:-1].std(), include_groups=False)
        sd_r = per.apply(lambda g: g.u_H.iloc[:-1].std(), include_groups=False)
        corr = per.apply(lambda g: np.corrcoef(g.u_H.iloc[:-1], g.true_u_H.iloc[:-1])[0, 1], include_groups=False)
        rows.append({"condition": c, "velocity RMSE (rad/s)": e_v.mean(), "u_H RMSE (N·m)": e_u.mean(),
                     "true u_H SD (N·m)": sd_u.mean(), "reconstructed u_H SD (N·m)": sd_r.mean(),
                     "correlation": corr.mean()})
    s = m[(m.subject == m.subject.iloc[0]) & (m.condition == "SC")].iloc[:300]
    fig, ax = plt.subplots(figsize=(10, 3))
    ax.plot(s.t, s.true_u_H, color="#555", lw=0.8, label="true u_H")
    ax.plot(s.t, s.u_H, color=SC_COLOR, lw=1.2, label="reconstructed from the encoder angle")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("human torque u_H (N·m)")
    ax.legend(fontsize=8)
    txt = ("<p>Velocity and torque are reconstructed from the quantized angle by a Kalman/RTS smoother of the "
           "plant (white plus slowly wandering torque, variances by marginal likelihood). Means over subjects of the "
           "per-segment errors in the analysis window:</p>")
    return txt + _table(pd.DataFrame(rows), left=("condition",)) + _fig_html(
        fig, "First 3 s of one SC window: the torque variability whose effect stays below the encoder's "
             "resolution is not recovered; the reconstruction is smoother than the truth.")


def section_truth(est: pd.DataFrame, truth: pd.DataFrame, est_true: pd.DataFrame | None,
                  est_paper: pd.DataFrame | None = None) -> str:
    m = est.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))
    sources = [("from encoder angle", m)]
    if est_true is not None:
        sources.append(("from true torques", est_true.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))))
    extra = []
    if est_paper is not None:
        extra.append(("from true torques, u_A exogenous (paper)",
                      est_paper.merge(truth, on=["subject", "condition"], suffixes=("", "_true"))))
    rows = []
    for label, d in sources + extra:
        for c in ("MC", "SC"):
            s = d[d.condition == c]
            rows.append({
                "estimates": label, "condition": c,
                "Spearman θ1": spearmanr(s.theta1, s.theta1_true)[0],
                "mean log(θ1/θ1_true)": np.mean(np.log(s.theta1 / s.theta1_true)),
                "mean log(R/R_true)": np.mean(np.log(s.R / s.R_true)),
                "θ2 > 0 (of N)": f"{int((s.theta2 > 0).sum())} of {len(s)}",
                "median SE log θ1": np.median(s.se_log_theta1),
            })
        w = d.pivot_table(index="subject", columns="condition", values=["theta1", "theta1_true"])
        if {"MC", "SC"} <= set(w.columns.get_level_values(1)):
            shift = np.log(w[("theta1", "SC")] / w[("theta1", "MC")]).mean()
            shift_true = np.log(w[("theta1_true", "SC")] / w[("theta1_true", "MC")]).mean()
            rows.append({"estimates": label, "condition": "SC − MC",
                         "mean log(θ1/θ1_true)": shift - shift_true,
                         "Spearman θ1": np.nan, "mean log(R/R_true)": np.nan, "θ2 > 0 (of N)": "",
                         "median SE log θ1": np.nan})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for ax, (label, d) in zip(axes, sources + [(None, None)] * (2 - len(sources))):
        if d is None:
            ax.axis("off")
            continue
        for c, col in (("MC", MC_COLOR), ("SC", SC_COLOR)):
            s = d[d.condition == c]
            ax.errorbar(s.theta1_true, s.theta1, yerr=[s.theta1 * (1 - np.exp(-s.se_log_theta1)),
                                                         s.theta1 * (np.exp(s.se_log_theta1) - 1)],
                        fmt="o", ms=3, color=col, label=c, alpha=0.8)
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
    txt = ("<p>The simulator's true parameters against the estimates (error bars: ±1 SE from the observed "
           "information). The row “SC − MC” gives the error of the mean log shift, the quantity the hypothesis is "
           "about. Estimates from the true torques show what the likelihood itself does; estimates from the angle "
           "add what the reconstruction costs. The simulated SC human plans with the assistant's feedback law, "
           "and so does the likelihood by default. The rows “u_A exogenous (paper)” use the paper's Eq. 15-16 "
           "instead, which takes the recorded u_A as known in advance although the assistant reacts to the "
           "human's own variability: the shift of SC θ1 there is what that mismatch costs.</p>")
    return txt + _table(pd.DataFrame(rows), left=("estimates", "condition")) + _fig_html(
        fig, "True vs estimated θ1 per subject and condition.")


def section_identification(est: pd.DataFrame, meta: dict | None) -> str:
    conv = int(est.converged.sum())
    txt = f"<p>{conv} of {len(est)} optimizations converged (SLSQP, exact gradient)."
    if meta:
        t = meta["timing_s"]
        txt += (f" Reconstruction took {t['reconstruct_s']:.2f} s and the optimization {t['optimize_s']:.2f} s for "
                f"{t['segments']} segments.")
    txt += "</p>"
    cols = ["subject", "condition", "theta1", "se_log_theta1", "theta2", "R", "se_log_R", "loglik", "converged",
            "iterations"]
    return txt + "<details><summary>All estimates</summary>" + _table(est[cols], left=("subject", "condition")) + "</details>"


def _sbc_pits(folder: Path, summary: dict) -> dict:
    from models.sbc import pit_from_rank

    n, L = summary["replications"], summary["L"]
    reps = [json.loads((folder / "reps" / f"rep_{i:05d}.json").read_text()) for i in range(n)]
    return {name: pit_from_rank([r["ranks"][name] for r in reps], L, [r["pit_u"][name] for r in reps])
            for name in summary["parameters"]}


def section_calibration(cal_dir: Path) -> str:
    from models.sbc import ecdf_band

    parts = []
    for level in ("unit", "study"):
        good_dir, bad_dir = cal_dir / level, cal_dir / f"{level}-negative"
        good = _read(good_dir / "summary.json")
        if good is None:
            continue
        bad = _read(bad_dir / "summary.json")
        parts.append(f"<h3>{level.capitalize()} level</h3>")
        cfg = good["config"]
        design = (f"{cfg['n_subjects']} subjects × 2 conditions, " if level == "study" else "one unit, ") + \
                 f"K = {cfg['K']} samples ({cfg['K'] / 100:g} s), {cfg['chains']} chains × {cfg['draws']} draws " \
                 f"after {cfg['tune']} tuning, ranks against L = {good['L']} thinned draws"
        verdict = lambda sm: ('<span class="ok">passes</span>' if sm["passed"]  # noqa: E731
                              else '<span class="bad">fails</span>')
        txt = (f"<p>{good['replications']} replications ({design}). Uniformity: Kolmogorov-Smirnov test of the "
               f"randomized PIT per parameter at {good['family_alpha']:g}/{len(good['parameters'])} (family-wise "
               f"false-failure rate {good['family_alpha']:g}). Correct model: {verdict(good)}")
        if bad:
            txt += f"; negative control ({html.escape(str(bad['negative_control']))}): {verdict(bad)}"
            txt += " (it must fail)"
        wall = good.get("wall_seconds_total", good["wall_seconds_this_run"])
        txt += (f". Measured wall time {wall:.0f} s on the local cluster (sum of the per-replication fitting times "
                f"{good['fit_seconds_total']:.0f} s); {good['divergences']} divergent transitions in all fits.</p>")
        parts.append(txt)
        rows = []
        for tag, sm in (("correct", good), ("negative control", bad)):
            if sm is None:
                continue
            for name, p in sm["parameters"].items():
                rows.append({"fit": tag, "parameter": name, "KS p": p["p_value"], "α": p["alpha"],
                             "uniform": "yes" if p["passed"] else "no",
                             **{f"cov {k}": v for k, v in p["coverage"].items()},
                             "contraction": p["contraction"], "ESS < L": p["low_ess"]})
        parts.append(_table(pd.DataFrame(rows), fmt={"KS p": lambda v: f"{v:.3g}", "α": lambda v: f"{v:.3g}"},
                            left=("fit", "parameter")))
        pits = {"correct": _sbc_pits(good_dir, good)}
        if bad:
            pits["negative control"] = _sbc_pits(bad_dir, bad)
        names = list(good["parameters"])
        fig, axes = plt.subplots(2, len(names), figsize=(3.6 * len(names), 6), squeeze=False)
        n = good["replications"]
        z, lo, hi = ecdf_band(n, 0.05)
        nb = 20
        for j, name in enumerate(names):
            ax = axes[0, j]
            for (tag, d), col in zip(pits.items(), ("#1f77b4", "#b02a37")):
                ax.hist(d[name], bins=nb, range=(0, 1), histtype="step", color=col, lw=1.4, label=tag)
            # 99 % band of a bin count under uniformity
            from scipy.stats import binom

            ax.axhspan(binom.ppf(0.005, n, 1 / nb), binom.ppf(0.995, n, 1 / nb), color="#ddd", zorder=0)
            ax.set_title(name)
            ax.set_xlabel("normalized rank (PIT)")
            ax.set_ylabel("replications per bin")
            if j == 0:
                ax.legend(fontsize=7)
            ax = axes[1, j]
            ax.fill_between(z, lo, hi, color="#ddd", label="95 % simultaneous band")
            for (tag, d), col in zip(pits.items(), ("#1f77b4", "#b02a37")):
                srt = np.sort(d[name])
                ax.plot(z, np.searchsorted(srt, z, side="right") / len(srt) - z, color=col, lw=1.2, label=tag)
            ax.axhline(0, color="#888", lw=0.6)
            ax.set_xlabel("PIT")
            ax.set_ylabel("ECDF − uniform CDF")
            if j == 0:
                ax.legend(fontsize=7)
        parts.append(_fig_html(fig, f"{level.capitalize()}-level SBC: rank histograms (grey: 99 % band per bin) and "
                                    "ECDF differences (grey: simultaneous 95 % band, Säilynoja et al. 2022)."))
    if not parts:
        return "<p class='note'>No calibration results yet: run <code>scioc calibrate</code>.</p>"
    return "".join(parts)


def build_report(root, *, subject: str | None = None, out=None, calibration=None, title: str | None = None) -> Path:
    """Assemble ``index.html`` from the artifacts under ``root``.

    Parameters
    ----------
    root : str or Path
        Run folder (as written by ``scioc run``).
    subject : str, optional
        Subject for the Fig. 6 trajectories (default: the third subject, as in the paper).
    out : str or Path, optional
        Report path (default ``root / "index.html"``).
    title : str, optional
        The run's name in the heading (default: the folder's name).
    """
    root = Path(root)
    sim = _read(root / "data" / "simulation.json")
    study = _read(root / "data" / "study.parquet")
    truth = _read(root / "data" / "truth.parquet")
    truth_traj = _read(root / "data" / "truth_trajectories.parquet")
    est = _read(root / "identify" / "estimates.parquet")
    traj = _read(root / "identify" / "trajectories.parquet")
    val = _read(root / "identify" / "validation.parquet")
    meta = _read(root / "identify" / "identify.json")
    est_true = _read(root / "identify_true_torque" / "estimates.parquet")
    est_paper = _read(root / "identify_true_torque_exogenous" / "estimates.parquet")
    cmp = _read(root / "compare.json")
    fit_res = _read(root / "fit" / "contrasts.json")
    adequacy = (meta or {}).get("adequacy")
    fit_adequacy = (fit_res or {}).get("adequacy")
    power = _read(root.parent / "power" / "power.json")
    if est is None:
        raise FileNotFoundError(f"{root / 'identify' / 'estimates.parquet'}: no estimates; run `scioc identify` first")
    subjects = sorted(est.subject.unique())
    subject = subject or (subjects[2] if len(subjects) > 2 else subjects[0])

    title = title or root.name
    body = [f"<h1>scioc report: {html.escape(title)}</h1>",
            "<p>Identification of human steering cost functions in manual and shared control, following Inga et al. "
            "(SMC 2018). Every number here was produced by <code>scioc</code> from the artifacts beside this file.</p>"]
    body.append(report_adequacy.headline(adequacy, fit_adequacy))
    body.append(section_design(root, sim, meta))
    if study is not None:
        body.append(section_reference(study, meta))
    body.append("<h2>Identified parameters and the paper's test</h2>")
    body.append(section_histogram(est))
    body.append(report_adequacy.caveat(adequacy))
    body.append(section_wilcoxon(cmp) if cmp else "<p class='note'>No compare.json: run `scioc compare`.</p>")
    if (root / "fit").exists():
        from pipelines.report_bayes import section_bayes

        body.append("<h2>Hierarchical Bayesian model</h2>")
        body.append(report_adequacy.caveat(fit_adequacy if fit_adequacy else adequacy))
        body.append(section_bayes(root))
    body.append(report_adequacy.section(est, adequacy, power))
    body.append("<h2>Model validation (Fig. 6)</h2>")
    if traj is not None:
        body.append(section_fig6(traj, subject))
    if val is not None:
        body.append(section_cross_prediction(val))
    body.append("<h2>Data acquisition: reconstruction from the angle</h2>")
    if traj is not None:
        body.append(section_reconstruction(traj, truth_traj))
    if truth is not None and truth["theta1"].notna().any():  # the crossover operator has no cost θ
        body.append("<h2>Ground truth vs estimates</h2>")
        body.append(section_truth(est, truth, est_true, est_paper))
    body.append("<h2>Identification details</h2>")
    body.append(section_identification(est, meta))
    body.append("<h2>Simulation-based calibration</h2>")
    body.append(section_calibration(Path(calibration) if calibration else root.parent / "calibration"))
    if sim and "versions" in sim:
        v = sim["versions"]
        body.append("<h2>Provenance</h2><p class='note'>" + html.escape(
            ", ".join(f"{k} {val_}" for k, val_ in v.items() if val_)) + "</p>")
    doc = (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>scioc report: {html.escape(title)}"
           f"</title><style>{CSS}</style></head><body>{''.join(body)}</body></html>\n")
    path = Path(out) if out else root / "index.html"
    write_text_atomic(path, doc)
    return path
