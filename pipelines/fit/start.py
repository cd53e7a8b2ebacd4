"""Where a hierarchical fit's chains start: near the ML estimates of ``scioc identify``.

PyMC's start (the population centres, offsets of 0) lies far from a posterior whose units the data fix tightly, and
the first warm-up draws then take very deep trees. :func:`start_point` minimizes over the free variables::

    -log p_prior(free variables)  +  1/2 sum_units sum_q ((q(free) - q_ML) / se_q)^2

q over the unit quantities the ML estimates give (log θ1, log R, θ2 per unit; τ_nm, σ_m per subject): a Gaussian
stand-in for the likelihood. The population scales are held, since the optimum over them is a funnel's neck: at
their units' spread (:func:`scale_estimate`) where :data:`SCALE_TARGETS` names them, else at PyMC's initial point.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: Unit targets: model deterministic -> (estimate column, SE column, transform to the deterministic's scale).
UNIT_TARGETS = {"log_theta1": ("theta1", "se_log_theta1", np.log), "log_R": ("R", "se_log_R", np.log),
                "theta2": ("theta2", "se_theta2", None)}
#: Subject quantities (per-subject parameters of the delayed model): the inverse-variance mean of the subject's units.
SUBJECT_TARGETS = {"tau_nm": ("tau_nm", "se_tau_nm"), "sigma_m": ("sigma_m", "se_sigma_m")}
#: Smallest SE a target is given (relative scale of its quantity: log units, s, N·m), so that one unit's
#: near-zero SE does not make the stand-in a constraint.
SE_FLOOR = {"log_theta1": 0.05, "log_R": 0.1, "theta2": 0.02, "tau_nm": 0.002, "sigma_m": 0.005}
#: The optimizer's box on every unconstrained coordinate (exp(-50) is still a positive scale).
UNCONSTRAINED_BOUND = 50.0
#: Population scales held at their units' spread: scale -> (unit target, values): "baseline" the first level's,
#: "shift" each later level's change from it, "zero" all (a half-normal population: the spread about 0).
SCALE_TARGETS = {"sigma_log_theta1": ("log_theta1", "baseline"), "sigma_beta": ("log_theta1", "shift"),
                 "sigma_log_R": ("log_R", "baseline"), "sigma_beta_log_R": ("log_R", "shift"),
                 "tau_theta2": ("theta2", "zero"), "tau_nm_scale": ("tau_nm", "zero"),
                 "sigma_m_scale": ("sigma_m", "zero")}


def scale_estimate(values, se, *, centred: bool, upper: float) -> float | None:
    """The spread s of a population from its units' estimates v_i and SEs se_i (None with too few).

    The maximum over t = log s of  t + Σ_i log N(v_i; c, s² + se_i²), c fitted (``centred``) or 0, s <= ``upper``:
    type-II maximum likelihood on the log scale the sampler moves s on (t is its Jacobian). Where the values agree
    within their SEs it is about se/√(n - 1), not the funnel's neck s = 0 of a maximum over s itself.
    """
    from scipy.optimize import minimize

    v, e = np.asarray(values, dtype=float).ravel(), np.asarray(se, dtype=float).ravel()
    ok = np.isfinite(v) & np.isfinite(e)
    v, e2 = v[ok], e[ok] ** 2
    if v.size < 2 or not np.isfinite(upper) or upper <= 0:
        return None

    def negative(p):
        t, c = p[0], (p[1] if centred else 0.0)
        V = np.exp(2 * t) + e2
        return -t + 0.5 * float(np.sum(np.log(V) + (v - c) ** 2 / V))

    t_max = float(np.log(upper))
    x0, bounds = [min(t_max, float(np.log(np.std(v) + np.sqrt(np.mean(e2)))))], [(-UNCONSTRAINED_BOUND, t_max)]
    if centred:
        x0, bounds = x0 + [float(np.mean(v))], bounds + [(None, None)]
    res = minimize(negative, x0, method="L-BFGS-B", bounds=bounds)
    return float(np.exp(res.x[0])) if np.isfinite(res.fun) else None


def _held_scale_values(model, targets: dict) -> dict:
    """RV name -> its start (constrained) for the held scales of :data:`SCALE_TARGETS` that ``targets`` inform
    (log-transformed ones), never above PyMC's initial point (the prior's scale)."""
    from pymc.logprob.transforms import LogTransform

    ip = model.initial_point()
    out = {}
    for name, (target, which) in SCALE_TARGETS.items():
        rv = model.named_vars.get(name)
        if (rv is None or rv not in model.free_RVs or target not in targets
                or not isinstance(model.rvs_to_transforms.get(rv), LogTransform)):
            continue
        value, se = targets[target]
        if which == "zero":
            groups = [(value, se, False)]
        elif which == "baseline":
            groups = [(value[:, 0], se[:, 0], True)]
        else:
            groups = [(value[:, j] - value[:, 0], np.hypot(se[:, j], se[:, 0]), True)
                      for j in range(1, value.shape[1])]
        t0 = np.asarray(ip[model.rvs_to_values[rv].name], dtype=float)
        uppers = np.broadcast_to(np.exp(t0), (len(groups),))
        est = [scale_estimate(v, e, centred=c, upper=float(u)) for (v, e, c), u in zip(groups, uppers)]
        if t0.size == len(est) and all(x is not None for x in est):
            out[name] = np.asarray(est, dtype=float).reshape(t0.shape)
    return out


def scale_sources(model, estimates: pd.DataFrame | None) -> dict:
    """Where each held population scale of ``model`` starts: ``"units' spread"`` where the estimates inform it
    (:func:`scale_estimate`), else ``"PyMC's initial point"`` (a scale without targets, such as s_m²)."""
    informed = set() if estimates is None or estimates.empty else set(_held_scale_values(model, _targets(model,
                                                                                                         estimates)))
    return {rv.name: "units' spread" if rv.name in informed else "PyMC's initial point"
            for rv in model.free_RVs if _is_population_scale(model, rv)}


def _se_at_bound(value, se) -> np.ndarray:
    """The SE, 0 (so the floor) where the estimate sits at its bound 0 without an SE: without a target such a τ_nm
    would start at the prior's scale, where the log-likelihood is so low that the chains never leave."""
    value, se = np.asarray(value, dtype=float), np.asarray(se, dtype=float)
    return np.where(np.isnan(se) & (value == 0.0), 0.0, se)


