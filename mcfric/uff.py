"""Universal File Format (UFF) access shared by the modal-table and measured-data readers.

pyuff is an optional dependency (``pip install "mcfric[uff]"``), imported only when a UFF
file is read or written: :func:`pyuff_module` gives it, or a one-line error telling how to
install it. :func:`read_datasets` reads datasets of given types and checks the file's
structure (pyuff silently drops a truncated last block); :func:`write_atomic` writes
through a temporary file and a rename. The UFF 58 vocabulary (function types, ordinate
data types, the ID-line tags mcfric reads and writes) is defined here once.
"""

from __future__ import annotations

import math
import os
import re
from datetime import datetime
from pathlib import Path

from .store.files import keep_mode
from .validators import existing_file

UFF_SUFFIXES = (".uff", ".unv", ".uf")
PYUFF_HINT = ('UFF files need the optional package pyuff: pip install ".[uff]" in the '
              'clone ("mcfric[uff]" where mcfric comes from a package index)')
#: Direction codes of UFF node values.
DIRECTIONS = {1: "X", 2: "Y", 3: "Z", 4: "RX", 5: "RY", 6: "RZ"}
#: UFF specific data types of the ordinate (record 9) for each quantity.
SPEC_TYPE = {"displacement": 8, "velocity": 11, "acceleration": 12}
QUANTITY_OF_SPEC = {v: k for k, v in SPEC_TYPE.items()}
#: UFF 58 function types, for messages.
FUNCTION_TYPES = {0: "general", 1: "time response", 2: "auto spectrum", 3: "cross spectrum",
                  4: "frequency response function", 5: "transmissibility", 6: "coherence",
                  7: "auto correlation", 8: "cross correlation", 9: "power spectral density",
                  10: "energy spectral density", 11: "probability density function",
                  12: "spectrum"}
FRF, GENERAL, SPECTRUM = 4, 0, 12
#: Tags in UFF ID lines 1-5, read by the measured-data reader and written by the export.
TAG = re.compile(r"\b(kind|force_n|percentile)\s*=\s*([^\s,;]+)", re.IGNORECASE)


def pyuff_module():
    """The ``pyuff`` module, or a one-line ``ImportError`` telling how to install it."""
    try:
        import pyuff
    except ImportError:
        raise ImportError(PYUFF_HINT) from None
    return pyuff


def _count_delimiters(raw):
    """Dataset delimiters as pyuff finds them: ``    -1`` followed by a line end, the end
    of the file or blanks to column 80 (in 58b files it follows the binary data directly).
    """
    n, i = 0, -1
    while True:
        i = raw.find(b"    -1", i + 1)
        if i < 0:
            return n
        rest = raw[i + 6:i + 80]
        if not rest or rest[:1] in (b"\n", b"\r") or (len(rest) == 74 and not rest.strip()):
            n += 1


def read_datasets(path, wanted):
    """Read the datasets of the types ``wanted`` from a UFF file, checking its structure.

    Parameters
    ----------
    path : str or Path
    wanted : tuple of int
        Dataset numbers to return (e.g. ``(55,)``; 58b is reported as 58).

    Returns
    -------
    sets : list of dict
        The datasets as pyuff returns them, in file order.
    units : tuple of float
        ``(length, force)`` factors of the file's dataset 164 (file unit per SI unit),
        ``(1.0, 1.0)`` without one.

    Raises
    ------
    ValueError
        One line naming the file: missing, empty, truncated, without the wanted datasets,
        or a dataset pyuff cannot parse.
    """
    pyuff = pyuff_module()
    path = Path(path)
    existing_file(path)
    raw = path.read_bytes()
    n_delim = _count_delimiters(raw)
    if n_delim == 0:
        raise ValueError(f"{path}: not a UFF file (no '    -1' dataset delimiters)")
    # pyuff silently drops an unterminated last block, so truncation is checked here
    if n_delim % 2 or not raw.rstrip().endswith(b"    -1"):
        raise ValueError(f"{path}: truncated UFF file (the last dataset has no closing "
                         f"'    -1' line)")
    try:
        uff = pyuff.UFF(str(path))
        types = [int(t) for t in uff.get_set_types()]
    except Exception as e:  # pyuff raises bare Exception
        raise ValueError(f"{path}: not a readable UFF file ({e})") from None
    if 2 * len(types) != n_delim:
        raise ValueError(f"{path}: malformed UFF file ({n_delim} delimiter lines for "
                         f"{len(types)} datasets)")
    units = (1.0, 1.0)
    if 164 in types:
        u = _read_set(uff, path, types, types.index(164))
        units = (float(u["length"]), float(u["force"]))
        if not all(math.isfinite(x) and x > 0 for x in units):
            raise ValueError(f"{path}: dataset 164 has invalid unit factors {units}")
    idx = [i for i, t in enumerate(types) if t in wanted]
    if not idx:
        found = ", ".join(str(t) for t in sorted(set(types)))
        want = " or ".join(str(w) for w in wanted)
        raise ValueError(f"{path}: no dataset {want} in the file (found dataset types: "
                         f"{found})")
    return [_read_set(uff, path, types, i) for i in idx], units


def _read_set(uff, path, types, i):
    try:
        return uff.read_sets(i)
    except Exception as e:  # pyuff raises bare Exception without detail
        raise ValueError(f"{path}: dataset {types[i]} (block {i + 1}) cannot be parsed "
                         f"({e})") from None


def write_atomic(path, dsets, overwrite):
    """Write datasets to ``path`` via a temporary file and an atomic rename."""
    pyuff = pyuff_module()
    path = Path(path)
    if path.exists() and not overwrite:
        raise ValueError(f"{path}: file exists (pass overwrite=True to replace it)")
    if not path.parent.is_dir():
        raise ValueError(f"{path}: directory {path.parent} does not exist")
    tmp = path.with_name(path.name + ".tmp")
    try:
        pyuff.UFF(str(tmp)).write_sets(list(dsets), mode="overwrite")
        keep_mode(tmp, path)
        os.replace(tmp, path)
    except Exception as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError):
            raise
        raise ValueError(f"{path}: pyuff could not write the file ({e})") from None


def si_units_dataset():
    """A dataset 164 declaring SI units (factors 1): written ahead of mcfric's data."""
    return {"type": 164, "units_code": 1, "units_description": "SI", "temp_mode": 1,
            "length": 1.0, "force": 1.0, "temp": 1.0, "temp_offset": 273.15}


def id_date():
    """UFF ID-line date convention ``DD-MMM-YY HH:MM:SS``."""
    return datetime.now().strftime("%d-%b-%y %H:%M:%S").upper()
