"""``python -m pipelines.cli``: the ``scioc`` command."""

import sys

from pipelines.cli import main

sys.exit(main())
