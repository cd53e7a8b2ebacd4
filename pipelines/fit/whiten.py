"""Sampling a hierarchical model in per-subject whitened coordinates (:mod:`scioc.models.bayes.whiten`), with nutpie.

1. x̂: from the start, the maximum of the log density over every coordinate but the held population scales (which
   a maximum would send into a funnel's neck), by L-BFGS; kept only if it improves on the start.
2. Each subject's Hessian block at x̂ and each other coordinate's own scale; given ``pivots``, each subject's pivot
   (:func:`scioc.models.bayes.whiten.nearest_fold`) and its ridge's curvature along it.
3. The model in w (:func:`scioc.models.bayes.whiten.whitened_model`) sampled by nutpie's diagonal mass matrix; with a
   ``pilot``, after short runs whose draws measure each block again (docs/decisions/delayed-pilot-run.md).
4. The draws mapped back to the original model's variables; then the pointwise log-likelihood.
"""

from __future__ import annotations

import json
import time

import numpy as np

from scioc.models.bayes.whiten import (
    WHITE,
    block_column,
    block_hessian,
    coordinate_scales,
    nearest_fold,
    pivot_curve,
    ridge_curvature,
    subject_blocks,
    to_unconstrained,
    whitened_model,
    whitening_factors,
)
from scioc.models.bayes.whiten_draws import draws_factors, to_white
from scioc.pipelines.fit.sampling import add_log_likelihood, sample_model
from scioc.pipelines.fit.start import held_mask

#: Most L-BFGS iterations of the search for x̂.
MODE_MAX_ITER = 1000
#: Central-difference step of the Hessian blocks, on the unconstrained scale.
HESSIAN_STEP = 1e-4


def whitening(model, start: dict | None, pivots=None):
    """(logp graph, its flat input, x̂, groups, point_map_info, record, folds) of ``model`` (module docstring, 1-2).

    ``groups`` as :func:`scioc.models.bayes.whiten.to_unconstrained` takes them (one curved group per pivot used);
    ``folds``: per group None, or whether each subject's pivot is signed. ``pivots``: (name, signed) pairs, ``name`` a
    free variable with one value per subject, ``signed`` (n_subjects,) where its coordinate is signed.
    """
    import pytensor.tensor as pt
    from pymc.blocking import DictToArrayBijection
    from pymc.initial_point import make_initial_point_fn
    from pymc.pytensorf import compile as compile_pymc
    from pymc.pytensorf import join_nonshared_inputs
    from scipy.optimize import minimize

    t0 = time.perf_counter()
    point = make_initial_point_fn(model=model, overrides=dict(start or {}), jitter_rvs=set(),
                                  return_transformed=True)(0)
    raveled = DictToArrayBijection.map({v.name: point[v.name] for v in model.value_vars})
    dims = [model.named_vars_to_dims.get(model.values_to_rvs[v].name) for v in model.value_vars]
    blocks = subject_blocks(raveled.point_map_info, dims, len(model.coords["subject"]))
    [logp], flat = join_nonshared_inputs(point, [model.logp()], model.value_vars)
    fn = compile_pymc([flat], [logp, pt.grad(logp, flat)])
    x_hat = raveled.data.astype(float)
    free = ~held_mask(model, raveled.point_map_info)

    def negative(z):
        x = x_hat.copy()
        x[free] = z
        f, g = fn(x)
        return -float(f), -np.asarray(g, dtype=float)[free]

    f0 = negative(x_hat[free])[0]
    res = minimize(negative, x_hat[free], jac=True, method="L-BFGS-B", options={"maxiter": MODE_MAX_ITER})
    moved = bool(np.isfinite(res.fun) and res.fun < f0)
    if moved:
        x_hat = x_hat.copy()
        x_hat[free] = res.x
    t1 = time.perf_counter()
    H = block_hessian(lambda x: fn(x)[1], x_hat, blocks, HESSIAN_STEP)
    L, n_neg = whitening_factors(H)
    others = np.setdiff1d(np.arange(x_hat.size), blocks.ravel())[:, None]
    S = coordinate_scales(lambda x: fn(x)[1], x_hat, others[:, 0], HESSIAN_STEP)
    sd = np.sqrt(np.einsum("ijk,ijk->ij", L, L))  # each coordinate's scale, sqrt(diag(L Lᵀ))
    block_groups, folds, curved = [(blocks, L)], [None], {}
    if pivots:
        n = len(model.coords["subject"])
        names = [name for name, _ in pivots]
        columns = [block_column(raveled.point_map_info, dims, n, model.rvs_to_values[model[p]].name) for p in names]
        signed_by_pivot = np.column_stack([np.broadcast_to(np.asarray(signed, dtype=bool), (n,))
                                           for _, signed in pivots])
        chosen = nearest_fold(x_hat, blocks, L, columns, signed_by_pivot)
        block_groups, folds, ridges, counts = [], [], {}, {}
        for j, (name, column) in enumerate(zip(names, columns)):
            rows = chosen == j
            if rows.any():
                a, ridges[name] = ridge_curvature(lambda x: fn(x)[1], x_hat, blocks[rows], L[rows], column)
                block_groups.append((blocks[rows], L[rows], (column, a)))
                folds.append(signed_by_pivot[rows, j])
                counts[name] = int(rows.sum())
        curved = {"curved_along": counts,
                  "pivot_by_subject": [names[j] for j in chosen], "ridge": ridges,
                  "subjects_without_curvature": sum(r["subjects_without_curvature"] for r in ridges.values()),
                  "largest_shift_in_scales": max(r["largest_shift_in_scales"] for r in ridges.values())}
    record = {"method": "per-subject " + ("whitening curved along each subject's ridge in "
                                          + " or ".join(curved["curved_along"]) if pivots else "affine whitening")
              + " (models/bayes/whiten.py), nutpie's diagonal mass matrix",
              "coordinates_per_subject": int(blocks.shape[1]), "mode_iterations": int(res.nit),
              "mode_log_density_gain": float(f0 - res.fun) if moved else 0.0, "mode_used": moved,
              "subjects_not_at_a_maximum": int(np.sum(n_neg > 0)),
              "scale_range": [float(sd.min()), float(sd.max())], "other_coordinates": int(others.shape[0]),
              "other_scale_range": [float(S.min()), float(S.max())] if others.size else [],
              **curved, "mode_s": t1 - t0, "hessian_s": time.perf_counter() - t1}
    groups = block_groups + ([(others, S)] if others.size else [])
    folds = folds + ([None] if others.size else [])
    return logp, flat, x_hat, groups, raveled.point_map_info, record, folds


