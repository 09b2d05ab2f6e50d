"""Ensemble benchmark: end-to-end vs kernel-only time, storage options, peak memory.

Run: ``python bench/ensemble.py [--samples N] [--n-freq F] [--memory A,B] [--repeat R]
[--dir DIR] [--quick]``.

Measured in one run (``python bench/ensemble.py``):

1. kernel-only: :func:`mcfric.hbm.solve` over the run's chunks of pre-drawn parameters
   (2000 samples x 1000 frequencies x 8 beams by default), no storage;
2. end-to-end: :func:`mcfric.ensemble.run` on the same configuration (sampling + kernel +
   metric + HDF5 writes + checkpoints + final rename), and a variant that writes in the
   main thread (no overlap) to show what the writer thread buys;
3. storage options on a block of real kernel output: write throughput and size of the
   unfiltered pre-allocated path used by the store, against lzf, gzip and shuffle, and the
   time each would add to the full run's response if writing were not overlapped;
4. peak resident memory (VmHWM, Linux) of ``mcfric run`` subprocesses at 10,000 and 100,000
   samples (and a small baseline), to show it is flat.

Goals (issue 3): end-to-end <= 1.3x kernel-only; peak memory flat and < 1 GB.
Kernel and storage measurements take the best of ``--repeat`` runs (the machine is shared).
``--quick`` shrinks everything for a smoke test.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np

from mcfric import config, ensemble, hbm, run_file
from mcfric.store import Store, partial_path


def cfg_for(samples, n_freq, **extra):
    # the ensemble path alone: the bounds (computed once before it) are bench/bounds.py's
    raw = {"model": {"preset": "eight-beam"}, "frequency": {"n": n_freq},
           "sampling": {"samples": samples, "seed": 1}, "bounds": {"enabled": False}}
    for k, v in extra.items():
        sec, key = k.split("__")
        raw.setdefault(sec, {})[key] = v
    return config.load(raw).spec


def kernel_only(spec, chunk):
    """Seconds of the run's solves over its chunks (parameters drawn beforehand)."""
    draws = [spec.sampler.draw(np.arange(a, min(spec.samples, a + chunk)))
             for a in range(0, spec.samples, chunk)]
    t = 0.0
    for d in draws:
        t0 = time.perf_counter()
        r = ensemble.solve_chunk(spec, d)
        t += time.perf_counter() - t0
        del r
    return t


def end_to_end(spec, path):
    t0 = time.perf_counter()
    s = ensemble.run(spec, path, force=True, progress=False)
    dt = time.perf_counter() - t0
    assert s.complete
    return dt, s


def synchronous(spec, path, chunk):
    """The same work with writes in the main thread (what the writer thread overlaps)."""
    coords, variables, attrs, ph = run_file.layout(spec)
    t0 = time.perf_counter()
    st = Store.create(path, record_dim="sample", n_records=spec.samples, coords=coords,
                      variables=variables, attrs=attrs, placeholders=ph)
    for a in range(0, spec.samples, chunk):
        d = spec.sampler.draw(np.arange(a, min(spec.samples, a + chunk)))
        r = ensemble.solve_chunk(spec, d)
        st.write(a, ensemble.record_arrays(spec, d, r))
        st.commit([(a, a + len(d.index))])
    st.finish({k: v for k, v in ph.items()})
    return time.perf_counter() - t0


STORAGE = [
    ("none, pre-allocated (used)", {}, "complex128"),
    ("none, pre-allocated, complex64", {}, "complex64"),
    ("lzf", {"compression": "lzf"}, "complex128"),
    ("lzf + shuffle", {"compression": "lzf", "shuffle": True}, "complex128"),
    ("gzip-1", {"compression": "gzip", "compression_opts": 1}, "complex128"),
    ("gzip-1 + shuffle", {"compression": "gzip", "compression_opts": 1, "shuffle": True},
     "complex128"),
    ("gzip-4 + shuffle", {"compression": "gzip", "compression_opts": 4, "shuffle": True},
     "complex128"),
]


