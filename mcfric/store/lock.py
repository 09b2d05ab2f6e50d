"""Exclusive ownership of an output file for the whole time a process writes it.

Every writer of a results file (``mcfric run``, its ``--resume`` and ``--force``, and
``mcfric bounds``) holds ``FILE.lock`` with an advisory ``flock`` from before its first
check of ``FILE`` and ``FILE.partial`` until after its last rename. A second writer of the
same ``FILE`` finds the lock taken and stops with one line naming the owner (PID, host,
start time), before it reads, deletes or renames anything.

The kernel releases a ``flock`` when its owner dies, however it dies (``kill -9``
included), so a lock file left behind by a crashed run blocks nobody: the next writer
takes the lock and rewrites the owner line. A clean exit removes the lock file while
still holding the lock. Locks are per host on most network file systems; two machines
writing one file over NFS are not guarded against.
"""

from __future__ import annotations

import errno
import json
import os
import socket
import time
from pathlib import Path

from .files import StoreError

SUFFIX = ".lock"


class LockError(StoreError):
    """Another live process owns the output (or the lock cannot be taken at all)."""


def lock_path(path):
    """``FILE.lock``: the lock of the output ``FILE``."""
    p = Path(path)
    return p.with_name(p.name + SUFFIX)


def _owner(fd):
    """The owner line stored in an open lock file ("unknown owner" if unreadable)."""
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", "replace")
        o = json.loads(text)
        return (f"PID {int(o['pid'])} on {o['host']}, started {o['started']}"
                + (f" ({o['command']})" if o.get("command") else ""))
    except (OSError, ValueError, KeyError, TypeError):
        return "another process (owner unknown)"


def holder(path):
    """Who writes the output ``path`` now: the owner line of a live lock, or None (no
    lock file, or one left by a process that ended). Reads only: never creates the
    lock file, and holds nothing after it returns."""
    import fcntl

    try:
        fd = os.open(lock_path(path), os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError as e:
        return _owner(fd) if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES) \
            else None
    finally:
        os.close(fd)                 # closing releases a shared lock taken just now
    return None


def _is_lock(fd):
    """Whether the open file is empty or holds an owner line (a lock file of ours, maybe
    left by a run that died)."""
    size = os.fstat(fd).st_size
    if size == 0:
        return True
    if size > 4096:
        return False
    try:
        o = json.loads(os.pread(fd, size, 0).decode("utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(o, dict) and "pid" in o and "host" in o


def _lock_briefly_retried(fd):
    """``flock(fd, LOCK_EX | LOCK_NB)``, tried again for about 50 ms: :func:`holder` (an
    ``mcfric info``) holds a shared lock for microseconds, which must not refuse a run."""
    import fcntl

    for attempt in range(6):
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except OSError as e:
            if attempt == 5 or e.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            time.sleep(0.01)


class OutputLock:
    """The lock of one output file, held from :meth:`acquire` to :meth:`release`.

    Parameters
    ----------
    path : str or Path
        The output ``FILE`` (its ``.partial`` is covered too).
    command : str
        What the owner is doing, shown to a second writer (e.g. ``"mcfric run"``).
    """

    def __init__(self, path, command=""):
        self.path = Path(path)
        self.lock_path = lock_path(path)
        self.command = command
        self._fd = None

    def acquire(self):
        """Take the lock or raise :class:`LockError` naming the owner (nothing changed)."""
        while True:
            try:
                fd = os.open(self.lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as e:
                raise LockError(f"{self.lock_path}: cannot create the lock file "
                                f"({e.strerror})") from None
            try:
                _lock_briefly_retried(fd)
            except OSError as e:
                owner = _owner(fd)
                os.close(fd)
                if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                    raise LockError(f"{self.path} is being written by {owner}; wait for "
                                    f"that run to end (or stop it), or choose another "
                                    f"-o") from None
                raise LockError(f"{self.lock_path}: cannot lock ({e.strerror}); this file "
                                f"system does not support flock") from None
            # the previous owner may have removed the file between our open and flock:
            # then we hold a lock on a name that no longer exists; take the new one
            try:
                same = os.stat(self.lock_path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same and not _is_lock(fd):
                # a file of another kind under the lock's name (a results file given
                # -o FILE.lock): truncating it and unlinking it at the end would lose it
                os.close(fd)
                raise LockError(f"{self.lock_path} exists and is not a lock file of "
                                f"mcfric (the lock of {self.path.name}); rename it or "
                                f"choose another -o")
            if same:
                break
            os.close(fd)
        owner = {"pid": os.getpid(), "host": socket.gethostname(),
                 "started": time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime()),
                 "command": self.command}
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(owner).encode(), 0)
        self._fd = fd
        return self

    def release(self):
        """Remove the lock file and release the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            os.unlink(self.lock_path)      # while still locked: no one can be mid-takeover
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
