"""Names and durability of output files: the ``.partial`` suffix, errors, fsync, and
the replacement of a small output (a CSV, a figure) in one step.

A run writes ``FILE.partial`` and renames it to ``FILE`` only when it is complete, after
everything is on disk (:func:`fsync_path`, then ``os.replace`` and :func:`fsync_dir`):
a file named ``FILE`` is always complete. Smaller outputs are written beside their name
and renamed when complete (:func:`replacing`).
"""

from __future__ import annotations

import os
import re
import shutil
import stat
from contextlib import contextmanager
from pathlib import Path

from ..memory import human

SUFFIX = ".partial"
LAYOUT_VERSION = 1
DONE = "done"
#: Free bytes needed before a results file is created at all (its layout and metadata), and
#: beyond its size before a complete one is copied to be changed.
MIN_FREE = 256 * 1024


class StoreError(Exception):
    """A results file that cannot be used as asked (incomplete, damaged, wrong layout)."""


def hdf5_reason(e):
    """One line from an HDF5 error (which spans lines and quotes the system's message)."""
    m = re.search(r"error message = '([^']*)'", str(e))
    if m:
        return m.group(1)
    return str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__


def require_room(part, need, path, what):
    """Raise :class:`StoreError` unless ``part``'s directory has ``need`` bytes free
    (the directory itself, beside a symbolic link, not at its target): HDF5 that runs
    out of space while it creates or closes a file can crash the process, past any
    cleanup (seen with a few kB free)."""
    free = shutil.disk_usage(Path(part).absolute().parent).free
    if free < need:
        raise StoreError(f"{path}: no space for {what} ({human(need)} needed, "
                         f"{human(free)} free)")


def abandon(h5, part, path, e):
    """Close ``h5`` (a close that fails too, as on a full disk, is ignored) and remove
    the half-written ``part``: nothing of a failed write stays. Returns the error to
    raise: one line (:class:`StoreError`) for the system's or HDF5's, ``e`` otherwise."""
    if h5 is not None:
        try:
            h5.close()
        except Exception:
            pass
    Path(part).unlink(missing_ok=True)
    # a full disk's is a RuntimeError, or (creating a dataset) a ValueError naming errno
    if (isinstance(e, (OSError, RuntimeError))
            or isinstance(e, ValueError) and re.search(r"errno = \d+", str(e))):
        return StoreError(f"{path}: cannot be written ({hdf5_reason(e)})")
    return e


def partial_path(path):
    """``FILE.partial``: where a run writes until it is complete."""
    p = Path(path)
    return p.with_name(p.name + SUFFIX)


def fsync_path(path):
    """Flush every dirty page of the file at ``path`` to disk."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)   # flushes every dirty page of the file, whoever wrote it
    finally:
        os.close(fd)


@contextmanager
def replacing(path, what):
    """Write an output through a temporary file beside ``path``, renamed to ``path`` only
    when the ``with`` block ends without error: an interrupted or failed write (Ctrl-C,
    a full disk) leaves ``path`` as it was, and no partial file.

    Parameters
    ----------
    path : str or Path
        The output's name.
    what : str
        What it is (``"figure"``, ``"CSV"``): an ``OSError`` names it and ``path``.

    Yields
    ------
    Path
        The temporary file to write (hidden, with ``path``'s suffix, which writers such
        as matplotlib read the format from).

    Notes
    -----
    A symbolic link at ``path`` is written through (its target is replaced), and an
    existing file's permission bits are kept; hard links to the old file keep the old
    contents.
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        yield tmp
        keep_mode(tmp, path)
        os.replace(tmp, path)
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError) and not isinstance(e, BrokenPipeError):
            # the message alone, without "[Errno N]"; the number stays on the error
            err = OSError(f"{what} {path}: {e.strerror or e}")
            err.errno = e.errno
            raise err from None
        raise


def keep_mode(new, old):
    """Give ``new`` the permission bits of ``old`` when ``old`` exists, before ``new``
    replaces it: a replaced output (a CSV, a figure, a results file made again with
    ``--force``) keeps the access its owner gave it, not the umask's."""
    try:
        mode = stat.S_IMODE(os.stat(old).st_mode)
    except FileNotFoundError:
        return
    os.chmod(new, mode)


def fsync_dir(path):
    """Flush the directory holding ``path`` (so a rename in it is durable)."""
    try:
        fsync_path(Path(path).resolve().parent)
    except OSError:   # some file systems cannot fsync a directory; the rename still happened
        pass
