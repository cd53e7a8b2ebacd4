"""Progress bars for long steps (on standard error, so standard output stays clean)."""

from __future__ import annotations

import sys

from tqdm.auto import tqdm

#: How many progress bars this process drew on stderr: a bar ends in a carriage return, not a newline, so the CLI
#: ends its line before an error message when a command drew one.
drawn = 0


def progress(iterable, *, desc: str, enabled: bool = True, total: int | None = None):
    """Wrap ``iterable`` in a progress bar on stderr unless disabled."""
    global drawn
    if not enabled:
        return iterable
    drawn += 1
    return tqdm(iterable, desc=desc, total=total, file=sys.stderr, leave=False, dynamic_ncols=True, mininterval=0.5)