def tail_count(groups) -> int:
    """How many subjects' pivots have a tail map (a finite b, :mod:`scioc.models.bayes.pivot_tails`) in ``groups``."""
    tails = [pivot_curve(curve[0])[2] for _, _, *curve in groups if curve]
    return sum(int(np.sum(np.isfinite(b))) for b in tails if b is not None)


def posterior_of(model, x: np.ndarray, point_map_info):
    """The posterior Dataset of ``model`` (free variables, deterministics) at unconstrained draws x (chain, draw, D)."""
    import pytensor
    import xarray as xr
    from pymc.blocking import DictToArrayBijection, RaveledVars

    outs = list(model.free_RVs) + list(model.deterministics)
    f = pytensor.function(model.value_vars, model.replace_rvs_by_values(outs), on_unused_input="ignore")
    chains, draws = x.shape[:2]
    values = {o.name: [] for o in outs}
    for c in range(chains):
        for d in range(draws):
            p = DictToArrayBijection.rmap(RaveledVars(x[c, d], point_map_info))
            for o, v in zip(outs, f(*[p[v.name] for v in model.value_vars])):
                values[o.name].append(np.asarray(v))
    coords = {"chain": np.arange(chains), "draw": np.arange(draws)}
    data = {}
    for o in outs:
        arr = np.stack(values[o.name]).reshape((chains, draws) + np.shape(values[o.name][0]))
        dims = list(model.named_vars_to_dims.get(o.name) or [f"{o.name}_dim_{i}" for i in range(arr.ndim - 2)])
        coords.update({d: np.asarray(model.coords[d]) for d in dims if model.coords.get(d) is not None})
        data[o.name] = (["chain", "draw", *dims], arr)
    return xr.Dataset(data, coords=coords)


def pilot_seeds(seed: int, n: int) -> list[int]:
    """The pilot runs' seeds, from the fit's sampler seed: ``SeedSequence(seed).spawn(n)``, a stream of their own."""
    return [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(int(seed)).spawn(n)]


def nutpie_setting(attrs, *path) -> float | None:
    """One of the settings nutpie sampled with (``path`` into ``sample_stats.attrs``' settings), as a float, or None."""
    try:
        value = json.loads(attrs["inference_library_settings"])["settings"]
        for key in path:
            value = value[key]
        return float(value)
    except (KeyError, TypeError, ValueError):
        return None


def _target_accept(attrs) -> float | None:
    """The target acceptance rate nutpie sampled at, from its settings in ``sample_stats.attrs`` (None if absent)."""
    return nutpie_setting(attrs, "adapt_options", "step_size_settings", "target_accept")


