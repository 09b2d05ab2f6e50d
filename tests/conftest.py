import json
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

import mcfric
from mcfric.model import TABLE_1, Excitation, Model

from . import naive  # noqa: F401  (tests import it as tests.naive)

# What every xdist worker would otherwise compile for itself, at the same time, on a cold
# numba cache: the run path of a two-beam and an eight-beam preset (the ensemble with its
# peaks, and the bounds with their certification). Two processes share the work before
# the workers start; the workers then load the machine code from the cache.
_WARM_UP = (
    [["run", "two-beam", "--samples", "2", "--n-freq", "8", "--no-bounds", "--no-figure"],
     ["run", "eight-beam", "--samples", "2", "--n-freq", "8", "--no-bounds", "--no-figure"]],
    [["bounds", "two-beam", "--n-freq", "8", "--no-figure"],
     ["bounds", "eight-beam", "--n-freq", "8", "--no-figure"]],
)


# The files that take longest, longest first (measured with --durations, warm cache):
# handed out first, a long file last would leave the other worker idle at the end.
# xdist's own order (by number of tests) is turned off in pyproject.toml.
_HEAVY_FIRST = ("test_moments.py", "test_distributed.py", "test_rings.py", "test_harmonics.py",
                "test_ensemble.py", "test_hbm.py", "test_bounds.py", "test_notebooks.py",
                "test_certified.py", "test_reliability.py", "test_peaks.py")


def pytest_collection_modifyitems(config, items):
    """Tests of the heavy files first (each file's own order kept)."""
    rank = {name: i for i, name in enumerate(_HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_setupnodes(config, specs):
    """Compile the shared kernels once, in two processes, before the xdist workers start
    (the whole suite only: about 20 s where the cache is warm)."""
    if config.option.collectonly or config.args_source != pytest.Config.ArgsSource.TESTPATHS:
        return                      # files or tests named: only the whole suite warms up
    start = time.perf_counter()
    script = ("import json, subprocess, sys\n"
              "for i, args in enumerate(json.loads(sys.argv[2])):\n"
              "    subprocess.run([sys.executable, '-m', 'mcfric', *args, '--no-progress',\n"
              "                    '-o', f'{sys.argv[1]}{i}.h5'], check=True,\n"
              "                   stdout=subprocess.DEVNULL)\n")
    failed = 0
    with tempfile.TemporaryDirectory() as d:
        # each chain in its own process group, so that a hung one is stopped whole
        procs = [subprocess.Popen([sys.executable, "-c", script, d + f"/{n}-",
                                   json.dumps(chain)], start_new_session=True)
                 for n, chain in enumerate(_WARM_UP)]
        for p in procs:
            try:
                failed += p.wait(timeout=max(1.0, start + 1200 - time.perf_counter())) != 0
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
                failed += 1
    # a failed warm-up costs only time: each test compiles what it needs itself and
    # reports its own failure
    print(f"\nkernel caches warmed in {time.perf_counter() - start:.0f} s"
          + (f" ({failed} warm-up process failed)" if failed else ""), file=sys.stderr)


def naive_beams(model):
    """A model's beams as tests/naive.py takes them (positions contact, output, drive)."""
    out = []
    for t in model.beams:
        cols = [t.positions.index(p) for p in (model.contact, model.output, model.drive)]
        out.append(dict(freq_hz=np.array(t.freq_hz), zeta=np.array(t.zeta),
                        u=np.array(t.shapes)[:, cols]))
    return out


def naive_pairs(model):
    a, b = model.dampers
    return list(zip(a.tolist(), b.tolist()))


@pytest.fixture(scope="session")
def two_beam():
    return mcfric.two_beam(0.22)


@pytest.fixture(scope="session")
def eight_beam():
    return mcfric.eight_beam(1.1)


def ring(n, mistuned, engine_order=1, F0=0.8):
    """A ring of ``n`` blades (Table 1 beams, 2 % mistuned in the first two modes if
    ``mistuned``) under a travelling wave of ``engine_order``, ``F0`` N."""
    rng = np.random.default_rng(100 + n)
    if mistuned:
        beams = tuple(TABLE_1.with_frequency(1, 16.2 * (1 + 0.02 * rng.standard_normal()))
                      .with_frequency(2, 105.8 * (1 + 0.02 * rng.standard_normal()))
                      for _ in range(n))
    else:
        beams = (TABLE_1,) * n
    return Model(beams, Excitation("travelling", F0, engine_order=engine_order),
                 topology="circular")
