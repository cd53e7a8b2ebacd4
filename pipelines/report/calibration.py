"""The report's simulation-based calibration section, from ``scioc calibrate``'s folders (never reruns)."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import xarray as xr
from markupsafe import Markup

from scioc.models.design import STUDY
from scioc.pipelines.experiment import parse_experiment
from scioc.pipelines.report import figures
from scioc.pipelines.report.render import figure, number, read_artifact, render, table

#: The calibration levels, in the order the report shows them.
LEVELS = ("unit", "study")


def _tree(folder: Path):
    """A calibration's DataTree (``sbc.nc``), or None if the folder has none."""
    path = folder / "sbc.nc"
    return xr.open_datatree(path, engine="h5netcdf").load() if path.exists() else None


def section_calibration(cal_dir: Path) -> Markup:
    """Per level: the verdicts, the per-quantity table and the rank plots, with the negative control beside."""
    levels = []
    for level in LEVELS:
        good_dir, bad_dir = cal_dir / level, cal_dir / f"{level}-negative"
        good = read_artifact(good_dir / "summary.json")
        if good is None:
            continue
        bad = read_artifact(bad_dir / "summary.json")
        cfg = good["config"]
        # The experiment calibrated (scioc calibrate --experiment); none recorded: the paper's study.
        exp = (parse_experiment(cfg["experiment"], f"{good_dir / 'summary.json'} (config.experiment)")
               if cfg.get("experiment") else STUDY)
        same = exp.dt == STUDY.dt and exp.ordered_levels == STUDY.ordered_levels
        rig = "" if same else f" at {exp.rate_hz:g} Hz, levels {', '.join(exp.ordered_levels)}"
        design = ((f"{cfg['n_subjects']} subjects × {len(exp.levels)} conditions, " if level == "study"
                   else "one unit, ")
                  + f"K = {cfg['K']} samples ({cfg['K'] * exp.dt:g} s{rig}), {cfg['chains']} chains × "
                  f"{cfg['draws']} draws after {cfg['tune']} tuning, ranks against L = {good['L']} thinned draws")
        rows = []
        for tag, sm in (("correct", good), ("negative control", bad)):
            if sm is None:
                continue
            for name, p in sm["parameters"].items():
                rows.append({"fit": tag, "parameter": name, "KS p": p["p_value"], "α": p["alpha"],
                             "uniform": "yes" if p["passed"] else "no", "pot_c p (ArviZ)": p.get("pot_c_p_value"),
                             **{f"cov {k}": v for k, v in p["coverage"].items()},
                             "contraction": p["contraction"], "ESS < L": p["low_ess"]})
        trees = {"correct": _tree(good_dir)}
        if bad:
            trees["negative control"] = _tree(bad_dir)
        figures_html = []
        if any(t is None for t in trees.values()):
            figures_html.append(render("note.html.j2", text=f"No sbc.nc in {good_dir} (results of an older scioc): "
                                                            "rerun scioc calibrate for the rank plots."))
        else:
            names = list(good["parameters"])
            figures_html.append(figure(
                figures.sbc_rank_histograms({k: t["pit"] for k, t in trees.items()}, names, good["replications"]),
                f"{level.capitalize()}-level SBC: rank histograms of the randomized PIT (grey: 99 % band of a bin "
                "count under uniformity)."))
            for tag, t in trees.items():
                figures_html.append(figure(
                    figures.sbc_ecdf(t),
                    f"{level.capitalize()}-level SBC, {tag} fit: ECDF of the PIT minus the uniform CDF "
                    "(arviz_plots.plot_ecdf_pit; p-value of ArviZ's pot_c uniformity test, marked points: the "
                    "largest contributions to a departure)."))
        levels.append({
            "name": level.capitalize(), "good": good, "bad": bad, "design": design,
            "wall": good.get("wall_seconds_total", good["wall_seconds_this_run"]),
            "table": table(pd.DataFrame(rows), fmt={"KS p": lambda v: f"{v:.3g}", "α": lambda v: f"{v:.3g}",
                                                    "pot_c p (ArviZ)": lambda v: number(v, ".3g")},
                           left=("fit", "parameter")),
            "figures": figures_html,
        })
    return render("calibration.html.j2", levels=levels)
