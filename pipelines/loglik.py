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
from typing import NamedTuple

import numpy as np
import pandas as pd

from scioc.models.cost import validate_theta
from scioc.models.delayed import DELAY_GRID_S, lag_coefficients, window_loglik, window_tau0
from scioc.models.delayed import loglik_grad as delayed_loglik_grad
from scioc.models.delayed.search import TAU_NM_MAX
from scioc.models.design import STUDY, Design
from scioc.models.maxent import loglik_segments
from scioc.models.plant import discretize
from scioc.models.segment import prepare_batch
from scioc.pipelines.identify import angle_windows
from scioc.pipelines.io import StudyFileError, load_study
from scioc.pipelines.prepare import IdentifySettings, check_human_model, prepare_study


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


class DelayedHuman(NamedTuple):
    """The ``delayed`` human's parameters besides θ."""

    delay: int  # perceptual delay, samples
    tau_nm: float  # neuromuscular time constant, s
    sigma_m: float  # motor-noise SD per sample, N·m


def delayed_human(human_model: str, dt: float, delay_s=None, tau_nm=None, sigma_m=None) -> DelayedHuman | None:
    """Check the human model and its parameters (ValueError naming the option); None for ``maxent``.

    ``delay_s``: whole samples within the identification's delay grid; ``tau_nm`` within
    [0, :data:`scioc.models.delayed.search.TAU_NM_MAX`] s; ``sigma_m`` finite and >= 0.
    """
    check_human_model(human_model)
    given = [v is not None for v in (delay_s, tau_nm, sigma_m)]
    if human_model == "maxent":
        if any(given):
            raise ValueError("--delay-s, --tau-nm and --sigma-m apply to --human-model delayed")
        return None
    if not all(given):
        raise ValueError("--human-model delayed needs --delay-s, --tau-nm and --sigma-m")
    delay_s, tau_nm, sigma_m = float(delay_s), float(tau_nm), float(sigma_m)
    top = DELAY_GRID_S[-1]
    if not (np.isfinite(delay_s) and 0.0 <= delay_s <= top + 1e-12):
        raise ValueError(f"--delay-s must be between 0 and {top:g} s (the identification's delay grid); "
                         f"got {delay_s:g}")
    d = delay_s / dt
    if abs(d - round(d)) > 1e-6:
        raise ValueError(f"--delay-s must be a whole number of samples of {dt:g} s; got {delay_s:g} s "
                         f"({d:g} samples)")
    if not (np.isfinite(tau_nm) and 0.0 <= tau_nm <= TAU_NM_MAX):
        raise ValueError(f"--tau-nm must be between 0 and {TAU_NM_MAX:g} s; got {tau_nm:g}")
    if not (np.isfinite(sigma_m) and sigma_m >= 0.0):
        raise ValueError(f"--sigma-m must be a finite number of N·m >= 0; got {sigma_m:g}")
    return DelayedHuman(int(round(d)), tau_nm, sigma_m)


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
    human = delayed_human(human_model, design.dt, delay_s, tau_nm, sigma_m)
    if likelihood == "angles" and human is None:
        raise ValueError("--likelihood angles is the delayed human's likelihood of the encoder's angles; "
                         "use it with --human-model delayed")
    study = load_study(path, design)
    for s in study.segments:
        if s.u_H is None and likelihood == "torques":
            hint = ("use --likelihood angles (the delayed human's likelihood of the recorded angles), "
                    if human is not None else "")
            raise StudyFileError(study.path, f"column is missing; segment {s.label} needs it for the likelihood "
                                 f"({hint}reconstruct it from the angle first, or use scioc identify)", column="u_H")
    if sets_analysis(experiment_file):
        settings = IdentifySettings.for_design(design, assistant_model=assistant_model, adequacy_boot=0)
    else:
        settings = IdentifySettings(window_start=None, window_seconds=None, preview=0.0,
                                    assistant_model=assistant_model, adequacy_boot=0, design=design)
    prepared = prepare_study(study, settings)
    plant = discretize(design.dt, design.wheel)
    if human is None:
        ll = loglik_segments(th, [p.segment for p in prepared.segments], plant).loglik
    elif likelihood == "angles":
        ll = np.array([window_loglik(th, human.tau_nm, human.sigma_m, human.delay, w, plant, sigma_y=design.encoder_sd,
                                     params=design.wheel).loglik
                       for w in angle_windows(prepared.segments, range(len(prepared.segments)))])
    else:
        ll = _delayed_loglik(th, prepared.segments, plant, human, design)
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


def _delayed_loglik(theta, prepared, plant, human: DelayedHuman, design: Design) -> np.ndarray:
    """The delayed human's log-likelihood of each prepared segment (batched by length)."""
    lag = lag_coefficients(human.tau_nm, plant.dt, design.wheel)
    tau0, _ = window_tau0([p.warmup for p in prepared], lag.a, lag.alpha)
    ll = np.empty(len(prepared))
    by_len: dict = {}
    for i, p in enumerate(prepared):
        by_len.setdefault((p.segment.K, p.segment.u_A.shape[0]), []).append(i)
    for idx in by_len.values():
        batch = prepare_batch(plant, [prepared[i].segment for i in idx])
        ll[idx] = delayed_loglik_grad(theta, batch, plant, tau_nm=human.tau_nm, sigma_m=human.sigma_m,
                                      delay=human.delay, tau0=tau0[idx], params=design.wheel).loglik
    return ll
