"""Threads: how many numba uses, and a pool that runs ``nogil`` kernels over work items.

Results never depend on either: the kernels write disjoint parts of their outputs.
"""

from __future__ import annotations

import contextlib
from concurrent.futures import ThreadPoolExecutor

import numba

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
            task(item)
        return
    pool = ThreadPoolExecutor(n)
    try:
        for future in [pool.submit(task, item) for item in items]:
            future.result()
    finally:
        # on an error or Ctrl-C the queued tasks are dropped, not run to the end
        pool.shutdown(wait=True, cancel_futures=True)
