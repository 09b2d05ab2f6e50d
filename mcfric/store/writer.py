"""The crash-safe writer of a results file: records written into pre-allocated chunks.

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

Chunks are not compressed: filtered chunks would be allocated as they are written, so
every checkpoint would rewrite the chunk index, and the crash-safety argument above needs
unfiltered, pre-allocated chunks (the measured cost of compression is in the docs'
performance page).
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from .files import DONE, LAYOUT_VERSION, StoreError, fsync_dir, fsync_path, partial_path
from .groups import write_group

#: Target size of one HDF5 chunk (HDF5 guidance: ~1 MiB).
CHUNK_BYTES = 1 << 20
#: Raw-data chunk cache per dataset, so partial-chunk writes do not thrash.
CACHE_BYTES = 8 << 20

def _record_chunk(row_bytes, n_records):
    """Rows per HDF5 chunk: a power of two giving <= ~1 MiB (at least 1 row)."""
    k = max(1, CHUNK_BYTES // max(1, row_bytes))
    k = 1 << (k.bit_length() - 1)
    return int(min(k, n_records))


def allocated_bytes(shape, dtype):
    """Bytes a record dataset of ``shape`` takes on disk once created: whole chunks are
    allocated, so the record count is rounded up to a multiple of the chunk."""
    dtype = np.dtype(dtype)
    row = int(np.prod(shape[1:], dtype=np.int64)) * dtype.itemsize
    k = _record_chunk(row, shape[0])
    return -(-int(shape[0]) // k) * k * row


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
                write_group(h5, gname, gvars, gattrs)
            h5.attrs.update(attrs)
            h5.attrs["layout_version"] = np.int64(LAYOUT_VERSION)
            h5.attrs["complete"] = np.int8(0)
            for k, v in placeholders.items():
                h5.attrs.create(k, v, dtype=np.asarray(v).dtype)
            h5.flush()
            fsync_path(part)
            fsync_dir(part)
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
        """Root attributes of the open file (h5py attribute manager)."""
        return self._h5.attrs

    def done(self):
        """Boolean mask (n_records,) of records holding valid data."""
        return self._h5[DONE][...].astype(bool)

    def write(self, start, arrays):
        """Write records ``start .. start + n`` of each named variable (not yet committed).

        Whole HDF5 chunks go straight to their pre-allocated place (``H5Dwrite_chunk``,
        no copy, no type conversion: less CPU than a selection write);
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
        fsync_path(self.path)       # data on disk before the marks that vouch for it
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
        fsync_path(self.path)
        os.replace(self.path, self.final_path)
        fsync_dir(self.final_path)
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