def storage_options(y, metric, workdir, repeat):
    """Write ``y`` (n, n_f, nb) and ``metric`` with each option.

    Returns (name, MB/s of complex128-equivalent input, complex128 size / stored size).
    """
    out = []
    raw = y.nbytes + metric.nbytes
    for name, kw, dtype in STORAGE:
        best = np.inf
        for _ in range(repeat):
            p = workdir / "opt.h5"
            p.unlink(missing_ok=True)
            yy = y.astype(dtype)
            t0 = time.perf_counter()
            with h5py.File(p, "w") as h5:
                k = max(1, (1 << 20) // (y.shape[1] * y.shape[2] * yy.itemsize))
                if kw:
                    d1 = h5.create_dataset("response", shape=yy.shape, dtype=yy.dtype,
                                           chunks=(k,) + y.shape[1:], **kw)
                    d2 = h5.create_dataset("metric", shape=metric.shape, dtype=metric.dtype,
                                           chunks=(min(len(metric), 128), metric.shape[1]),
                                           **kw)
                else:   # the store's own path (early allocation, no filter)
                    st = Store.create(workdir / "opt-store.h5", record_dim="sample",
                                      n_records=len(y), coords={
                                          "frequency": (np.arange(y.shape[1]), {}),
                                          "beam": (np.arange(y.shape[2]), {})},
                                      variables={"response": (("sample", "frequency", "beam"),
                                                              yy.dtype, {}),
                                                 "metric": (("sample", "frequency"),
                                                            np.float64, {})},
                                      attrs={}, placeholders={})
                    t0 = time.perf_counter()     # creation is once per run, not per byte
                    st.write(0, {"response": yy, "metric": metric})
                    st.commit([(0, len(y))])     # includes the fsync of the data
                    dt = time.perf_counter() - t0
                    st.close()
                    partial_path(workdir / "opt-store.h5").unlink()
                    best = min(best, dt)
                    size = yy.nbytes + metric.nbytes
                    continue
                d1[...] = yy
                d2[...] = metric
            best = min(best, time.perf_counter() - t0)
            size = p.stat().st_size
        # MB/s of the full-precision data the run has to keep (complex128 response)
        out.append((name, raw / best / 1e6, raw / size))
    return out


MEM_SCRIPT = textwrap.dedent("""
    import sys, time
    from mcfric import config, ensemble
    samples, n_freq, path = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    cfg = config.load({"model": {"preset": "eight-beam"}, "frequency": {"n": n_freq},
                       "sampling": {"samples": samples, "seed": 1},
                       "bounds": {"enabled": False}})
    t0 = time.perf_counter()
    s = ensemble.run(cfg, path, force=True, progress=False)
    dt = time.perf_counter() - t0
    # VmHWM: this process's own peak (ru_maxrss would carry the parent's across the spawn)
    kb = next(int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM"))
    print(kb, dt, s.not_converged, s.complete)
""")


def peak_memory(samples, n_freq, workdir):
    path = workdir / f"mem-{samples}.h5"
    r = subprocess.run([sys.executable, "-c", MEM_SCRIPT, str(samples), str(n_freq),
                        str(path)], capture_output=True, text=True, check=True)
    kb, dt, bad, complete = r.stdout.split()
    size = path.stat().st_size
    path.unlink()
    return int(kb) / 1024, float(dt), int(bad), size


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, help="ensemble size (default 2000; quick 200)")
    ap.add_argument("--n-freq", type=int, help="frequencies (default 1000; quick 200)")
    ap.add_argument("--memory",
                    help="ensemble sizes for the peak-memory runs (comma-separated, '' = "
                         "skip; default 10000,100000; quick 1000,4000)")
    ap.add_argument("--repeat", type=int, help="alternated repeats (default 5; quick 1)")
    ap.add_argument("--dir", help="scratch directory (default: a temporary one)")
    ap.add_argument("--quick", action="store_true",
                    help="small sizes, a smoke test (flags given still apply)")
    a = ap.parse_args()
    # --quick fills in only what was not given
    for name, full, quick in (("samples", 2000, 200), ("n_freq", 1000, 200),
                              ("memory", "10000,100000", "1000,4000"), ("repeat", 5, 1)):
        if getattr(a, name) is None:
            setattr(a, name, quick if a.quick else full)
    workdir = Path(a.dir or tempfile.mkdtemp(prefix="mcfric-bench-"))
    workdir.mkdir(parents=True, exist_ok=True)
    try:
        run_bench(a, workdir)
    finally:
        if not a.dir:
            shutil.rmtree(workdir, ignore_errors=True)


