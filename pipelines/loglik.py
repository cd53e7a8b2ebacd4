"""``scioc loglik``: the log-likelihood of every segment of a study file under one θ.

Each trial is evaluated whole (the plan ends with the trial) unless the experiment file's
``[analysis]`` sets a window or preview; then segments are cut as ``scioc identify`` cuts them.
The human is the paper's max-ent one (:func:`scioc.models.maxent.loglik_segments`) or the
``delayed`` one (:func:`scioc.models.delayed.loglik_grad`), whose arm torque at a window's start
follows from the torques before it. ``likelihood="angles"`` evaluates the ``delayed`` human's
likelihood of the encoder's angles, log p(y_1..y_K | y_0) (:func:`scioc.models.delayed.window_loglik`,
as identify does without a torque sensor); the file then needs no ``u_H``.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pandas as pd

from scioc.models.cost import validate_theta
from scioc.models.design import STUDY, Design
from scioc.models.plant import discretize
from scioc.pipelines.human_model.registry import get
from scioc.pipelines.io import StudyFileError, load_study
from scioc.pipelines.prepare import IdentifySettings, prepare_study


class NonFiniteLoglik(ArithmeticError):
    """A log-likelihood double precision cannot represent (θ far outside the data's scale); exit status 1."""


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


#: What ``scioc loglik`` can evaluate the likelihood of.
LIKELIHOODS = ("torques", "angles")


def study_loglik(path, theta, assistant_model: str = "feedback", *, design: Design = STUDY,
                 experiment_file=None, human_model: str = "maxent", delay_s=None, tau_nm=None,
                 sigma_m=None, likelihood: str = "torques") -> pd.DataFrame:
    """Log-likelihood (nats) of each segment of a study file.

    Parameters
    ----------
    path : str or Path
        Study file in the data convention (with ``u_H`` unless ``likelihood="angles"``).
    theta : array_like, shape (3,)
        [q11, q22, R]; for the ``delayed`` human, its command cost.
    assistant_model : {"feedback", "exogenous"}
    design : Design
    experiment_file : str, optional
        Where ``design`` came from; an ``[analysis]`` table in it cuts the segments.
    human_model : {"maxent", "delayed"}
    delay_s, tau_nm, sigma_m : float, optional
        The ``delayed`` human's delay (s), lag (s) and motor noise (N·m per sample): required for
        it, refused for ``maxent`` (:func:`delayed_human`).
    likelihood : {"torques", "angles"}

    Returns
    -------
    DataFrame
        ``subject``, ``condition`` (``trial`` if present), ``K`` and ``loglik``, in file order.

    Raises
    ------
    NonFiniteLoglik
        If a segment's log-likelihood is not finite (naming the first).
    ValueError
        If the human model or its parameters are not valid.
    """
    th = validate_theta(theta)
    if likelihood not in LIKELIHOODS:
        raise ValueError(f"likelihood must be one of {', '.join(LIKELIHOODS)}; got {likelihood!r}")
    model = get(human_model)
    human = model.loglik_parameters(design.dt, delay_s, tau_nm, sigma_m)
    if likelihood not in model.likelihoods:
        raise ValueError(f"--likelihood {likelihood}: the {model.name} human model has no such likelihood (it has "
                         f"{', '.join(model.likelihoods)})")
    study = load_study(path, design)
    for s in study.segments:
        if s.u_H is None and likelihood == "torques":
            hint = ("use --likelihood angles (the delayed human's likelihood of the recorded angles), "
                    if "angles" in model.likelihoods else "")
            raise StudyFileError(study.path, f"column is missing; segment {s.label} needs it for the likelihood "
                                 f"({hint}reconstruct it from the angle first, or use scioc identify)", column="u_H")
    if sets_analysis(experiment_file):
        settings = IdentifySettings.for_design(design, assistant_model=assistant_model, adequacy_boot=0)
    else:
        settings = IdentifySettings(window_start=None, window_seconds=None, preview=0.0,
                                    assistant_model=assistant_model, adequacy_boot=0, design=design)
    prepared = prepare_study(study, settings)
    plant = discretize(design.dt, design.wheel)
    ll = model.loglik(th, prepared, plant, design, human, likelihood)
    bad = ~np.isfinite(ll)
    if bad.any():
        seg = study.segments[int(np.flatnonzero(bad)[0])]
        raise NonFiniteLoglik(
            f"{study.path}: the log-likelihood of {int(bad.sum())} of {bad.size} segments is not finite under "
            f"θ = [{', '.join(f'{v:g}' for v in th)}] (first: segment {seg.label}, "
            f"{ll[bad][0]:g}); θ is beyond what double precision can evaluate for these data")
    trial = any(s.trial is not None for s in study.segments)
    return pd.DataFrame(
        {
            "subject": [s.subject for s in study.segments],
            "condition": [s.condition for s in study.segments],
            **({"trial": [s.trial for s in study.segments]} if trial else {}),
            "K": [p.segment.K for p in prepared.segments],
            "loglik": ll,
        }
    )
