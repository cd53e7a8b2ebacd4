"""The ``scioc`` command line: :func:`main`, the parser (:mod:`scioc.pipelines.cli.parser`, all options; their
values' checks and names in :mod:`scioc.pipelines.cli.values`) and the commands (:mod:`scioc.pipelines.cli.commands`, one
pipeline function each). ``python -m scioc`` runs it too.
"""

from __future__ import annotations

import os
import sys

from scioc.models.runtime import configure
from scioc.pipelines.cli.parser import build_parser
from scioc.pipelines.cli.values import HUMAN_NAMES, MIN_WINDOW_SECONDS, PARAMETERIZATION_BLOCKS

#: Exit statuses (README "Errors and exit codes"). Usage errors found by argparse exit 2 too.
EXIT_OK, EXIT_FAILED_CHECK, EXIT_USAGE, EXIT_BAD_DATA, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
#: What a shell reports for a process ended by SIGPIPE (128 + 13).
EXIT_BROKEN_PIPE = 141


def _bars_drawn() -> int:
    """Progress bars drawn so far (:data:`scioc.pipelines.progress.drawn`; none where that module is not loaded)."""
    bars = sys.modules.get("scioc.pipelines.progress")
    return 0 if bars is None else bars.drawn


def main(argv=None) -> int:
    """Run ``scioc`` with ``argv`` (default: the command line); returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    configure()
    bars = _bars_drawn()
    try:
        return args.func(args)
    except BrokenPipeError:
        # The reader of stdout went away (`scioc loglik ... | head`): end quietly. Output still
        # buffered goes to /dev/null, so the interpreter's final flush cannot fail again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt:
        print(("\n" if _bars_drawn() > bars else "") + f"scioc {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (ValueError, OSError) as exc:
        from scioc.pipelines.io import InputDataError  # lazy: pandas takes a second to import; only errors need it

        # A progress bar's line ends in a carriage return: the error goes on a line of its own.
        print(("\n" if _bars_drawn() > bars else "") + f"scioc {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_DATA if isinstance(exc, InputDataError) else EXIT_USAGE



__all__ = ["main", "build_parser", "HUMAN_NAMES", "MIN_WINDOW_SECONDS", "PARAMETERIZATION_BLOCKS", "EXIT_OK",
           "EXIT_FAILED_CHECK", "EXIT_USAGE", "EXIT_BAD_DATA", "EXIT_INTERRUPTED", "EXIT_BROKEN_PIPE"]