def run_bench(a, workdir):
    import numba

    cfg = cfg_for(a.samples, a.n_freq)
    model = cfg.model
    chunk = run_file.auto_chunk(cfg)
    n_pts = a.samples * a.n_freq
    print(f"mcfric ensemble benchmark: eight-beam, {a.samples} samples x {a.n_freq} "
          f"frequencies x {model.n_beams} beams; {numba.get_num_threads()} threads, "
          f"chunk {chunk} samples (auto), scratch {workdir}")
    print("load average before: %.2f %.2f %.2f (the machine may be shared)" % os.getloadavg())
    hbm.solve(model, cfg.freq_hz[:8], 0.5, 6000.0, 0.5)     # load / compile kernel
    small = cfg_for(16, 16)
    ensemble.run(small, workdir / "warm.h5", force=True, progress=False)

    # 1 + 2: back-to-back pairs, so a load change from other users hits both alike
    k_t, e_t, s_t = [], [], []
    summary = None
    for _ in range(a.repeat):
        k_t.append(kernel_only(cfg, chunk))
        dt, summary = end_to_end(cfg, workdir / "e2e.h5")
        e_t.append(dt)
        s_t.append(synchronous(cfg, workdir / "sync.h5", chunk))
    size = (workdir / "e2e.h5").stat().st_size
    k, e, s = min(k_t), min(e_t), min(s_t)
    pair = [b / c for b, c in zip(e_t, k_t)]
    pair_s = [b / c for b, c in zip(s_t, k_t)]
    print()
    print("end-to-end vs kernel-only (best of %d; and the median of back-to-back pairs)"
          % a.repeat)
    print(f"  kernel only (hbm.solve over the run's chunks)  {k:7.2f} s   "
          f"{n_pts / k / 1e6:5.2f} M solves/s")
    print(f"  end to end  (mcfric.ensemble.run)              {e:7.2f} s   "
          f"ratio {e / k:.3f} (best), {np.median(pair):.3f} (median pair)  goal <= 1.3")
    print(f"  end to end, writes in the main thread          {s:7.2f} s   "
          f"ratio {s / k:.3f} (best), {np.median(pair_s):.3f} (median pair)")
    print(f"  all runs: kernel {', '.join(f'{x:.2f}' for x in k_t)} s; "
          f"end to end {', '.join(f'{x:.2f}' for x in e_t)} s; "
          f"main-thread writes {', '.join(f'{x:.2f}' for x in s_t)} s")
    print(f"  file {size / 1e6:.0f} MB ({size / e / 1e6:.0f} MB/s of output), "
          f"not converged: {summary.not_converged} points")
    print("  load average after: %.2f %.2f %.2f" % os.getloadavg())

    # 3: storage options on a block of real kernel output
    n_blk = min(a.samples, 256)
    d = cfg.sampler.draw(np.arange(n_blk))
    r = hbm.solve(model, cfg.freq_hz, d.mu0, d.kc, d.N0)
    y, m = r.response, r.metric()
    opts = storage_options(y, m, workdir, max(1, a.repeat))
    full_bytes = a.samples * a.n_freq * (model.n_beams * 16 + 8)
    print()
    print(f"storage options ({n_blk} samples of real output, {(y.nbytes + m.nbytes) / 1e6:.0f} "
          f"MB; response + metric)")
    print(f"  {'option':<32} {'MB/s':>7} {'ratio':>6}   {'write time of the full run':>26}")
    for name, mbs, ratio in opts:
        t = full_bytes / (mbs * 1e6)
        print(f"  {name:<32} {mbs:7.0f} {ratio:6.3f}   {t:7.2f} s = {t / k:5.2f}x kernel time")
    print("  (ratio = uncompressed / stored size; the write time is what a filter would add "
          "if it could not overlap the kernel, which needs both cores)")

    # 4: peak memory
    sizes = [int(x) for x in a.memory.split(",") if x.strip()]
    if sizes:
        print()
        print(f"peak memory of `mcfric run` (eight-beam, {a.n_freq} frequencies, keep_response "
              f"= true, subprocess VmHWM)")
        for n in [min(sizes[0] // 10, 1000)] + sizes:
            mb, dt, bad, fsize = peak_memory(n, a.n_freq, workdir)
            print(f"  {n:>8} samples: peak {mb:7.0f} MB   ({dt:7.1f} s, file "
                  f"{fsize / 1e9:6.2f} GB, not converged {bad})")


if __name__ == "__main__":
    main()
