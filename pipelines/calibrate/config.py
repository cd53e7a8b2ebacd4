"""What a calibration run is: its configuration, the level defaults and the replication seeds."""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, field

import numpy as np

from scioc.models.design import STUDY, Design
from scioc.pipelines.human_model.registry import get

#: Version of how replications simulate and fit; part of every fingerprint. Bump it when
#: the data-generating process or the fitted likelihood changes.
GENERATOR = ("3: SC human plans with the assistant's feedback law; assistant re-solves every sample; "
             "ArviZ's bulk/tail-ESS thinning; log-likelihood test quantity; thinned draws stored")



@dataclass(frozen=True)
class CalibrationConfig:
    """What to calibrate and how (``chains``, ``tune``, ``draws``: the sampler's settings per fit)."""

    level: str = "unit"  # or "study"
    replications: int = 1000
    seed: int = 2018
    L: int = 99  # posterior draws per rank after thinning (ranks take L + 1 values)
    chains: int = 2
    tune: int = 500
    draws: int = 500
    K: int = 1500  # samples per segment (window length × the experiment's rate)
    n_subjects: int = 8  # subjects per simulated study (study level only)
    negative_control: str | None = None  # None: the correct model; else one of the model's negative_controls
    batch_size: int = 10  # replications per Dask task
    extra: dict = field(default_factory=dict)
    experiment: dict | None = None  # pipelines.experiment.resolved form; None: the paper's study
    human_model: str = "maxent"  # a registered human model, at the levels its calibration has
    likelihood: str = "torques"  # what the replications record and fit: the human's torques, or the encoder's angles

    def __post_init__(self):
        if self.level not in ("unit", "study"):
            raise ValueError(f"level must be 'unit' or 'study'; got {self.level!r}")
        model = get(self.human_model)
        if self.level not in model.calibration_levels:
            raise ValueError(f"the {self.human_model} human model is calibrated at the "
                             f"{' and '.join(model.calibration_levels)} level only")
        for name in ("replications", "L", "chains", "tune", "draws", "K", "n_subjects", "batch_size"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 1:
                raise ValueError(f"{name} must be a positive integer; got {value!r}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0; got {self.seed!r}")
        through = model.calibration_likelihoods[self.level]
        if self.likelihood not in through:
            raise ValueError(f"the {self.human_model} human model is calibrated at the {self.level} level through "
                             f"{' or '.join(through)}; got likelihood {self.likelihood!r}")
        allowed = model.negative_controls
        if self.negative_control not in (None, *allowed):
            raise ValueError(f"negative_control of the {self.human_model} model must be None or one of "
                             f"{', '.join(map(repr, allowed))}; got {self.negative_control!r}")
        if self.chains * self.draws < self.L:
            raise ValueError(f"chains × draws = {self.chains * self.draws} cannot give L = {self.L} draws")

    def fingerprint(self) -> str:
        """Hash of everything that changes a replication's result: not ``batch_size`` nor ``replications``
        (replication i is the same in a run of 100 or of 1000, so a run can be extended)."""
        d = asdict(self)
        d.pop("batch_size")
        d.pop("replications")
        for name, default in (("experiment", None), ("likelihood", "torques")):
            if d[name] == default:
                d.pop(name)  # a default is left out, so stored runs keep resuming
        d["generator"] = GENERATOR  # a changed simulator invalidates stored replications
        d = get(self.human_model).calibration_fingerprint(d)
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]

#: Default sizes per level; the study level is reduced (docs/decisions/sbc-study-level-size.md).
DEFAULTS = {
    "unit": {"replications": 1000, "K": 1500, "chains": 2, "tune": 500, "draws": 500, "batch_size": 10, "L": 99},
    "study": {"replications": 200, "K": 200, "n_subjects": 6, "chains": 2, "tune": 300, "draws": 200, "batch_size": 3,
              "L": 39},
}



def level_configs(level: str, *, seed: int = 2018, replications: int | None = None, batch_size: int | None = None,
                  n_subjects: int | None = None, seconds: float | None = None,
                  negative_control: str | None = None, design: Design | None = None,
                  human_model: str = "maxent", likelihood: str = "torques") -> list[tuple[str, CalibrationConfig]]:
    """The calibration of one level and, unless ``negative_control == "none"``, its negative control.

    ``replications``, ``batch_size`` and ``n_subjects`` override the level's :data:`DEFAULTS`.
    ``seconds``: window length, s (default: :data:`DEFAULTS` for the paper's study, else the
    experiment's analysis window or whole run at the unit level). ``negative_control``: one of
    the model's ``negative_controls`` or "none" (default: its ``default_negative_control``). ``design``: the
    experiment (None: the paper's study). ``human_model``: at the levels its calibration has; ``likelihood``: what
    the replications record and fit (``torques`` or, where the model has it, ``angles``).

    Returns the folder names and validated configurations: ``(stem, correct)`` and
    ``(stem + "-negative", wrong)``, the stem being the level (``unit-delayed`` for the delayed human,
    ``unit-delayed-angles`` through its angles).
    """
    if level not in DEFAULTS:
        raise ValueError(f"level must be 'unit' or 'study'; got {level!r}")
    d = dict(DEFAULTS[level])
    for key, value in (("replications", replications), ("batch_size", batch_size), ("n_subjects", n_subjects)):
        if value is not None:
            d[key] = value
    experiment = None
    if design is not None and design != STUDY:
        from scioc.pipelines.experiment import resolved  # the experiment travels to the workers as data

        experiment = resolved(design)
        if level == "unit" and seconds is None:
            seconds = design.run_seconds if design.whole else design.window_seconds
    dt = STUDY.dt if design is None else design.dt
    if seconds is not None:
        d["K"] = int(round(seconds / dt))
    if likelihood == "angles" and not (design or STUDY).encoder_sd > 0:
        raise ValueError("the angle calibration reads the angles through the experiment's encoder: "
                         "encoder.counts_per_rev must be > 0")
    model = get(human_model)
    stem = level + model.calibration_suffix + ("" if likelihood == "torques" else f"-{likelihood}")
    runs = [(stem, None)]
    nc = model.default_negative_control[level] if negative_control is None else negative_control
    if nc != "none":
        runs.append((f"{stem}-negative", nc))
    return [(name, CalibrationConfig(level=level, seed=seed, negative_control=wrong, experiment=experiment,
                                     human_model=human_model, likelihood=likelihood, **d))
            for name, wrong in runs]


def replication_seed(seed: int, i: int) -> np.random.SeedSequence:
    """The i-th child of ``SeedSequence(seed)``, without spawning the others."""
    return np.random.SeedSequence(entropy=int(seed), spawn_key=(int(i),))
