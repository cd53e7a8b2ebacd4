"""Which subjects' noise the delayed fit samples in polar coordinates (``rho_form = "polar"`` in ``--sampler-config``), and their k.

:mod:`scioc.models.bayes.noise_blocks` straightens a subject's arc ρ² + k σ_m² ≈ c given k; :func:`noise_arcs`
sets ρ² to :data:`RHO2_SCALES` times its ML value, maximizes the likelihood over σ_m² at each, and takes
k = -1 / slope where σ_m² falls by at least :data:`ARC_MIN` of its ML value (else NaN: folded centred coordinates).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

from scioc.models.delayed.likelihood import loglik_grad
from scioc.models.segment import prepare_batch

#: Smallest fall of the maximizing σ_m², from ρ² halved to doubled, relative to its ML value, for polar coordinates.
ARC_MIN = 0.3
#: The multiples of the subject's ρ² at which σ_m² is maximized.
RHO2_SCALES = (0.5, 1.0, 2.0)


def subject_arc(loglik, rho2: float, sigma2: float) -> tuple[float, float]:
    """(fall, k) of one subject, ``loglik(s, v)`` its log-likelihood with ρ² times s and σ_m² = v.

    fall: (v*(½) - v*(2)) / ``sigma2``, v*(s) the maximizing σ_m² in [0, 4 ``sigma2``]; k: -1 / the least-squares
    slope of v* on s ``rho2`` (NaN where the slope is not negative).
    """
    vs = []
    for s in RHO2_SCALES:
        res = minimize_scalar(lambda v: -loglik(s, v), bounds=(0.0, 4.0 * sigma2), method="bounded",
                              options={"xatol": 1e-4 * sigma2})
        vs.append(res.x)
    vs = np.asarray(vs)
    slope = np.polyfit(np.asarray(RHO2_SCALES) * rho2, vs, 1)[0]
    return float((vs[0] - vs[-1]) / sigma2), float(-1.0 / slope) if slope < 0 else float("nan")


def noise_arcs(prepared, plant, estimates: pd.DataFrame, delay_samples, tau0_at, subjects) -> tuple[tuple, dict]:
    """k per subject of ``subjects`` (the model's order; NaN: not polar) and, per subject, its fall and k.

    ``estimates``: per unit ``theta1``, ``theta2``, ``R``, ``tau_nm``, ``sigma_m``; a subject's τ_nm and σ_m are its
    units' means, its ρ² that of its baseline unit. ``tau0_at(position, τ_nm)``: a window's arm torque at its start.
    """
    missing = [c for c in ("theta1", "theta2", "R", "tau_nm", "sigma_m") if c not in estimates.columns]
    if missing:
        raise ValueError(f"polar coordinates need the ML estimates' {', '.join(missing)}")
    rows = {(str(r.subject), str(r.condition)): r for r in estimates.itertuples()}
    baseline = str(prepared.settings.design.ordered_levels[0])
    delay_samples = np.asarray(delay_samples)
    wheel = prepared.settings.design.wheel
    ks, record = [], {}
    for subject in subjects:
        units = [(key, idx) for key, idx in prepared.units.items() if str(key[0]) == str(subject)]
        if not units or any((str(s), str(c)) not in rows for (s, c), _ in units):
            ks.append(float("nan"))  # a unit without ML estimates: no arc to read, the folded centred coordinates
            record[str(subject)] = {"fall": None, "k": None}
            continue
        pos = [i for _, idx in units for i in idx]
        est = [rows[(str(s), str(c))] for (s, c), idx in units for _ in idx]
        R = np.array([e.R for e in est], dtype=float)
        tau = float(np.mean([rows[(str(s), str(c))].tau_nm for (s, c), _ in units]))
        sigma = float(np.mean([rows[(str(s), str(c))].sigma_m for (s, c), _ in units]))
        theta = np.vstack([[e.theta1 for e in est], [e.theta2 for e in est], np.ones(len(est))]) * R
        base = [float(rows[(str(s), str(c))].R) for (s, c), _ in units if str(c) == baseline]
        rho2 = 1.0 / base[0] if base else float("nan")
        if not (np.isfinite(rho2) and rho2 > 0 and np.isfinite(sigma) and sigma > 0 and np.all(np.isfinite(theta))):
            ks.append(float("nan"))
            record[str(subject)] = {"fall": None, "k": None}
            continue
        batch = prepare_batch(plant, [prepared.segments[i].segment for i in pos])
        tau0 = [tau0_at(i, tau) for i in pos]
        d = delay_samples[pos]

        def loglik(s, v):
            return float(loglik_grad(theta / s, batch, plant, tau_nm=tau, sigma_m=np.sqrt(max(v, 0.0)), delay=d,
                                     tau0=tau0, params=wheel).loglik.sum())

        fall, k = subject_arc(loglik, rho2, sigma**2)
        polar = np.isfinite(k) and k > 0 and fall >= ARC_MIN
        ks.append(k if polar else float("nan"))
        record[str(subject)] = {"fall": fall, "k": k if np.isfinite(k) else None}
    return tuple(ks), record


__all__ = ["ARC_MIN", "RHO2_SCALES", "noise_arcs", "subject_arc"]
