"""The experiment a run recorded, and the words the report uses for it: levels, assistants, rig, protocol.

The report follows the run's experiment (:func:`run_experiment`), not the paper's literals; the other
functions turn a :class:`scioc.models.design.Design` into phrases, with the paper's words for its labels
("manual control (MC)", "shared control (SC)").
"""

from __future__ import annotations

from typing import NamedTuple

from scioc.models.design import STUDY, AssistantSpec, Design
from scioc.pipelines.experiment import experiment_hash, parse_experiment

#: The paper's names of its two levels, used when an experiment has exactly those labels.
PAPER_NAMES = {"MC": "manual control", "SC": "shared control"}


class RunExperiment(NamedTuple):
    """The experiment of a run folder."""

    design: Design
    source: str  # where the report read it, as a phrase: "as recorded in identify/identify.json"
    sha256: str  # the experiment's hash as recorded (computed for the built-in study)
    file: str | None  # the experiment file the stage read (None: the built-in study)


def run_experiment(meta: dict | None, sim: dict | None) -> RunExperiment:
    """The experiment recorded in ``identify.json`` (``meta``), else ``simulation.json`` (``sim``), else the paper's."""
    for side, name in ((meta, "identify/identify.json"), (sim, "data/simulation.json")):
        if side and side.get("experiment"):
            design = parse_experiment(side["experiment"], f"{name} (experiment)")
            return RunExperiment(design, f"as recorded in {name}",
                                 side.get("experiment_sha256") or experiment_hash(design),
                                 side.get("experiment_file"))
    return RunExperiment(STUDY, "the built-in paper's study (the run recorded no experiment)",
                         experiment_hash(STUDY), None)


def paper_labels(design: Design) -> bool:
    """Whether the levels are the paper's MC (baseline, unassisted) and SC (assisted)."""
    return (design.ordered_levels == ("MC", "SC") and design.assistant("MC") is None
            and design.assistant("SC") is not None)


def level_name(design: Design, level: str) -> str:
    """``level`` as prose: "manual control (MC)" with the paper's labels, else the label itself."""
    return f"{PAPER_NAMES[level]} ({level})" if paper_labels(design) else level


def key(level: str) -> str:
    """The suffix of a level's columns in ``trajectories.parquet`` and ``validation.parquet``."""
    return level.lower()


def assistant_text(spec: AssistantSpec | None) -> str:
    """An assistant's law in one line (units: rad, rad/s, N·m)."""
    if spec is None:
        return "none (u_A = 0)"
    if spec.kind == "mpc":
        return (f"MPC, θ_A = [{', '.join(f'{v:g}' for v in spec.theta)}], N_P = {spec.horizon} × {spec.step_s:g} s, "
                f"re-solved every {spec.period_s:g} s")
    g0, g1 = spec.gain
    return (f"linear, u_A = −{g0:g}·φ − {g1:g}·φ̇ + {spec.reference_gain:g}·φ_ref "
            f"(gains {g0:g} N·m/rad, {g1:g} N·m·s/rad)")


def assisted(design: Design) -> list[str]:
    """The levels with an assistant, in the experiment's order."""
    return [v for v in design.ordered_levels if design.assistant(v) is not None]


def joined(items, last: str = "and") -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    items = list(items)
    if len(items) <= 1:
        return "".join(items)
    return ", ".join(items[:-1]) + f" {last} " + items[-1]


def duration(seconds: float) -> str:
    """A run's length as an adjective: "4-minute", "12-s"."""
    return f"{seconds / 60:g}-minute" if seconds >= 60 and seconds % 60 == 0 else f"{seconds:g}-s"


def window_text(design: Design) -> str:
    """The analysis window in words: "210 s to 225 s" or "the whole trial"."""
    if design.whole:
        return "every trial whole"
    return f"{design.window_start:g} s to {design.window_start + design.window_seconds:g} s"


def window_noun(design: Design) -> str:
    """What one segment covers: "the 15-s window" or "the whole trial"."""
    return "the whole trial" if design.whole else f"the {design.window_seconds:g}-s window"


def encoder_text(design: Design) -> str:
    """The angle sensor: "encoder 40000 increments per revolution" or "angle not quantized"."""
    if design.encoder_counts:
        return f"encoder {design.encoder_counts} increments per revolution"
    return "angle not quantized (no encoder resolution)"


def wheel_text(design: Design) -> str:
    """The wheel's parameters (paper Eq. 18), naming Table I when they are the paper's."""
    w = design.wheel
    text = f"inertia {w.inertia:g} kg·m², spring {w.spring:g} N·m/rad, damper {w.damper:g} N·m·s/rad"
    return text + (" (the paper's Table I)" if w == STUDY.wheel else "")


def acquisition(design: Design, reconstructed: bool) -> tuple[str, str]:
    """The acquisition chain the adequacy bootstrap repeats: (noun phrase, clause), e.g. ("the same encoder and
    reconstruction", "quantized by the same encoder and reconstructed by the same smoother")."""
    nouns = (["encoder"] if design.encoder_counts else []) + (["reconstruction"] if reconstructed else [])
    clauses = ((["quantized by the same encoder"] if design.encoder_counts else [])
               + (["reconstructed by the same smoother"] if reconstructed else []))
    if not nouns:
        return "the same unquantized angle and recorded torque", "with the angle unquantized and the torque as recorded"
    return "the same " + " and ".join(nouns), " and ".join(clauses)


def contrast_label(design: Design, level: str) -> str:
    """A contrast as the tables name it: "SC − MC"."""
    return f"{level} − {design.baseline}"


__all__ = ["PAPER_NAMES", "RunExperiment", "run_experiment", "paper_labels", "level_name", "key", "assistant_text",
           "assisted", "joined", "duration", "window_text", "window_noun", "encoder_text", "wheel_text",
           "acquisition", "contrast_label"]
