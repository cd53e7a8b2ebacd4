"""The human-model seam: stages find a model by name in the registry and never compare its name; a third model
registered here runs through identify and fit without any stage changing."""

import ast
import json
from pathlib import Path

import pytest

from scioc.pipelines.human_model import HumanModel, get, names, register, unregister
from scioc.pipelines.human_model.maxent import MaxEnt

ROOT = Path(__file__).resolve().parents[3]
REGISTRY = ROOT / "pipelines" / "human_model"
#: Files where a registered name is also another thing's name.
OTHER_MEANINGS = {"pipelines/bench/suite.py": "'delayed' is also a part of scioc bench"}


def _name_literals(node, known) -> list:
    """The registered names a comparison node compares with as string literals (also inside tuples, lists, sets)."""
    found = []
    for side in (node.left, *node.comparators):
        items = side.elts if isinstance(side, (ast.Tuple, ast.List, ast.Set)) else [side]
        found += [i.value for i in items if isinstance(i, ast.Constant) and i.value in known]
    return found


def name_comparisons(source: str, known) -> list:
    """``(line, names)`` of every comparison in ``source`` with a human model's name as a literal."""
    return [(n.lineno, found) for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Compare)
            for found in [_name_literals(n, known)] if found]


def test_no_stage_compares_a_human_models_name():
    known = set(names())
    bad = {str(p.relative_to(ROOT)): hits for pkg in ("models", "pipelines") for p in sorted((ROOT / pkg).rglob("*.py"))
           if REGISTRY not in p.parents and str(p.relative_to(ROOT)) not in OTHER_MEANINGS
           for hits in [name_comparisons(p.read_text(), known)] if hits}
    assert not bad, bad


def test_a_comparison_of_a_name_would_be_found():
    source = ('if human_model == "delayed":\n    pass\n'
              'x = side.get("human_model") in ("maxent", "other")\n'
              'y = name == PRIMARY\n')
    assert name_comparisons(source, {"maxent", "delayed"}) == [(1, ["delayed"]), (3, ["maxent"])]


def test_the_registry_names_the_built_in_models_and_refuses_an_unknown_one():
    assert names()[:2] == ("maxent", "delayed")
    assert isinstance(get("delayed"), HumanModel)
    with pytest.raises(ValueError, match="human model must be one of maxent, delayed"):
        get("nobody")


def test_the_clis_names_are_the_registered_ones():
    from scioc.pipelines.cli.values import HUMAN_MODEL_NAMES

    assert HUMAN_MODEL_NAMES == names()[:2]


class Dummy(MaxEnt):
    """A third human model: the max-ent one under another name, counting the calls the stages make."""

    name = "dummy"
    description = "a test model"

    def __init__(self):
        self.calls = []

    def identify_unit(self, prepared, idx, plant, settings):
        self.calls.append("identify_unit")
        return super().identify_unit(prepared, idx, plant, settings)

    def fit(self, ctx):
        self.calls.append("fit")
        return super().fit(ctx)


@pytest.fixture
def dummy():
    model = register(Dummy())
    yield model
    unregister(model.name)


@pytest.mark.validation
def test_a_third_model_runs_through_identify_and_fit_without_any_stage_changing(dummy, small_fit, tmp_path):
    from dataclasses import replace

    from scioc.pipelines.fit import fit_to_dir
    from scioc.pipelines.identify import identify_to_dir
    from scioc.pipelines.prepare import IdentifySettings

    root, sim, _ = small_fit
    settings = replace(IdentifySettings(), human_model="dummy", adequacy_boot=0)
    paths = identify_to_dir(sim["study"], tmp_path / "identify", settings, show_progress=False)
    meta = json.loads(Path(paths["meta"]).read_text())
    assert meta["human_model"] == "dummy" and meta["converged"] == meta["segments"] > 0
    fit = fit_to_dir(sim["study"], tmp_path / "fit", estimates_path=paths["estimates"], human_model="dummy",
                     seed=1, chains=1, draws=30, tune=30, cores=1)
    side = json.loads(Path(fit["sidecar"]).read_text())
    assert side["human_model"] == "dummy" and side["identify_settings"]["human_model"] == "dummy"
    assert side["identify_settings_from"].startswith("the identification of")
    assert dummy.calls.count("identify_unit") == meta["segments"] and dummy.calls[-1] == "fit"
