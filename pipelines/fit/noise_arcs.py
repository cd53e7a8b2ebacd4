"""Which subjects' policy and motor noise the delayed fit samples in polar coordinates, and their k.

:mod:`scioc.models.bayes.noise_blocks` ("polar") straightens a subject's arc ρ² + k σ_m² ≈ c when it is
given the subject's k. :func:`noise_arcs` reads both off the subject's own likelihood at its ML
estimates: with θ1, θ2, τ_nm and the delay held there, ρ² is moved to half, once and twice its ML
value (every unit's R divided by s = ½, 1, 2) and σ_m² is maximized at each (a bounded scalar
search of the exact likelihood, :func:`scioc.models.delayed.likelihood.loglik_grad`). Along an arc the
maximizing σ_m² falls as ρ² grows: k = -1 / slope of the maximizing σ_m² on ρ² (least squares over
the three). The subject goes to polar coordinates where that fall, from s = ½ to s = 2, is at least
:data:`ARC_MIN` of its ML σ_m² (and ρ, σ_m and k are positive); elsewhere k is NaN and the subject
keeps the folded centred coordinates (ρ near 0: no arc; σ_m² barely moved: ρ and σ_m fixed apart).

Measured ad hoc on the full-size ``kbl`` study (``scioc bench --parts fit_delayed --humans kbl``'s
data, 42 subjects, each unit at its own ML delay): the fall was 0.6-1.6 of σ_m² for 9 subjects (k
1.8-4.7), about 0.4 for 3 more, and below 0.25 for the other 30 (ρ at 0, or σ_m fixed whatever ρ):
12 reached the 0.3. Measured on a subset: :mod:`scioc.pipelines.fit.delayed_forms`, "Polar, squared, and
the low-rank mass matrix".
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.optimize import minimize_scalar

from scioc.models.delayed.likelihood import loglik_grad
from scioc.models.segment import prepare_batch

#: Smallest fall of the maximizing σ_m², from ρ² halved to ρ² doubled, relative to its ML value, for polar coordinates.
ARC_MIN = 0.3
#: The multiples of the subject's ρ² at which σ_m² is maximized.
RHO2_SCALES = (0.5, 1.0, 2.0)


def subject_arc(loglik, rho2: float, sigma2: float) -> tuple[float, float]:
    """(fall, k) of one subject: ``loglik(s, v)`` its log-likelihood with ρ² times s and σ_m² = v.

    fall: (v*(½) - v*(2)) / ``sigma2``, v*(s) the maximizing σ_m² (bounded to [0, 4 ``sigma2``]);
    k: -1 / the least-squares slope of v* on s ``rho2`` (NaN where the slope is not negative). Where v* reaches
    the bound 0 at s = 2 the slope is shallower than the arc's and k larger.
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

    ``estimates``: per unit (subject, condition) ``theta1``, ``theta2``, ``R``, ``tau_nm``, ``sigma_m``
    (``scioc identify --human-model delayed``); a subject's τ_nm and σ_m are its units' means, its ρ² that
    of its unit in the design's baseline level (the model's ρ). ``delay_samples``: each segment's delay;
    ``tau0_at(position, τ_nm)``: a window's arm torque at its start (:func:`scioc.pipelines.fit.delayed.tau0_function`).
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
