"""The process settings that bit-for-bit results need, applied by one idempotent :func:`configure`.

Importing a module of scioc changes no process-wide setting. The CLI, the test configuration and the
public entry points call :func:`configure` before the first kernel compiles; it

- points numba's on-disk cache at a folder named by a hash of this package's compiled code
  (:func:`numba_cache_dir`), and only then turns on caching for the kernels declared with
  ``cache=True``. numba keys a cached kernel by its own file's modification time, not by its callees':
  a kernel whose callee in another file changed would load stale machine code. A folder per code
  version means a cache is only ever read by the code that wrote it. Docstrings and comments do not
  enter the hash, so editing prose recompiles nothing.
- compiles PyTensor's numba graphs without fast-math, so a graph computes the same last bits whether
  the kernels it calls were just compiled or loaded from the cache.

Without :func:`configure`, kernels compile uncached and PyTensor keeps its defaults: correct, slower,
and not bit-for-bit across processes. See ``docs/decisions/numba-cache.md``.
"""

import ast
import hashlib
import os
import sys
import tempfile
from pathlib import Path

import numba

#: numba's ``fastmath`` of the delayed likelihood's kernels and of every function they call
#: (:mod:`scioc.models.delayed.kernel`): reassociated sums (vectorized), no "contract", whose fused
#: multiply-adds made bits depend on the cache state. Every other kernel computes without fast-math.
FASTMATH = {"reassoc"}

_CACHED = []  # the dispatchers declared with cache=True, in declaration order
_STATE = {"cache_dir": None}


def njit(**options):
    """``numba.njit`` whose ``cache=True`` takes effect when :func:`configure` has run (at once if it has).

    Used as numba's own, with keywords: ``@njit(cache=True, fastmath=False, error_model="python")`` or
    ``njit(...)(f)``.
    """
    cache = options.pop("cache", False)

    def wrap(function):
        dispatcher = numba.njit(**options)(function)
        if cache:
            _CACHED.append(dispatcher)
            if _STATE["cache_dir"] is not None:
                dispatcher.enable_caching()
        return dispatcher

    return wrap


def _code_digest(source: str) -> bytes:
    """The module's abstract syntax tree without docstrings (comments are not in it): what compiles."""
    tree = ast.parse(source)
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and body
                and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)):
            node.body = body[1:] or [ast.Pass()]
    return ast.dump(tree, include_attributes=False).encode()


def numba_cache_dir(package: Path | None = None, root: Path | None = None) -> Path:
    """The numba cache folder of this package's code: ``root / <hash of every module's code under package>``.

    ``package`` defaults to the folder of :mod:`scioc.models`; ``root`` to ``$NUMBA_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/scioc/numba`` (``~/.cache``). Docstrings and comments do not change the folder;
    any other change of any module, or a module's move, does.
    """
    package = Path(__file__).resolve().parent if package is None else Path(package)
    if root is None:
        env = os.environ.get("NUMBA_CACHE_DIR")
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "scioc" / "numba"
        root = Path(env) if env else base
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(b"\0")
        digest.update(_code_digest(path.read_text()))
        digest.update(b"\0")
    return Path(root) / digest.hexdigest()[:16]


def _writable(path: Path) -> Path:
    """``path``, or the same folder under the temporary directory where ``path`` cannot be written."""
    for candidate in (path, Path(tempfile.gettempdir()) / "scioc-numba" / path.name):
        try:
            candidate.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(candidate, os.W_OK):
            return candidate
    return path


def configure() -> Path:
    """Apply the settings bit-for-bit results need (see the module's docstring); idempotent.

    Returns
    -------
    Path
        numba's cache folder for this code.
    """
    if _STATE["cache_dir"] is None:
        path = _writable(numba_cache_dir())
        numba.config.CACHE_DIR = str(path)
        _STATE["cache_dir"] = path
        for dispatcher in _CACHED:
            dispatcher.enable_caching()
    if "pytensor" in sys.modules:
        sys.modules["pytensor"].config.numba__fastmath = False
    else:
        flags = os.environ.get("PYTENSOR_FLAGS", "")
        if "numba__fastmath" not in flags:
            os.environ["PYTENSOR_FLAGS"] = ",".join(f for f in (flags, "numba__fastmath=False") if f)
    return _STATE["cache_dir"]
