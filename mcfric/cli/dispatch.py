"""``mcfric``'s dispatch to the commands, and errors as one line (the entry point,
:func:`mcfric.cli.main`, loads it and holds the signals)."""

from __future__ import annotations

import os
import sys

from .. import stop_signals
from ..store import StoreError
from .bounds import cmd_bounds
from .compiling import announce_compilation
from .errors import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, UsageError, one_line
from .hbm import cmd_hbm
from .info import cmd_config, cmd_info
from .outputs import MADE_DIRS
from .parser import COMMANDS, build_parser
from .plot import cmd_plot
from .run import cmd_run
from .verify import cmd_verify


def _command_typo(word):
    """A message where ``word``, the first argument, is no command, preset or file but
    close to a command's name (``runn``: read as ``mcfric run runn`` it failed on the
    arguments after it, or as a missing file), else None."""
    import difflib

    from ..presets import PRESETS

    if (word in COMMANDS or word.startswith("-") or word in PRESETS or os.path.exists(word)
            or any(c in word for c in "./\\")):       # a file's name: "no such file" says it
        return None
    close = difflib.get_close_matches(word, COMMANDS, n=1, cutoff=0.6)
    return (f"unknown command {word!r} (did you mean {close[0]!r}? commands: "
            f"{', '.join(COMMANDS)})" if close else None)


class _StdoutGone:
    """``sys.stdout`` for the length of a command: once its reader goes away
    (``mcfric run ... | head -1``) the rest of the output is dropped and the command goes
    on, so that its files are made and its exit code is the work's. (Stopping at the first
    line that could not be printed left no results file and said exit 0.)"""

    def __init__(self, stream):
        self.stream = stream

    def _gone(self):
        # the stream's own buffer and any later flush, at exit too, go to /dev/null
        try:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, self.stream.fileno())
            os.close(null)
        except (OSError, ValueError, AttributeError):
            self.stream = open(os.devnull, "w")

    def write(self, text):
        try:
            return self.stream.write(text)
        except BrokenPipeError:
            self._gone()
            return len(text)

    def flush(self):
        try:
            self.stream.flush()
        except BrokenPipeError:
            self._gone()
            self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)


def main(argv=None):
    """The commands' dispatch, behind the entry point :func:`mcfric.cli.main`; returns
    the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    typo = _command_typo(argv[0]) if argv else None
    if typo:
        print(f"mcfric: error: {typo}", file=sys.stderr)
        return EXIT_USAGE
    if not argv or (argv[0] not in COMMANDS and argv[0] not in ("-h", "--help", "--version")):
        argv = ["run"] + argv        # `mcfric` alone (or `mcfric two-beam`) means `mcfric run`
    undo = lambda: None        # noqa: E731
    try:
        args = build_parser().parse_args(argv)
        if args.command in ("run", "hbm", "bounds", "verify"):     # the ones that solve
            undo = announce_compilation()
        from ..threads import leaving_on_interrupt

        stdout = sys.stdout
        sys.stdout = _StdoutGone(stdout)
        try:
            # the process ends after an interrupt: a chunk's kernel may be left running
            with leaving_on_interrupt():
                stop_signals.check()
                rc = {"run": cmd_run, "config": cmd_config, "info": cmd_info,
                      "hbm": cmd_hbm, "bounds": cmd_bounds, "plot": cmd_plot,
                      "verify": cmd_verify}[args.command](args)
            sys.stdout.flush()       # a closed pipe shows here, not at interpreter exit
        finally:
            sys.stdout = stdout
        return rc
    except UsageError as e:
        print(f"mcfric: error: {one_line(e)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("mcfric: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # a write past the wrapper (from a library holding the stream): stop quietly
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_OK
    except (OSError, StoreError) as e:   # disk full, unreadable file: one line, no traceback
        print(f"mcfric: error: {one_line(e)}", file=sys.stderr)
        return EXIT_FAIL
    except MemoryError:
        print("mcfric: error: out of memory (a model or ensemble this large needs more RAM "
              "than is free: fewer beams, frequencies or samples per chunk)", file=sys.stderr)
        return EXIT_FAIL
    finally:
        undo()
        while MADE_DIRS:
            try:
                MADE_DIRS.pop().rmdir()         # only an empty one
            except OSError:
                pass
