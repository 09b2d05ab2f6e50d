"""Is this a results file that mcfric can read? A structural check before reading it.

``mcfric info`` and ``mcfric plot`` read files that may have been edited, truncated by
hand or written by another tool. :func:`check_file` checks what they rely on: the layout
version, the configuration record, the required datasets, every dataset's dimensions
against its coordinates and the record's sizes, the kinds of the known datasets, the
frequencies' values and, in a file marked complete, that every sample is done. It reads
metadata, the frequencies and ``done`` only (a byte per sample) and raises one
:class:`~mcfric.store.StoreError` naming the first problem.
"""

from __future__ import annotations

import json

import numpy as np

from .store import LAYOUT_VERSION, StoreError, describe, read, read_group

#: dtype kinds of the known datasets (numpy ``dtype.kind``): f float, c complex, b bool,
#: i/u integer.
KINDS = {
    "metric": "f", "converged": "b", "response": "c", "amplitude": "f", "mu0": "f", "kc": "f",
    "N0": "f",
    "harmonic_indicator": "f", "response_peak": "f", "response_harmonics": "c",
    "from_above": "b",
    "from_rest": "b",
    "peak_metric": "f", "peak_frequency": "f", "peak_status": "i", "fold": "i",
    "peak_metric_down": "f", "peak_frequency_down": "f", "peak_response": "c",
    "modal_freq_hz": "f", "done": "iu", "sample": "iu", "frequency": "f",
}
#: What every ensemble file (``samples > 0``) has.
REQUIRED = ("sample", "frequency", "done", "metric", "converged", "mu0", "kc", "N0")
#: Sections and keys of ``config_json`` that the readers use.
CONFIG_KEYS = {"model": ("name", "n_beams", "topology"), "excitation": ("pattern", "F0"),
               "frequency": ("n", "f_min", "f_max", "spacing"),
               "sampling": ("seed", "mu0", "kc", "N0"), "metric": ("quantity",)}


def check_file(path):
    """Check the structure of a results or bounds file; returns ``(attrs, config)``.

    Parameters
    ----------
    path : str or Path
        A results file (complete or ``.partial``) or a bounds file.

    Returns
    -------
    attrs : dict
        Root attributes.
    config : dict
        The run's configuration (from ``config_json``).

    Raises
    ------
    StoreError
        Not an HDF5 file, not an mcfric file, another layout version, a dataset that is
        missing, misshapen or of the wrong type, or samples not done in a file marked
        complete (one line, naming it).
    """
    d = describe(path)          # StoreError for a file HDF5 cannot open
    a, ds = d["attrs"], d["datasets"]
    if "layout_version" not in a:
        raise StoreError(f"{path}: not an mcfric results file")
    if a["layout_version"] != LAYOUT_VERSION:
        raise StoreError(f"{path}: layout_version {a['layout_version']}, but this mcfric "
                         f"reads layout {LAYOUT_VERSION} (a newer or older mcfric wrote it)")
    if "config_json" not in a:
        raise StoreError(f"{path}: no configuration record (root attribute config_json)")
    try:
        cfg = json.loads(a["config_json"])
        for section, keys in CONFIG_KEYS.items():
            for k in keys:
                cfg[section][k]
    except KeyError as e:
        raise StoreError(f"{path}: the configuration record (config_json) lacks {e}") from None
    except (TypeError, ValueError):
        raise StoreError(f"{path}: the configuration record (config_json) is not "
                         "readable") from None
    n = a.get("samples")
    if not isinstance(n, int) or n < 0:
        raise StoreError(f"{path}: attribute samples = {n!r} is not a sample count")
    missing = [k for k in (REQUIRED if n > 0 else ("frequency",)) if k not in ds]
    if missing:
        raise StoreError(f"{path}: dataset {missing[0]} is missing")
    for name, (dims, shape, dtype) in ds.items():
        want = KINDS.get(name)
        if want and dtype.kind not in want:
            raise StoreError(f"{path}: dataset {name} has type {dtype}, expected "
                             f"{_kind_name(want)}")
        if len(dims) != len(shape) or "?" in dims:
            raise StoreError(f"{path}: dataset {name} has no dimension labels")
        for dim, size in zip(dims, shape):
            expected = n if dim == "sample" else (ds[dim][1][0] if dim in ds else None)
            if expected is None:
                raise StoreError(f"{path}: dataset {name} uses dimension {dim}, which the "
                                 "file does not define")
            if size != expected:
                raise StoreError(f"{path}: dataset {name} has {size} along {dim}, expected "
                                 f"{expected}")
    _check_against_record(path, cfg, ds)
    if a.get("complete") == 1 and n > 0:
        # the readers take a complete file's members as all there: a sample not done
        # would be left out of every count and figure without a word
        left = n - int(np.count_nonzero(read(path, "done") == 1))
        if left:
            raise StoreError(f"{path}: marked complete, but {left:,} of {n:,} samples are "
                             f"not done (an edited or damaged file)")
    g = read_group(path, "bounds")
    if g is not None:
        check_bounds(path, *g, ds["frequency"][1][0])
    return a, cfg


