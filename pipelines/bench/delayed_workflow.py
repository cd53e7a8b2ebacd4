"""The speed goal of the ``delayed`` hierarchical fit, measured on the path a user runs (``scioc bench --parts fit_delayed``).

:func:`bench_delayed_workflow` runs the functions of these commands, with their defaults, and times them::

    scioc simulate --experiment data/examples/paper-torque-sensor/experiment.toml --human H --out D
    scioc identify D/study.parquet --out D/identify_delayed --human-model delayed
    scioc fit D/study.parquet --out D/fit_delayed --human-model delayed \\
        --estimates D/identify_delayed/estimates.parquet

(the paper's study with a torque sensor, each subject's delay at its profile maximum, chains started at
the ML estimates on whitened coordinates). The time judged is the fit's own ``seconds.total_s``.
:data:`WORKFLOW_HUMANS`: ``maxent`` (the paper's agent) and ``kbl`` (Kleinman-Baron-Levison's operator,
whose longer delays make the kernel dearer). :mod:`scioc.pipelines.bench.fit_delayed` measures another path.

:func:`bench_angle_workflow` does the same on the paper's own design, angles only (``scioc bench --parts
fit_angles``): the delayed fit scores the encoder's angles, and the max-ent human is fitted through the same
likelihood (``scioc fit --human-model maxent --likelihood angles``). Its goals: the delayed fit with its
identification within :data:`FIT_ANGLES_GOAL_S`, the max-ent one within :data:`MAXENT_ANGLES_GOAL_S`.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

from scioc.pipelines.experiment import load_experiment
from scioc.pipelines.identify import identify_to_dir
from scioc.pipelines.io import load_study
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.simulate import simulate_to_dir

#: The goal for the full delayed fit (``scioc fit``'s ``seconds.total_s``), s.
FIT_DELAYED_GOAL_S = 900.0
#: The size the goal is for: the default study's segments, chains and draws per chain.
FIT_DELAYED_GOAL_SIZE = {"segments": 84, "chains": 4, "draws": 1000}
#: The study the goal is measured on: the paper's, with a torque sensor.
EXPERIMENT = Path(__file__).resolve().parents[2] / "data" / "examples" / "paper-torque-sensor" / "experiment.toml"
#: The humans ``scioc bench --parts fit_delayed`` fits by default.
WORKFLOW_HUMANS = ("maxent", "kbl")
#: The goal for the delayed fit from angles, identification included, s.
FIT_ANGLES_GOAL_S = 1800.0
#: The goal for the max-ent fit through the angle likelihood, s.
MAXENT_ANGLES_GOAL_S = 900.0
#: The humans ``scioc bench --parts fit_angles`` fits by default: two the max-ent model does not describe.
ANGLE_WORKFLOW_HUMANS = ("kbl", "combined")
#: The true mean shifts of log θ1 (SC against MC) each of them is simulated with: a change and none.
ANGLE_WORKFLOW_EFFECTS = (-0.7, 0.0)


def within_goal(segments: int, chains: int, draws: int, fit_s: float) -> bool | None:
    """Whether a fit of this size met :data:`FIT_DELAYED_GOAL_S`; None for a fit smaller than the goal's size."""
    size = {"segments": segments, "chains": chains, "draws": draws}
    if any(size[k] < v for k, v in FIT_DELAYED_GOAL_SIZE.items()):
        return None
    return fit_s <= FIT_DELAYED_GOAL_S


def bench_delayed_workflow(*, human: str = "maxent", seed: int = 2018, chains: int = 4, draws: int = 1000,
                           tune: int | None = None, n_subjects: int | None = None, adequacy_boot: int | None = None,
                           keep=None) -> dict:
    """Simulate, identify and fit the ``delayed`` human as ``scioc`` does (module docstring) and time it.

    ``n_subjects`` and ``adequacy_boot`` shrink it for tests (no verdict on the goal, :func:`within_goal`).
    ``keep``: a new folder that keeps ``data/``, ``identify_delayed/`` and ``fit_delayed/`` (default: a
    temporary one). Returns :func:`summarize`'s dict: settings, seconds (identify, fit, sample), the
    sampler's steps and gradients, convergence, adequacy, recovery of the truth and the goal's verdict.
    """
    design = load_experiment(EXPERIMENT)
    settings = IdentifySettings.for_design(design, human_model="delayed")
    if adequacy_boot is not None:
        settings = replace(settings, adequacy_boot=adequacy_boot)
    with _workspace(keep) as root:
        _, identify_s, side, res = _delayed_workflow(root, design, settings, human=human, seed=seed,
                                                     n_subjects=n_subjects, chains=chains, draws=draws, tune=tune)
    return summarize(side, res, human=human, identify_s=identify_s)