def _targets(model, estimates: pd.DataFrame) -> dict:
    """name -> (target array, SE array) in the model's dims (subject, condition) or (subject,); every SE floored at
    :data:`SE_FLOOR` (NaN where there is none), a subject's both before and after combining its units."""
    subjects = [str(s) for s in model.coords["subject"]]
    levels = [str(c) for c in model.coords.get("condition", ())]
    est = estimates.assign(subject=estimates["subject"].astype(str), condition=estimates["condition"].astype(str))
    by_unit = est.set_index(["subject", "condition"])
    out = {}
    for name, (col, se_col, f) in UNIT_TARGETS.items():
        if name not in model.named_vars or col not in est or se_col not in est:
            continue
        idx = pd.MultiIndex.from_product([subjects, levels])
        value = by_unit[col].reindex(idx).to_numpy(float).reshape(len(subjects), len(levels))
        se = _se_at_bound(value, by_unit[se_col].reindex(idx).to_numpy(float).reshape(len(subjects), len(levels)))
        se = np.maximum(se, SE_FLOOR[name])  # NaN stays NaN
        out[name] = (f(value) if f is not None else value, se)
    for name, (col, se_col) in SUBJECT_TARGETS.items():
        if name not in model.named_vars or col not in est or se_col not in est:
            continue
        value, se = [], []
        for s in subjects:
            rows = est[est["subject"] == s]
            v = rows[col].to_numpy(float)
            e = np.maximum(_se_at_bound(v, rows[se_col].to_numpy(float)), SE_FLOOR[name])
            ok = np.isfinite(v) & np.isfinite(e)
            w = 1.0 / e[ok] ** 2
            value.append(float(np.sum(w * v[ok]) / np.sum(w)) if ok.any() else np.nan)
            se.append(float(np.sqrt(1.0 / np.sum(w))) if ok.any() else np.nan)
        out[name] = (np.array(value), np.maximum(np.array(se), SE_FLOOR[name]))  # the subject's SE floored too
    return out


