"""Hierarchical Bayesian model of the ``delayed`` human: the max-ent cost blocks plus lag and motor noise.

The cost blocks are :mod:`scioc.models.bayes.hierarchical`'s, θ the commands' cost. Added per subject i, in every
level (they are the person's), with the delay d as data, one per subject (docs/decisions/delayed-plugin-delay.md)::

    τ_nm[i] ~ HalfNormal(s_τ)      neuromuscular lag, s              s_τ ~ HalfN(0.1)
    σ_m[i]  ~ HalfNormal(s_m)      motor-noise SD, N·m per sample    s_m² ~ InvGamma(1, 0.03)
    u_H[segment] ~ delayed(θ, τ_nm[i], σ_m[i], d[segment] | x0, angle_ref, assistant, τ_0)

Within a subject log R is tied to τ_nm and σ_m (policy and motor noise explain the same torque variability), so
log R is non-centred and τ_nm, σ_m centred; and ``scioc fit`` samples each subject's block whitened and curved
along its ridge (docs/decisions/delayed-whitening.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pymc as pm
import pytensor.tensor as pt
from pytensor.graph.basic import Constant

from scioc.models.bayes.blocks import Parameterization
from scioc.models.bayes.delay_step import DelayMetropolis
from scioc.models.bayes.delayed_blocks import (
    DELAYED_POPULATION_PARAMETERS,
    R_POPULATIONS,
    DelayedForm,
    DelayedPriors,
    cost_blocks,
    motor_blocks,
)
from scioc.models.bayes.delayed_op import DelayedLoglikOp, pack_tau0, warmups_of
from scioc.models.bayes.delayed_value import DelayedLoglikValueOp  # noqa: F401 (registers its rewrite)
from scioc.models.bayes.hierarchical import Priors
from scioc.models.delayed import sample_delayed
from scioc.models.delayed.lag import lag_coefficients, window_tau0
from scioc.models.design import CONDITIONS, WheelParameters
from scioc.models.plant import DiscretePlant
from scioc.models.segment import Feedback, as_batch
from scioc.models.units import index_study

#: Name of the sampled delays' grid indices (dims ``subject``) in a model built with ``delay=None``.
DELAY_INDEX = "delay_index"
#: The cost blocks' default forms: log R non-centred (docs/decisions/delayed-log-R-form.md), the rest the max-ent's.
DELAYED_PARAMETERIZATION = Parameterization(R_mc="noncentred", R_sc="noncentred")
#: nutpie's options on the model's own coordinates (``scioc bench-fit``: no mode to whiten at).
DELAYED_NUTS = {"adaptation": "low_rank"}
#: nutpie's target acceptance rate on whitened coordinates (docs/decisions/delayed-target-accept.md).
WHITENED_TARGET_ACCEPT = 0.9
#: The rate with a pilot run and ρ signed, whose pivots' tail maps remove the divergences 0.9 prevents.
PILOT_ADAPTATION_TARGET_ACCEPT = 0.8


def nutpie_options(rho_signed: bool = False) -> dict:
    """nutpie's options on the whitened, curved coordinates of ``scioc fit`` (profile delays): its diagonal mass
    matrix and the target rate; ``rho_signed``: ρ's coordinate is signed."""
    return {"adaptation": "diag",
            "target_accept": PILOT_ADAPTATION_TARGET_ACCEPT if rho_signed else WHITENED_TARGET_ACCEPT}


def _tau0_at(spec, n: int, dt: float, params: WheelParameters):
    """A function (segment j, τ_nm) -> τ_0, N·m: the fixed value, or the warm-up's arm torque at that lag."""
    warmups = warmups_of(spec, n)
    if warmups is not None:
        def from_warmup(j, tau_nm):
            lag = lag_coefficients(tau_nm, dt, params)
            return float(window_tau0([warmups[j]], lag.a, lag.alpha)[0][0])

        return from_warmup
    fixed = pack_tau0(spec, n)[2]
    return lambda j, tau_nm: float(fixed[j])


