"""The one place that sets the numba policy of every kernel in :mod:`mcfric.core`."""

import numba

# cache=True: a later process loads machine code instead of compiling (~0.2 s vs ~30 s).
# error_model="numpy": division by zero gives inf/nan instead of raising, as in numpy;
# kernels check isfinite themselves and report a status code.
_POLICY = dict(cache=True, error_model="numpy")
# A kernel called from another kernel compiles once per distinct argument type. A
# literal argument (-1, 0, True, a module constant) and a prange index (uint64) each
# give another signature beside int64 or bool, so call sites pass np.int64(...) or
# np.bool_(...): one compile instead of several.


def jit(*args, **kwargs):
    """``numba.njit`` with the project's policy (cache, numpy error model)."""
    opts = dict(_POLICY)
    opts.update(kwargs)
    if args and callable(args[0]):
        return numba.njit(**opts)(args[0])
    return numba.njit(*args, **opts)


def inline_jit(func):
    """``jit`` for small hot helpers: inlined into the caller at the numba IR level.

    Inlining removes ~25 ns of call overhead per array-argument call in the Newton loop.
    """
    return jit(inline="always")(func)
