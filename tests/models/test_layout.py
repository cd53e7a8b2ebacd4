"""The structure of models/: imports point one way, no private names cross modules, the numba core needs no PyMC."""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

MODELS = Path(__file__).resolve().parents[2] / "models"


def _imports():
    """{module: [(imported module, imported name or None), ...]} of every module under models/, from the source."""
    out = {}
    for path in sorted(MODELS.rglob("*.py")):
        name = ".".join(path.relative_to(MODELS.parent).with_suffix("").parts).removesuffix(".__init__")
        found = []
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found += [(a.name, None) for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                found += [(node.module, a.name) for a in node.names]
        out[name] = found
    return out


def test_models_never_import_pipelines():
    bad = [(m, t) for m, imps in _imports().items() for t, _ in imps if t.split(".")[0] == "pipelines"]
    assert not bad


def test_no_private_name_is_imported_from_another_module():
    bad = [(m, t, n) for m, imps in _imports().items() for t, n in imps
           if n and n.startswith("_") and not n.startswith("__") and t != m]
    assert not bad


def test_the_models_import_graph_has_no_cycle():
    imports = _imports()
    graph = {m: {t for t, _ in imps if t in imports and t != m} for m, imps in imports.items()}
    done, path = set(), []

    def visit(m):
        if m in path:
            raise AssertionError("import cycle: " + " -> ".join(path[path.index(m):] + [m]))
        if m in done:
            return
        path.append(m)
        for t in sorted(graph[m]):
            visit(t)
        path.pop()
        done.add(m)

    for m in sorted(graph):
        visit(m)


@pytest.mark.parametrize("modules", [
    "models.maxent, models.adequacy, models.simulate, models.humans, models.identify, models.maxent_dense, "
    "models.units, models.design",
])
def test_the_numba_core_imports_without_pymc_or_pytensor(modules):
    code = (f"import sys; import {modules}; "
            "bad = [m for m in ('pymc', 'pytensor') if m in sys.modules]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=MODELS.parent)
