"""``scioc loglik``: the max-ent log-likelihood of every segment of a study file under one θ.

Each trial is evaluated whole, with the plan ending where the trial ends, unless the
experiment file's ``[analysis]`` sets a window or a preview; then the segments are cut
as ``scioc identify`` cuts them. The file must hold the human torque ``u_H`` (measured,
or reconstructed beforehand); a missing ``velocity`` follows from the plant
(:mod:`pipelines.prepare`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

import tomllib

from models.cost import validate_theta
from models.design import STUDY, Design
from models.maxent import loglik_segments
from models.plant import discretize
from pipelines.io import StudyFileError, load_study
from pipelines.prepare import IdentifySettings, prepare_study


class NonFiniteLoglik(ArithmeticError):
    """A log-likelihood that double precision cannot represent (θ far outside the data's scale).

    ``scioc loglik`` exits with status 1 on it.
    """


def parse_theta(text: str) -> np.ndarray:
    """Parse ``"q11,q22,R"`` into a validated θ, with a clear error."""
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 3:
        raise ValueError(f"--theta needs three comma-separated numbers q11,q22,R; got {text!r}")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"--theta needs three comma-separated numbers q11,q22,R; got {text!r}") from None
    return validate_theta(values, name="--theta")


def sets_analysis(experiment_file) -> bool:
    """Whether the experiment file sets a window, ``whole`` or a preview in its ``[analysis]`` table."""
    if experiment_file is None:
        return False
    with open(experiment_file, "rb") as fh:
        return bool(tomllib.load(fh).get("analysis"))


def study_loglik(path, theta, assistant_model: str = "feedback", *, design: Design = STUDY,
                 experiment_file=None) -> pd.DataFrame:
    """Log-likelihood (nats) of each segment of a study file.

    Parameters
    ----------
    path : str or Path
        Study file in the data convention with ``u_H``.
    theta : array_like, shape (3,)
        [q11, q22, R].
    assistant_model : {"feedback", "exogenous"}
        How the human on an assisted level models the assistant (:mod:`pipelines.prepare`).
    design : Design
        The experiment (rate, wheel, levels and their assistants).
    experiment_file : str, optional
        The file ``design`` came from; if its ``[analysis]`` sets a window or preview,
        the segments are cut that way, else each trial is evaluated whole without preview.

    Returns
    -------
    DataFrame
        Columns ``subject``, ``condition`` (and ``trial`` if the file has it), ``K``
        (torque samples) and ``loglik``, in file order.

    Raises
    ------
    NonFiniteLoglik
        If any segment's log-likelihood is not finite, naming the first such segment.
    """
    th = validate_theta(theta)
    study = load_study(path, design)
    for s in study.segments:
        if s.u_H is None:
            raise StudyFileError(study.path, f"column is missing; segment {s.label} needs it for the likelihood "
                                 "(reconstruct it from the angle first, or use scioc identify)", column="u_H")
    if sets_analysis(experiment_file):
        settings = IdentifySettings.for_design(design, assistant_model=assistant_model, adequacy_boot=0)
    else:
        settings = IdentifySettings(window_start=None, window_seconds=None, preview=0.0,
                                    assistant_model=assistant_model, adequacy_boot=0, design=design)
    prepared = prepare_study(study, settings)
    res = loglik_segments(th, [p.segment for p in prepared.segments], discretize(design.dt, design.wheel))
    bad = ~np.isfinite(res.loglik)
    if bad.any():
        seg = study.segments[int(np.flatnonzero(bad)[0])]
        raise NonFiniteLoglik(
            f"{study.path}: the log-likelihood of {int(bad.sum())} of {bad.size} segments is not finite under "
            f"θ = [{', '.join(f'{v:g}' for v in th)}] (first: segment {seg.label}, "
            f"{res.loglik[bad][0]:g}); θ is beyond what double precision can evaluate for these data")
    trial = any(s.trial is not None for s in study.segments)
    return pd.DataFrame(
        {
            "subject": [s.subject for s in study.segments],
            "condition": [s.condition for s in study.segments],
            **({"trial": [s.trial for s in study.segments]} if trial else {}),
            "K": [p.segment.K for p in prepared.segments],
            "loglik": res.loglik,
        }
    )
