"""Names and durability of results files: the ``.partial`` suffix, errors, fsync.

A run writes ``FILE.partial`` and renames it to ``FILE`` only when it is complete, after
everything is on disk (:func:`fsync_path`, then ``os.replace`` and :func:`fsync_dir`):
a file named ``FILE`` is always complete.
"""

from __future__ import annotations

import os
from pathlib import Path

SUFFIX = ".partial"
LAYOUT_VERSION = 1
DONE = "done"


class StoreError(Exception):
    """A results file that cannot be used as asked (incomplete, damaged, wrong layout)."""


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


def fsync_dir(path):
    """Flush the directory holding ``path`` (so a rename in it is durable)."""
    try:
        fsync_path(Path(path).resolve().parent)
    except OSError:   # some file systems cannot fsync a directory; the rename still happened
        pass