def _delayed_workflow(root: Path, design, settings, *, human: str, seed: int, n_subjects, chains: int, draws: int,
                      tune):
    """Into ``root``: simulate ``design``, identify the delayed human (timed) and fit it from the estimates.
    Returns (simulate_to_dir's paths, identification seconds, the fit's posterior.json and contrasts.json)."""
    from scioc.pipelines.fit import fit_to_dir  # lazy: PyMC takes seconds to import

    sim = simulate_to_dir(root / "data", design=design, seed=seed, human=human, n_subjects=n_subjects)
    t0 = time.perf_counter()
    prepared = prepare_study(load_study(sim["study"], design), settings)
    identify_to_dir(sim["study"], root / "identify_delayed", settings, show_progress=False, prepared=prepared,
                    experiment_file=sim["experiment"])
    identify_s = time.perf_counter() - t0
    paths = fit_to_dir(sim["study"], root / "fit_delayed", seed=seed, chains=chains, draws=draws, tune=tune,
                       settings=settings, prepared=prepared, experiment_file=sim["experiment"],
                       truth_dir=root / "data", estimates_path=root / "identify_delayed" / "estimates.parquet")
    return (sim, identify_s, json.loads(Path(paths["sidecar"]).read_text()),
            json.loads(Path(paths["contrasts"]).read_text()))


def bench_angle_workflow(*, human: str = "kbl", effect: float = ANGLE_WORKFLOW_EFFECTS[0], seed: int = 2018,
                         chains: int = 4, draws: int = 1000, tune: int | None = None, n_subjects: int | None = None,
                         adequacy_boot: int | None = None, keep=None) -> dict:
    """Simulate the paper's design (angles only) with the true mean shift ``effect`` of log θ1, identify and fit the
    ``delayed`` human from the angles and the max-ent human through the same likelihood, as ``scioc`` does, and time
    it (module docstring). The other arguments as :func:`bench_delayed_workflow`'s; ``keep`` also keeps
    ``fit_angles/``. Returns the delayed fit's :func:`summarize`, with ``maxent`` (:func:`summarize_maxent`) and
    the goals' verdicts."""
    from scioc.models.design import STUDY
    from scioc.pipelines.fit import fit_to_dir  # lazy: PyMC takes seconds to import

    design = replace(STUDY, effects=(float(effect),))
    settings = IdentifySettings.for_design(design, human_model="delayed")
    maxent_settings = IdentifySettings.for_design(design)
    if adequacy_boot is not None:
        settings = replace(settings, adequacy_boot=adequacy_boot)
        maxent_settings = replace(maxent_settings, adequacy_boot=adequacy_boot)
    with _workspace(keep) as root:
        sim, identify_s, side, res = _delayed_workflow(root, design, settings, human=human, seed=seed,
                                                       n_subjects=n_subjects, chains=chains, draws=draws, tune=tune)
        mpaths = fit_to_dir(sim["study"], root / "fit_angles", seed=seed, chains=chains, draws=draws, tune=tune,
                            settings=maxent_settings, experiment_file=sim["experiment"], truth_dir=root / "data",
                            human_model="maxent", likelihood="angles")
        mside = json.loads(Path(mpaths["sidecar"]).read_text())
        mres = json.loads(Path(mpaths["contrasts"]).read_text())
    out = summarize(side, res, human=human, identify_s=identify_s,
                    experiment=f"the paper's design, angles only, true shift of log θ1 {float(effect):g}")
    out["maxent"] = summarize_maxent(mside, mres)
    full = within_goal(side["n_segments"], chains, draws, 0.0) is not None
    out["goals"] = {"delayed_s": FIT_ANGLES_GOAL_S, "maxent_s": MAXENT_ANGLES_GOAL_S,
                    "delayed_met": (identify_s + out["seconds"]["fit"] <= FIT_ANGLES_GOAL_S) if full else None,
                    "maxent_met": (out["maxent"]["fit_s"] <= MAXENT_ANGLES_GOAL_S) if full else None}
    out["within_goal"] = None  # the torque fit's goal does not apply
    return out


def summarize_maxent(side: dict, res: dict) -> dict:
    """The max-ent fit through the angle likelihood: its time, sampler, convergence, adequacy and β."""
    diag = side["diagnostics"]["condition"]
    truth = res.get("truth") or {}
    return {"fit_s": float(side["seconds"]["total_s"]), "likelihood": side.get("likelihood"),
            "divergences": diag["sampler"]["divergences"], "convergence_verdict": diag["convergence_verdict"],
            "adequacy": {k: res["adequacy"][k] for k in ("verdict", "segments", "segments_flagged")},
            "beta": truth.get("beta")}


