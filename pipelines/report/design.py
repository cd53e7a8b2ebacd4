"""The report's opening sections: the experiment (rig, levels, protocol), the simulated study and the reference."""

from __future__ import annotations

import numpy as np
import pandas as pd
from markupsafe import Markup

from scioc.models.design import REFERENCE_DT, Design
from scioc.pipelines.report import figures
from scioc.pipelines.report.levels import (
    RunExperiment,
    assistant_text,
    assisted,
    duration,
    encoder_text,
    joined,
    level_name,
    paper_labels,
    wheel_text,
    window_noun,
    window_text,
)
from scioc.pipelines.report.render import figure, render, table


def _levels_table(design: Design) -> Markup:
    rows = [{"level": v, "role": "baseline" if v == design.baseline else f"compared with {design.baseline}",
             "assistant": assistant_text(design.assistant(v))} for v in design.ordered_levels]
    return table(pd.DataFrame(rows), left=("level", "role", "assistant"))


def _runs(design: Design, run_seconds: float, trials: int) -> str:
    """What each simulated subject did: "a 4-minute run in manual control (MC) and one in shared control (SC)"."""
    names = [level_name(design, v) for v in design.ordered_levels]
    if trials == 1 and len(names) == 2:
        return f"a {duration(run_seconds)} run in {names[0]} and one in {names[1]}"
    if trials == 1:
        return f"a {duration(run_seconds)} run in each of {joined(names)}"
    return f"{trials} trials of {run_seconds:g} s in each of {joined(names)}"


def _population(pop: dict, design: Design) -> Markup:
    base, others = design.baseline, design.contrasts
    betas = pop.get("betas") or [pop["beta"]] * len(others)
    rows = [(f"median θ1 = q11/R in {base} (1/rad²)", np.exp(pop["log_theta1_mc"])),
            ("between-subject SD of log θ1", pop["sd_log_theta1"])]
    if len(others) == 1:
        rows.append((f"mean {others[0]} shift β of log θ1", betas[0]))
    else:
        rows += [(f"mean shift β of log θ1, {v} − {base}", b) for v, b in zip(others, betas)]
    rows.append(("between-subject SD of the shift", pop["sd_change"]))
    r_note = "" if design.dt == REFERENCE_DT else (
        f", stated per {REFERENCE_DT:g}-s sample: per sample at {design.rate_hz:g} Hz it is "
        f"{design.r_scale:g} times this")
    rows += [(f"median R in {base} (1/(N·m)²{r_note})", np.exp(pop["log_R"])),
             ("between-subject SD of log R", pop["sd_log_R"]),
             (f"mean {others[0]} shift of log R" if len(others) == 1 else "mean shift of log R in every other level",
              pop["gamma"]),
             ("θ2 = q22/R", pop["theta2"])]
    return table(pd.DataFrame(rows, columns=["parameter", "value"]), left=("parameter",))


def _human(design: Design) -> str:
    """How the simulated max-ent human treats the assistants."""
    helped = assisted(design)
    if not helped:
        return "no level is assisted."
    specs = [design.assistant(v) for v in helped]
    periods = {s.period_s for s in specs}
    every = (f" (re-solved every {next(iter(periods)) * 1000:g} ms)"
             if all(s.kind == "mpc" for s in specs) and len(periods) == 1 else "")
    return (f"in {joined(helped)} it knows the assistant's law and plans on the wheel the assistant's state feedback "
            f"closes, with its reference feedforward as a known input, while the assistant{every} reacts to the "
            "actual state.")


def section_design(sim: dict | None, ident_meta: dict | None, exp: RunExperiment, *, trials: int = 1,
                   torque_measured: bool = False) -> Markup:
    """The experiment ``exp`` (rig, levels, assistants, analysis), the simulated study and the identification
    settings; ``trials``: the most of one unit; ``torque_measured``: u_H recorded, not reconstructed."""
    design = exp.design
    helped = assisted(design)
    rig = (f"Sampled at {design.rate_hz:g} Hz; wheel {wheel_text(design)}; {encoder_text(design)}; "
           + ("the human torque u_H is recorded (torque sensor) beside the angle" if torque_measured else
              "the angle only is recorded (no torque sensor): velocity and torque are reconstructed from it"))
    population = assistant = None
    runs = None
    if sim:
        runs = _runs(design, sim["run_seconds"], trials)
        population = _population(sim["population"], design)
        assistant = (sim.get("assistant_alone") or {}).get("run")
    settings = window = None
    if ident_meta:
        settings = ident_meta["settings"]
        window = ("every trial whole" if settings["window_start"] is None else
                  f"{settings['window_start']:g} s to {settings['window_start'] + settings['window_seconds']:g} s")
    mpc = design.assistant(helped[0]) if len(helped) == 1 and design.assistant(helped[0]).kind == "mpc" else None
    return render("design.html.j2", sim=sim, human=(sim or {}).get("human", {}).get("name", "maxent"),
                  rig=rig, levels=_levels_table(design), baseline=design.baseline, n_levels=len(design.levels),
                  contrasts=joined(design.contrasts), trials=trials,
                  names=joined(level_name(design, v) for v in design.ordered_levels), analysis=window_text(design),
                  preview=design.preview, exp=exp, runs=runs, sensor=torque_measured,
                  encoder=encoder_text(design), rate=design.rate_hz, human_plans=_human(design),
                  population=population, assistant=assistant, mpc=mpc, mpc_level=helped[0] if mpc else None,
                  mpc_theta=", ".join(f"{v:g}" for v in mpc.theta) if mpc else None,
                  settings=settings, window=window, helped=joined(helped),
                  feedback=(settings or {}).get("assistant_model", "exogenous") == "feedback",
                  paper=paper_labels(design))


def section_reference(study: pd.DataFrame, ident_meta: dict | None, design: Design) -> Markup:
    """The reference angle every subject saw, with the analysis window (Fig. 4); none when trials are analysed whole."""
    settings = (ident_meta or {}).get("settings")
    start = settings["window_start"] if settings else (None if design.whole else design.window_start)
    length = settings["window_seconds"] if settings else (None if design.whole else design.window_seconds)
    where = ("in every condition" if len(design.levels) > 2 else "in both conditions")
    shown = (f"grey: the {length:g}-s analysis window" if start is not None
             else f"{window_noun(design)} is analysed, no window")
    return Markup("<h2>Reference trajectory</h2>") + figure(
        figures.reference(study, start, length), f"Reference angle shown to every subject {where}; {shown}.")
