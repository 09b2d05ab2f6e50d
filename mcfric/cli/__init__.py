"""``mcfric`` command line: wires config, ensemble, store and plots together.

One module per command (:mod:`.run`, :mod:`.bounds`, :mod:`.plot`, :mod:`.info` with
``config``, :mod:`.hbm`, :mod:`.verify`), beside the parser, the configuration a command
runs (:mod:`.inputs`), its output paths (:mod:`.outputs`), the errors and exit codes
(:mod:`.errors`) and the dispatch to the commands (:mod:`.dispatch`).

::

    mcfric                                   # = mcfric run: the embedded default
    mcfric run [PRESET|CONFIG.toml] [-o FILE] [--samples N] [--seed S] [--resume]
               [--force] [--threads T] [--chunk N] [--scheduler ADDRESS] [--peaks N]
               [--peak-rtol X] [--no-peaks] [--F0 N] [--f-min HZ] [--f-max HZ] [--n-freq N]
               [--no-certify] [--no-bounds] [--moments | --first-order] [--no-progress]
               [--no-figure] [--skip-space-check]
    mcfric config [PRESET|CONFIG.toml|FILE.h5]  # complete TOML on stdout (of a file: its run)
    mcfric info FILE                         # summary of a results file
    mcfric hbm [PRESET|CONFIG.toml] [--mu0 X] [--kc N_PER_M] [--N0 N] [--F0 N]
               [--f-min HZ] [--f-max HZ] [--n-freq N] [-o OUT.csv] [--no-figure]
    mcfric bounds [PRESET|CONFIG.toml] [-o FILE] [--F0 N] [--f-min HZ] [--f-max HZ]
               [--n-freq N] [--k-max N_PER_M] [--F-lim N] [--threads T] [--no-certify]
               [--moments | --first-order] [--no-progress] [--no-figure]
    mcfric plot FILE [-o FIG.png|pdf] [--quantity Q] [--f-min HZ] [--f-max HZ]
               [--member I] [--measured DATA ...] [--nodes N1,N2,...] [--normalise]
               [--measured-quantity Q] [--measured-force N] [--measured-direction D]
               [--no-indicator]
    mcfric verify [PRESET|CONFIG.toml] --f HZ [HZ ...] [--mu0 X] [--kc N_PER_M] [--N0 N]
               [--F0 N] [--harmonics H] [--start single|rest] [-o OUT.csv] [--no-figure]
               [--no-progress]
    mcfric verify FILE.h5 --member I --f HZ [HZ ...] [--harmonics H] ...

``run`` and ``hbm`` also take ``--harmonics H`` (multi-harmonic balance of the odd
harmonics 1..H) and ``--n-time N`` (AFT samples per period).

Exit codes: 0 done, 1 a run-time failure (disk full, I/O error, out of memory), 2 bad
configuration, arguments or input files, or a refused run (one line on stderr, nothing
written), 130 interrupted by Ctrl-C, SIGTERM or SIGHUP (the finished chunks are kept;
continue with ``--resume``).
"""

import sys

from .errors import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, UsageError


def main(argv=None):
    """Entry point of ``mcfric`` (:func:`.dispatch.main`); returns the exit code.

    The commands, numpy and numba load here rather than when the package is imported,
    so Ctrl-C, SIGTERM or SIGHUP while they load is an interrupt like any other: one
    line, exit 130. SIGTERM and SIGHUP stop a run as Ctrl-C does (the finished chunks
    are committed, a message says how to resume) from here until the command returns;
    their handlers are restored when it is called with ``argv``. Called as the program
    (``argv`` None), it ignores those signals once the command has returned: the
    interpreter's shutdown (numba, h5py) takes up to a second, and a signal then would
    end a finished command as killed.
    """
    import signal
    import threading

    from .. import stop_signals

    main_thread = threading.current_thread() is threading.main_thread()

    def interrupt(signum, frame):
        name = signal.Signals(signum).name
        # noted too: raised inside a callback from C (a weak reference's, numba
        # compiling) the exception is dropped, and the work checks the note
        stop_signals.RECEIVED.append(name)
        raise KeyboardInterrupt(name)

    def unraisable(info, default=sys.unraisablehook):
        # the dropped interrupt is the note's to act on: no traceback for it
        if not (isinstance(info.exc_value, KeyboardInterrupt) and stop_signals.RECEIVED):
            default(info)

    stop_signals.RECEIVED.clear()   # a caller's earlier command
    stops = [getattr(signal, s) for s in ("SIGTERM", "SIGHUP") if hasattr(signal, s)]
    previous = {s: signal.signal(s, interrupt) for s in stops} if main_thread else {}
    hook, sys.unraisablehook = sys.unraisablehook, unraisable
    try:
        try:
            from .dispatch import main as dispatch

            stop_signals.check()    # dropped while the modules loaded
        except KeyboardInterrupt:
            print("mcfric: interrupted", file=sys.stderr)
            return EXIT_INTERRUPTED
        try:
            rc = dispatch(argv)
        except KeyboardInterrupt:       # in the instants before and after its own guard
            print("mcfric: interrupted", file=sys.stderr)
            rc = EXIT_INTERRUPTED
        if argv is None and main_thread:
            for s in [signal.SIGINT, *stops]:
                signal.signal(s, signal.SIG_IGN)
        return rc
    finally:
        if argv is not None:
            sys.unraisablehook = hook
            for s, h in previous.items():
                signal.signal(s, h)


__all__ = ["main", "UsageError", "EXIT_OK", "EXIT_FAIL", "EXIT_USAGE", "EXIT_INTERRUPTED"]
