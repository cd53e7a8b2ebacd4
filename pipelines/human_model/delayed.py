"""The ``delayed`` human model: the max-ent human with a perceptual delay, a neuromuscular lag and motor noise.

Identification profiles the delay and fits θ, τ_nm and σ_m per unit (:func:`scioc.models.delayed.identify_unit_delayed`),
from the recorded torques, or from the encoder's angles where the torque is reconstructed
(docs/decisions/delayed-angle-likelihood.md). The hierarchical fit is :mod:`scioc.pipelines.fit.delayed`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from scioc.models.delayed import (
    DELAY_GRID_S,
    delay_grid,
    forward_delayed,
    identify_unit_delayed,
    lag_coefficients,
    window_loglik,
    window_tau0,
)
from scioc.models.delayed import loglik_grad as delayed_loglik_grad
from scioc.models.delayed.search import TAU_NM_MAX
from scioc.models.segment import prepare_batch
from scioc.pipelines.adequacy import CHECK_TEXT_DELAYED
from scioc.pipelines.human_model.registry import HumanModel, parameterization_text
from scioc.pipelines.prepare import angle_windows, from_angles
from scioc.pipelines.simulate import BODY_COLUMNS


class DelayedParameters:
    """The delayed human's parameters besides θ: ``delay`` (samples), ``tau_nm`` (s), ``sigma_m`` (N·m)."""

    def __init__(self, delay: int, tau_nm: float, sigma_m: float):
        self.delay, self.tau_nm, self.sigma_m = delay, tau_nm, sigma_m


def arm_torque_at_start(p, tau_nm: float, dt: float, wheel) -> float:
    """The arm torque at the start of prepared segment ``p``'s window for lag ``tau_nm``, where the recorded torques
    before the window leave it (:func:`scioc.models.delayed.window_tau0`)."""
    lag = lag_coefficients(tau_nm, dt, wheel)
    return float(window_tau0([p.warmup], lag.a, lag.alpha)[0][0])


#: Version of how the delayed human's calibration replications simulate and fit; part of their fingerprints.
DELAYED_GENERATOR = ("3: the likelihood's held-torque convention; the delay sampled (NUTS then DelayMetropolis); "
                     "numba-compiled once per worker")
#: Version of how the angle calibration's replications simulate and fit; part of their fingerprints.
ANGLE_GENERATOR = ("1: the physically lagged wheel; start velocity and arm torque from the likelihood's start prior; "
                   "Gaussian encoder noise of the experiment's encoder SD")
#: Tolerance for "the delay is exact", s (delays are whole samples).
DELAY_EXACT_S = 1e-9


#: Drops of a subject's summed profile log-likelihood, nats, within which the grid delays are counted.
PROFILE_DROPS = (3.0, 6.0, 10.0)


def delay_profile_spread(estimates: pd.DataFrame) -> dict:
    """How sharply the data fix each subject's delay: grid delays within :data:`PROFILE_DROPS` nats of its best.

    A subject's profile sums its units' ``profile_loglik``, as the hierarchical model shares the delay
    across levels. Returns the grid size, the subjects and, per drop, the median and range over subjects.
    """
    totals = {}
    for r in estimates.itertuples():
        prof = np.nan_to_num(np.asarray(r.profile_loglik, dtype=float), nan=-np.inf)
        totals[r.subject] = totals.get(r.subject, 0.0) + prof
    totals = {k: v for k, v in totals.items() if np.isfinite(v.max())}  # a unit without any profile value: skip
    if not totals:
        return {"grid_delays": 0, "subjects": 0, "within": {}}
    counts = {d: [int(np.sum(v >= v.max() - d)) for v in totals.values()] for d in PROFILE_DROPS}
    return {"grid_delays": int(len(next(iter(totals.values())))), "subjects": len(totals),
            "within": {f"{d:g}": {"median": float(np.median(c)), "min": int(min(c)), "max": int(max(c))}
                       for d, c in counts.items()}}


def curved_along(counts: dict) -> str:
    """A curved whitening's pivots for the sidecar: the name alone, or each with its number of subjects."""
    if len(counts) == 1:
        return next(iter(counts))
    return ", ".join(f"{name} ({n} subjects)" for name, n in counts.items())


