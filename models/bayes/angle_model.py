"""Hierarchical model of the ``delayed`` human from the encoder's angles (recordings without a torque sensor).

The population and condition blocks are the torque fit's (:func:`scioc.models.bayes.delayed_model.build_delayed_model`);
the likelihood is the angles' (:class:`scioc.models.bayes.angle_op.AngleLoglikOp`), each subject's delay fixed at its
profile maximum as in the torque fit. With ``motor=False`` the human has no delay, lag or motor noise: the max-ent
human seen through the same likelihood, so the two models are scored on the same data.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.basic import Constant

from scioc.models.bayes.angle_op import AngleLoglikOp
from scioc.models.bayes.blocks import Parameterization
from scioc.models.bayes.delayed_blocks import DelayedForm, DelayedPriors, cost_blocks, motor_blocks
from scioc.models.bayes.hierarchical import Priors
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.angles import AngleWindow
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.design import CONDITIONS, WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.units import index_study

#: The cost blocks' default forms in the angle fit: the torque fit's (log R non-centred).
ANGLE_PARAMETERIZATION = Parameterization(R_mc="noncentred", R_sc="noncentred")
#: Name of the observed angles in the model (dims ``segment``, ``sample``).
OBSERVED = "angle"


def build_angle_model(subjects: Sequence, conditions: Sequence, windows: Sequence[AngleWindow], plant: DiscretePlant,
                      *, delay, sigma_y: float, motor: bool = True, priors: Priors = Priors(),
                      delayed_priors: DelayedPriors = DelayedPriors(),
                      parameterization: Parameterization = ANGLE_PARAMETERIZATION,
                      delayed_form: DelayedForm = DelayedForm(), segment_ids: Sequence | None = None,
                      levels: Sequence = CONDITIONS, params: WheelParameters = WheelParameters()) -> pm.Model:
    """The hierarchical model of a study's recorded angles (module docstring).

    ``subjects``, ``conditions``: each window's labels; ``windows``: the recorded windows; ``delay``: each window's
    delay, samples (ignored, 0, with ``motor=False``); ``sigma_y``: the encoder's noise SD, rad. The rest as
    :func:`scioc.models.bayes.delayed_model.build_delayed_model`.
    """
    levels = tuple(str(v) for v in levels)
    index = index_study(subjects, conditions, levels)
    n = len(windows)
    if n != index.subject_idx.shape[0]:
        raise ValueError(f"got {n} windows but {index.subject_idx.shape[0]} subject/condition labels")
    ids = list(range(n)) if segment_ids is None else list(segment_ids)
    if len(ids) != n:
        raise ValueError(f"segment_ids must have {n} entries; got {len(ids)}")
    op = AngleLoglikOp(windows, plant, delay=delay if motor else 0, sigma_y=sigma_y, params=params)
    y_obs = op.data["y"]
    coords = {"subject": index.subjects, "condition": levels, "segment": ids, "sample": np.arange(y_obs.shape[1])}
    L = len(levels)
    effect = {} if L == 2 else {"dims": "contrast"}
    if L > 2:
        coords["contrast"] = levels[1:]
    s_idx, c_idx = index.subject_idx, index.condition_idx

    def logp(value, q11, q22, R, tau_nm, sigma_m, segment, template):
        if not (isinstance(value, Constant) and np.array_equal(value.data, y_obs)):
            raise NotImplementedError("the angle likelihood of this model is bound to the recorded angles")
        ll, _ = op(pt.stack([q11, q22, R]), tau_nm, sigma_m)
        return ll

    def random(q11, q22, R, tau_nm, sigma_m, segment, template, rng=None, size=None):
        return draw_angles(windows, plant, op.delay, sigma_y, params, (q11, q22, R, tau_nm, sigma_m), segment, rng,
                           size)

    with pm.Model(coords=coords) as model:
        _, log_R, theta2, R = cost_blocks(priors, parameterization, L, effect, delayed_priors, delayed_form)
        log_theta1 = model["log_theta1"]
        R_s = R[s_idx, c_idx]
        q11 = pt.exp(log_theta1[s_idx, c_idx] + log_R[s_idx, c_idx])
        q22 = theta2[s_idx, c_idx] * R_s
        if motor:
            tau_nm, sigma_m = motor_blocks(delayed_priors, delayed_form)
            tau_s, sigma_s = tau_nm[s_idx], sigma_m[s_idx]
        else:
            tau_s = sigma_s = pt.zeros(n)
        # the last input, the recorded angles, only gives the draws' length
        pm.CustomDist(OBSERVED, q11, q22, R_s, tau_s, sigma_s, np.arange(n), y_obs, logp=logp, random=random,
                      signature="(),(),(),(),(),(),(k)->(k)", observed=y_obs, dims=("segment", "sample"))
    return model


def draw_angles(windows, plant, delay, sigma_y, params, parameters, segment, rng, size):
    """Recorded angles drawn from the delayed human at ``parameters`` (q11, q22, R, τ_nm, σ_m), each window from its
    own start (its first angle, velocity and arm torque), read by an encoder of noise SD ``sigma_y``; padded as the
    observed angles."""
    shape = tuple(size) if size is not None else np.broadcast_shapes(*(np.shape(p) for p in parameters),
                                                                      np.shape(segment))
    ps = [np.broadcast_to(p, shape) for p in parameters]
    seg = np.broadcast_to(segment, shape)
    width = max(np.asarray(w.angles).shape[0] for w in windows)
    out = np.zeros(shape + (width,))
    for idx in np.ndindex(*shape):
        j = int(seg[idx])
        w = windows[j]
        K = np.asarray(w.angles).shape[0] - 1
        tau = float(ps[3][idx])
        lag = lag_coefficients(tau, plant.dt, params)
        tau0 = float(window_tau0([w.warmup], lag.a, lag.alpha)[0][0])
        draw = sample_delayed([ps[0][idx], ps[1][idx], ps[2][idx]], [float(w.angles[0]), w.velocity0], w.angle_ref,
                              plant, rng, u_A=w.u_A, feedback=w.feedback, tau_nm=tau, sigma_m=float(ps[4][idx]),
                              delay=int(delay[j]), tau0=tau0, n_obs=K, params=params)
        out[idx + (slice(0, K + 1),)] = draw.x[:, 0] + rng.normal(0.0, sigma_y, K + 1)
    return out


__all__ = ["ANGLE_PARAMETERIZATION", "OBSERVED", "build_angle_model", "draw_angles"]