def format_angle_workflow(res: dict) -> str:
    """The angle workflow as plain text: the delayed fit (:func:`format_delayed_workflow`), the max-ent one, goals."""
    g, m = res["goals"], res["maxent"]
    verdict = {None: "not this size", True: "met", False: "NOT met"}
    total = res["seconds"]["identify"] + res["seconds"]["fit"]
    lines = [format_delayed_workflow(res),
             f"  identification and delayed fit together {total:.0f} s (goal ≤ {g['delayed_s']:.0f} s: "
             f"{verdict[g['delayed_met']]})",
             f"  max-ent fit through the angle likelihood: {m['fit_s']:.0f} s (goal ≤ {g['maxent_s']:.0f} s: "
             f"{verdict[g['maxent_met']]}); sampler convergence {m['convergence_verdict']} ({m['divergences']} "
             f"divergent); adequacy {m['adequacy']['verdict']} ({m['adequacy']['segments_flagged']} of "
             f"{m['adequacy']['segments']} segments flagged)"]
    b = m["beta"]
    if b:
        lines.append(f"  max-ent β = {b['posterior_mean']:.3f}, 94 % HDI [{b['hdi'][0]:.3f}, {b['hdi'][1]:.3f}] "
                     f"(truth {b['truth']:g}: {'inside' if b['in_hdi'] else 'OUTSIDE'})")
    return "\n".join(lines)


def refuse_used_folder(keep) -> Path:
    """``keep`` as a Path; ValueError if it exists and is not an empty folder (a benchmark keeps its files in a new
    one, never beside or over another run's)."""
    keep = Path(keep)
    if keep.exists() and (not keep.is_dir() or any(keep.iterdir())):
        raise ValueError(f"{keep} exists and is not empty: the benchmark keeps its study, estimates and fit in a new "
                         "folder")
    return keep


@contextmanager
def _workspace(keep):
    """The folder the benchmark writes into: ``keep`` (kept; must not hold anything yet), else a temporary one."""
    if keep is None:
        with tempfile.TemporaryDirectory() as tmp:
            yield Path(tmp)
        return
    keep = refuse_used_folder(keep)
    keep.mkdir(parents=True, exist_ok=True)
    yield keep


def summarize(side: dict, res: dict, *, human: str, identify_s: float, experiment: str | None = None) -> dict:
    """:func:`bench_delayed_workflow`'s result from a delayed fit's ``posterior.json`` and ``contrasts.json``
    (``experiment``: what was simulated, default :data:`EXPERIMENT`)."""
    diag, sec = side["diagnostics"]["condition"], side["seconds"]
    st, smp = side["sampler"], diag["sampler"]
    chains, draws, tune = st["chains"], st["draws"], st["tune"]
    cores = min(int(st["cores"]), chains)
    pilots = (side.get("whitening") or {}).get("pilot") or []
    pilot_gradients = sum(p["tuning_leapfrog_steps"] + p["leapfrog_steps"] for p in pilots)
    gradients = (chains * (tune * smp["tuning_mean_steps_per_draw"] + draws * smp["mean_steps_per_draw"])
                 + pilot_gradients)
    delays = [u["delay_samples"] for u in side["delay"]["by_unit"].values()]
    truth = res.get("truth") or {}
    fit_s = float(sec["total_s"])
    return {
        "settings": {"human": human,
                     "experiment": experiment or str(EXPERIMENT.relative_to(EXPERIMENT.parents[3])),
                     "segments": side["n_segments"], "subjects": side["n_subjects"], "K": side["K"],
                     "chains": chains, "draws": draws, "tune": tune, "seed": side["seed"], "cores": cores,
                     "cpus": os.cpu_count(), "delays": [min(delays), max(delays)],
                     "adaptation": st["adaptation"], "delayed_form": side["delayed_form"]},
        "seconds": {"identify": identify_s, "fit": fit_s, "sample": float(sec["condition"]["sample_s"])},
        "sampler": {"warmup_steps_per_draw": smp["tuning_mean_steps_per_draw"],
                    "warmup_steps_by_tenth": smp["tuning_steps_by_tenth"],
                    "steps_per_draw": smp["mean_steps_per_draw"], "divergences": smp["divergences"],
                    "pilot": [{"tune": p["tune"], "draws": p["draws"], "chains": p.get("chains", chains),
                               "steps_per_draw": (p["tuning_leapfrog_steps"] + p["leapfrog_steps"])
                               / (p.get("chains", chains) * (p["tune"] + p["draws"]))} for p in pilots],
                    "gradients": gradients, "ms_per_gradient_on_a_core": 1e3 * sec["condition"]["sample_s"] * cores
                    / gradients},
        "convergence_verdict": diag["convergence_verdict"],
        "worst": {**diag["worst"], "rhat_parameter": max(diag["population"], key=lambda k: diag["population"][k]["rhat"])},
        "adequacy": {k: res["adequacy"][k] for k in ("verdict", "segments", "segments_flagged")},
        "truth": {"beta": truth.get("beta"), "motor": truth.get("motor")},
        "goal_s": FIT_DELAYED_GOAL_S, "within_goal": within_goal(side["n_segments"], chains, draws, fit_s),
    }


