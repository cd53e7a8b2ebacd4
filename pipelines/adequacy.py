"""Model adequacy of a fitted study: per-segment bootstrap checks and the study verdict.

Per prepared segment: the acquisition chain (fitted policy over the reconstruction span, the
assistant as the human models it, encoder, reconstruction), a bootstrap from the fitted human
model (``maxent``: :mod:`scioc.models.bootstrap`; ``delayed``: :mod:`scioc.models.delayed.bootstrap`)
and the statistics of :mod:`scioc.models.adequacy`, combined into one verdict on the *human model*:
"fail" means the costs, and any difference between conditions, may be artifacts of misfit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scioc.models import adequacy as adq
from scioc.models.assistant import human_feedback
from scioc.models.bootstrap import Chain, bootstrap_records
from scioc.models.delayed.bootstrap import DelayedChain, delayed_records
from scioc.models.design import WheelParameters
from scioc.models.lq import lq_policy
from scioc.models.segment import planning_plant
from scioc.pipelines.prepare import IdentifySettings, assistant_law

#: What each check asks, for the CLI and the report.
CHECK_TEXT = {
    "whiteness": "residual whiteness (autocorrelation of the standardized policy residuals, lags 10-100 ms)",
    "variance": "residual variance (is the torque as variable as R says)",
    "xcorr": "error-to-torque cross-correlation at lags 0-300 ms (reaction delay)",
    "spectrum": "torque spectrum in 5 bands (0-0.5-1.5-4-10-50 Hz)",
    "coverage_angle": "90 % predictive coverage of the recorded angle",
    "coverage_torque": "90 % predictive coverage of the torque",
}
#: The same checks' wording when the human model is ``delayed`` (z: its standardized innovations).
CHECK_TEXT_DELAYED = {
    **CHECK_TEXT,
    "whiteness": "innovation whiteness (autocorrelation of the delayed model's standardized innovations, "
                 "lags 10-100 ms)",
    "variance": "innovation variance (is the torque as variable as the delayed model says)",
}
#: What the bootstrap draws from, per human model (recorded in the summary).
DRAWS_FROM = {
    "maxent": "the fitted max-ent model at theta, its policy noise at the reconstruction's sigma_eps where the "
              "torque is reconstructed (models.bootstrap)",
    "delayed": "the fitted delayed model at theta, tau_nm, sigma_m, delay and tau0, its noises as the model states "
               "(models.delayed.bootstrap)",
}
#: The delayed human's per-segment parameters :func:`assess_study` takes besides θ.
DELAYED_KEYS = ("tau_nm", "sigma_m", "delay", "tau0")


def _acquisition(p, assistant):
    """What every human model's chain takes from a prepared segment: the assistant as the human models it
    (gain, known input from the span's start), the recorded velocity and the reconstruction's filter."""
    d = p.data
    j0 = p.span.start
    if p.segment.feedback is not None:
        if assistant is None:
            raise ValueError("a feedback segment needs the assistant to rebuild its law over the span")
        fb = human_feedback(assistant, d.angle_ref[j0:])
        gain, known = np.asarray(fb.gain, dtype=float), fb.feedforward
    else:
        gain, known = np.zeros(2), d.u_A[j0:]
    velocity = d.velocity
    if velocity is None and not p.reconstructed:  # measured torque: the velocity the plant implies
        velocity = np.full(d.t.shape[0], np.nan)
        velocity[p.rows] = p.velocity
    recon = None
    if p.reconstructed:
        r = p.smoother  # the very filter the recorded segment went through
        recon = (r.F, r.Kg, r.Sv, r.C)
    return gain, known, velocity, recon


def segment_chain(p, theta, plant, *, resolution: float, assistant=None) -> Chain:
    """The max-ent acquisition chain of a prepared segment at θ (past the plan's horizon, a plan to the span's end)."""
    d = p.data
    j0, j1 = p.span.start, p.span.stop
    i0, K, M = p.rows.start, p.segment.K, p.segment.preview
    n = j1 - j0
    end = i0 + K + M  # the plan's last state (sample index in the segment)
    gain, known, velocity, recon = _acquisition(p, assistant)
    plan_plant = planning_plant(plant, gain) if p.segment.feedback is not None else plant
    pol = lq_policy(plan_plant, theta, d.angle_ref[j0 : end + 1], known[: end - j0])
    L, f, S = pol.L, pol.f, pol.S
    if end < j1 - 1:
        tail = lq_policy(plan_plant, theta, d.angle_ref[j0:j1], known[: n - 1])
        L = np.concatenate([L, tail.L[end - j0 :]])
        f = np.concatenate([f, tail.f[end - j0 :]])
        S = np.concatenate([S, tail.S[end - j0 :]])
    scale = 1.0
    if p.reconstructed:
        # Draw the policy noise at the level the reconstruction measured (models.adequacy).
        scale = p.sigma_eps * np.sqrt(2.0 * S[i0 - j0])
    c = np.ascontiguousarray
    return Chain(
        A=c(plant.A), b=c(plant.b), gain=gain, known=c(known[: n - 1], dtype=float),
        L=c(L[: n - 1]), f=c(f[: n - 1]), S=c(S[: n - 1]), x0=c(p.span_state0, dtype=float),
        angle=c(d.angle[j0:j1]), velocity=None if velocity is None else c(velocity[j0:j1]),
        u_H=None if d.u_H is None else c(d.u_H[j0:j1]), u_A=c(d.u_A[j0:j1]), ref=c(d.angle_ref[j0:j1]),
        w0=i0 - j0, K=K, recon=recon, resolution=float(resolution), noise_scale=float(scale))


def delayed_segment_chain(p, theta, plant, *, tau_nm: float, sigma_m: float, delay: int, tau0: float,
                          resolution: float, assistant=None, params: WheelParameters = WheelParameters()
                          ) -> DelayedChain:
    """:func:`segment_chain` for the ``delayed`` human at θ, τ_nm (s), σ_m (N·m), delay (samples), ``tau0`` (N·m).

    Its policy noise is the model's own (:mod:`scioc.models.delayed.bootstrap` says why).
    """
    d = p.data
    j0, j1 = p.span.start, p.span.stop
    i0, K, M = p.rows.start, p.segment.K, p.segment.preview
    gain, known, velocity, recon = _acquisition(p, assistant)
    end = i0 + K + M  # the plan's last state (sample index in the segment)
    c = np.ascontiguousarray
    return DelayedChain(
        plant=plant, params=params, theta=c(theta, dtype=float), tau_nm=float(tau_nm), sigma_m=float(sigma_m),
        delay=int(delay), tau0=float(tau0), gain=gain, feedback=p.segment.feedback is not None,
        known=c(known[: max(end, j1 - 1) - j0], dtype=float), ref=c(d.angle_ref[j0 : max(end + 1, j1)], dtype=float),
        x0=c(p.span_state0, dtype=float), x0_window=c(p.segment.x0, dtype=float), angle=c(d.angle[j0:j1]),
        velocity=None if velocity is None else c(velocity[j0:j1]),
        u_H=None if d.u_H is None else c(d.u_H[j0:j1]), u_A=c(d.u_A[j0:j1]), w0=i0 - j0, K=K, M=M, recon=recon,
        resolution=float(resolution))


def assess_study(prepared, thetas, plant, settings: IdentifySettings, *, delayed: dict | None = None):
    """Bootstrap adequacy of every segment at its fitted human model, and the study verdict.

    Parameters
    ----------
    prepared : list of PreparedSegment
        From :func:`scioc.pipelines.prepare.prepare_segment` with ``settings``.
    thetas : array_like, shape (n, 3)
        [q11, q22, R] per segment.
    plant : DiscretePlant
    settings : IdentifySettings
        ``adequacy_boot`` data sets per segment (segment i draws from
        ``SeedSequence(adequacy_seed).spawn(n)[i]``) and the encoder ``resolution``.
    delayed : dict, optional
        None for the ``maxent`` human; else the ``delayed`` human's :data:`DELAYED_KEYS`, each
        shape (n,): ``tau_nm`` (s), ``sigma_m`` (N·m), ``delay`` (samples), ``tau0`` (N·m).

    Returns
    -------
    columns : DataFrame
        Per segment (per unit with trials, :func:`_per_unit`): ``adequacy_p`` (min-P),
        ``adequacy_flagged`` and ``adequacy_p_<check>``.
    summary : dict
        The verdict (:func:`scioc.models.adequacy.study_verdict`), flagged segments and
        settings; no timings, so the same seed gives the same summary.
    """
    n_boot, seed, design = settings.adequacy_boot, settings.adequacy_seed, settings.design
    thetas = np.asarray(thetas, dtype=float)
    extra = None if delayed is None else _check_delayed(delayed, len(prepared))
    seeds = np.random.SeedSequence(int(seed)).spawn(len(prepared))
    rows, details = [], []
    for i, (p, th, ss) in enumerate(zip(prepared, thetas, seeds)):
        rng = np.random.default_rng(ss)
        law = assistant_law(design, p.data.condition)
        if extra is None:
            chain = segment_chain(p, th, plant, resolution=settings.resolution, assistant=law)
            rec = bootstrap_records(chain, n_boot, rng)
        else:
            chain = delayed_segment_chain(p, th, plant, **{k: v[i] for k, v in extra.items()},
                                          resolution=settings.resolution, assistant=law, params=design.wheel)
            rec = delayed_records(chain, n_boot, rng)
        res = adq.segment_adequacy(rec, design.dt)
        rows.append({"adequacy_p": res.p_segment, "adequacy_flagged": res.p_segment <= adq.SEGMENT_ALPHA,
                     **{f"adequacy_p_{k}": v for k, v in res.p.items()}})
        details.append(res)
    cols = pd.DataFrame(rows)
    keys = [(p.data.subject, p.data.condition) for p in prepared]
    if len(set(keys)) < len(keys):  # trials: one p per unit
        cols, keys = _per_unit(cols, keys)
        rows = cols.to_dict("records")
    summary = adq.study_verdict({k: cols[f"adequacy_p_{k}"].to_numpy() for k in adq.STATISTICS},
                                cols["adequacy_p"].to_numpy())
    flagged = []
    for key, r in zip(keys, rows):
        if r["adequacy_flagged"]:
            checks = sorted((k for k in adq.STATISTICS if r[f"adequacy_p_{k}"] <= adq.SEGMENT_ALPHA),
                            key=lambda k: r[f"adequacy_p_{k}"])
            flagged.append({"subject": key[0], "condition": key[1], "p": r["adequacy_p"],
                            "checks_at_5_percent": checks})
    summary.update({
        "judges": "the human model (does it describe the data?), not the sampler or the optimizer",
        "flagged_segments": flagged,
        "checks": {k: (CHECK_TEXT if extra is None else CHECK_TEXT_DELAYED)[k] for k in adq.STATISTICS},
        "bootstrap": {"replicates_per_segment": int(n_boot), "seed": int(seed),
                      "human_model": "maxent" if extra is None else "delayed",
                      "draws_from": DRAWS_FROM["maxent" if extra is None else "delayed"],
                      "theta": "plug-in (not refitted per replicate: conservative)",
                      "reconstruction": "variances held at the recorded segment's values"},
        "null_statistic_means": _mean_null(details),
    })
    return cols, summary


def _check_delayed(delayed: dict, n: int) -> dict:
    """The delayed human's per-segment parameters as arrays of shape (n,), or ValueError naming the bad one."""
    if not isinstance(delayed, dict) or set(delayed) != set(DELAYED_KEYS):
        got = sorted(delayed) if isinstance(delayed, dict) else type(delayed).__name__
        raise ValueError(f"delayed must be a dict with exactly the keys {', '.join(DELAYED_KEYS)}; got {got}")
    out = {}
    for k in DELAYED_KEYS:
        v = np.asarray(delayed[k], dtype=float)
        if v.shape != (n,) or not np.all(np.isfinite(v)):
            raise ValueError(f"delayed[{k!r}] must hold {n} finite values, one per segment; got shape {v.shape}")
        if k != "tau0" and np.any(v < 0):
            raise ValueError(f"delayed[{k!r}] must be >= 0; got {float(v[v < 0][0])!r}")
        if k == "delay" and np.any(v != np.round(v)):
            raise ValueError(f"delayed['delay'] must be whole samples; got {float(v[v != np.round(v)][0])!r}")
        out[k] = v.astype(np.int64) if k == "delay" else v
    return out


def _per_unit(cols: pd.DataFrame, keys: list):
    """Each unit's p-values as Fisher's combination of its trials' (:func:`scioc.models.adequacy.fisher`).

    Trials are independent given θ, so the combination is a valid (conservative) p-value.
    Returns the columns, one row per unit in order of first appearance, and the units.
    """
    units = list(dict.fromkeys(keys))
    pcols = [c for c in cols.columns if c.startswith("adequacy_p")]
    out = []
    for u in units:
        sel = cols[[k == u for k in keys]]
        row = {c: adq.fisher(sel[c].to_numpy(dtype=float)) for c in pcols}
        row["adequacy_flagged"] = row["adequacy_p"] <= adq.SEGMENT_ALPHA
        out.append(row)
    return pd.DataFrame(out)[list(cols.columns)], units


def _mean_null(details) -> dict:
    """Mean over segments of the recorded and the bootstrap statistics (for the report)."""
    out = {}
    for k in adq.STATISTICS:
        obs = np.mean([np.asarray(d.observed[k], dtype=float) for d in details], axis=0)
        null = np.mean([np.asarray(d.null_mean[k], dtype=float) for d in details], axis=0)
        out[k] = {"observed": np.round(obs, 6).tolist(), "model": np.round(null, 6).tolist()}
    return out


def not_checked(reason: str) -> dict:
    """The adequacy block when no check ran."""
    return {"verdict": "not checked", "reason": reason, "failed_checks": []}


def format_adequacy(summary: dict) -> str:
    """The verdict in a few lines for the console."""
    v = summary.get("verdict")
    if v == "not checked":
        return f"model adequacy: NOT CHECKED ({summary.get('reason', '')})"
    head = ("model adequacy: PASS (no check found the data unlike the fitted model's own data)" if v == "pass" else
            "model adequacy: FAIL: the human model does not describe these data; the identified costs and any "
            "difference between conditions may be artifacts of model misfit")
    lines = [head]
    for k in summary["combined_p"]:
        mark = "FAIL" if k in summary["failed_checks"] else "ok"
        lines.append(f"  {mark:4s} {k:16s} combined p = {summary['combined_p'][k]:.2g}  ({summary.get('checks', CHECK_TEXT)[k]})")
    lines.append(f"  segments flagged at the {summary['segment_alpha']:.0%} per-segment level: "
                 f"{summary['segments_flagged']} of {summary['segments']} "
                 f"(about {summary['segments_flagged_expected_by_chance']:.1f} expected by chance); "
                 f"study verdict at family-wise rate {summary['study_alpha']:.0%}")
    return "\n".join(lines)
