"""The study design: the paper's values, its aliases, and the code that takes its defaults from it."""

import math

import pytest

from scioc.models import design
from scioc.models.assistant import design_assistant
from scioc.models.design import STUDY, AssistantSpec, Design, WheelParameters
from scioc.models.plant import discretize
from scioc.models.reconstruct import DEFAULT_RESOLUTION
from scioc.models.reference import reference_trajectory, window_slice


def test_defaults_are_the_papers_study():
    # Inga et al. (SMC 2018): Table I, Section IV-A (encoder), IV-D (assistant), IV-F (window).
    assert STUDY.wheel == WheelParameters(0.04, 1.146, 0.286)
    assert (STUDY.dt, STUDY.rate_hz, STUDY.encoder_counts) == (0.01, 100.0, 40000)
    sc = STUDY.assistant("SC")
    assert (sc.kind, sc.theta, sc.horizon, sc.step_s, sc.period_s) == ("mpc", (5.0, 0.0, 1.0), 50, 0.02, 0.01)
    assert STUDY.levels == ("MC", "SC") and STUDY.baseline == "MC" and STUDY.contrasts == ("SC",)
    assert STUDY.assistant("MC") is None
    assert (STUDY.subjects, STUDY.trials, STUDY.torque_sensor, STUDY.whole) == (42, 1, False, False)
    assert (STUDY.run_seconds, STUDY.window_start, STUDY.window_seconds, STUDY.preview) == (240.0, 210.0, 15.0, 2.0)
    assert STUDY.encoder_step == 2.0 * math.pi / 40000


def test_module_constants_are_aliases_of_the_default_design():
    assert (design.DT_HUMAN, design.DT_ASSISTANT, design.ENCODER_COUNTS) == (STUDY.dt, STUDY.assistant("SC").step_s,
                                                                             STUDY.encoder_counts)
    assert (design.MANUAL, design.SHARED) == STUDY.levels == design.CONDITIONS
    assert (design.WINDOW_START, design.WINDOW_SECONDS, design.PREVIEW_SECONDS) == (210.0, 15.0, 2.0)
    assert DEFAULT_RESOLUTION == design.ENCODER_STEP


def test_models_take_their_defaults_from_the_design():
    assert discretize().dt == STUDY.dt
    a = design_assistant()
    sc = STUDY.assistant("SC")
    assert tuple(a.theta) == sc.theta and a.preview_weights.shape == (sc.horizon,)
    assert a.plant.dt == sc.step_s
    assert reference_trajectory().t[-1] == pytest.approx(STUDY.run_seconds)
    w = window_slice()
    assert (w.start, w.stop - w.start - 1) == (21000, 1500)


@pytest.mark.parametrize("field, value, message", [
    ("dt", 0.0, "dt must be a finite number > 0"),
    ("window_seconds", float("nan"), "window_seconds"),
    ("preview", -1.0, "preview must be a finite number >= 0"),
    ("encoder_counts", -1, "encoder_counts must be an integer >= 0"),
    ("levels", ("MC", "MC"), "two or more distinct"),
    ("levels", ("MC",), "two or more distinct"),
    ("baseline", "XX", "baseline must be one of the levels"),
    ("assistants", (("XX", AssistantSpec()),), "not one of the levels"),
    ("assistants", (("SC", AssistantSpec(step_s=0.015)),), "whole multiple of the sample time"),
    ("whole", 1, "whole must be true or false"),
    ("trials", 0, "trials must be a positive integer"),
])
def test_a_bad_design_names_the_field(field, value, message):
    with pytest.raises(ValueError, match=message):
        Design(**{field: value})


def test_an_unquantized_encoder_has_no_step():
    assert Design(encoder_counts=0).encoder_step == 0.0


@pytest.mark.parametrize("kwargs, message", [
    ({"kind": "pid"}, "kind must be one of"),
    ({"theta": (5.0, 0.0, 0.0)}, "R > 0"),
    ({"horizon": 0}, "horizon must be a positive integer"),
    ({"kind": "linear", "gain": (1.0,)}, "gain must be two finite numbers"),
    ({"kind": "linear", "reference_gain": float("inf")}, "reference_gain must be a finite number"),
])
def test_a_bad_assistant_names_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        AssistantSpec(**kwargs)
