"""Groups of labelled arrays (e.g. ``bounds/``) in a results file, and small files made of
coordinates and groups alone, written atomically."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np

from .files import (
    LAYOUT_VERSION,
    MIN_FREE,
    StoreError,
    abandon,
    fsync_dir,
    fsync_path,
    keep_mode,
    partial_path,
    replacing,
    require_room,
)
from .reader import read_attrs


def add_group(path, name, variables, attrs=None):
    """Add (or replace) a group of arrays to a complete results file.

    The hook for later stages (e.g. ``bounds/`` from the bounds stage): each variable is
    labelled with dimensions of the root (``frequency``, ``beam``, ...), so
    ``xarray.open_dataset(path, engine="h5netcdf", group=name)`` reads it. The file is
    copied, the copy changed and renamed over it (:func:`~mcfric.store.files.replacing`):
    an error or a crash on the way leaves the file as it was, never half-changed (at the
    cost of a copy of the file; mcfric itself writes its groups at creation).

    Parameters
    ----------
    path : str or Path
        A complete results file.
    name : str
        Group name, e.g. ``"bounds"``.
    variables : dict
        ``{var: (dims, array, attrs)}``; every dim must be a root dimension and
        ``array.shape`` must match their lengths.
    attrs : dict, optional
        Attributes of the group.
    """
    a = read_attrs(path)
    if a.get("complete") != 1:
        raise StoreError(f"{path}: add_group needs a complete results file")
    with replacing(path, "results file") as tmp:
        # the copy and the group need room of their own (a full disk midway is an
        # error, not a crash)
        require_room(tmp, Path(path).stat().st_size + MIN_FREE
                     + groups_bytes({name: (variables, attrs)}), path, "a copy of the file")
        shutil.copyfile(path, tmp)
        with h5py.File(tmp, "r+") as h5:
            write_group(h5, name, variables, attrs)
        fsync_path(tmp)
    fsync_dir(path)


def write_group(h5, name, variables, attrs):
    """Write (or replace) group ``name`` of labelled arrays in an open file."""
    for var, (dims, array, _) in variables.items():
        array = np.asarray(array)
        expect = tuple(h5[d].shape[0] if d in h5 else -1 for d in dims)
        if array.shape != expect:
            raise ValueError(f"{name}/{var}: shape {array.shape} does not match dims "
                             f"{dims} {expect}")
    if name in h5:
        del h5[name]
    g = h5.create_group(name, track_order=True)
    g.attrs.update(attrs or {})
    for var, (dims, array, vattrs) in variables.items():
        ds = g.create_dataset(var, data=np.asarray(array), track_times=False)
        for i, d in enumerate(dims):
            ds.dims[i].attach_scale(h5[d])
        ds.attrs.update(vattrs or {})


def write_file(path, coords, groups, attrs):
    """A complete file made of coordinates and groups only (no records), written atomically.

    It is written to ``path + ".partial"``, fsynced and renamed, so that a killed write never
    leaves a complete-looking file; ``layout_version`` and ``complete = 1`` are added to
    ``attrs``.

    Parameters
    ----------
    path : str or Path
        Final path.
    coords : dict
        ``{dim: (values, attrs)}``: the dimensions and their coordinate values.
    groups : dict
        ``{group: (variables, attrs)}`` in the form of :func:`add_group`.
    attrs : dict
        Root attributes.

    Returns
    -------
    Path
        The final path.
    """
    path = Path(path)
    part = partial_path(path)
    # room first (require_room)
    size = _FILE_BYTES + sum(len(str(v)) for v in attrs.values()) + groups_bytes(groups)
    size += sum(np.asarray(v).nbytes + _DATASET_BYTES for v, _ in coords.values())
    require_room(part, size, path, "the file")
    h5 = None
    try:
        h5 = h5py.File(part, "w")
        for dim, (values, dattrs) in coords.items():
            d = h5.create_dataset(dim, data=np.asarray(values), track_times=False)
            d.make_scale(dim)
            d.attrs.update(dattrs)
        for name, (variables, gattrs) in groups.items():
            write_group(h5, name, variables, gattrs)
        h5.attrs.update(attrs)
        h5.attrs.update({"layout_version": np.int64(LAYOUT_VERSION), "complete": np.int8(1)})
        h5.close()
        h5 = None
        fsync_path(part)
        keep_mode(part, path)
        part.replace(path)
    except BaseException as e:
        # nothing half-written stays: a .partial of a bounds file cannot be resumed
        raise abandon(h5, part, path, e) from None
    return path


#: Bytes of HDF5 metadata allowed per file and per dataset in the room check (a bounds
#: file of two beams at 20 frequencies: 31 kB, 3.4 kB of it data, in 20 datasets).
_FILE_BYTES = 64 * 1024
_DATASET_BYTES = 4 * 1024


def groups_bytes(groups):
    """Bytes that ``groups`` (the form of :func:`add_group`) need in a file, allowing
    for HDF5's metadata (the room checks)."""
    size = 0
    for variables, gattrs in (groups or {}).values():
        size += sum(len(str(v)) for v in (gattrs or {}).values())
        size += sum(np.asarray(a).nbytes + _DATASET_BYTES for _, a, _ in variables.values())
    return size
