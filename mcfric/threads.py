"""Threads: how many numba uses, a pool that runs ``nogil`` kernels over work items (whose
long tasks stop at a :func:`check` when the pool is left), and a call that Ctrl-C can
leave while its kernel runs.

Results never depend on any of them: the kernels write disjoint parts of their outputs.
"""

from __future__ import annotations

import contextlib
import threading
from concurrent.futures import ThreadPoolExecutor

import numba

from . import stop_signals
from .validators import InputError, is_int


@contextlib.contextmanager
def threads(n):
    """Run numba parallel kernels with ``n`` threads (None: leave as is); a bad ``n`` is
    an :class:`~mcfric.validators.InputError` naming ``n_threads``, the API's argument."""
    if n is None:
        yield
        return
    if not is_int(n):                   # 1.5 is not 1
        raise InputError("n_threads", f"expected an integer, got {n!r}")
    n = int(n)
    if not 1 <= n <= numba.config.NUMBA_NUM_THREADS:
        raise InputError("n_threads", f"expected 1..{numba.config.NUMBA_NUM_THREADS}, "
                         f"got {n}")
    old = numba.get_num_threads()
    numba.set_num_threads(n)
    try:
        yield
    finally:
        numba.set_num_threads(old)


def in_threads(task, items):
    """``task(item)`` for every item, on ``numba.get_num_threads()`` threads, each taking
    the next item when it is free; the first exception is raised here.

    The tasks are ``nogil`` kernels that write disjoint parts of the output, so the result
    does not depend on the number of threads or the order. Python threads rather than
    ``prange``: each ``prange`` kernel compiled the whole search again (compile times
    in the docs' performance page).
    """
    items = list(items)
    n = min(numba.get_num_threads(), len(items))
    if n <= 1:
        for item in items:
            stop_signals.check()
            task(item)
        return
    abandon = threading.Event()
    pool = ThreadPoolExecutor(n)
    try:
        for future in [pool.submit(_item, task, item, abandon) for item in items]:
            stop_signals.check()
            future.result()
    except BaseException:
        # the running tasks stop at their next check(): a task of many solver calls
        # (a frequency's second-order relaxations) had kept Ctrl-C waiting 15 s
        abandon.set()
        raise
    finally:
        # on an error or Ctrl-C the queued tasks are dropped, not run to the end
        pool.shutdown(wait=True, cancel_futures=True)


class Abandoned(Exception):
    """Raised by :func:`check` in a task whose :func:`in_threads` call is being left."""


#: The abandon event of the :func:`in_threads` call whose task this thread runs.
_TASK = threading.local()


def _item(task, item, abandon):
    _TASK.abandon = abandon
    try:
        return task(item)
    finally:
        _TASK.abandon = None


def check():
    """For a task of :func:`in_threads` made of many steps, between them: raise
    :class:`Abandoned` if its call is being left (an interrupt, another task's error),
    ``KeyboardInterrupt`` if a stop signal has been noted; elsewhere the latter only.

    Raises
    ------
    Abandoned, KeyboardInterrupt
    """
    stop_signals.check()
    abandon = getattr(_TASK, "abandon", None)
    if abandon is not None and abandon.is_set():
        raise Abandoned


#: Held by the call :func:`interruptible` runs: one abandoned by an interrupt holds it
#: until its kernel returns, and the next call waits for it.
_KERNEL_BUSY = threading.Lock()
#: Whether :func:`interruptible` may leave a call behind: only where the process ends
#: after an interrupt (the command line, :func:`leaving_on_interrupt`).
_LEAVE = [False]


@contextlib.contextmanager
def leaving_on_interrupt():
    """Within the block, :func:`interruptible` calls run on a thread of their own, and an
    interrupt leaves them behind: for a process that exits after an interrupt (the
    command line). Elsewhere a kernel left running could meet the next one (other entry
    points, numba's workqueue layer aborts on two parallel kernels at once)."""
    old = _LEAVE[0]
    _LEAVE[0] = True
    try:
        yield
    finally:
        _LEAVE[0] = old


def interruptible(fn, *args, **kwargs):
    """``fn(*args, **kwargs)``; within :func:`leaving_on_interrupt`, on a thread of its own
    while the main thread waits.

    A signal's handler runs only in the main thread, and only between Python steps: while
    a kernel runs there, Ctrl-C or SIGTERM waits for the kernel to return (minutes for a
    chunk of a large model). Waiting here instead, the main thread raises the
    ``KeyboardInterrupt`` within a tenth of a second. The abandoned call runs on in the
    background (``nogil`` kernels cannot be stopped from outside) and its result is
    dropped; the process, which exits after the interrupt, ends it (another call through
    here would wait for it first).

    Parameters
    ----------
    fn : callable
        Calls ``nogil`` kernels (the ``parallel`` ones use this thread's count of numba
        threads, as the caller's).
    *args, **kwargs
        Passed to ``fn``.

    Returns
    -------
    object
        What ``fn`` returns; what it raises is raised here. Outside
        :func:`leaving_on_interrupt`, or off the main thread (where no signal arrives),
        ``fn`` is simply called.
    """
    if not _LEAVE[0] or threading.current_thread() is not threading.main_thread():
        return fn(*args, **kwargs)
    stop_signals.check()
    n = numba.get_num_threads()      # thread-local in numba: the new thread starts at all
    out = {}

    def call():
        with _KERNEL_BUSY:
            try:
                numba.set_num_threads(n)
                out["value"] = fn(*args, **kwargs)
            except BaseException as e:   # re-raised by the caller
                out["error"] = e

    worker = threading.Thread(target=call, name="mcfric-kernel", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(0.1)             # a signal's handler runs between these waits
    if "error" in out:
        raise out.pop("error")
    return out["value"]
