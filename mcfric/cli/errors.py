"""What the command line reports and how it exits: :class:`UsageError` (one line,
exit code 2) and the exit codes."""

from __future__ import annotations

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class UsageError(Exception):
    """Bad input from the user: one line on stderr, exit code 2."""


def one_line(e):
    """An error's text on one line: a key or a library's message may hold line breaks
    (a quoted TOML key with a line break in it, HDF5's own errors)."""
    return " ".join(str(e).split())