def goal_text(res: dict) -> str:
    """Whether the goal was met, or why it does not apply."""
    if "goals" in res:  # the angle workflow's goals count the identification too
        return "its goal, with the identification, below"
    if res["within_goal"] is None:
        g = FIT_DELAYED_GOAL_SIZE
        return (f"the goal ≤ {res['goal_s']:.0f} s is for {g['segments']} segments, {g['chains']} chains × "
                f"{g['draws']} draws: not this size")
    return f"goal ≤ {res['goal_s']:.0f} s: {'met' if res['within_goal'] else 'NOT met'}"


def format_delayed_workflow(res: dict) -> str:
    """One workflow fit as plain text."""
    st, s, smp, w = res["settings"], res["seconds"], res["sampler"], res["worst"]
    beta, motor = res["truth"]["beta"], res["truth"]["motor"] or {}
    lines = [
        "",
        f"Delayed fit as scioc runs it, {st['human']} human ({st['experiment']}: {st['segments']} segments × K = "
        f"{st['K']}, delays {st['delays'][0]}-{st['delays'][1]} samples at the profile maxima; {st['chains']} chains × "
        f"{st['draws']} draws after {st['tune']} warm-up; {st['adaptation']})",
        f"  scioc fit: {s['fit']:.0f} s ({goal_text(res)}); sampling {s['sample']:.0f} s; scioc identify before it "
        f"{s['identify']:.0f} s",
        f"  sampler: {smp['steps_per_draw']:.1f} leapfrog steps per kept draw, {smp['warmup_steps_per_draw']:.1f} per "
        f"warm-up draw (by tenth " + " ".join(f"{x:.0f}" for x in smp["warmup_steps_by_tenth"]) + "); "
        + "".join(f"after a pilot of {p['tune']} + {p['draws']} draws on {p['chains']} chains at "
                  f"{p['steps_per_draw']:.1f} steps per draw; "
                  for p in smp.get("pilot", []))
        + f"{smp['gradients'] / 1e3:.0f} k gradients, {smp['ms_per_gradient_on_a_core']:.1f} ms each on a core; "
        f"{smp['divergences']} divergent",
        f"  sampler convergence: {res['convergence_verdict']} (worst R-hat {w['rhat']:.3f}, {w['rhat_parameter']}; smallest ESS "
        f"{w['ess']:.0f}, {w['ess_parameter']}); adequacy {res['adequacy']['verdict']} "
        f"({res['adequacy']['segments_flagged']} of {res['adequacy']['segments']} segments flagged)",
    ]
    if beta:
        lines.append(f"  β = {beta['posterior_mean']:.3f}, 94 % HDI [{beta['hdi'][0]:.3f}, {beta['hdi'][1]:.3f}] "
                     f"(truth {beta['truth']:g}: {'inside' if beta['in_hdi'] else 'OUTSIDE'})"
                     + "".join(f"; {k}: truth in its interval for {m['truth_in_interval']} of {m['n']}"
                               for k, m in motor.items()))
    return "\n".join(lines)


__all__ = ["ANGLE_WORKFLOW_EFFECTS", "ANGLE_WORKFLOW_HUMANS", "EXPERIMENT", "FIT_ANGLES_GOAL_S", "FIT_DELAYED_GOAL_S", "FIT_DELAYED_GOAL_SIZE",
           "MAXENT_ANGLES_GOAL_S", "WORKFLOW_HUMANS", "bench_angle_workflow", "bench_delayed_workflow",
           "format_angle_workflow", "format_delayed_workflow", "goal_text", "refuse_used_folder", "summarize",
           "summarize_maxent", "within_goal"]
