"""The signature rule of mcfric/core/_jit.py: a kernel called from a kernel compiles once
per distinct argument type, and a literal (``-1``, ``True``, a module constant) or a
prange index (an unsigned integer) is a type of its own, so call sites pass
``np.int64(...)`` / ``np.bool_(...)``. A call site that breaks the rule costs a compile
of its own (seconds to a minute per kernel, in every fresh environment) and shows here as
a signature with a literal or unsigned argument."""

import importlib
import pkgutil

import numba
import numpy as np
from numba.core import types

import mcfric
import mcfric.core
from mcfric.bounds import compute_bounds, force_limit


def _kernels():
    """Every jitted kernel defined in mcfric.core: (module.name, dispatcher)."""
    for info in pkgutil.iter_modules(mcfric.core.__path__):
        mod = importlib.import_module(f"mcfric.core.{info.name}")
        for name, obj in vars(mod).items():
            if (isinstance(obj, numba.core.registry.CPUDispatcher)
                    and obj.py_func.__module__ == mod.__name__):
                yield f"{info.name}.{name}", obj


def _against_the_rule(sig):
    """The arguments of ``sig`` typed as a literal or an unsigned integer."""
    return [t for t in sig if isinstance(t, types.Literal)
            or (isinstance(t, types.Integer) and not t.signed)]


def test_the_check_sees_a_literal_and_a_prange_index():
    """The detector itself: a kernel called with a literal from a kernel, and with a
    prange index, has signatures against the rule; called with np.int64, it has none."""
    @numba.njit
    def inner(x, k):
        return x[k]

    @numba.njit
    def literal(x):
        return inner(x, 1)

    @numba.njit(parallel=True)
    def index(x, out):
        for i in numba.prange(len(x)):
            out[i] = inner(x, i)

    @numba.njit
    def plain(x):
        return inner(x, np.int64(1))

    x = np.arange(3.0)
    plain(x)
    assert not any(_against_the_rule(s) for s in inner.signatures)
    literal(x)
    index(x, np.empty(3))
    bad = [s for s in inner.signatures if _against_the_rule(s)]
    assert len(bad) == 2


def test_no_kernel_is_compiled_for_a_literal_or_an_unsigned_index():
    """After small runs of the ensemble solver (one harmonic with its peaks refined, and
    three harmonics) and of the searched and certified bounds (eight beams, two
    frequencies, 40 relaxations of parts), no kernel of mcfric.core has a signature
    against the rule in numba's on-disk cache: every signature compiled for the current
    source of its module, by this test or any process before it (a kernel called from a
    kernel loaded from the cache is never typed in this process, so the process's own
    dispatchers do not show them)."""
    rng = np.random.default_rng(0)
    two = mcfric.two_beam(0.5)
    f = np.linspace(60.0, 64.0, 3)
    mcfric.solve(two, f, rng.uniform(0, 1, (2, 1)), rng.uniform(0, 15000, (2, 1)), 0.5,
                 n_threads=2, peaks=1)
    mcfric.hbm.solve(two, f, rng.uniform(0, 1, (2, 1)), rng.uniform(0, 15000, (2, 1)), 0.5,
                     harmonics=3, n_threads=2)
    chain = mcfric.preset("eight-beam", 0.5)
    compute_bounds(chain, np.array([71.0, 121.8]), 15000.0, F_lim=force_limit(1.0, 0.5),
                   split=40, n_threads=2, moments=False)
    cached = {name: [key[0] for key in d._cache._cache_file._load_index()]
              for name, d in _kernels()}
    offenders = {name: [str(s) for s in sigs if _against_the_rule(s)]
                 for name, sigs in cached.items()}
    offenders = {k: v for k, v in offenders.items() if v}
    # every index is stamped with all of core's sources (_jit.py): an edit anywhere in
    # core empties them, so no signature here is left from earlier call sites
    assert not offenders, f"kernels compiled against the signature rule: {offenders}"
    # the runs above reach the kernels called from kernels too
    for name in ("relaxation.relaxed_bound", "relaxation_branch.branch", "newton.newton",
                 "multi_harmonic._stuck_back", "aft._segment", "peaks._val"):
        assert cached[name], name


def test_no_kernel_lets_llvm_fuse_or_reorder_arithmetic():
    """docs/guarantees.md: no kernel uses the fastmath flags that fuse or reorder
    (``contract``, ``reassoc``, ``arcp``, ``afn``, or ``fastmath=True``, all of them):
    a kernel compiled with its callees inlined and one against cached callees then gave
    different last bits. ``nsz`` (the sign of a zero) changes no other result."""
    allowed = {"nsz"}
    found = []
    for name, k in _kernels():
        flags = k.targetoptions.get("fastmath") or set()
        if flags is True or not set(flags) <= allowed:
            found.append((name, flags))
    assert found == []
