"""Write this folder's lab export from scioc's simulator: ``python data/examples/lab-export/make_export.py``.

The study is ``scioc simulate`` of this folder's experiment in scioc's own convention (seed
:data:`SEED`). Each subject's runs go to one CSV in the format its ``[columns]`` and ``[units]``
describe, as the rig prints them: time in whole milliseconds, the encoder's angle in degrees to
0.001° (one count is 0.009°), every other value at full precision.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from scioc.pipelines.experiment import EXPERIMENT_FILE, load_experiment
from scioc.pipelines.export import convention, export_of, to_export
from scioc.pipelines.io import read_table
from scioc.pipelines.simulate import simulate_to_dir

HERE = Path(__file__).resolve().parent
SEED = 2018


def simulate(out) -> dict:
    """``scioc simulate --experiment experiment.toml --seed SEED --out OUT`` in scioc's convention: its paths."""
    return simulate_to_dir(out, seed=SEED, design=convention(load_experiment(HERE / EXPERIMENT_FILE)))


def lab_files(study) -> dict[str, pd.DataFrame]:
    """The simulated study file ``study`` as the lab's files: {file name: table}, one per subject."""
    export = export_of(load_experiment(HERE / EXPERIMENT_FILE))
    table = to_export(read_table(study), export)
    table[export.name("t")] = np.round(table[export.name("t")]).astype(np.int64)
    table[export.name("angle")] = np.round(table[export.name("angle")], 3)
    return {f"{subject}.csv": rows for subject, rows in table.groupby(export.name("subject"), sort=False)}


def main(out=HERE) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for name, rows in lab_files(simulate(Path(tmp) / "study")["study"]).items():
            rows.to_csv(Path(out) / name, index=False)
            print(f"wrote {Path(out) / name}")


if __name__ == "__main__":
    main()
