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


def reading(path, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, which reads the results file ``path``: a dataset missing
    (a StoreError) or an attribute edited into another type or shape is one line, exit 2
    (a traceback, or exit 1, before). ``fn`` reports bad arguments as a
    :class:`UsageError` of its own (a ``ValueError`` here is blamed on the file)."""
    from ..store import StoreError

    try:
        return fn(*args, **kwargs)
    except StoreError as e:
        raise UsageError(str(e)) from None
    except (AttributeError, KeyError, TypeError, ValueError) as e:
        raise UsageError(f"{path}: a damaged or edited results file ({type(e).__name__}: "
                         f"{one_line(e)})") from None


def interrupted_after(out, cut="the checks or the figure", rest=""):
    """Exit status of an interrupt after ``out`` was complete (written by a rename, so
    whole): said on stderr, with what was ``cut`` short and how to see it."""
    import sys

    print(f"interrupted: {out} is complete; {cut} after it were cut short "
          f"(`mcfric info {out}`, `mcfric plot {out}`){rest}", file=sys.stderr)
    return EXIT_INTERRUPTED
