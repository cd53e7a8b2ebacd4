"""The ``maxent`` human model: the paper's maximum-entropy LQ human (Eq. 8, 15, 16).

Identification maximises its exact torque likelihood per unit (:func:`scioc.models.identify.identify_unit`); the
hierarchical fit samples the condition and the pooled models (:mod:`scioc.pipelines.fit.maxent`).
"""

from __future__ import annotations

import numpy as np

from scioc.models.identify import identify_unit
from scioc.models.maxent import forward_optimal_control, loglik_segments
from scioc.models.segment import plan_inputs, prepare_batch
from scioc.pipelines.adequacy import CHECK_TEXT
from scioc.pipelines.human_model.registry import HumanModel, parameterization_text


class MaxEnt(HumanModel):
    name = "maxent"
    description = "the paper's max-ent LQ human"
    adequacy_check_text = CHECK_TEXT
    calibration_levels = ("unit", "study")
    #: ``inertia`` fits a wheel 10 % too heavy; ``ignore-uA`` gives the assistant's torque to the human. The unit
    #: level must catch the first, the study level the second.
    negative_controls = ("inertia", "ignore-uA")
    default_negative_control = {"unit": "inertia", "study": "ignore-uA"}
    #: ``angles``: the delayed human's angle likelihood with no delay, lag or motor noise, which is this human's.
    likelihoods = ("torques", "angles")

    def identify_unit(self, prepared, idx, plant, settings):
        return identify_unit([prepare_batch(plant, [prepared[i].segment]) for i in idx], plant)

    def cross_prediction_parameters(self, row):
        return np.array([row.q11, row.q22, row.R])

    def mean_behaviour(self, p, parameters, plant, settings):
        s = p.segment
        plan_plant, known = plan_inputs(s, plant)  # θ's plan against this segment's assistant
        return forward_optimal_control(parameters, s.x0, s.angle_ref, known, plan_plant)

    def loglik_parameters(self, dt, delay_s, tau_nm, sigma_m):
        if any(v is not None for v in (delay_s, tau_nm, sigma_m)):
            raise ValueError("--delay-s, --tau-nm and --sigma-m apply to --human-model delayed")
        return None

    def loglik(self, theta, prepared, plant, design, parameters, likelihood):
        if likelihood == "angles":
            from scioc.models.delayed import window_loglik
            from scioc.pipelines.prepare import angle_windows

            segs = prepared.segments
            return np.array([window_loglik(theta, 0.0, 0.0, 0, w, plant, sigma_y=design.encoder_sd,
                                           params=design.wheel).loglik
                             for w in angle_windows(segs, range(len(segs)))])
        return loglik_segments(theta, [p.segment for p in prepared.segments], plant).loglik

    def default_tune(self, options):
        from scioc.pipelines.fit.warmup import TUNE

        return TUNE

    def plan(self, ctx):
        from scioc.pipelines.fit.diagnostics import NUTPIE_TARGET_ACCEPT

        angles = ctx.likelihood == "angles"
        return {"models": {"value": "condition effects" if angles else
                           "condition effects, and pooled (for the LOO comparison)",
                           "reason": "the max-ent human's fit of the angles: leave-one-subject-out against the "
                                     "delayed fit of the same angles replaces the pooled model's comparison"
                           if angles else "the max-ent human's fit"},
                "parameterization": {"value": parameterization_text(ctx.form), "reason": ctx.form_reason},
                "tune": {"value": ctx.tune, "reason": "given" if ctx.tune_given else "the default warm-up"},
                "target_accept": {"value": ctx.target_accept or NUTPIE_TARGET_ACCEPT,
                                  "reason": "given" if ctx.target_accept else "nutpie's default"}}

    def fit(self, ctx):
        from scioc.pipelines.fit.maxent import fit_maxent

        return fit_maxent(ctx)

    def subject_loo_terms(self, side, folder, prepared, batch, plant):
        if side.get("likelihood") != "angles":
            return None
        from scioc.models.bayes.delayed_loo import MaxentAngleTerms
        from scioc.pipelines.fit.angles import angle_op

        op = angle_op(prepared, plant, 0)
        return lambda flat: MaxentAngleTerms(op)

    def sampler_record(self, ctx, outcome):
        return {"name": "nutpie", "via": "pymc.sample(nuts_sampler='nutpie')", "adaptation": "diag (nutpie default)"}

    def calibration_replication(self, level):
        if level == "unit":
            from scioc.pipelines.calibrate.unit import unit_replication

            return unit_replication
        from scioc.pipelines.calibrate.study import study_replication

        return study_replication

    def calibration_fingerprint(self, d):
        d.pop("human_model")  # the paper's model is left out, so stored runs keep resuming
        return d

    def posterior_adequacy(self, idata, prepared, plant, side, folder, at):
        from scioc.pipelines.fit.checks import posterior_adequacy

        return posterior_adequacy(idata, prepared, plant, at=at)


MAXENT = MaxEnt()
