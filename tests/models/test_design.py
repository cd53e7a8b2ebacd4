"""The study design: the paper's values, its aliases, and the code that takes its defaults from it."""

import math

import pytest

from models import design
from models.assistant import design_assistant
from models.design import STUDY, Design, WheelParameters
from models.plant import discretize
from models.reconstruct import DEFAULT_RESOLUTION
from models.reference import reference_trajectory, window_slice


def test_defaults_are_the_papers_study():
    # Inga et al. (SMC 2018): Table I, Section IV-A (encoder), IV-D (assistant), IV-F (window).
    assert STUDY.wheel == WheelParameters(0.04, 1.146, 0.286)
    assert (STUDY.dt, STUDY.dt_assistant, STUDY.encoder_counts) == (0.01, 0.02, 40000)
    assert (STUDY.theta_assistant, STUDY.assistant_horizon) == ((5.0, 0.0, 1.0), 50)
    assert STUDY.conditions == ("MC", "SC")
    assert (STUDY.run_seconds, STUDY.window_start, STUDY.window_seconds, STUDY.preview) == (240.0, 210.0, 15.0, 2.0)
    assert STUDY.encoder_step == 2.0 * math.pi / 40000


def test_module_constants_are_aliases_of_the_default_design():
    assert (design.DT_HUMAN, design.DT_ASSISTANT, design.ENCODER_COUNTS) == (STUDY.dt, STUDY.dt_assistant,
                                                                             STUDY.encoder_counts)
    assert (design.MANUAL, design.SHARED) == STUDY.conditions == design.CONDITIONS
    assert (design.WINDOW_START, design.WINDOW_SECONDS, design.PREVIEW_SECONDS) == (210.0, 15.0, 2.0)
    assert DEFAULT_RESOLUTION == design.ENCODER_STEP


def test_models_take_their_defaults_from_the_design():
    assert discretize().dt == STUDY.dt
    a = design_assistant()
    assert tuple(a.theta) == STUDY.theta_assistant and a.preview_weights.shape == (STUDY.assistant_horizon,)
    assert a.plant.dt == STUDY.dt_assistant
    assert reference_trajectory().t[-1] == pytest.approx(STUDY.run_seconds)
    w = window_slice()
    assert (w.start, w.stop - w.start - 1) == (21000, 1500)


@pytest.mark.parametrize("field, value, message", [
    ("dt", 0.0, "dt must be a finite number > 0"),
    ("window_seconds", float("nan"), "window_seconds"),
    ("preview", -1.0, "preview must be a finite number >= 0"),
    ("encoder_counts", 0, "encoder_counts must be a positive integer"),
    ("conditions", ("MC", "MC"), "two distinct labels"),
])
def test_a_bad_design_names_the_field(field, value, message):
    with pytest.raises(ValueError, match=message):
        Design(**{field: value})
