"""The stop signals (SIGTERM, SIGHUP) the command line received: a note that outlives a
dropped ``KeyboardInterrupt``.

The command line's handler raises ``KeyboardInterrupt``. Raised inside a callback from C
(a weak reference's, or ctypes' while numba compiles) the exception is dropped there, and
the work would run on. So the handler notes the signal here too, and the work checks the
note at its next step (a chunk, a kernel call, a batch of frequencies), stopping as if the
exception had arrived. Outside the command line nothing is noted.
"""

#: Names of the stop signals received during the current command.
RECEIVED = []


def check():
    """Raise ``KeyboardInterrupt`` if a stop signal has been noted.

    Raises
    ------
    KeyboardInterrupt
        Naming the last signal noted.
    """
    if RECEIVED:
        raise KeyboardInterrupt(RECEIVED[-1])
