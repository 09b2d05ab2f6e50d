"""What wrote a file: the versions of mcfric and of its numerical stack, and when.

Results files (:mod:`mcfric.ensemble`) and bounds files (:mod:`mcfric.bounds.results`)
carry the same attributes, so that either says what made its numbers.
"""

from __future__ import annotations

import platform
from datetime import datetime, timezone

#: This package's version (``mcfric.__version__``; pyproject.toml's ``version``).
__version__ = "0.1.0"


def software_attrs():
    """Root attributes naming the software and the time of writing.

    Returns
    -------
    dict
        ``mcfric_version``, ``numba_version``, ``numpy_version``, ``scipy_version``,
        ``h5py_version``, ``hdf5_version``, ``python_version`` (strings) and
        ``created_utc`` (ISO 8601, seconds).
    """
    import h5py
    import numba
    import numpy as np
    import scipy

    return {
        "mcfric_version": __version__,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "scipy_version": scipy.__version__,
        "h5py_version": h5py.__version__,
        "hdf5_version": h5py.version.hdf5_version,
        "python_version": platform.python_version(),
        "created_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
    }
