"""A line on a terminal when numba compiles the kernels: the first command after an
install or an upgrade spends minutes there (a ring's multi-harmonic kernel about four on
two cores) and would otherwise sit silent."""

from __future__ import annotations

import sys
import threading

#: Said once per process, whichever thread compiles first.
_SAID = threading.Event()

MESSAGE = ("mcfric: compiling the numba kernels (the first run after an install or an "
           "upgrade: minutes, once; cached after)")


def announce_compilation(stream=None):
    """Say :data:`MESSAGE` on ``stream`` (default stderr) when a kernel starts to compile.

    Only on a terminal: a log or a test keeps its lines as they were. numba announces a
    compilation only when its cache misses, so a warm run says nothing.

    Returns
    -------
    callable
        Removes the listener.
    """
    stream = sys.stderr if stream is None else stream
    try:
        terminal = stream.isatty()
    except (AttributeError, ValueError):          # a closed or odd stream
        terminal = False
    if not terminal:
        return lambda: None
    from numba.core import event

    class _Announce(event.Listener):
        def on_start(self, ev):
            if not _SAID.is_set():
                _SAID.set()
                print(MESSAGE, file=stream, flush=True)

        def on_end(self, ev):
            pass

    listener = _Announce()
    event.register("numba:compile", listener)
    return lambda: event.unregister("numba:compile", listener)