class Delayed(HumanModel):
    name = "delayed"
    description = "with a perceptual delay, a neuromuscular lag and motor noise"
    adequacy_check_text = CHECK_TEXT_DELAYED
    slow_identification = True
    likelihoods = ("torques", "angles")
    calibration_levels = ("unit", "study")
    #: ``no-delay`` fixes the delay at 0; ``inertia`` fits a wheel 10 % too heavy.
    negative_controls = ("no-delay", "inertia")
    default_negative_control = {"unit": "no-delay", "study": "no-delay"}
    calibration_suffix = "-delayed"
    calibration_likelihoods = {"unit": ("torques", "angles"), "study": ("angles",)}

    @property
    def sampler_keys(self):
        from scioc.models.bayes.delayed_blocks import MOTOR_FORMS, R_POPULATIONS
        from scioc.pipelines.fit.delayed import DELAY_MODES
        from scioc.pipelines.fit.delayed_forms import LOG_R_FORMS

        return {"delay": DELAY_MODES, "R_population": R_POPULATIONS, "rho_form": MOTOR_FORMS,
                "log_R_form": LOG_R_FORMS}

    def sampler_options(self, options, source):
        options = super().sampler_options(options, source)
        if "rho_form" in options and options.get("R_population") != "policy_scale":
            raise ValueError(f"{source}: rho_form is the form of R^(-1/2) under R_population = \"policy_scale\": "
                             "set that too")
        return options

    # identification
    def identify_unit(self, prepared, idx, plant, settings):
        batches = [prepare_batch(plant, [prepared[i].segment]) for i in idx]
        angles = angle_windows(prepared, idx) if from_angles(prepared, idx) else None
        # Every grid delay: the fit and the recovery sum each subject's unit profiles over the whole grid.
        return identify_unit_delayed(batches, plant, params=settings.design.wheel,
                                     tau0=[[prepared[i].warmup] for i in idx], angles=angles,
                                     sigma_y=settings.design.encoder_sd, delay_search="grid")

    def estimate_columns(self, e, prepared, idx):
        return {"delay_s": e.delay_s, "tau_nm": e.tau_nm, "sigma_m": e.sigma_m, "se_tau_nm": e.se_tau_nm,
                "se_sigma_m": e.se_sigma_m, "lag_at_bound": e.lag_at_bound,
                "profile_loglik": [float(v) for v in e.profile],
                "likelihood": "angles" if from_angles(prepared, idx) else "torques"}

    def adequacy_parameters(self, prepared, fitted, plant, settings):
        tau0 = np.array([arm_torque_at_start(p, e.tau_nm, plant.dt, settings.design.wheel)
                         for p, e in zip(prepared, fitted)])
        return {"tau_nm": np.array([e.tau_nm for e in fitted]), "sigma_m": np.array([e.sigma_m for e in fitted]),
                "delay": np.array([e.delay for e in fitted], dtype=np.int64), "tau0": tau0}

    def cross_prediction_parameters(self, row):
        return np.array([row.q11, row.q22, row.R]), float(row.tau_nm)

    def mean_behaviour(self, p, parameters, plant, settings):
        theta, tau_nm = parameters
        s, wheel = p.segment, settings.design.wheel
        assistant = {"feedback": s.feedback} if s.feedback is not None else {"u_A": s.u_A}
        return forward_delayed(theta, s.x0, s.angle_ref, plant, tau_nm=tau_nm, params=wheel,
                               tau0=arm_torque_at_start(p, tau_nm, plant.dt, wheel), **assistant)

    def identify_sidecar(self, estimates, settings):
        samples = [int(d) for d in delay_grid(settings.design.dt)]
        # nominal: DELAY_GRID_S; samples and seconds: the delays of estimates.parquet's profile_loglik
        return {"delay_grid": {"nominal_s": list(DELAY_GRID_S), "samples": samples,
                               "seconds": [d * settings.design.dt for d in samples]}}

    def implausible_fields(self, row):
        return {"tau_nm": row.tau_nm, "lag_at_bound": row.lag_at_bound}

    def identify_notes(self, meta):
        if not meta.get("reconstructed_units", 0):
            return []
        return [f"  NOTE: {meta['reconstructed_units']} of {meta['segments']} units have no recorded torque: the "
                "delayed model identified them from their encoder angles (docs/methods.md, \"Human models\"; the "
                "delay and the lag less precisely than from a torque sensor); scioc fit --human-model delayed fits "
                "them from their angles too."]

    # likelihood
    def loglik_parameters(self, dt, delay_s, tau_nm, sigma_m):
        if any(v is None for v in (delay_s, tau_nm, sigma_m)):
            raise ValueError("--human-model delayed needs --delay-s, --tau-nm and --sigma-m")
        delay_s, tau_nm, sigma_m = float(delay_s), float(tau_nm), float(sigma_m)
        top = DELAY_GRID_S[-1]
        if not (np.isfinite(delay_s) and 0.0 <= delay_s <= top + 1e-9):
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
        return DelayedParameters(int(round(d)), tau_nm, sigma_m)

    def loglik(self, theta, prepared, plant, design, human, likelihood):
        segs = prepared.segments
        if likelihood == "angles":
            return np.array([window_loglik(theta, human.tau_nm, human.sigma_m, human.delay, w, plant,
                                           sigma_y=design.encoder_sd, params=design.wheel).loglik
                             for w in angle_windows(segs, range(len(segs)))])
        lag = lag_coefficients(human.tau_nm, plant.dt, design.wheel)
        tau0, _ = window_tau0([p.warmup for p in segs], lag.a, lag.alpha)
        ll = np.empty(len(segs))
        by_len: dict = {}
        for i, p in enumerate(segs):  # batched by length
            by_len.setdefault((p.segment.K, p.segment.u_A.shape[0]), []).append(i)
        for idx in by_len.values():
            batch = prepare_batch(plant, [segs[i].segment for i in idx])
            ll[idx] = delayed_loglik_grad(theta, batch, plant, tau_nm=human.tau_nm, sigma_m=human.sigma_m,
                                          delay=human.delay, tau0=tau0[idx], params=design.wheel).loglik
        return ll

    # hierarchical fit
    def fit_likelihood(self, prepared, requested):
        from scioc.pipelines.fit.delayed import check_angle_fit, likelihood_of
        from scioc.pipelines.io import InputDataError

        found = likelihood_of(prepared)
        if requested == "torques" and found == "angles":
            rec = sum(p.reconstructed for p in prepared.segments)
            raise InputDataError(
                f"{prepared.path}: {rec} of {len(prepared.segments)} segments have no recorded torque (u_H) or are "
                "reconstructed by --reconstruct always; a reconstructed torque is smoothed, which the delayed model's "
                "torque likelihood would read as neuromuscular lag. Fit the encoder's angles (--likelihood angles)")
        chosen = found if requested is None else super().fit_likelihood(prepared, requested)
        if chosen == "angles":
            check_angle_fit(prepared, "profile")
        return chosen

    def default_tune(self, options):
        from scioc.pipelines.fit.warmup import default_tune

        return default_tune(options.get("delay", "profile"))

    def plan(self, ctx):
        from scioc.pipelines.fit.delayed import delayed_choices, unit_delays

        opts = ctx.options
        delays = unit_delays(ctx.prepared, ctx.estimates, ctx.plant, ctx.estimates_path)
        population = opts.get("R_population")
        if population is not None:
            from scioc.models.bayes.delayed_blocks import DelayedPriors

            population = DelayedPriors(R_population=population)
        c = delayed_choices(ctx.prepared, ctx.plant, delays, estimates=ctx.estimates,
                            delay_mode=opts.get("delay", "profile"), delayed_priors=population,
                            rho_form=opts.get("rho_form"), log_R=opts.get("log_R_form"),
                            target_accept=ctx.target_accept)
        return {"models": {"value": "the delayed model with condition effects", "reason": "the delayed human's fit"},
                "delays": {"value": opts.get("delay", "profile"), "reason": delays.source},
                "parameterization": {"value": f"log θ1: {parameterization_text(ctx.form)}; log R: {c.log_R}; θ2: quantile",
                                     "reason": f"{ctx.form_reason}; log R: {c.log_R_reason}"},
                "R_population": {"value": c.delayed_priors.R_population, "reason": c.R_population_reason},
                "lag_and_noise_forms": {"value": f"τ_nm {c.delayed_form.tau_nm}, σ_m {c.delayed_form.sigma_m}, "
                                                 f"ρ {c.delayed_form.rho}", "reason": c.form_reason},
                "adaptation": {"value": "nutpie diag, per-subject whitened, curved along each ridge, after a pilot run"
                               if c.whiten else "PyMC's NUTS (diag) beside DelayMetropolis",
                               "reason": f"with {opts.get('delay', 'profile')} delays"},
                "tune": {"value": ctx.tune, "reason": "given" if ctx.tune_given else
                         "the default warm-up (after the pilot run where there is one)"},
                "target_accept": {"value": c.nuts.get("target_accept"),
                                  "reason": "given" if ctx.target_accept else "the adaptation's default"}}

    def fit(self, ctx):
        from scioc.pipelines.fit.delayed import fit_delayed

        return fit_delayed(ctx)

    def sampler_record(self, ctx, outcome):
        if ctx.options.get("delay", "profile") == "sampled":
            return {"name": "PyMC NUTS + DelayMetropolis", "via": "pymc.sample(step=[DelayMetropolis])",
                    "adaptation": "diag (PyMC's NUTS)"}
        whitening = outcome.sidecar.get("whitening")
        return {"name": "nutpie", "via": "pymc.sample(nuts_sampler='nutpie')",
                "adaptation": f"{outcome.sidecar['nutpie_options']['adaptation']} (nutpie)"
                + (", per-subject whitened" if whitening is not None else "")
                + (", curved along " + curved_along(whitening["curved_along"])
                   if whitening and "curved_along" in whitening else "")
                + (", measured again on a pilot run's draws" if whitening and whitening.get("pilot") else "")}

    def fit_summary_lines(self, side):
        lines = [f"human model: {side['human_model']} (delays: {side['delay']['source']})"]
        population = side.get("delayed_priors", {}).get("R_population")
        if population is not None and "R_population_reason" in side:  # a sidecar may lack the reason
            reason = side["R_population_reason"]
            lines.append(f"population of R: {population} (given)" if reason == "given" else
                         f"population of R, chosen by the estimates: {reason}")
        return lines

    def subject_loo_terms(self, side, folder, prepared, batch, plant):
        from scioc.models.bayes.delayed_loo import AngleSubjectTerms, DelayedSubjectTerms
        from scioc.pipelines.fit.human_models import sidecar_delays, unpooled_log_R_prior

        delay = sidecar_delays(side, folder, prepared)
        warm = [p.warmup for p in prepared.segments]
        base_R = unpooled_log_R_prior(side, folder)
        wheel = prepared.settings.design.wheel
        if side.get("likelihood") == "angles":
            from scioc.pipelines.fit.angles import angle_op

            op = angle_op(prepared, plant, delay)
            return lambda flat: AngleSubjectTerms(flat, op, baseline_log_R_prior=base_R)
        return lambda flat: DelayedSubjectTerms(flat, batch, plant, delay, warm, params=wheel,
                                                baseline_log_R_prior=base_R)

    def calibration_replication(self, level):
        if level == "study":
            from scioc.pipelines.calibrate.study_angles import study_angle_replication

            return study_angle_replication
        from scioc.pipelines.calibrate.unit_delayed import unit_delayed_replication

        return unit_delayed_replication

    def calibration_fingerprint(self, d):
        d["delayed_generator"] = DELAYED_GENERATOR  # a changed simulator or likelihood invalidates stored runs
        if d.get("likelihood") == "angles":
            d["angle_generator"] = ANGLE_GENERATOR
        return d

    def posterior_adequacy(self, idata, prepared, plant, side, folder, at):
        from scioc.pipelines.fit.delayed import Delays, delayed_adequacy
        from scioc.pipelines.fit.human_models import sidecar_delays

        delays = Delays(sidecar_delays(side, folder, prepared), side["delay"]["by_unit"],
                        f"{folder / 'posterior.json'} (delay.by_unit)")
        return delayed_adequacy(idata, prepared, plant, delays, at=at)

    def recovery(self, estimates, truth):
        out = {}
        if set(BODY_COLUMNS) <= set(truth.columns):
            m = estimates.merge(truth.drop_duplicates(["subject", "condition"])[["subject", "condition", "delay_s",
                                                                               "tau_nm", "motor_sd"]],
                                on=["subject", "condition"], suffixes=("", "_true"))
            d_err, t_err = m["delay_s"] - m["delay_s_true"], m["tau_nm"] - m["tau_nm_true"]
            out["delayed"] = {"units": int(len(m)),
                              "delay_exact": int((d_err.abs() < DELAY_EXACT_S).sum()),
                              "delay_mean_error_s": float(d_err.mean()),
                              "delay_mean_abs_error_s": float(d_err.abs().mean()),
                              "tau_nm_mean_error_s": float(t_err.mean()),
                              "tau_nm_mean_abs_error_s": float(t_err.abs().mean()),
                              "sigma_m_mean": float(m["sigma_m"].mean()),
                              "motor_sd_true_mean": float(m["motor_sd"].mean())}
        if "profile_loglik" in estimates.columns:
            out["delay_profile"] = delay_profile_spread(estimates)
        return out


DELAYED = Delayed()

__all__ = ["DELAYED", "DELAY_EXACT_S", "PROFILE_DROPS", "Delayed", "DelayedParameters", "arm_torque_at_start",
           "curved_along", "delay_profile_spread"]
