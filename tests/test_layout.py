"""The structure of models/ and pipelines/, drawn from the imports in the source (``ast``, nothing imported);
the numba core without PyMC; every imported package declared.

Every import counts, including those inside functions: a lazy import may save start-up
time, but it must not hide a cycle. ``from package import name`` counts as an import of
``package.name`` when that is a module, else of ``package``; a submodule's implicit
import of its parent package does not count (it is how Python loads packages, not a
dependency the code chose).
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("models", "pipelines")


def _module_name(path: Path) -> str:
    """``models/lq.py`` -> ``scioc.models.lq`` (the folders install as subpackages of ``scioc``)."""
    return "scioc." + ".".join(path.relative_to(ROOT).with_suffix("").parts).removesuffix(".__init__")


def _files() -> dict:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports() -> dict:
    """{module: [(imported module, imported name or None), ...]} for every module of models/ and pipelines/."""
    files = _files()
    out = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        found = []
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                found += [(a.name, None) for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:  # relative: resolve against this module's package
                    parts = package.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
                for a in node.names:
                    sub = f"{base}.{a.name}"
                    found.append((sub, None) if sub in files else (base, a.name))
        out[name] = found
    return out


def _graph() -> dict:
    imports = _imports()
    return {m: {t for t, _ in imps if t in imports and t != m} for m, imps in imports.items()}


def _find_cycle(graph: dict) -> list | None:
    """The first import cycle of ``graph`` (depth-first, modules in sorted order) as a list of modules, or None."""
    done, path = set(), []

    def visit(m):
        if m in path:
            return path[path.index(m):] + [m]
        if m in done:
            return None
        path.append(m)
        for t in sorted(graph[m]):
            cycle = visit(t)
            if cycle:
                return cycle
        path.pop()
        done.add(m)
        return None

    for m in sorted(graph):
        cycle = visit(m)
        if cycle:
            return cycle
    return None


def test_the_import_graph_has_no_cycle():
    cycle = _find_cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_a_cycle_would_be_found():
    """Negative control: the search reports a cycle planted in a copy of the graph."""
    graph = _graph()
    graph["scioc.pipelines.io"] = graph["scioc.pipelines.io"] | {"scioc.pipelines.identify"}
    cycle = _find_cycle(graph)
    assert cycle and {"scioc.pipelines.io", "scioc.pipelines.identify"} <= set(cycle)  # the planted edge closes it


def test_models_never_import_pipelines():
    bad = [(m, t) for m, imps in _imports().items() if m.startswith("scioc.models")
           for t, _ in imps if t.startswith("scioc.pipelines")]
    assert not bad


def test_no_private_name_is_imported_from_another_module():
    bad = [(m, t, n) for m, imps in _imports().items() for t, n in imps
           if t != m and (n or t.rpartition(".")[2]).startswith("_") and not (n or "").startswith("__")
           and t.startswith("scioc.")]
    assert not bad


def test_stages_never_import_the_cli():
    bad = [(m, t) for m, imps in _imports().items() if not m.startswith("scioc.pipelines.cli")
           for t, _ in imps if t.startswith("scioc.pipelines.cli")]
    assert not bad


@pytest.mark.parametrize("modules", [
    "scioc.models.maxent, scioc.models.adequacy, scioc.models.simulate, scioc.models.humans, "
    "scioc.models.identify, scioc.models.maxent_dense, scioc.models.units, scioc.models.design, "
    "scioc.models.bootstrap",
])
def test_the_numba_core_imports_without_pymc_or_pytensor(modules):
    code = (f"import sys; import {modules}; "
            "bad = [m for m in ('pymc', 'pytensor') if m in sys.modules]; assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_every_imported_third_party_package_is_declared():
    import ast
    import re
    import tomllib
    from importlib.metadata import packages_distributions

    root = ROOT
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    declared = {re.split(r"[\[<>=!~ ;]", d)[0].lower().replace("_", "-") for d in project["dependencies"]}
    imported = set()
    for path in [*(root / "models").rglob("*.py"), *(root / "pipelines").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0:
                imported.add(node.module.split(".")[0])
    dists = packages_distributions()
    third_party = {m for m in imported - set(sys.stdlib_module_names) - {"scioc", "__future__"}}
    missing = {m for m in third_party if not {d.lower() for d in dists.get(m, [m])} & declared}
    assert not missing, f"imported but not declared in pyproject.toml: {sorted(missing)}"


def _is_jit(f) -> bool:
    """``f`` (a decorator, or the function of a call) names ``njit`` or ``jit``, bare or as ``numba.njit``."""
    return (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", None)) in ("njit", "jit")


def _jitted(source: str) -> list:
    """(function name, keywords) for every function of ``source`` that numba compiles: decorated by ``njit`` or
    ``jit`` (called, or bare: no keywords), or wrapped as ``njit(...)(f)``; once per decoration or wrap."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef):
            for dec in node.decorator_list:
                if isinstance(dec, ast.Call) and _is_jit(dec.func):
                    out.append((node.name, {k.arg: k.value for k in dec.keywords}))
                elif _is_jit(dec):
                    out.append((node.name, {}))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Call) and _is_jit(node.func.func)
              and len(node.args) == 1 and isinstance(node.args[0], ast.Name)):
            out.append((node.args[0].id, {k.arg: k.value for k in node.func.keywords}))
    return out