def build_delayed_model(subjects: Sequence, conditions: Sequence, segments, plant: DiscretePlant, *, delay,
                        tau0=0.0, priors: Priors = Priors(), delayed_priors: DelayedPriors = DelayedPriors(),
                        parameterization: Parameterization = DELAYED_PARAMETERIZATION,
                        delayed_form: DelayedForm = DelayedForm(), segment_ids: Sequence | None = None,
                        levels: Sequence = CONDITIONS, params: WheelParameters = WheelParameters(),
                        delay_grid=None) -> pm.Model:
    """The hierarchical ``delayed`` model of a study (module docstring).

    ``subjects``, ``conditions``, ``segments``, ``plant``, ``priors``, ``parameterization``, ``segment_ids``,
    ``levels``: as :func:`scioc.models.bayes.hierarchical.build_model`. ``delay``: each segment's delay, samples, or
    None to sample one per subject over ``delay_grid`` (:func:`delay_step`). ``tau0``: the arm torque at each
    window's start, N·m (:func:`scioc.models.bayes.delayed_op.pack_tau0`). ``params``: the wheel ``plant`` is from.
    """
    levels = tuple(str(v) for v in levels)
    index = index_study(subjects, conditions, levels)
    batch = as_batch(segments, plant)
    n, K = batch.n, batch.K
    if n != index.subject_idx.shape[0]:
        raise ValueError(f"got {n} segments but {index.subject_idx.shape[0]} subject/condition labels")
    ids = list(range(n)) if segment_ids is None else list(segment_ids)
    if len(ids) != n:
        raise ValueError(f"segment_ids must have {n} entries; got {len(ids)}")
    coords = {"subject": index.subjects, "condition": levels, "segment": ids, "step": np.arange(K)}
    L = len(levels)
    effect = {} if L == 2 else {"dims": "contrast"}
    if L > 2:
        coords["contrast"] = levels[1:]
    s_idx, c_idx = index.subject_idx, index.condition_idx
    sampled = delay is None
    if sampled:
        if delay_grid is None:
            raise ValueError("a sampled delay (delay=None) needs its delay_grid")
        grid = np.asarray(delay_grid, dtype=np.int64)
        if grid.ndim != 1 or grid.shape[0] < 2 or np.any(grid < 0) or np.any(np.diff(grid) <= 0):
            raise ValueError(f"delay_grid must be increasing whole samples >= 0, two or more; got {delay_grid!r}")
        delay = 0
    op = DelayedLoglikOp(batch, plant, delay=delay, tau0=tau0, params=params)
    u_obs = op.bound[3]
    d_seg = op.delay

    def logp(value, q11, q22, R, tau_nm, sigma_m, d, u_A):
        if not (isinstance(value, Constant) and np.array_equal(value.data, u_obs)):
            raise NotImplementedError("the delayed likelihood of this model is bound to the observed torques")
        ll, _ = op(pt.stack([q11, q22, R]), tau_nm, sigma_m, d if sampled else None)
        return ll

    x0 = np.column_stack([batch.x1[:, 0], batch.x2[:, 0]])
    tau0_at = _tau0_at(tau0, n, plant.dt, params)

    def random(q11, q22, R, tau_nm, sigma_m, d, u_A_window, rng=None, size=None):
        # Exact draws of the delayed human (models.delayed.sample_delayed); the last batch axis is the segment.
        shape = tuple(size) if size is not None else np.broadcast_shapes(q11.shape, tau_nm.shape)
        ps = [np.broadcast_to(p, shape) for p in (q11, q22, R, tau_nm, sigma_m, d)]
        out = np.empty(shape + (K,))
        for idx in np.ndindex(*shape):
            j = idx[-1]
            fb = Feedback(batch.fb[j], batch.a[j]) if np.any(batch.fb[j] != 0) else None
            tau = float(ps[3][idx])
            out[idx] = sample_delayed([ps[0][idx], ps[1][idx], ps[2][idx]], x0[j], batch.r[j], plant, rng,
                                      u_A=None if fb is not None else batch.a[j], feedback=fb, tau_nm=tau,
                                      sigma_m=float(ps[4][idx]), delay=int(ps[5][idx]),
                                      tau0=tau0_at(j, tau), n_obs=K, params=params).u_H
        return out

    with pm.Model(coords=coords) as model:
        _, log_R, theta2, R = cost_blocks(priors, parameterization, L, effect, delayed_priors, delayed_form)
        tau_nm, sigma_m = motor_blocks(delayed_priors, delayed_form)
        log_theta1 = model["log_theta1"]
        R_s = R[s_idx, c_idx]
        q11 = pt.exp(log_theta1[s_idx, c_idx] + log_R[s_idx, c_idx])
        q22 = theta2[s_idx, c_idx] * R_s
        if sampled:
            index_var = pm.DiscreteUniform(DELAY_INDEX, 0, grid.shape[0] - 1, dims="subject")
            d = pt.as_tensor(grid)[index_var][s_idx]
        else:
            d = pt.as_tensor(np.asarray(d_seg, dtype=np.int64))
        pm.CustomDist("u_H", q11, q22, R_s, tau_nm[s_idx], sigma_m[s_idx], d, batch.a[:, :K], logp=logp, random=random,
                      signature="(),(),(),(),(),(),(k)->(k)", observed=u_obs, dims=("segment", "step"))
        if sampled:
            # Each subject's log-likelihood, for the delay's Metropolis step (delay_step).
            ll_seg, _ = op(pt.stack([q11, q22, R_s]), tau_nm[s_idx], sigma_m[s_idx], d)
            member = np.zeros((len(index.subjects), n))
            member[s_idx, np.arange(n)] = 1.0
            model.delay_group_loglik = pt.dot(pt.as_tensor(member), ll_seg)
            model.delay_grid = grid
    return model


def delay_step(model: pm.Model, **kwargs) -> DelayMetropolis:
    """The Metropolis step of a sampled-delay model's ``delay_index`` (:func:`build_delayed_model` with delay=None)."""
    if not hasattr(model, "delay_group_loglik"):
        raise ValueError("this model's delays are fixed (built with a delay): there is no delay to sample")
    return DelayMetropolis([model[DELAY_INDEX]], model.delay_group_loglik, model.delay_grid.shape[0], model=model,
                           **kwargs)


__all__ = ["DELAY_INDEX", "DELAYED_NUTS", "DELAYED_PARAMETERIZATION", "DELAYED_POPULATION_PARAMETERS", "DelayedForm",
           "DelayedPriors", "PILOT_ADAPTATION_TARGET_ACCEPT", "R_POPULATIONS", "WHITENED_TARGET_ACCEPT",
           "build_delayed_model", "delay_step", "nutpie_options"]
