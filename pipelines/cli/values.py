"""The values of ``scioc``'s options: the argparse types that check them (exit 2 on a bad value) and the names
and defaults the parser offers, spelled out so that parsing imports no model code (tests hold each equal to its
source)."""

from __future__ import annotations

import argparse
import math

#: Shortest analysis window, s. Shorter windows leave θ unidentified: measured on a simulated
#: study, 0.02 s drives the optimizer to θ = ∞ and 0.05 s gives θ1 ≈ 1800 where longer
#: windows give 10-30.
MIN_WINDOW_SECONDS = 0.1
#: The study design's defaults (models.design.STUDY), spelled out so that parsing imports no model
#: code (tests/pipelines/cli/test_parser.py holds them equal): sample time, analysis window
#: (start, length), preview and run length, s.
SAMPLE_TIME, WINDOW, PREVIEW, RUN_SECONDS = 0.01, (210, 15), 2.0, 240.0
#: The longest preview, s (models.design.MAX_PREVIEW).
MAX_PREVIEW = 60.0
WINDOW_TEXT = f"{WINDOW[0]:g},{WINDOW[1]:g}"


def checked_number(kind, accept, wanted: str):
    """An argparse ``type`` that parses with ``kind`` and rejects values ``accept`` refuses (exit 2)."""

    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {wanted}; got {text!r}") from None
        if not accept(value):
            raise argparse.ArgumentTypeError(f"expected {wanted}; got {text!r}")
        return value

    return parse


positive_int = checked_number(int, lambda v: v >= 1, "a positive integer")
nonnegative_int = checked_number(int, lambda v: v >= 0, "an integer >= 0")
positive_seconds = checked_number(float, lambda v: math.isfinite(v) and v > 0, "a finite number of seconds > 0")
nonnegative_seconds = checked_number(float, lambda v: math.isfinite(v) and v >= 0, "a finite number of seconds >= 0")
preview_seconds = checked_number(float, lambda v: 0 <= v <= MAX_PREVIEW,
                                 f"a number of seconds >= 0 and at most {MAX_PREVIEW:g}")
significance_level = checked_number(float, lambda v: 0 < v < 1, "a significance level between 0 and 1")
finite_float = checked_number(float, math.isfinite, "a finite number")
nonnegative_float = checked_number(float, lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0")
acceptance = checked_number(float, lambda v: 0 < v < 1, "a target acceptance rate between 0 and 1")


def window_spec(text: str) -> str:
    """Check ``--window START,SECONDS`` at parse time; ``commands.window_settings`` splits it later."""
    usage = f"expected START,SECONDS in s (e.g. {WINDOW_TEXT}); got {text!r}"
    try:
        start, seconds = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(usage) from None
    if not (math.isfinite(start) and math.isfinite(seconds)):
        raise argparse.ArgumentTypeError(f"start and length must be finite numbers of seconds; got {text!r}")
    if seconds < MIN_WINDOW_SECONDS:
        raise argparse.ArgumentTypeError(
            f"a {seconds:g}-s window is too short to identify θ: it needs at least {MIN_WINDOW_SECONDS:g} s "
            f"({round(MIN_WINDOW_SECONDS / SAMPLE_TIME)} samples of {SAMPLE_TIME:g} s); got {text!r}")
    return text


# The names of models.humans.HUMANS, spelled out so parsing imports no model code (a test holds them equal).
HUMAN_NAMES = ("maxent", "delay", "lag", "coloured", "combined", "kbl", "crossover")

# The blocks of models.bayes.hierarchical.Parameterization and their defaults, spelled out so parsing imports
# no PyMC (a test holds them equal).
PARAMETERIZATION_BLOCKS = {"theta1_mc": "mean", "theta1_sc": "noncentred", "R_mc": "centred", "R_sc": "centred",
                           "theta2": "noncentred"}

# The names of the registered human models (scioc.pipelines.human_model), spelled out so parsing imports no model code (a test holds them
# equal), and the last delay of models.delayed.DELAY_GRID_S, s.
HUMAN_MODEL_NAMES = ("maxent", "delayed")
MAX_DELAY_S = 0.3
#: What ``scioc loglik`` evaluates the likelihood of (:data:`scioc.pipelines.loglik.LIKELIHOODS`, tested equal).
LIKELIHOOD_NAMES = ("torques", "angles")
#: The delayed model's baseline-R populations (:data:`scioc.models.bayes.delayed_model.R_POPULATIONS`, tested equal).
R_POPULATION_NAMES = ("lognormal", "policy_scale", "unpooled")
#: The forms of ρ (:data:`scioc.models.bayes.delayed_blocks.MOTOR_FORMS`, tested equal).
RHO_FORM_NAMES = ("centred", "noncentred", "folded", "folded_centred")
#: Points of the adequacy check at the posterior (:data:`scioc.pipelines.fit.checks.ADEQUACY_POINTS`, tested equal).
ADEQUACY_AT_NAMES = ("draw", "means")
ADEQUACY_AT_HELP = ("posterior point of the adequacy check (default draw: one joint posterior draw picked by the "
                     "adequacy seed; means: each parameter's posterior mean)")


def human_models_list(text: str) -> tuple:
    """``--human-model maxent,delayed`` of ``scioc run``: known names, none twice, maxent among them; in the order of the names."""
    names = [v.strip() for v in text.split(",") if v.strip()]
    unknown = [v for v in names if v not in HUMAN_MODEL_NAMES]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of {', '.join(HUMAN_MODEL_NAMES)}; "
                                         f"got {text!r}")
    if len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"a human model is named twice in {text!r}")
    primary = HUMAN_MODEL_NAMES[0]
    if primary not in names:
        raise argparse.ArgumentTypeError(f"the list must include {primary} (the run's identify, compare and fit are "
                                         f"the paper's model; the others run beside it); got {text!r}")
    return tuple(v for v in HUMAN_MODEL_NAMES if v in names)


def humans_list(text: str) -> tuple:
    """``scioc bench --humans maxent,kbl``: simulated humans by name, at least one, none unknown."""
    names = [v.strip() for v in text.split(",") if v.strip()]
    unknown = [v for v in names if v not in HUMAN_NAMES]
    if not names or unknown:
        raise argparse.ArgumentTypeError(f"expected a comma-separated list of {', '.join(HUMAN_NAMES)}; got {text!r}")
    return tuple(dict.fromkeys(names))
