"""Progress bars for long steps (on standard error, so standard output stays clean)."""

from __future__ import annotations

import sys

from tqdm.auto import tqdm


def progress(iterable, *, desc: str, enabled: bool = True, total: int | None = None):
    """Wrap ``iterable`` in a progress bar on stderr unless disabled."""
    if not enabled:
        return iterable
    return tqdm(iterable, desc=desc, total=total, file=sys.stderr, leave=False, dynamic_ncols=True, mininterval=0.5)
