"""``scioc loglik``: the max-ent log-likelihood of every segment of a study file under one θ."""

from __future__ import annotations

import numpy as np
import pandas as pd

from models.cost import validate_theta
from models.maxent import loglik_segments
from models.plant import DT_HUMAN, discretize
from pipelines.io import load_study, to_maxent_segment
from pipelines.prepare import with_assistant_model


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


def study_loglik(path, theta, assistant_model: str = "feedback") -> pd.DataFrame:
    """Log-likelihood (nats) of each (subject, condition) segment of a study file.

    Parameters
    ----------
    path : str or Path
        Study file in the data convention with ``velocity`` and ``u_H``.
    theta : array_like, shape (3,)
        [q11, q22, R].
    assistant_model : {"feedback", "exogenous"}
        How the SC human models the assistant (:mod:`pipelines.prepare`).

    Returns
    -------
    DataFrame
        Columns ``subject``, ``condition``, ``K`` (torque samples) and ``loglik``,
        in file order.

    Raises
    ------
    NonFiniteLoglik
        If any segment's log-likelihood is not finite, naming the first such segment.
    """
    th = validate_theta(theta)
    study = load_study(path)
    segs = [with_assistant_model(to_maxent_segment(s, study.path), s.condition, s.angle_ref, 0, assistant_model)
            for s in study.segments]
    res = loglik_segments(th, segs, discretize(DT_HUMAN))
    bad = ~np.isfinite(res.loglik)
    if bad.any():
        seg = study.segments[int(np.flatnonzero(bad)[0])]
        raise NonFiniteLoglik(
            f"{study.path}: the log-likelihood of {int(bad.sum())} of {bad.size} segments is not finite under "
            f"θ = [{', '.join(f'{v:g}' for v in th)}] (first: segment ({seg.subject}, {seg.condition}), "
            f"{res.loglik[bad][0]:g}); θ is beyond what double precision can evaluate for these data")
    return pd.DataFrame(
        {
            "subject": [s.subject for s in study.segments],
            "condition": [s.condition for s in study.segments],
            "K": [s.K for s in study.segments],
            "loglik": res.loglik,
        }
    )
