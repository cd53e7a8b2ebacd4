"""``python -m scioc``: the ``scioc`` command."""

import sys

from scioc.pipelines.cli import main

sys.exit(main())
