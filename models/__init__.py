"""The mathematics of scioc: plant, costs, optimal control, max-ent likelihood, simulators.

Pure functions on arrays; no file I/O, no printing, no CLI. Never imports ``pipelines``.

One exception, here, before any kernel is compiled: numba's on-disk cache (``cache=True``)
is keyed by the modification time of the file that defines each function, not of the
files it calls. A kernel whose callee in another file changed would load its old machine
code, silently computing with the old callee. So the cache lives in a folder named by a
hash of every source file of this package (:func:`numba_cache_dir`): any edit starts a
fresh cache, and a cache is only ever read by the code that wrote it.

The second fact about numba that decides bits: a function that does not state ``fastmath`` or
``error_model`` takes them from the caller that first compiles it, and the cache then keeps that
version under the function's signature alone. The delayed kernel's callees (the arm torque's
recursion, the plans) compiled inside :data:`FASTMATH` kernels reassociated their sums; compiled
first from Python, they did not, and a kernel compiled later against that cached callee computed
other last bits: the same seed gave another profile argmax of the perceptual delay (measured
2026-12-06, ``tests/models/test_numba_cache.py``). So every ``njit`` here states both
(``tests/test_layout.py``).
"""

import hashlib
import os
import tempfile
from pathlib import Path

import numba

#: numba's ``fastmath`` of the delayed likelihood's kernels and of every function they call
#: (:mod:`models.delayed.kernel`): reassociated sums (vectorized), no "contract": with it, bits
#: depended on numba's cache state. Every other kernel computes without fast-math.
FASTMATH = {"reassoc"}


def numba_cache_dir(package: Path | None = None, root: Path | None = None) -> Path:
    """The numba cache folder of this package's sources: ``root / <hash of every .py under package>``.

    ``root`` defaults to ``$NUMBA_CACHE_DIR``, else ``$XDG_CACHE_HOME/scioc/numba`` (``~/.cache``).
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
        digest.update(path.read_bytes())
        digest.update(b"\0")
    return Path(root) / digest.hexdigest()[:16]


def _writable_cache_dir() -> Path:
    """:func:`numba_cache_dir`, or the same folder under the temporary directory where that cannot be written
    (numba would otherwise refuse to compile any cached kernel)."""
    path = numba_cache_dir()
    for candidate in (path, Path(tempfile.gettempdir()) / "scioc-numba" / path.name):
        try:
            candidate.mkdir(parents=True, exist_ok=True)
        except OSError:
            continue
        if os.access(candidate, os.W_OK):
            return candidate
    return path


numba.config.CACHE_DIR = str(_writable_cache_dir())
