"""Reading results files: attributes, layout, records in blocks, groups, xarray."""

from __future__ import annotations

import os

import h5py
import numpy as np

from ..scalars import is_bool, is_int
from .files import DONE, StoreError, hdf5_reason


def _open_read(path):
    if not (isinstance(path, (str, bytes, os.PathLike)) or hasattr(path, "read")):
        # h5py's TypeError names no input (a file-like object h5py takes stays allowed)
        raise StoreError(f"path: expected a results file's path, got {type(path).__name__}")
    if not hasattr(path, "read") and os.path.isdir(path):
        # HDF5's text for it is an errno and a time stamp
        raise StoreError(f"{os.fsdecode(path)}: a directory, not a results file")
    if not hasattr(path, "read") and os.path.exists(path) and not os.path.isfile(path):
        # HDF5 needs a file it can seek in: opening a pipe without a writer never returns
        raise StoreError(f"{os.fsdecode(path)}: not a regular file (a pipe or a device), "
                         f"not a results file")
    try:
        # locking=False: readable while a run writes it (its metadata does not change)
        return h5py.File(path, "r", locking=False)
    except FileNotFoundError:
        raise StoreError(f"{path}: no such file") from None
    except OSError as e:
        if "locking flag" in str(e):
            raise StoreError(f"{path}: open elsewhere in this process with HDF5 file locking "
                             f"(h5py.File's default): close it, or open it with "
                             f"locking=False as mcfric does") from None
        # h5py's text may run over several lines (a directory's does)
        first = (str(e).strip().splitlines() or [""])[0].rstrip(" ,")
        raise StoreError(f"{path}: not a readable HDF5 file ({first})") from None


def read_attrs(path):
    """Root attributes of a results file (complete or partial).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    dict
        Attribute name to value, bytes decoded and numpy scalars as Python's (the names:
        docs, results file).
    """
    with _open_read(path) as h5:
        return {k: _plain(v) for k, v in h5.attrs.items()}


