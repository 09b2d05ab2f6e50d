"""The one place that sets the numba policy of every kernel in :mod:`mcfric.core`."""

import functools
import hashlib
import inspect
import warnings
from pathlib import Path

import numba

# cache=True: a later process loads machine code instead of compiling (~0.2 s vs ~30 s).
# error_model="numpy": division by zero gives inf/nan instead of raising, as in numpy;
# kernels check isfinite themselves and report a status code.
_POLICY = dict(cache=True, error_model="numpy")
# A kernel called from another kernel compiles once per distinct argument type. A
# literal argument (-1, 0, True, a module constant) and a prange index (uint64) each
# give another signature beside int64 or bool, so call sites pass np.int64(...) or
# np.bool_(...): one compile instead of several.


@functools.cache
def source_stamp(directory):
    """sha256 of every ``*.py`` file in ``directory`` (names and contents, sorted).

    numba stamps a kernel's cache with its own file's hash alone, so a kernel whose file
    is unchanged keeps the machine code of callees (and constants) from other files as
    they were when it compiled: after an edit or an upgrade it would silently run old
    code. :mod:`mcfric.core` imports nothing else from mcfric, so the hash of all its
    sources covers everything a kernel's code can hold.
    """
    h = hashlib.sha256()
    for p in sorted(Path(directory).glob("*.py")):
        h.update(p.name.encode() + b"\0" + p.read_bytes() + b"\0")
    return h.digest()


def _stamp_with_package(dispatcher):
    """Give ``dispatcher``'s numba cache the stamp of its whole source directory.

    Uses numba's cache internals (``Dispatcher._cache._cache_file._source_stamp``, as in
    numba 0.59-0.68); where they are missing, the kernel compiles without a cache rather
    than risk stale code.
    """
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None or not hasattr(cache_file, "_source_stamp"):
        global _WARNED
        if not _WARNED:
            _WARNED = True
            warnings.warn(f"numba {numba.__version__}: cannot stamp the kernel caches; "
                          "compiling without them", RuntimeWarning, stacklevel=2)
        from numba.core.caching import NullCache
        dispatcher._cache = NullCache()
        return dispatcher
    directory = Path(inspect.getfile(dispatcher.py_func)).resolve().parent
    cache_file._source_stamp = source_stamp(directory)
    return dispatcher


_WARNED = False


def jit(*args, **kwargs):
    """``numba.njit`` with the project's policy (cache, numpy error model).

    The cache is stamped with the hash of every source in the kernel's directory (see
    :func:`source_stamp`), not of its own file alone. Explicit signatures are refused:
    numba would compile them, and load or save the cache, before the stamp is set.
    """
    opts = dict(_POLICY)
    opts.update(kwargs)
    stamp = _stamp_with_package if opts["cache"] else (lambda d: d)
    if args and callable(args[0]):
        return stamp(numba.njit(**opts)(args[0]))
    if args:
        raise TypeError("mcfric.core._jit.jit: no explicit signatures (lazy compilation "
                        "only, so that the cache stamp is set first)")
    decorate = numba.njit(**opts)
    return lambda func: stamp(decorate(func))


def inline_jit(func):
    """``jit`` for small hot helpers: inlined into the caller at the numba IR level.

    Inlining removes ~25 ns of call overhead per array-argument call in the Newton loop.
    """
    return jit(inline="always")(func)
