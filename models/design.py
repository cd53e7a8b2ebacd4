"""The study design as data: the rig (wheel, sampling, encoder, assistants) and the protocol.

Every literal of the paper's experiment (Inga et al., SMC 2018, Section IV) lives here once, as the
defaults of :class:`Design`; the module constants are aliases of them. A lab describes its own
experiment in an ``experiment.toml`` (read by :mod:`scioc.pipelines.experiment`); without one, every
command uses :data:`STUDY`. R is stated at the paper's 100 Hz and θ1 = q11/R, θ2 = q22/R are rate-free:
docs/decisions/cost-rate-scaling.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

#: The sample time R is stated at (the paper's 100 Hz), s.
REFERENCE_DT = 0.01
#: The simulated population's default mean shift of log θ1 from the baseline to another level.
DEFAULT_EFFECT = -0.7
#: The kinds of assistant an experiment can declare (:class:`AssistantSpec`).
ASSISTANT_KINDS = ("mpc", "linear")


class WheelParameters(NamedTuple):
    """The steering wheel (paper Table I): inertia Θ_L, kg·m²; spring c, N·m/rad; damper d, N·m·s/rad."""

    inertia: float = 0.04
    spring: float = 1.146
    damper: float = 0.286


#: Longest preview, s: a minute is thirty times what a point of the reference takes to cross the subject's screen
#: (docs/decisions/plan-preview.md), and a preview in milliseconds given as seconds lies beyond it.
MAX_PREVIEW = 60.0


def _finite(value, lo=None, strict=True) -> bool:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        return False
    if lo is None:
        return True
    return value > lo if strict else value >= lo


@dataclass(frozen=True)
class AssistantSpec:
    """One assisted condition's law; the other kind's fields are unused.

    ``"mpc"``: the paper's assistant (Eq. 19, Section IV-D) with θ_A = ``theta``, ``horizon`` steps of
    ``step_s`` s, re-solved every ``period_s`` s. ``"linear"``:
    ``u_A = -gain[0]·angle - gain[1]·velocity + reference_gain·angle_ref`` at every sample.
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
    """The rig and the protocol of a study; the defaults are the paper's (Section IV).

    ``wheel`` (Table I); ``dt``, s; ``encoder_counts`` per revolution (IV-A; 0: not quantized); the assisted
    levels' laws ``assistants`` (IV-D; others have u_A = 0); ``levels`` and the ``baseline`` of contrasts;
    the window ``window_start``, ``window_seconds`` (IV-F) on each trial's axis, or ``whole``; ``preview`` (0: the
    paper's horizon). Simulation only: ``run_seconds``, ``subjects`` (IV-B), ``trials`` per unit,
    ``torque_sensor``, and the true mean shift of log θ1 per non-baseline level, ``effects``.
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
        if self.preview > MAX_PREVIEW:
            raise ValueError(f"Design.preview must be at most {MAX_PREVIEW:g} s; got {self.preview!r}")
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
        """``dt / REFERENCE_DT``: a per-sample R at this rate is the 100-Hz R times this."""
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
    "MAX_PREVIEW",
]