def _pilot_stage(stage, chains: int, nuts: dict | None):
    """One pilot run's (tune, draws, chains, nutpie options) from (tune, draws[, chains[, target_accept[,
    max_tree_depth]]]); None for chains, target_accept or max_tree_depth: the fit's own."""
    stage = tuple(stage)
    bad = ValueError("pilot needs (tune >= 0, draws >= 2[, chains >= 1[, target_accept[, max_tree_depth >= 1]]]) "
                     f"per run; got {stage!r}")
    if not 2 <= len(stage) <= 5:
        raise bad
    tune, draws = int(stage[0]), int(stage[1])
    p_chains = int(stage[2]) if len(stage) > 2 and stage[2] is not None else int(chains)
    accept = stage[3] if len(stage) > 3 else None
    depth = stage[4] if len(stage) > 4 else None
    if (tune < 0 or draws < 2 or p_chains < 1 or (accept is not None and not 0.0 < float(accept) < 1.0)
            or (depth is not None and (int(depth) != depth or depth < 1))):
        raise bad
    own = {**({} if accept is None else {"target_accept": float(accept)}),
           **({} if depth is None else {"maxdepth": int(depth)})}
    return tune, draws, p_chains, ({**(nuts or {}), **own} if own else nuts)


def sample_whitened(model, start: dict | None, *, seed: int, chains: int, draws: int, tune: int,
                    cores: int | None = None, show_progress: bool = False, nuts: dict | None = None,
                    pivots=None, pilot=None):
    """Sample ``model`` in whitened coordinates (module docstring); returns (idata, seconds, record).

    ``idata`` as :func:`scioc.pipelines.fit.sampling.sample_model` returns it; ``seconds`` adds ``whitening``;
    ``record``: what the whitening found, and each pilot run's draws and steps. ``pilot``: runs of (tune, draws[,
    chains[, target_accept[, max_tree_depth]]]), None for the fit's own, each on the coordinates measured on the draws
    of the one before (seeds :func:`pilot_seeds`).
    """
    t0 = time.perf_counter()
    logp, flat, x_hat, groups, info, record, folds = whitening(model, start, pivots)
    white = whitened_model(logp, flat, x_hat, groups)
    t1 = time.perf_counter()
    pilot = [_pilot_stage(stage, chains, nuts) for stage in (pilot or ())]
    spent, refit_s, runs, init = {"sample": 0.0, "compile_and_sample": 0.0}, 0.0, [], None
    for (p_tune, p_draws, p_chains, p_nuts), p_seed in zip(pilot, pilot_seeds(seed, len(pilot))):
        first, sec = sample_model(white, seed=p_seed, chains=p_chains, draws=p_draws, tune=p_tune, cores=cores,
                                  show_progress=show_progress, log_likelihood=False, nuts=p_nuts, initvals=init)
        spent = {k: spent[k] + sec[k] for k in spent}
        t2 = time.perf_counter()
        stats = first["sample_stats"]
        x = to_unconstrained(first["posterior"][WHITE].values, x_hat, groups)
        x_hat, groups, kept = draws_factors(x, x_hat, groups, folds)
        white = whitened_model(logp, flat, x_hat, groups)
        init = {WHITE: to_white(x[0, -1], x_hat, groups)}  # the next run starts where the first chain ended
        refit_s += time.perf_counter() - t2
        attrs = {**first["posterior"].attrs, **stats.attrs}
        runs.append({"tune": p_tune, "draws": p_draws, "chains": int(first["posterior"].sizes["chain"]),
                     "target_accept": _target_accept(attrs), "max_tree_depth": nutpie_setting(attrs, "maxdepth"),
                     "sample_s": sec["sample"],
                     "tuning_leapfrog_steps": int(stats.attrs.get("tuning_leapfrog_steps", 0)),
                     "leapfrog_steps": int(stats["n_steps"].values.sum()),
                     "divergences": int(stats["diverging"].values.sum()), "blocks_kept_from_before": kept,
                     "pivots_with_tail_map": tail_count(groups)})
    if runs:
        record["pilot"] = runs
        record["method"] += (f"; then measured again on the draws of {len(runs)} pilot run(s), each on the last's "
                             "(models/bayes/whiten_draws.py)")
    idata, sec = sample_model(white, seed=seed, chains=chains, draws=draws, tune=tune, cores=cores,
                              show_progress=show_progress, log_likelihood=False, nuts=nuts, initvals=init)
    sec = {**sec, **{k: sec[k] + spent[k] for k in spent}}
    attrs = dict(idata["posterior"].attrs)
    posterior = posterior_of(model, to_unconstrained(idata["posterior"][WHITE].values, x_hat, groups), info)
    posterior.attrs.update(attrs)
    idata["posterior"] = posterior
    t2 = time.perf_counter()
    add_log_likelihood(idata, model)
    sec = {**sec, "whitening": t1 - t0 + refit_s, "log_likelihood": time.perf_counter() - t2}
    return idata, sec, record


__all__ = ["HESSIAN_STEP", "MODE_MAX_ITER", "nutpie_setting", "pilot_seeds", "posterior_of", "sample_whitened",
           "tail_count", "whitening"]
