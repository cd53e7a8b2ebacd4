"""Posterior predictive check of the fit: exact draws of one subject's segments from the human the likelihood
assumes, stored as the DataTree's ``posterior_predictive`` group and summarized as 5/50/95 % bands (``ppc.parquet``)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd
import xarray as xr

from scioc.models.cost import from_normalized
from scioc.models.delayed.sample import closed_loop, delayed_setup, sample_delayed
from scioc.models.maxent import forward_optimal_control, sample_maxent
from scioc.models.plant import discretize
from scioc.models.segment import plan_inputs
from scioc.pipelines.prepare import PreparedStudy

#: Posterior draws used for the posterior predictive bands.
PPC_DRAWS = 100


class PosteriorPredictive(NamedTuple):
    """What :func:`posterior_predictive` returns.

    Attributes
    ----------
    bands : DataFrame
        One row per window sample k = 0..K of each of the subject's segments: subject, condition (trial), t (s),
        angle_ref, angle, u_H, u_A, ``angle_q05/q50/q95`` (rad), ``u_H_q05/q50/q95`` (N·m), ``angle_opt``,
        ``u_H_opt``; torques NaN at k = K.
    draws : xarray.Dataset
        ``u_H`` (chain, draw, segment, step), N·m, and ``angle`` (chain, draw, segment, sample), rad; one chain,
        ``source_draw`` each draw's flat index into the posterior.
    """

    bands: pd.DataFrame
    draws: xr.Dataset


def posterior_predictive(idata, prepared: PreparedStudy, subject: str, rng: np.random.Generator,
                         n_draws: int = PPC_DRAWS, delayed: dict | None = None) -> PosteriorPredictive:
    """Posterior predictive angle and torque of one subject, every level and trial (ValueError if not in the study).

    For each of ``n_draws`` evenly spaced posterior draws, one exact max-ent demonstration per segment from its x0 and
    reference (planning with the recorded u_A, or in closed loop with the assistant's law); the 5/50/95 % quantiles per
    step; the forward optimal control at the posterior median θ. ``delayed`` (``delay`` per segment, samples; ``tau0``:
    (segment position, τ_nm) -> τ_0, N·m) draws from the ``delayed`` human instead, with its noise-free closed loop.
    """
    design = prepared.settings.design
    plant = discretize(design.dt, design.wheel)
    post = idata["posterior"]
    n_chain, n_draw = post.sizes["chain"], post.sizes["draw"]
    flat = np.linspace(0, n_chain * n_draw - 1, min(n_draws, n_chain * n_draw)).round().astype(int)
    ci, di = np.divmod(flat, n_draw)
    frames, labels, angles, torques = [], [], [], []
    for pos, (p, label) in enumerate(zip(prepared.segments, prepared.labels)):
        if p.data.subject != subject:
            continue
        cond = p.data.condition
        sel = {"subject": subject, "condition": cond}
        lt1 = post["log_theta1"].sel(sel).values[ci, di]
        lR = post["log_R"].sel(sel).values[ci, di]
        t2 = post["theta2"].sel(sel).values[ci, di]
        seg, K = p.segment, p.segment.K
        # The human the likelihood assumes: with Feedback the draws run in closed loop.
        plan_plant, known = plan_inputs(seg, plant)
        ang = np.empty((flat.size, K + 1))
        tq = np.empty((flat.size, K))
        if delayed is None:
            for j in range(flat.size):
                theta = from_normalized(np.exp(lt1[j]), t2[j], np.exp(lR[j]))
                demo = sample_maxent(theta, seg.x0, seg.angle_ref, known, plan_plant, rng)
                ang[j] = demo.x[: K + 1, 0]
                tq[j] = demo.u_H[:K]
            theta = from_normalized(np.exp(np.median(lt1)), np.median(t2), np.exp(np.median(lR)))
            opt = forward_optimal_control(theta, seg.x0, seg.angle_ref, known, plan_plant)
        else:
            opt = delayed_draws(post, ci, di, subject, (lt1, lR, t2), seg, int(delayed["delay"][pos]),
                                lambda tau: delayed["tau0"](pos, tau), plant, design.wheel, rng, ang, tq)
        qa = np.quantile(ang, [0.05, 0.5, 0.95], axis=0)
        qu = np.quantile(tq, [0.05, 0.5, 0.95], axis=0)
        pad = lambda x: np.append(x, np.nan)  # noqa: E731  torques act from k to k + 1: none at k = K
        trial = {} if p.data.trial is None else {"trial": p.data.trial}
        frames.append(pd.DataFrame({
            "subject": subject, "condition": cond, **trial, "t": p.data.t[p.rows], "angle_ref": seg.angle_ref[: K + 1],
            "angle": p.data.angle[p.rows], "u_H": pad(p.u_H[:K]), "u_A": pad(seg.u_A[:K]),
            "angle_q05": qa[0], "angle_q50": qa[1], "angle_q95": qa[2],
            "u_H_q05": pad(qu[0]), "u_H_q50": pad(qu[1]), "u_H_q95": pad(qu[2]),
            "angle_opt": opt.x[: K + 1, 0], "u_H_opt": pad(opt.u_H[:K]),
        }))
        labels.append(label)
        angles.append(ang)
        torques.append(tq)
    if not frames:
        raise ValueError(f"subject {subject!r} is not in the study (subjects: {', '.join(dict.fromkeys(prepared.subjects))})")
    K = torques[0].shape[1]
    coords = {"chain": [0], "draw": np.arange(flat.size), "segment": labels, "step": np.arange(K),
              "sample": np.arange(K + 1), "source_draw": ("draw", flat)}
    draws = xr.Dataset(
        {"u_H": (("chain", "draw", "segment", "step"), np.stack(torques, axis=1)[None]),
         "angle": (("chain", "draw", "segment", "sample"), np.stack(angles, axis=1)[None])},
        coords=coords,
        attrs={"note": f"{flat.size} posterior draws evenly spaced over chains × draws (flat index: source_draw), "
                       f"one exact max-ent demonstration each, for the segments of subject {subject}"})
    return PosteriorPredictive(pd.concat(frames, ignore_index=True), draws)


def delayed_draws(post, ci, di, subject, cost, seg, delay: int, tau0, plant, params, rng, ang, tq):
    """Fill ``ang`` (n, K + 1) and ``tq`` (n, K) with draws of the ``delayed`` human for one segment; return the
    noise-free closed loop at the posterior medians (``x``, ``u_H``) as its "optimal" curves."""
    lt1, lR, t2 = cost
    tau = post["tau_nm"].sel(subject=subject).values[ci, di]
    sig = post["sigma_m"].sel(subject=subject).values[ci, di]
    K = seg.K
    for j in range(tau.size):
        theta = from_normalized(np.exp(lt1[j]), t2[j], np.exp(lR[j]))
        demo = sample_delayed(theta, seg.x0, seg.angle_ref, plant, rng, u_A=None if seg.feedback else seg.u_A,
                              feedback=seg.feedback, tau_nm=float(tau[j]), sigma_m=float(sig[j]), delay=delay,
                              tau0=tau0(float(tau[j])), n_obs=K, params=params)
        ang[j] = demo.x[: K + 1, 0]
        tq[j] = demo.u_H[:K]
    theta = from_normalized(np.exp(np.median(lt1)), np.median(t2), np.exp(np.median(lR)))
    t_med = float(np.median(tau))
    setup = delayed_setup(theta, seg.angle_ref, plant, u_A=None if seg.feedback else seg.u_A, feedback=seg.feedback,
                          tau_nm=t_med, params=params)
    z0 = np.array([seg.x0[0], seg.x0[1], tau0(t_med)])
    # The closed loop as models.delayed.sample_delayed runs it, with every noise 0.
    z, uH, _ = closed_loop(plant.A, plant.b, setup.a, setup.alpha, setup.A, setup.b_c, setup.b_a, setup.gain,
                           setup.feedback, setup.known, setup.policy.L, setup.policy.f, z0, np.zeros((K, 1)),
                           np.zeros((K + delay, 1)), delay, setup.true_A, setup.true_b, setup.physical)
    return NoiseFree(z[:, :2, 0], uH[:, 0])


class NoiseFree(NamedTuple):
    """The ``delayed`` human's closed loop without policy or motor noise (the "optimal" curves of the PPC table)."""

    x: np.ndarray
    u_H: np.ndarray


def constant_data(prepared: PreparedStudy) -> xr.Dataset:
    """What the likelihood conditions on, per segment: x0, the reference, u_A, the time axis and the recorded angle
    (dims ``segment``, ``sample`` k = 0..K, ``step`` k = 0..K-1 and ``state``)."""
    segs = prepared.segments
    K = segs[0].segment.K
    trials = {} if segs[0].data.trial is None else {"trial": ("segment", [p.data.trial for p in segs])}
    return xr.Dataset(
        {"x0": (("segment", "state"), np.stack([p.segment.x0 for p in segs])),
         "t": (("segment", "sample"), np.stack([p.data.t[p.rows] for p in segs])),
         "angle": (("segment", "sample"), np.stack([p.data.angle[p.rows] for p in segs])),
         "angle_ref": (("segment", "sample"), np.stack([p.segment.angle_ref[: K + 1] for p in segs])),
         "u_A": (("segment", "step"), np.stack([p.segment.u_A[:K] for p in segs]))},
        coords={"segment": prepared.labels, "state": ["angle", "velocity"], "step": np.arange(K),
                "sample": np.arange(K + 1),
                "subject": ("segment", prepared.subjects), "condition": ("segment", prepared.conditions),
                **trials},
        attrs={"units": "x0: rad, rad/s; t: s; angle, angle_ref: rad; u_A: N·m"})


def ppc_coverage(ppc: pd.DataFrame) -> dict:
    """Share of the data inside the 5-95 % band, per condition level (0.9 if calibrated per sample; trials pooled)."""
    out = {}
    for c, d in ppc.groupby("condition", sort=False):
        u = d.dropna(subset=["u_H_q05"])
        out[c] = {"u_H": float(((u.u_H >= u.u_H_q05) & (u.u_H <= u.u_H_q95)).mean()),
                  "angle": float(((d.angle >= d.angle_q05) & (d.angle <= d.angle_q95)).mean())}
    return out


__all__ = ["PPC_DRAWS", "PosteriorPredictive", "posterior_predictive", "constant_data", "ppc_coverage"]
