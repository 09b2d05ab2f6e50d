"""The kernels' numba cache follows every source of mcfric/core, not only a kernel's own
file: numba alone would keep a caller's machine code, with its callees from other files
inlined as they were, until the caller's own file changed."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import mcfric.core
from mcfric.core._jit import jit, source_stamp

from .test_signatures import _kernels


def test_every_kernel_is_stamped_with_all_of_core():
    core = Path(mcfric.core.__file__).resolve().parent
    stamp = source_stamp(core)
    kernels = dict(_kernels())
    assert len(kernels) > 50
    wrong = [name for name, k in kernels.items()
             if k._cache._cache_file._source_stamp != stamp]
    assert not wrong


def _run(directory, cache):
    out = subprocess.run(
        [sys.executable, "-c", "import caller; print(caller.f(1.0))"], cwd=directory,
        env={"PYTHONPATH": str(directory), "NUMBA_CACHE_DIR": str(cache), "PATH": ""},
        capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def test_editing_a_callee_in_another_file_recompiles_the_caller(tmp_path):
    """Two files as in mcfric/core: ``caller.f`` calls ``callee.g``. After ``g``'s file
    changes, a new process must run the new ``g`` through ``f``, though ``f``'s file did
    not change and its compiled code sits in the cache."""
    (tmp_path / "caller.py").write_text(textwrap.dedent("""
        from mcfric.core._jit import jit
        from callee import g

        @jit
        def f(x):
            return g(x) * 10.0
    """))
    callee = tmp_path / "callee.py"
    callee.write_text("from mcfric.core._jit import jit\n\n@jit\ndef g(x):\n    return x + 1.0\n")
    cache = tmp_path / "cache"
    assert _run(tmp_path, cache) == 20.0
    assert _run(tmp_path, cache) == 20.0            # from the cache
    callee.write_text(callee.read_text().replace("x + 1.0", "x + 2.0"))
    assert _run(tmp_path, cache) == 30.0


def test_explicit_signatures_are_refused():
    """numba compiles an explicit signature, and loads or saves its cache, inside the
    decorator: before the stamp could be set. So ``jit`` takes none."""
    with pytest.raises(TypeError, match="signatures"):
        jit("float64(float64)")


@pytest.mark.slow
def test_results_do_not_depend_on_which_kernels_came_from_the_cache(tmp_path):
    """An eight-beam ensemble run in a process that compiles every kernel, and again in
    one that compiles only the sweep kernels against callees loaded from numba's cache
    (so it cannot inline them): the same bytes. With fused multiply-add (fastmath
    ``contract``) in the chain kernels, 407 of 5000 metric values differed (about 1e-15
    relative): a Dask worker or a resumed run could then differ from a local one."""
    import h5py
    import numpy as np

    cache = tmp_path / "cache"

    def run(out):
        subprocess.run([sys.executable, "-m", "mcfric", "run", "eight-beam", "--samples",
                        "50", "--n-freq", "100", "--no-certify", "--no-figure",
                        "--no-progress", "-o", str(out)],
                       env={**os.environ, "NUMBA_CACHE_DIR": str(cache)},
                       check=True, capture_output=True)
        with h5py.File(out) as f:
            return {k: f[k][()] for k in ("metric", "response")}

    first = run(tmp_path / "a.h5")
    sweeps = list(cache.rglob("sweep.*.nb[ic]"))
    assert sweeps
    for p in sweeps:
        p.unlink()
    second = run(tmp_path / "b.h5")
    for k in first:
        assert np.array_equal(first[k], second[k], equal_nan=True), k


def test_core_is_forbidden_every_other_module_of_mcfric():
    """The stamp covers mcfric/core only, so core must import nothing else of mcfric. The
    import contract lists the forbidden modules by name: one missing from the list
    (memory and quantiles were) could be imported by a kernel unnoticed, and editing it
    would leave stale kernels in the cache. Every module is also in a layer."""
    import tomllib

    root = Path(mcfric.core.__file__).parents[1]
    modules = {f"mcfric.{p.stem}" for p in root.glob("*.py") if not p.stem.startswith("_")}
    modules |= {f"mcfric.{p.parent.name}" for p in root.glob("*/__init__.py")}
    modules.discard("mcfric.core")
    cfg = tomllib.loads((root.parent / "pyproject.toml").read_text())["tool"]["importlinter"]
    core = next(c for c in cfg["contracts"] if c["source_modules"] == ["mcfric.core"])
    assert modules - set(core["forbidden_modules"]) == set()
    layers = next(c for c in cfg["contracts"] if c["type"] == "layers")["layers"]
    layered = {m.strip() for layer in layers for m in layer.split("|")}
    assert modules | {"mcfric.core"} <= layered, modules - layered
