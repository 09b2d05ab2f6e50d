"""Type tests for scalars that Python's and numpy's types share.

The bottom of the package: the validators and the store both use them, and neither may
import the other.
"""

from __future__ import annotations

import numpy as np


def is_bool(v):
    """True for ``True``/``False``, numpy's included (a word such as ``"no"`` is not)."""
    return isinstance(v, (bool, np.bool_))


def is_int(v):
    """True for an integer that is not a boolean."""
    return isinstance(v, (int, np.integer)) and not is_bool(v)
