"""``python -m dfrmot_jax.cli ...``: the ``dfrmot`` command."""

import sys

from . import main

sys.exit(main())
