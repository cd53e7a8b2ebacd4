"""The study design as data: the rig (wheel, sampling, encoder, assistant) and the protocol.

Every literal of the paper's experiment (Inga et al., SMC 2018, Section IV) lives here
once, as the defaults of :class:`Design`; the module constants below are aliases of
those defaults for the code that needs only one of them. The rest of :mod:`models`
takes the design from here and never writes one of these numbers again.

=====================  ==========================  ==========================================
field                  default                     paper
=====================  ==========================  ==========================================
``wheel``              0.04 kg·m², 1.146 N·m/rad,  Table I (:class:`WheelParameters`)
                       0.286 N·m·s/rad
``dt``                 0.01 s                      100-Hz recording and human model
``encoder_counts``     40000 per revolution        Section IV-A
``theta_assistant``    [5, 0, 1]                   Section IV-D, "slight assistance"
``assistant_horizon``  50 steps                    N_P, Section IV-D
``dt_assistant``       0.02 s                      T_C, the assistant's prediction step
``conditions``         ("MC", "SC")                manual and shared control
``run_seconds``        240 s                       a 4-minute run
``window_start``       210 s                       analysis from 3:30 (Section IV-F)
``window_seconds``     15 s                        length of the analysis window
``preview``            2 s                         a point of the reference crosses the screen
=====================  ==========================  ==========================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple


class WheelParameters(NamedTuple):
    """Physical parameters of the steering wheel (paper Table I).

    Attributes
    ----------
    inertia : float
        Rotational inertia Θ_L, kg·m². Default 0.04.
    spring : float
        Spring constant c, N·m/rad. Default 1.146.
    damper : float
        Damping constant d, N·m·s/rad. Default 0.286.
    """

    inertia: float = 0.04
    spring: float = 1.146
    damper: float = 0.286


@dataclass(frozen=True)
class Design:
    """The rig and the protocol of a study; the defaults are the paper's (see the module docstring).

    Attributes
    ----------
    wheel : WheelParameters
        The steering wheel (Table I).
    dt : float
        Sample time of the recordings and of the human model, s.
    encoder_counts : int
        Encoder increments per revolution of the wheel.
    theta_assistant : tuple of float
        The assistant's cost θ_A = [q11, q22, R].
    assistant_horizon : int
        The assistant's prediction horizon N_P, in steps of ``dt_assistant``.
    dt_assistant : float
        The assistant's prediction step T_C, s.
    conditions : tuple of str
        Labels of manual and shared control, in this order.
    run_seconds : float
        Length of one run, s.
    window_start, window_seconds : float
        Start and length of the analysis window, s.
    preview : float
        How far the human sees the reference ahead, s.

    Examples
    --------
    >>> Design().window_start, Design().encoder_step
    (210.0, 0.00015707963267948965)
    """

    wheel: WheelParameters = WheelParameters()
    dt: float = 0.01
    encoder_counts: int = 40000
    theta_assistant: tuple[float, float, float] = (5.0, 0.0, 1.0)
    assistant_horizon: int = 50
    dt_assistant: float = 0.02
    conditions: tuple[str, str] = ("MC", "SC")
    run_seconds: float = 240.0
    window_start: float = 210.0
    window_seconds: float = 15.0
    preview: float = 2.0

    def __post_init__(self):
        for name in ("dt", "dt_assistant", "run_seconds", "window_seconds"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"Design.{name} must be a finite number > 0; got {value!r}")
        for name in ("window_start", "preview"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"Design.{name} must be a finite number >= 0; got {value!r}")
        for name in ("encoder_counts", "assistant_horizon"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"Design.{name} must be a positive integer; got {value!r}")
        if len(self.conditions) != 2 or len(set(self.conditions)) != 2:
            raise ValueError(f"Design.conditions must be two distinct labels (manual, shared); got {self.conditions!r}")

    @property
    def encoder_step(self) -> float:
        """One encoder increment, rad."""
        return 2.0 * math.pi / self.encoder_counts


#: The paper's study.
STUDY = Design()

#: Sample time of the recordings and of the human model (100 Hz), s.
DT_HUMAN = STUDY.dt
#: The assistant's prediction step T_C (Section IV-D), s.
DT_ASSISTANT = STUDY.dt_assistant
#: Encoder increments per revolution (Section IV-A).
ENCODER_COUNTS = STUDY.encoder_counts
#: One encoder increment, rad.
ENCODER_STEP = STUDY.encoder_step
#: The assistant's cost θ_A = [q11, q22, R] (Section IV-D: "slight assistance").
THETA_ASSISTANT = STUDY.theta_assistant
#: The assistant's prediction horizon N_P, in assistant steps.
ASSISTANT_HORIZON = STUDY.assistant_horizon
#: Condition labels, manual control first.
CONDITIONS = STUDY.conditions
#: Manual and shared control.
MANUAL, SHARED = CONDITIONS
#: Length of one run, s.
RUN_SECONDS = STUDY.run_seconds
#: Start of the analysis window (3:30), s.
WINDOW_START = STUDY.window_start
#: Length of the analysis window, s.
WINDOW_SECONDS = STUDY.window_seconds
#: How far the human sees the reference ahead, s.
PREVIEW_SECONDS = STUDY.preview

__all__ = [
    "WheelParameters",
    "Design",
    "STUDY",
    "DT_HUMAN",
    "DT_ASSISTANT",
    "ENCODER_COUNTS",
    "ENCODER_STEP",
    "THETA_ASSISTANT",
    "ASSISTANT_HORIZON",
    "CONDITIONS",
    "MANUAL",
    "SHARED",
    "RUN_SECONDS",
    "WINDOW_START",
    "WINDOW_SECONDS",
    "PREVIEW_SECONDS",
]
