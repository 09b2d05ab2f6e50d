"""``python -m mcfric.cli``: the same as ``mcfric``."""

import sys

from . import main

sys.exit(main())