def _is_population_scale(model, rv) -> bool:
    """A positive (transformed) free variable without a subject dimension: a population's scale."""
    return model.rvs_to_transforms.get(rv) is not None and "subject" not in (model.named_vars_to_dims.get(rv.name) or ())


def _held(model, rv) -> bool:
    """Held at PyMC's initial point: a population's scale, or a discrete variable (the sampled delays)."""
    return _is_population_scale(model, rv) or rv.dtype.startswith("int")


def held_mask(model, point_map_info) -> np.ndarray:
    """Which coordinates of the joined unconstrained vector (``point_map_info`` in ``model.free_RVs``' order) are
    held: population scales and discrete variables (module docstring)."""
    return np.concatenate([np.full(size, _held(model, rv))
                           for rv, (_, _, size, _) in zip(model.free_RVs, point_map_info)])


def start_point(model, estimates: pd.DataFrame | None, *, max_iter: int = 2000) -> dict | None:
    """Initial values (RV name -> value, constrained scale, as PyMC's ``initvals``) near the ML estimates (module
    docstring); None without estimates with the cost targets, or when the optimizer does not improve on its start or
    reaches its box. Units without a finite estimate or SE do not pull, but for an estimate at its bound 0."""
    if estimates is None or estimates.empty:
        return None
    import pytensor
    import pytensor.tensor as pt
    from pymc.blocking import DictToArrayBijection, RaveledVars
    from pymc.pytensorf import compile as compile_pymc
    from pymc.pytensorf import join_nonshared_inputs
    from scipy.optimize import minimize

    targets = _targets(model, estimates)
    if not targets or any(name in model.named_vars and name not in targets for name in UNIT_TARGETS):
        return None  # without every unit cost target, units the targets leave free collapse onto their population
    penalty = pt.constant(0.0)
    for name, (value, se) in targets.items():
        ok = np.isfinite(value) & np.isfinite(se)
        scale = np.where(ok, np.nan_to_num(se, nan=1.0), 1.0)
        z = (model.named_vars[name] - np.nan_to_num(value)) / scale
        penalty = penalty + 0.5 * pt.sum(pt.where(ok, z, 0.0) ** 2)
    objective = -model.varlogp + model.replace_rvs_by_values([penalty])[0]
    ip = model.initial_point()
    for name, value in _held_scale_values(model, targets).items():
        ip[model.rvs_to_values[model.named_vars[name]].name] = np.log(value)
    [obj], flat = join_nonshared_inputs(ip, [objective], model.value_vars)
    # PyMC's compile turns a parameter check (sigma > 0, ...) into an objective of +inf, not an exception.
    fn = compile_pymc([flat], [obj, pt.grad(obj, flat)])
    raveled = DictToArrayBijection.map({v.name: ip[v.name] for v in model.value_vars})  # join's order
    x0 = raveled.data.astype(float)
    f0 = float(fn(x0)[0])
    # The box keeps exp() of a log-transformed scale positive in floating point; held coordinates get equal bounds.
    held = held_mask(model, raveled.point_map_info)
    bounds = [(x, x) if h else (-UNCONSTRAINED_BOUND, UNCONSTRAINED_BOUND) for x, h in zip(x0, held)]
    res = minimize(lambda x: tuple(np.asarray(a, float) for a in fn(x)), x0, jac=True, method="L-BFGS-B",
                   bounds=bounds, options={"maxiter": int(max_iter)})
    if not (np.isfinite(res.fun) and res.fun < f0) or np.any(np.abs(res.x[~held]) >= UNCONSTRAINED_BOUND * (1 - 1e-9)):
        return None  # no improvement, or a coordinate at the box
    point = DictToArrayBijection.rmap(RaveledVars(res.x, raveled.point_map_info))  # back to each dtype
    rvs = model.free_RVs
    constrained = pytensor.function(model.value_vars, model.replace_rvs_by_values(rvs), on_unused_input="ignore")
    values = constrained(*[point[v.name] for v in model.value_vars])
    return {rv.name: np.asarray(val) for rv, val in zip(rvs, values)}


__all__ = ["SCALE_TARGETS", "SE_FLOOR", "held_mask", "scale_estimate", "scale_sources", "start_point", "SUBJECT_TARGETS",
           "UNCONSTRAINED_BOUND", "UNIT_TARGETS"]
