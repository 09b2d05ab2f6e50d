"""``python -m mcfric``: the same as the ``mcfric`` command."""

import sys

from .cli import main

sys.exit(main())