def _plain(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def _dims(path, name, ds):
    """The dimension names of dataset ``name`` (``"?"`` where none is attached)."""
    if ds.is_scale:
        return (name,)
    out = []
    for i, d in enumerate(ds.dims):
        try:
            scale = d[0].name if len(d) else "?"
        except RuntimeError:
            scale = None        # HDF5 cannot follow the reference: the scale was deleted
        if not scale:
            raise StoreError(f"{path}: a damaged or edited results file (dimension {i} of "
                             f"{name}: its scale dataset is missing)")
        out.append(scale.lstrip("/"))
    return tuple(out)


def describe(path):
    """Layout summary: root attributes, and per dataset its dims, shape and dtype."""
    with _open_read(path) as h5:
        try:
            out = {"attrs": {k: _plain(v) for k, v in h5.attrs.items()}, "datasets": {}}
            for name, ds in h5.items():
                if isinstance(ds, h5py.Dataset):
                    out["datasets"][name] = (_dims(path, name, ds), ds.shape, ds.dtype)
            if DONE in h5:
                out["done"] = int(np.count_nonzero(h5[DONE][...]))
        except (AttributeError, KeyError, RuntimeError, TypeError, ValueError,
                OSError) as e:
            raise StoreError(f"{path}: a damaged or edited results file "
                             f"({hdf5_reason(e)})") from None
        return out


def iter_records(path, names, block=4096, only_done=True):
    """Yield ``(start, {name: array})`` in blocks of records (memory stays flat).

    Parameters
    ----------
    path : str or Path
        A results file, complete or partial.
    names : list of str
        Datasets with the record (sample) dimension first, e.g. ``["metric",
        "converged"]``; ``"sample"`` gives the records' sample numbers.
    block : int
        Records per block read.
    only_done : bool
        Skip records not marked done (they may hold garbage).

    Yields
    ------
    start : int
        Index of the block's first record.
    arrays : dict of str to ndarray
        Each dataset's rows of the block (only the done ones with ``only_done``).
    """
    if isinstance(names, (str, bytes)):       # "metric" would be read letter by letter
        raise StoreError(f"names: expected a list of dataset names, got {names!r}")
    if is_bool(block) or not is_int(block) or block < 1:
        raise StoreError(f"block: expected an integer >= 1, got {block!r}")
    if not is_bool(only_done):
        raise StoreError(f"only_done: expected True or False, got {only_done!r}")
    with _open_read(path) as h5:
        missing = [k for k in (DONE, *names) if k not in h5]
        if missing:
            raise StoreError(f"{path}: not an mcfric results file (no {missing[0]!r} "
                             f"dataset)")
        n = h5[DONE].shape[0]
        for a in range(0, n, block):
            b = min(n, a + block)
            done = h5[DONE][a:b].astype(bool)
            if only_done and not done.any():
                continue
            arrays = {k: h5[k][a:b] for k in names}
            if only_done and not done.all():
                arrays = {k: v[done] for k, v in arrays.items()}
            yield a, arrays


def read(path, name, row=None):
    """One whole dataset, or only its record ``row`` (use :func:`iter_records` to go
    through big ones)."""
    with _open_read(path) as h5:
        if name not in h5:
            # a file of another kind (a bounds file's partial, say): one line, not a
            # KeyError from h5py
            raise StoreError(f"{path}: not an mcfric results file (no {name!r} dataset)")
        ds = h5[name]
        if not isinstance(ds, h5py.Dataset):
            raise StoreError(f"{path}: {name!r} is a group, not a dataset (read_group)")
        if row is None:
            return ds[...]
        if is_bool(row) or not is_int(row) or not -ds.shape[0] <= row < ds.shape[0]:
            raise StoreError(f"row: expected a record in 0..{ds.shape[0] - 1}, got {row!r}")
        return ds[row]


def open_results(path, allow_incomplete=False):
    """The results file as an ``xarray.Dataset`` (lazy; needs xarray and h5netcdf).

    Parameters
    ----------
    path : str or Path
        A results file written by ``mcfric run``.
    allow_incomplete : bool
        Open a ``.partial`` file too (records with ``done == 0`` hold garbage).

    Raises
    ------
    StoreError
        The file is incomplete (and ``allow_incomplete`` is False) or not a results file.
    """
    try:
        import xarray as xr
    except ImportError:   # pragma: no cover - depends on the environment
        raise ImportError("open_results needs xarray and h5netcdf: pip install xarray "
                          "h5netcdf (the extra: pip install '.[xarray]' in mcfric's "
                          "clone)") from None
    attrs = read_attrs(path)
    if attrs.get("layout_version") is None:
        raise StoreError(f"{path}: not an mcfric results file (no layout_version)")
    if not is_bool(allow_incomplete):         # "no" would be true
        raise StoreError(f"allow_incomplete: expected True or False, got "
                         f"{allow_incomplete!r}")
    if attrs.get("complete") != 1 and not allow_incomplete:
        raise StoreError(f"{path}: incomplete run (complete = 0); continue it with "
                         f"`mcfric run ... --resume`, or pass allow_incomplete=True")
    # the same locking flag as every other reader here: HDF5 refuses a second handle on a
    # file with another flag, so read_bounds and the like failed while a Dataset was open
    return xr.open_dataset(path, engine="h5netcdf", driver_kwds={"locking": False})


def read_group(path, name):
    """A group of labelled arrays and its attributes, or None if the file has no such group.

    Returns
    -------
    (dict, dict) or None
        ``{var: array}`` (the group's datasets, whole) and the group's attributes (bytes
        decoded, numpy scalars as Python numbers, arrays as they are).
    """
    with _open_read(path) as h5:
        if name not in h5:
            return None
        g = h5[name]
        if not isinstance(g, h5py.Group):
            raise StoreError(f"{path}: {name!r} is a dataset, not a group (read)")
        return ({k: v[()] for k, v in g.items() if isinstance(v, h5py.Dataset)},
                {k: _plain(v) for k, v in g.attrs.items()})


def dataset_names(path):
    """Names of the datasets and groups at the root of a file."""
    with _open_read(path) as h5:
        return set(h5.keys())

