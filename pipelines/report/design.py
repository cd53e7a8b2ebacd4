"""The report's opening sections: the study design and the reference trajectory."""

from __future__ import annotations

import numpy as np
import pandas as pd
from markupsafe import Markup

from models.design import ASSISTANT_HORIZON, DT_ASSISTANT, THETA_ASSISTANT
from pipelines.report import figures
from pipelines.report.render import figure, render, table


def section_design(sim: dict | None, ident_meta: dict | None) -> Markup:
    """The simulated experiment (population, human, assistant alone) and the identification settings."""
    population = assistant = None
    if sim:
        pop = sim["population"]
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
        population = table(pd.DataFrame(rows, columns=["parameter", "value"]), left=("parameter",))
        assistant = (sim.get("assistant_alone") or {}).get("run")
    settings = window = None
    if ident_meta:
        settings = ident_meta["settings"]
        window = ("the whole run" if settings["window_start"] is None else
                  f"{settings['window_start']:g} s to {settings['window_start'] + settings['window_seconds']:g} s")
    return render("design.html.j2", sim=sim, human=(sim or {}).get("human", {}).get("name", "maxent"),
                  population=population, assistant=assistant,
                  theta_assistant=", ".join(f"{v:g}" for v in THETA_ASSISTANT), horizon=ASSISTANT_HORIZON,
                  dt_assistant=DT_ASSISTANT, settings=settings, window=window,
                  feedback=(settings or {}).get("assistant_model", "exogenous") == "feedback")


def section_reference(study: pd.DataFrame, ident_meta: dict | None) -> Markup:
    """The reference angle every subject saw, with the analysis window (Fig. 4)."""
    start = ident_meta["settings"]["window_start"] if ident_meta else None
    length = ident_meta["settings"]["window_seconds"] if ident_meta else None
    return Markup("<h2>Reference trajectory</h2>") + figure(
        figures.reference(study, start, length),
        "Reference angle shown to every subject in both conditions; grey: the 15-s analysis window.")
