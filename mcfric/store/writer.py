"""The crash-safe writer of a results file: records written into pre-allocated chunks.

Crash safety
------------
* A run writes ``FILE.partial`` and renames it to ``FILE`` only after the last byte is on
  disk (``os.replace`` is atomic). A file named ``FILE`` is therefore always complete; its
  root attribute ``complete`` is 1. ``FILE.partial`` has ``complete = 0``.
* Every record dataset is created at the start with all its chunks allocated
  (``H5D_ALLOC_TIME_EARLY``, no filters), its disk blocks reserved (:func:`reserve`), and
  the file is flushed and fsynced. From then on a run only writes raw bytes at fixed
  offsets, with ``os.pwrite`` at the byte offsets of the chunks (a chunk holds whole rows,
  so the rows of a record range are contiguous in it): the HDF5 metadata (object headers,
  chunk indices, superblock) is never modified until :meth:`Store.finish`. A ``kill -9``
  or a power cut in the middle of a write leaves metadata that is exactly as created, so
  the file always opens. A failed write (disk full, I/O error) raises at once; nothing is
  left dirty in HDF5's caches, where a failure would only show when the file is closed
  (and could crash the process).
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

import ctypes
import errno
import os
import shutil
import stat
import sys
from pathlib import Path

import h5py
import numpy as np

from ..memory import human
from .files import (
    DONE,
    LAYOUT_VERSION,
    MIN_FREE,
    StoreError,
    abandon,
    fsync_dir,
    fsync_path,
    hdf5_reason,
    keep_mode,
    partial_path,
    require_room,
)
from .groups import groups_bytes, write_group

#: Target size of one HDF5 chunk (HDF5 guidance: ~1 MiB).
CHUNK_BYTES = 1 << 20
#: No raw-data chunk cache: records are written with os.pwrite, never through HDF5, so a
#: cached chunk could only be stale.
CACHE_BYTES = 0


def _fallocate(fd, size):
    """Allocate ``size`` bytes of ``fd`` on disk; OSError where that fails.

    On Linux the system call itself (through ctypes): ``posix_fallocate`` falls back, where
    the file system has no ``fallocate``, to writing one byte per block, which over NFS
    takes minutes per GB; the system call reports EOPNOTSUPP instead.
    """
    fn = _libc_fallocate()
    if fn is None:
        os.posix_fallocate(fd, 0, size)
        return
    if fn(fd, 0, 0, size) != 0:
        e = ctypes.get_errno()
        raise OSError(e, os.strerror(e))


def _libc_fallocate():
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = getattr(libc, "fallocate64", None) or libc.fallocate
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int64, ctypes.c_int64]
    fn.restype = ctypes.c_int
    return fn


def reserve(path):
    """Allocate the disk blocks of the whole file now (``fallocate``).

    The chunks are allocated in the HDF5 sense at creation, but the file is sparse: without
    this, a full disk would show only when a chunk is written, hours into a run. With it,
    a file that cannot fit fails here, before any work, and later writes cannot run out
    of space. A file larger than the free space is refused first, on every file system
    (``--skip-space-check`` skips the estimate, not this); file systems without
    ``fallocate`` are then left as they are.

    Raises
    ------
    StoreError
        The file system has no room for the file (ENOSPC, EDQUOT).
    """
    st = os.stat(path)
    size = st.st_size
    # measured before: a failing fallocate can hold every free block until it gives up
    # (ext4), so a file that cannot fit is refused without trying, and the free space
    # said is the disk's, not what the attempt left
    free = shutil.disk_usage(Path(path).resolve().parent).free
    if size - st.st_blocks * 512 > free:
        raise StoreError(f"{path}: no space for the results file ({human(size)} needed, "
                         f"{human(free)} free)")
    fd = os.open(path, os.O_RDWR)
    try:
        _fallocate(fd, size)
    except OSError as e:
        if e.errno == errno.EDQUOT:
            # the disk may have room: the user's quota has not
            raise StoreError(f"{path}: no space for the results file ({human(size)} "
                             f"needed: disk quota exceeded)") from None
        if e.errno == errno.ENOSPC:
            raise StoreError(f"{path}: no space for the results file ({human(size)} "
                             f"needed, {human(free)} free)") from None
        if e.errno not in (errno.EOPNOTSUPP, errno.EINVAL, errno.ENOSYS):
            raise
    finally:
        os.close(fd)


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
        # where each record dataset's chunks sit in the file, for raw writes
        self._raw = {}
        for name, ds in h5.items():
            if (isinstance(ds, h5py.Dataset) and ds.chunks is not None
                    and ds.shape[0] == self.n_records and ds.dtype in _RAW_KINDS
                    and ds.compression is None and not ds.shuffle
                    and ds.chunks[1:] == ds.shape[1:]):
                self._raw[name] = _chunk_offsets(ds)
        self._fd = os.open(self.path, os.O_RDWR)

    # -- creation ---------------------------------------------------------------------

    @staticmethod
    def require_floor(path, extra_bytes=0):
        """Check that ``path``'s directory has the room :meth:`create` needs at least,
        before a run's work (the bounds take minutes), even where the space check is
        skipped.

        Parameters
        ----------
        path : str or Path
            Final path of the results file.
        extra_bytes : int
            Bytes of the groups :meth:`create` will write (e.g. an estimate of the
            bounds group, known before the bounds are computed).

        Raises
        ------
        StoreError
            Less free than ``MIN_FREE + extra_bytes``, counting the blocks of an old
            ``.partial`` that :meth:`create` removes first (a regular file with no other
            link: removing a symbolic link or one of two links frees nothing; on a
            copy-on-write file system with snapshots even that may free less, and
            :meth:`create` then refuses after the work).
        """
        part = partial_path(path)
        freed = 0
        try:
            st = part.lstat()
            if stat.S_ISREG(st.st_mode) and st.st_nlink == 1:
                freed = st.st_blocks * 512
        except OSError:
            pass
        require_room(part, MIN_FREE + extra_bytes - freed, path, "the results file")

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
        # not even the layout and the groups written with it fit (nothing to credit now)
        cls.require_floor(path, groups_bytes(groups))
        h5 = None
        try:
            h5 = h5py.File(part, "w", rdcc_nbytes=CACHE_BYTES)
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
            reserve(part)
            fsync_path(part)
            fsync_dir(part)
        except BaseException as e:
            raise abandon(h5, part, path, e) from None
        return cls(h5, path, record_dim)

    @classmethod
    def reopen(cls, path, record_dim):
        """Reopen ``path + ".partial"`` to continue writing it."""
        part = partial_path(path)
        try:
            h5 = h5py.File(part, "r+", rdcc_nbytes=CACHE_BYTES)
        except OSError as e:
            raise StoreError(f"{part}: cannot be reopened ({e})") from None
        complete = int(h5.attrs.get("complete", -1))
        if complete not in (0, 1) or DONE not in h5 or record_dim not in h5:
            h5.close()
            raise StoreError(f"{part}: not a partial results file of this layout")
        if complete == 1:
            # stopped after :meth:`finish` marked it complete, before the rename: it is
            # finished again (nothing left to solve) and renamed
            h5.attrs.modify("complete", np.int8(0))
        try:
            reserve(part)
        except BaseException:
            h5.close()
            raise
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

        The bytes go straight to their pre-allocated place in the file (``os.pwrite``: no
        copy, no type conversion, nothing cached by HDF5).

        Raises
        ------
        StoreError
            The write failed (disk full, I/O error): one line with the system's reason.
        """
        try:
            self._write(start, arrays)
        except (OSError, RuntimeError) as e:
            raise StoreError(f"{self.path}: writing failed: {hdf5_reason(e)}") from None

    def _write(self, start, arrays):
        for name, arr in arrays.items():
            arr = np.ascontiguousarray(arr)
            raw = self._raw.get(name)
            if raw is not None and arr.dtype == raw[2]:
                self._pwrite(raw, start, arr)
                continue
            ds = self._h5[name]            # another dtype: HDF5 converts (not used today)
            ds[start:start + len(arr)] = arr
            # write the chunk cache out now: a failure here raises, whereas at the
            # dataset's close (when `ds` is collected) HDF5 would only print it
            ds.flush()

    def _pwrite(self, raw, start, arr):
        """Rows ``start .. start + len(arr)`` as raw bytes at their chunks' offsets."""
        offsets, k, dtype, row = raw
        data = memoryview(arr).cast("B")
        stop = start + len(arr)
        r = start
        while r < stop:
            c = r // k
            end = min(stop, (c + 1) * k)
            _pwrite_all(self._fd, data[(r - start) * row:(end - start) * row],
                        int(offsets[c]) + (r - c * k) * row)
            r = end

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
        try:
            self._h5.flush()
            os.fsync(self._fd)          # data on disk before the marks that vouch for it
            for a, b in ranges:
                self._write(a, {DONE: np.ones(b - a, np.int8)})
        except (OSError, RuntimeError) as e:
            raise StoreError(f"{self.path}: writing failed: {hdf5_reason(e)}") from None

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
        os.close(self._fd)
        fsync_path(self.path)
        keep_mode(self.path, self.final_path)
        os.replace(self.path, self.final_path)
        fsync_dir(self.final_path)
        return self.final_path

    def close(self):
        """Close without completing (the ``.partial`` file stays, resumable).

        Errors while flushing are ignored: whatever did not reach the disk is not marked
        done (:meth:`commit` marks only what it flushed), so ``--resume`` recomputes it,
        and the error that stopped the run is the one to report.
        """
        if self._h5.id.valid:
            try:
                self._h5.flush()
            except (OSError, RuntimeError):
                pass
            try:
                self._h5.close()
            except (OSError, RuntimeError):
                pass
            os.close(self._fd)


#: dtypes whose numpy bytes are exactly the HDF5 file type's bytes (as created here)
_RAW_KINDS = {np.dtype(t) for t in ("<f8", "<f4", "<c16", "|b1", "|i1", "<i8")}


def _chunk_offsets(ds):
    """``(byte offset of each chunk, rows per chunk, dtype, bytes per row)`` of a record
    dataset whose chunks are all allocated."""
    k = ds.chunks[0]
    n_chunks = -(-ds.shape[0] // k)
    offsets = np.full(n_chunks, -1, dtype=np.int64)
    for i in range(ds.id.get_num_chunks()):
        info = ds.id.get_chunk_info(i)
        offsets[info.chunk_offset[0] // k] = info.byte_offset
    if (offsets < 0).any():
        raise StoreError(f"{ds.file.filename}: dataset {ds.name} has unallocated chunks")
    row = int(np.prod(ds.shape[1:], dtype=np.int64)) * ds.dtype.itemsize
    return offsets, k, ds.dtype, row


def _pwrite_all(fd, data, offset):
    """``os.pwrite`` until every byte is written (a regular file may take fewer)."""
    while len(data):
        n = os.pwrite(fd, data, offset)
        data = data[n:]
        offset += n


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
