"""The study design as data: the rig (wheel, sampling, encoder, assistants) and the protocol.

Every literal of the paper's experiment (Inga et al., SMC 2018, Section IV) lives here
once, as the defaults of :class:`Design`; the module constants below are aliases of
those defaults for the code that needs only one of them. A lab describes its own
experiment in an ``experiment.toml`` (:mod:`scioc.pipelines.experiment` reads it into a
:class:`Design`); without one, every command uses :data:`STUDY`.

=====================  ==========================  ==========================================
field                  default                     paper
=====================  ==========================  ==========================================
``wheel``              0.04 kg·m², 1.146 N·m/rad,  Table I (:class:`WheelParameters`)
                       0.286 N·m·s/rad
``dt``                 0.01 s                      100-Hz recording and human model
``encoder_counts``     40000 per revolution        Section IV-A (0: angle not quantized)
``levels``             ("MC", "SC")                manual and shared control
``baseline``           "MC"                        contrasts are taken against it
``assistants``         SC: the MPC below           Section IV-D, "slight assistance"
                       θ_A = [5, 0, 1], N_P = 50,
                       T_C = 0.02 s, re-solved
                       every 0.01 s
``run_seconds``        240 s                       a 4-minute run (simulation)
``subjects``           42                          Section IV-B (simulation)
``trials``             1                           runs per subject × condition (simulation)
``torque_sensor``      False                       the rig records the angle only (simulation)
``effects``            -0.7 per non-baseline       true mean shift of log θ1 (simulation): θ1
                       level                       about halves in SC, the paper's finding
``window_start``       210 s                       analysis from 3:30 (Section IV-F)
``window_seconds``     15 s                        length of the analysis window
``whole``              False                       True: analyse every trial whole
``preview``            2 s                         a point of the reference crosses the screen
=====================  ==========================  ==========================================

How the cost parameters transform with the sample rate
-------------------------------------------------------
The cost J = Σ_k e_kᵀ Q e_k + R u_k² is a sum over samples: it approximates
(1/dt) ∫ (eᵀ Q_c e + R_c u²) dt with Q = Q_c dt and R = R_c dt, so the same human
recorded at another rate has per-sample weights proportional to the sample time.
Hence:

* θ1 = q11 / R and θ2 = q22 / R are ratios and do not depend on the rate: they are the
  reported parameters, and their priors hold at any rate.
* R is a per-sample precision: R ∝ dt. Under maximum entropy the torque's per-sample
  variance 1 / (2 S) ≈ 1 / (2 R) then grows as 1/dt, which is white noise of the same
  spectral density at every rate. The rate-free quantity is R at the paper's 100 Hz,
  ``R · REFERENCE_DT / dt`` (:meth:`Design.r_scale`); the simulator's population and the
  hierarchical model's prior on log R are stated at :data:`REFERENCE_DT` and shifted by
  ``log(dt / REFERENCE_DT)``. At 100 Hz nothing changes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

#: The sample time R is stated at (the paper's 100 Hz), s; see the module docstring.
REFERENCE_DT = 0.01
#: The simulated population's default mean shift of log θ1 from the baseline to another level.
DEFAULT_EFFECT = -0.7
#: The kinds of assistant an experiment can declare (:class:`AssistantSpec`).
ASSISTANT_KINDS = ("mpc", "linear")


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


def _finite(value, lo=None, strict=True) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    if lo is None:
        return True
    return value > lo if strict else value >= lo


@dataclass(frozen=True)
class AssistantSpec:
    """One assisted condition's law.

    ``kind = "mpc"``: the paper's model-predictive assistant (Eq. 19) with cost ``theta``
    = θ_A, ``horizon`` prediction steps of ``step_s`` seconds, re-solved every
    ``period_s`` seconds (:func:`scioc.models.assistant.design_assistant`).

    ``kind = "linear"``: ``u_A = -gain[0]·angle - gain[1]·velocity + reference_gain·angle_ref``
    at every sample (:func:`scioc.models.assistant.linear_assistant`).

    The fields of the other kind keep their defaults and are not used.
    """

    kind: str = "mpc"
    theta: tuple[float, float, float] = (5.0, 0.0, 1.0)
    horizon: int = 50
    step_s: float = 0.02
    period_s: float = 0.01
    gain: tuple[float, float] = (0.0, 0.0)
    reference_gain: float = 0.0

    def __post_init__(self):
        if self.kind not in ASSISTANT_KINDS:
            raise ValueError(f"assistant kind must be one of {ASSISTANT_KINDS}; got {self.kind!r}")
        if self.kind == "mpc":
            th = tuple(self.theta)
            if len(th) != 3 or not all(_finite(v, 0.0, strict=False) for v in th) or not th[2] > 0:
                raise ValueError(f"assistant theta must be three finite numbers >= 0 with R > 0; got {self.theta!r}")
            if isinstance(self.horizon, bool) or int(self.horizon) != self.horizon or self.horizon < 1:
                raise ValueError(f"assistant horizon must be a positive integer; got {self.horizon!r}")
            for name in ("step_s", "period_s"):
                if not _finite(getattr(self, name), 0.0):
                    raise ValueError(f"assistant {name} must be a finite number > 0; got {getattr(self, name)!r}")
        else:
            g = tuple(self.gain)
            if len(g) != 2 or not all(_finite(v) for v in g):
                raise ValueError(f"assistant gain must be two finite numbers; got {self.gain!r}")
            if not _finite(self.reference_gain):
                raise ValueError(f"assistant reference_gain must be a finite number; got {self.reference_gain!r}")


#: The paper's assistant (Section IV-D).
PAPER_ASSISTANT = AssistantSpec()


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
        Encoder increments per revolution of the wheel; 0 for an angle that is not quantized.
    levels : tuple of str
        Condition labels, the baseline among them.
    baseline : str
        The level every contrast is taken against.
    assistants : tuple of (str, AssistantSpec)
        The assisted levels and their laws; a level without an entry has u_A = 0.
    run_seconds : float
        Length of one simulated run, s.
    subjects, trials : int
        Subjects, and runs per subject × condition, of a simulated study.
    torque_sensor : bool
        Whether the simulated rig records u_H besides the angle.
    effects : tuple of float
        Simulation truth: the population's mean shift of log θ1 from the baseline to each
        non-baseline level, in order (default :data:`DEFAULT_EFFECT` for every one).
    window_start, window_seconds : float
        Start and length of the analysis window on each trial's own time axis, s.
    whole : bool
        Analyse every trial whole instead of one window.
    preview : float
        How far the human sees the reference ahead, s (0: the paper's horizon).

    Examples
    --------
    >>> Design().window_start, Design().encoder_step
    (210.0, 0.00015707963267948965)
    >>> Design().assistant("SC").kind, Design().assistant("MC")
    ('mpc', None)
    """

    wheel: WheelParameters = WheelParameters()
    dt: float = 0.01
    encoder_counts: int = 40000
    levels: tuple[str, ...] = ("MC", "SC")
    baseline: str = "MC"
    assistants: tuple[tuple[str, AssistantSpec], ...] = field(default=(("SC", PAPER_ASSISTANT),))
    run_seconds: float = 240.0
    subjects: int = 42
    trials: int = 1
    torque_sensor: bool = False
    effects: tuple[float, ...] = ()
    window_start: float = 210.0
    window_seconds: float = 15.0
    whole: bool = False
    preview: float = 2.0

    def __post_init__(self):
        for name in ("dt", "run_seconds", "window_seconds"):
            if not _finite(getattr(self, name), 0.0):
                raise ValueError(f"Design.{name} must be a finite number > 0; got {getattr(self, name)!r}")
        for name in ("window_start", "preview"):
            if not _finite(getattr(self, name), 0.0, strict=False):
                raise ValueError(f"Design.{name} must be a finite number >= 0; got {getattr(self, name)!r}")
        if not (isinstance(self.wheel, tuple) and len(self.wheel) == 3
                and all(_finite(v, 0.0) for v in self.wheel)):
            raise ValueError(f"Design.wheel must be three finite numbers > 0; got {self.wheel!r}")
        c = self.encoder_counts
        if isinstance(c, bool) or not isinstance(c, int) or c < 0:
            raise ValueError(f"Design.encoder_counts must be an integer >= 0 (0: not quantized); got {c!r}")
        for name in ("whole", "torque_sensor"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"Design.{name} must be true or false; got {getattr(self, name)!r}")
        for name in ("subjects", "trials"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ValueError(f"Design.{name} must be a positive integer; got {v!r}")
        levels = tuple(self.levels)
        if len(levels) < 2 or len(set(levels)) != len(levels) or not all(isinstance(v, str) and v for v in levels):
            raise ValueError(f"Design.levels must be two or more distinct non-empty labels; got {self.levels!r}")
        if self.baseline not in levels:
            raise ValueError(f"Design.baseline must be one of the levels {levels}; got {self.baseline!r}")
        names = [name for name, _ in self.assistants]
        for name, spec in self.assistants:
            if name not in levels:
                raise ValueError(f"Design.assistants: {name!r} is not one of the levels {levels}")
            if not isinstance(spec, AssistantSpec):
                raise ValueError(f"Design.assistants: {name!r} needs an AssistantSpec; got {spec!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"Design.assistants: a level appears twice in {names}")
        n_contrasts = len(levels) - 1
        effects = tuple(self.effects) if self.effects else (DEFAULT_EFFECT,) * n_contrasts
        if len(effects) != n_contrasts or not all(_finite(v) for v in effects):
            raise ValueError(f"Design.effects must be {n_contrasts} finite numbers, one per non-baseline level; "
                             f"got {self.effects!r}")
        object.__setattr__(self, "effects", tuple(float(v) for v in effects))
        for name, spec in self.assistants:
            if spec.kind == "mpc":
                for what, value in (("step_s", spec.step_s), ("period_s", spec.period_s)):
                    n = round(value / self.dt)
                    if n < 1 or abs(n * self.dt - value) > 1e-9 * max(1.0, value):
                        raise ValueError(f"Design.assistants: {name!r} {what} = {value} must be a whole multiple "
                                         f"of the sample time {self.dt} s")

    @property
    def rate_hz(self) -> float:
        """Sampling rate, Hz."""
        return 1.0 / self.dt

    @property
    def r_scale(self) -> float:
        """``dt / REFERENCE_DT``: a per-sample R at this rate is the 100-Hz R times this (1.0 at 100 Hz)."""
        return self.dt / REFERENCE_DT

    @property
    def encoder_step(self) -> float:
        """One encoder increment, rad (0.0 for an angle that is not quantized)."""
        return 2.0 * math.pi / self.encoder_counts if self.encoder_counts else 0.0

    @property
    def encoder_sd(self) -> float:
        """SD of the recorded angle's quantization error, rad: uniform over one encoder step q, so q / √12."""
        return self.encoder_step / math.sqrt(12.0)

    def assistant(self, level: str) -> AssistantSpec | None:
        """The law of ``level``'s assistant, or None for an unassisted level."""
        return dict(self.assistants).get(level)

    @property
    def ordered_levels(self) -> tuple[str, ...]:
        """The baseline, then the other levels in order (condition index 0, 1, ...)."""
        return (self.baseline,) + self.contrasts

    @property
    def contrasts(self) -> tuple[str, ...]:
        """The non-baseline levels, in order: one condition effect each."""
        return tuple(v for v in self.levels if v != self.baseline)

    def steps(self, seconds: float) -> int:
        """``seconds`` in whole samples."""
        return int(round(seconds / self.dt))


#: The paper's study.
STUDY = Design()

#: Sample time of the recordings and of the human model (100 Hz), s.
DT_HUMAN = STUDY.dt
#: The assistant's prediction step T_C (Section IV-D), s.
DT_ASSISTANT = PAPER_ASSISTANT.step_s
#: Encoder increments per revolution (Section IV-A).
ENCODER_COUNTS = STUDY.encoder_counts
#: One encoder increment, rad.
ENCODER_STEP = STUDY.encoder_step
#: The assistant's cost θ_A = [q11, q22, R] (Section IV-D: "slight assistance").
THETA_ASSISTANT = PAPER_ASSISTANT.theta
#: The assistant's prediction horizon N_P, in assistant steps.
ASSISTANT_HORIZON = PAPER_ASSISTANT.horizon
#: Condition labels, manual control first.
CONDITIONS = STUDY.levels
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
    "ASSISTANT_KINDS",
    "REFERENCE_DT",
    "DEFAULT_EFFECT",
    "AssistantSpec",
    "PAPER_ASSISTANT",
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
