"""``python -m mcfric.cli``: the same as ``mcfric``."""

import sys

from .main import main

sys.exit(main())