def _check_against_record(path, cfg, ds):
    """The frequencies (finite, positive, rising: the peaks and the plot rely on it) and
    the sizes the configuration record states against the datasets' (an edited record
    would otherwise describe another run)."""
    f = read(path, "frequency")
    if f.ndim != 1 or not (np.all(np.isfinite(f)) and np.all(f > 0)
                           and np.all(np.diff(f) > 0)):
        raise StoreError(f"{path}: dataset frequency is not finite, positive and rising")
    for key, value, dim in (("frequency.n", cfg["frequency"]["n"], "frequency"),
                            ("model.n_beams", cfg["model"]["n_beams"], "beam")):
        # a value of another type is the keys' check's to report (cli.outputs)
        if dim in ds and type(value) is int and value != ds[dim][1][0]:
            raise StoreError(f"{path}: the configuration record says {key} = {value!r}, "
                             f"but the file holds {ds[dim][1][0]} along {dim}")


#: What ``bounds.results.read_bounds`` reads: datasets (name, dtype kinds, dimensions:
#: 1 per frequency, 2 per frequency and damper), then those of a certificate, then
#: attributes.
BOUNDS_DATASETS = (("upper", "f", 1), ("lower", "f", 1), ("upper_box", "f", 1),
                   ("upper_force", "f", 1), ("limited_by", "iu", 1), ("K_upper", "c", 2),
                   ("K_lower", "c", 2))
CERTIFICATE_DATASETS = (("upper_certified", "f", 1), ("lower_certified", "f", 1),
                        ("upper_witness", "f", 1), ("lower_witness", "f", 1),
                        ("K_upper_witness", "c", 2), ("K_lower_witness", "c", 2),
                        ("certified_converged", "iu", 1), ("upper_evaluations", "iu", 1),
                        ("lower_evaluations", "iu", 1))
BOUNDS_ATTRS = ("k_max_re", "k_max_im", "F_lim", "quantity", "beams")


def check_bounds(path, g, attrs, n_f):
    """Raise :class:`StoreError` unless every dataset and attribute of ``bounds/`` that
    the readers use is there, with one value (or row) per frequency (``n_f``); ``g``,
    ``attrs``: the group and its attributes (:func:`mcfric.store.read_group`)."""
    # any part of a certificate means all of it: with upper_certified deleted the file
    # read as "not certified (--no-certify)"
    certified = (any(k in g for k, _, _ in CERTIFICATE_DATASETS)
                 or any(k.startswith("certify_") for k in attrs))
    names = BOUNDS_DATASETS + (CERTIFICATE_DATASETS if certified else ())
    for k, kinds, ndim in names:
        v = g.get(k)
        shape = getattr(v, "shape", ())
        if (v is None or len(shape) != ndim or shape[0] != n_f
                or v.dtype.kind not in kinds):
            raise StoreError(f"{path}: bounds/{k} is missing or not {n_f} "
                             f"{_kind_name(kinds)} values" + (" per damper" * (ndim == 2)))
    for k in BOUNDS_ATTRS + (("certify_budget",) if certified else ()):
        if k not in attrs:
            raise StoreError(f"{path}: bounds/ lacks the attribute {k}")


def _kind_name(kinds):
    return {"f": "float", "c": "complex", "b": "bool", "i": "integer",
            "iu": "integer"}.get(kinds, kinds)
