"""Benchmark of the second built-in example (``data/examples/three-assistants``): identification and the full fit.

The example differs from the paper's study in every respect (rate, wheel, torque sensor, three levels
with linear assistants, trials). Both stages run as ``scioc identify`` and ``scioc fit`` do.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from scioc.pipelines.experiment import load_experiment
from scioc.pipelines.identify import identify_prepared
from scioc.pipelines.io import load_study
from scioc.pipelines.prepare import IdentifySettings, prepare_study
from scioc.pipelines.simulate import simulate_to_dir

#: The example's experiment file.
EXAMPLE = Path(__file__).resolve().parents[2] / "data" / "examples" / "three-assistants" / "experiment.toml"


def bench_example(*, fit: bool = True, seed: int = 2018) -> dict:
    """Wall times of identifying (adequacy checks included) and fitting the example study."""
    design = load_experiment(EXAMPLE)
    settings = IdentifySettings.for_design(design)
    with tempfile.TemporaryDirectory() as tmp:
        sim = simulate_to_dir(Path(tmp) / "data", design=design, seed=seed)
        t0 = time.perf_counter()
        prepared = prepare_study(load_study(sim["study"], design), settings)
        ident = identify_prepared(prepared)
        out = {"segments": len(prepared.segments), "units": int(len(ident.estimates)),
               "samples_per_segment": int(prepared.segments[0].segment.K),
               "identify_s": time.perf_counter() - t0, "identify_parts_s": ident.timing,
               "adequacy_verdict": ident.adequacy["verdict"]}
        if fit:
            from scioc.pipelines.fit import fit_to_dir  # lazy: PyMC takes seconds to import

            t0 = time.perf_counter()
            paths = fit_to_dir(sim["study"], Path(tmp) / "fit", seed=seed, settings=settings, prepared=prepared,
                               experiment_file=sim["experiment"], truth_dir=Path(tmp) / "data")
            out["fit_s"] = time.perf_counter() - t0
            side = json.loads(Path(paths["sidecar"]).read_text())
            out["fit_parts_s"] = side["seconds"]
            out["fit_convergence_verdict"] = side["convergence_verdict"]
    return out


def format_example(res: dict) -> str:
    lines = ["", f"Second example (data/examples/three-assistants): {res['units']} units, {res['segments']} trials of "
                 f"{res['samples_per_segment']} samples at 200 Hz",
             f"  identify (reconstruction, optimization, adequacy checks): {res['identify_s']:.1f} s; adequacy "
             f"verdict {res['adequacy_verdict']}"]
    if "fit_s" in res:
        lines.append(f"  full hierarchical fit (scioc fit: 4 chains × 1000 draws, both models, LOO, checks): "
                     f"{res['fit_s']:.0f} s; sampler convergence {res['fit_convergence_verdict']}")
    return "\n".join(lines)