def _functions_cached_twice(source: str) -> list:
    """Names of the functions of ``source`` that numba compiles with ``cache=True`` more than once
    (decorated and wrapped, or wrapped twice as in ``njit(cache=True, parallel=True)(f)``)."""
    count = {}
    for name, kw in _jitted(source):
        if getattr(kw.get("cache"), "value", False) is True:
            count[name] = count.get(name, 0) + 1
    return sorted(name for name, n in count.items() if n > 1)


def _njit_without_flags(source: str) -> list:
    """Names of the functions of ``source`` that numba compiles without stating both ``fastmath`` and
    ``error_model``."""
    return sorted(name for name, kw in _jitted(source) if not {"fastmath", "error_model"} <= set(kw))


def _offending_files(find) -> dict:
    """{file: names} where ``find(source)`` names something, over every module of models/ and pipelines/."""
    found = {str(p.relative_to(ROOT)): find(p.read_text())
             for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}
    return {rel: names for rel, names in found.items() if names}


def test_no_function_is_compiled_into_the_numba_cache_twice():
    """numba's cache keys a function by its file, name and first line: two cached dispatchers of one
    function share their entries, and one loads the other's code (the delayed batch kernel's parallel
    version ran serially that way, models/delayed/kernel.py)."""
    bad = _offending_files(_functions_cached_twice)
    assert not bad, bad


def test_a_function_cached_twice_would_be_found():
    source = ("from numba import njit\n"
              "def _batch(x):\n    return x\n"
              "batch = njit(cache=True, parallel=True)(_batch)\n"
              "batch_serial = njit(cache=True)(_batch)\n"
              "@njit(cache=True)\ndef once(x):\n    return x\n"
              "uncached = njit(once.py_func)\n")
    assert _functions_cached_twice(source) == ["_batch"]


def test_every_numba_function_states_its_fastmath_and_error_model():
    """numba gives a function that does not state ``fastmath`` or ``error_model`` those of the caller that
    first compiles it, and caches that version under its signature alone: which caller came first, in this
    process or in the one that filled the cache, then decided the bits of every later kernel compiled against
    it (models/__init__.py; the delayed kernel's callees, measured 2026-12-06)."""
    bad = {rel: names for rel, names in _offending_files(_njit_without_flags).items()
           if rel != "models/runtime.py"}  # the wrapper passes its caller's flags on
    assert not bad, bad


def test_a_numba_function_without_its_flags_would_be_found():
    source = ("from numba import njit\n"
              "@njit(cache=True, error_model='numpy')\ndef callee(x):\n    return x\n"
              "@njit\ndef bare(x):\n    return x\n"
              "@njit(cache=True, fastmath=False, error_model='python')\ndef stated(x):\n    return x\n"
              "def _f(x):\n    return x\n"
              "wrapped = njit(fastmath={'reassoc'})(_f)\n")
    assert _njit_without_flags(source) == ["_f", "bare", "callee"]


def test_one_import_name_and_every_package_folder_installed(tmp_path):
    """Outside the repository, ``scioc`` imports and no top-level ``models`` or ``pipelines`` exists; pyproject's
    package list names every folder of models/ and pipelines/ that holds an ``__init__.py``."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {_module_name(p.parent / "x.py").rpartition(".")[0]
               for pkg in PACKAGES for p in (ROOT / pkg).rglob("__init__.py")}
    assert listed == folders | {"scioc"}
    code = ("import importlib.util as u, scioc, scioc.models.lq, scioc.pipelines.cli; "
            "assert u.find_spec('models') is None and u.find_spec('pipelines') is None")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp_path)
