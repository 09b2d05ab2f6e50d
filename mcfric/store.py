"""The results file: a chunked HDF5 store that survives being killed at any moment.

The store knows records (rows along one "record" dimension, here the samples), named
dimensions and arrays; it knows nothing of physics. The layout that :mod:`mcfric.ensemble`
writes into it is documented in the README (section "Results file"), a public interface.

Crash safety
------------
* A run writes ``FILE.partial`` and renames it to ``FILE`` only after the last byte is on
  disk (``os.replace`` is atomic). A file named ``FILE`` is therefore always complete; its
  root attribute ``complete`` is 1. ``FILE.partial`` has ``complete = 0``.
* Every record dataset is created at the start with all its chunks allocated
  (``H5D_ALLOC_TIME_EARLY``, no filters) and the file is flushed and fsynced. From then on
  a run only writes raw bytes at fixed offsets: the HDF5 metadata (object headers, chunk
  indices, superblock) is never modified until :meth:`Store.finish`. A ``kill -9`` or a
  power cut in the middle of a write leaves metadata that is exactly as created, so the file
  always opens.
* Which records hold valid data is recorded in the ``done`` dataset (int8, 1 = valid),
  written by :meth:`Store.commit` only after the data it covers has been flushed and
  ``fsync``-ed. Records with ``done = 0`` may hold garbage and are recomputed on resume.
* :meth:`Store.finish` overwrites pre-created fixed-size attributes in place (no new
  metadata), fsyncs, closes and renames.

Compression
-----------
None, measured (``bench/ensemble.py``, real 8-beam output): the response is float64 noise to
a compressor (lzf 1.00x, lzf+shuffle 1.13x, gzip-1+shuffle 1.19x) while the filters write
35-115 MB/s on one core against ~730 MB/s unfiltered (fsync included); the kernel produces
~150-250 MB/s of response on two cores. Filtered chunks would also be allocated as they
are written, so every checkpoint would rewrite the chunk index: the crash-safety argument
above needs unfiltered, pre-allocated chunks.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

SUFFIX = ".partial"
LAYOUT_VERSION = 1
DONE = "done"
#: Target size of one HDF5 chunk (HDF5 guidance: ~1 MiB).
CHUNK_BYTES = 1 << 20
#: Raw-data chunk cache per dataset, so partial-chunk writes do not thrash.
CACHE_BYTES = 8 << 20


class StoreError(Exception):
    """A results file that cannot be used as asked (incomplete, damaged, wrong layout)."""


def partial_path(path):
    """``FILE.partial``: where a run writes until it is complete."""
    p = Path(path)
    return p.with_name(p.name + SUFFIX)


def _fsync_path(path):
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)   # flushes every dirty page of the file, whoever wrote it
    finally:
        os.close(fd)


def _fsync_dir(path):
    try:
        _fsync_path(Path(path).resolve().parent)
    except OSError:   # some file systems cannot fsync a directory; the rename still happened
        pass


def _record_chunk(row_bytes, n_records):
    """Rows per HDF5 chunk: a power of two giving <= ~1 MiB (at least 1 row)."""
    k = max(1, CHUNK_BYTES // max(1, row_bytes))
    k = 1 << (k.bit_length() - 1)
    return int(min(k, n_records))


class Store:
    """A results file being written (created fresh or reopened to resume).

    Use :meth:`create` or :meth:`reopen`; then :meth:`write` records, :meth:`commit` them,
    and :meth:`finish` (complete and rename) or :meth:`close` (leave it partial).
    """

    def __init__(self, h5, final_path, record_dim):
        self._h5 = h5
        self.final_path = Path(final_path)
        self.path = partial_path(final_path)
        self.record_dim = record_dim
        self.n_records = h5[record_dim].shape[0]

    # -- creation ---------------------------------------------------------------------

    @classmethod
    def create(cls, path, *, record_dim, n_records, coords, variables, attrs, placeholders,
               groups=None):
        """Create ``path + ".partial"`` (replacing one that exists) with every chunk allocated.

        Parameters
        ----------
        path : str or Path
            Final path of the results file.
        record_dim : str
            Name of the record dimension (its coordinate is 0 .. n_records - 1).
        n_records : int
        coords : dict
            ``{dim: (values, attrs)}``: the other dimensions and their coordinate values.
        variables : dict
            ``{name: (dims, dtype, attrs)}``; ``dims[0]`` must be ``record_dim``.
        attrs : dict
            Root attributes written now.
        placeholders : dict
            Root attributes set now and overwritten in place by :meth:`finish`: numeric
            numpy scalars (their dtype is kept).
        groups : dict, optional
            ``{group: (variables, attrs)}`` written whole now (e.g. ``bounds/``), in the
            form of :func:`add_group`; written at creation so that nothing but raw chunk
            bytes changes afterwards.
        """
        part = partial_path(path)
        part.unlink(missing_ok=True)
        h5 = h5py.File(part, "w", rdcc_nbytes=CACHE_BYTES)
        try:
            rec = h5.create_dataset(record_dim, shape=(n_records,), dtype=np.int64,
                                    track_times=False)
            block = 1 << 20
            for a in range(0, n_records, block):   # memory stays flat for huge ensembles
                b = min(n_records, a + block)
                rec[a:b] = np.arange(a, b, dtype=np.int64)
            rec.make_scale(record_dim)
            for dim, (values, dattrs) in coords.items():
                d = h5.create_dataset(dim, data=np.asarray(values), track_times=False)
                d.make_scale(dim)
                d.attrs.update(dattrs)
            all_vars = dict(variables)
            all_vars[DONE] = ((record_dim,), np.int8,
                              {"long_name": "1 = this record holds valid data"})
            for name, (dims, dtype, vattrs) in all_vars.items():
                if dims[0] != record_dim:
                    raise ValueError(f"{name}: the first dimension must be {record_dim!r}")
                shape = tuple(h5[d].shape[0] for d in dims)
                ds = _create_allocated(h5, name, shape, np.dtype(dtype), fill=name == DONE)
                for i, d in enumerate(dims):
                    ds.dims[i].attach_scale(h5[d])
                ds.attrs.update(vattrs)
            for gname, (gvars, gattrs) in (groups or {}).items():
                _write_group(h5, gname, gvars, gattrs)
            h5.attrs.update(attrs)
            h5.attrs["layout_version"] = np.int64(LAYOUT_VERSION)
            h5.attrs["complete"] = np.int8(0)
            for k, v in placeholders.items():
                h5.attrs.create(k, v, dtype=np.asarray(v).dtype)
            h5.flush()
            _fsync_path(part)
            _fsync_dir(part)
        except BaseException:
            h5.close()
            part.unlink(missing_ok=True)
            raise
        return cls(h5, path, record_dim)

    @classmethod
    def reopen(cls, path, record_dim):
        """Reopen ``path + ".partial"`` to continue writing it."""
        part = partial_path(path)
        try:
            h5 = h5py.File(part, "r+", rdcc_nbytes=CACHE_BYTES)
        except OSError as e:
            raise StoreError(f"{part}: cannot be reopened ({e})") from None
        if int(h5.attrs.get("complete", -1)) != 0 or DONE not in h5 or record_dim not in h5:
            h5.close()
            raise StoreError(f"{part}: not a partial results file of this layout")
        return cls(h5, path, record_dim)

    # -- writing ----------------------------------------------------------------------

    @property
    def attrs(self):
        return self._h5.attrs

    def done(self):
        """Boolean mask (n_records,) of records holding valid data."""
        return self._h5[DONE][...].astype(bool)

    def write(self, start, arrays):
        """Write records ``start .. start + n`` of each named variable (not yet committed).

        Whole HDF5 chunks go straight to their pre-allocated place (``H5Dwrite_chunk``,
        no copy, no type conversion: ~2x less CPU than a selection write, measured);
        partial chunks at the edges go through the normal path.
        """
        for name, arr in arrays.items():
            ds = self._h5[name]
            arr = np.ascontiguousarray(arr)
            stop = start + len(arr)
            k = ds.chunks[0]
            first = -(-start // k) * k          # first chunk boundary >= start
            last = (stop // k) * k              # last chunk boundary <= stop
            if first >= last or not _raw_compatible(ds, arr):
                ds[start:stop] = arr
                continue
            if start < first:
                ds[start:first] = arr[:first - start]
            zeros = (0,) * (arr.ndim - 1)
            for c in range(first, last, k):
                block = arr[c - start:c - start + k]
                ds.id.write_direct_chunk((c,) + zeros, memoryview(block).cast("B"))
            if last < stop:
                ds[last:stop] = arr[last - start:]

    def commit(self, ranges):
        """Make written records durable, then mark them done.

        Parameters
        ----------
        ranges : iterable of (start, stop)
            Record ranges whose data has been passed to :meth:`write`.
        """
        ranges = list(ranges)
        if not ranges:
            return
        self._h5.flush()
        _fsync_path(self.path)       # data on disk before the marks that vouch for it
        d = self._h5[DONE]
        for a, b in ranges:
            d[a:b] = 1
        self._h5.flush()

    def finish(self, summary):
        """Set the summary attributes, mark complete, fsync and rename to the final path.

        Parameters
        ----------
        summary : dict
            New values of the ``placeholders`` given to :meth:`create` (same dtypes).

        Returns
        -------
        Path
            The final path.
        """
        for k, v in summary.items():
            self._h5.attrs.modify(k, v)     # in place: same size, no new metadata
        self._h5.attrs.modify("complete", np.int8(1))
        self._h5.flush()
        self._h5.close()
        _fsync_path(self.path)
        os.replace(self.path, self.final_path)
        _fsync_dir(self.final_path)
        return self.final_path

    def close(self):
        """Close without completing (the ``.partial`` file stays, resumable)."""
        if self._h5.id.valid:
            self._h5.flush()
            self._h5.close()


#: dtypes whose numpy bytes are exactly the HDF5 file type's bytes (as created here)
_RAW_KINDS = {np.dtype(t) for t in ("<f8", "<c16", "|b1", "|i1", "<i8")}


def _raw_compatible(ds, arr):
    """Can ``arr`` be written as raw chunk bytes of ``ds`` (same layout, no filter)?"""
    return (arr.dtype == ds.dtype and arr.dtype in _RAW_KINDS and ds.compression is None
            and not ds.shuffle and ds.chunks[1:] == ds.shape[1:] == arr.shape[1:])


def _create_allocated(h5, name, shape, dtype, fill):
    """A chunked, unfiltered dataset with all chunks allocated now (see the module notes)."""
    row = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize
    k = _record_chunk(row, shape[0])
    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
    dcpl.set_chunk((k,) + tuple(shape[1:]))
    dcpl.set_alloc_time(h5py.h5d.ALLOC_TIME_EARLY)
    dcpl.set_obj_track_times(False)
    if fill:
        dcpl.set_fill_value(np.zeros((), dtype))
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_ALLOC)   # small: the done mask starts at 0
    else:
        dcpl.set_fill_time(h5py.h5d.FILL_TIME_NEVER)   # big: do not write it twice
    space = h5py.h5s.create_simple(shape)
    tid = h5py.h5t.py_create(dtype, logical=True)
    dsid = h5py.h5d.create(h5.id, name.encode(), tid, space, dcpl=dcpl)
    return h5py.Dataset(dsid)


# ----------------------------------------------------------------------------- reading

def _open_read(path):
    try:
        # locking=False: readable while a run writes it (its metadata does not change)
        return h5py.File(path, "r", locking=False)
    except FileNotFoundError:
        raise StoreError(f"{path}: no such file") from None
    except OSError as e:
        raise StoreError(f"{path}: not a readable HDF5 file ({e})") from None


def read_attrs(path):
    """Root attributes of a results file (complete or partial) as a dict."""
    with _open_read(path) as h5:
        return {k: _plain(v) for k, v in h5.attrs.items()}


def _plain(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.generic):
        return v.item()
    return v


def describe(path):
    """Layout summary: root attributes, and per dataset its dims, shape and dtype."""
    with _open_read(path) as h5:
        out = {"attrs": {k: _plain(v) for k, v in h5.attrs.items()}, "datasets": {}}
        for name, ds in h5.items():
            if isinstance(ds, h5py.Dataset):
                dims = (name,) if ds.is_scale else tuple(
                    d[0].name.lstrip("/") if len(d) else "?" for d in ds.dims)
                out["datasets"][name] = (dims, ds.shape, ds.dtype)
        if DONE in h5:
            out["done"] = int(np.count_nonzero(h5[DONE][...]))
        return out


def iter_records(path, names, block=4096, only_done=True):
    """Yield ``(start, {name: array})`` in blocks of records (memory stays flat).

    Records not marked done are skipped when ``only_done`` (they may hold garbage).
    """
    with _open_read(path) as h5:
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


def read(path, name):
    """One whole dataset (use :func:`iter_records` for big ones)."""
    with _open_read(path) as h5:
        return h5[name][...]


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
        raise ImportError("open_results needs xarray and h5netcdf: "
                          "pip install 'mcfric[test]' or pip install xarray h5netcdf") from None
    attrs = read_attrs(path)
    if attrs.get("layout_version") is None:
        raise StoreError(f"{path}: not an mcfric results file (no layout_version)")
    if attrs.get("complete") != 1 and not allow_incomplete:
        raise StoreError(f"{path}: incomplete run (complete = 0); continue it with "
                         f"`mcfric run ... --resume`, or pass allow_incomplete=True")
    return xr.open_dataset(path, engine="h5netcdf")


def add_group(path, name, variables, attrs=None):
    """Add (or replace) a group of arrays to a complete results file.

    The hook for later stages (e.g. ``bounds/`` from the bounds stage): each variable is
    labelled with dimensions of the root (``frequency``, ``beam``, ...), so
    ``xarray.open_dataset(path, engine="h5netcdf", group=name)`` reads it.

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
    with h5py.File(path, "r+") as h5:
        _write_group(h5, name, variables, attrs)
        h5.flush()


def _write_group(h5, name, variables, attrs):
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
