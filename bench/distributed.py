"""Cluster benchmark: a run on a Dask ``LocalCluster`` against the same run in one process.

Run: ``python bench/distributed.py [--samples N] [--n-freq F] [--workers W] [--repeat R]
[--memory A,B] [--dir DIR] [--quick]`` (needs ``mcfric[dask]``).

Measured in one run (``python bench/distributed.py``):

1. start-up: a ``local:N`` cluster started from nothing, up to every worker having loaded
   the kernels (what ``--scheduler local:N`` adds to a run), as the median of
   ``--repeat`` starts;
2. efficiency: the eight-beam ensemble (20,000 x 1000 by default, bounds off, peaks on)
   end to end with :func:`mcfric.ensemble.run` in this process (``--workers`` numba
   threads) and on an already started cluster of ``--workers`` processes with one
   thread each, alternated ``--repeat`` times; efficiency = local time / (cluster time -
   its connection and warm-up), medians. Both output modes: the complex response per beam
   (what the single writer must take in: MB/s printed) and the metric only;
3. client memory: peak resident memory (VmHWM) of ``mcfric run --scheduler ADDRESS``
   client processes at two ensemble sizes, to show it is flat in the samples.

Goal (issue 20): efficiency >= 0.8 once the cluster is up. ``--quick`` shrinks everything
for a smoke test.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

# run as a script, this file's directory comes first on sys.path, where its name would
# hide the `distributed` package from every import below
sys.path[:] = [p for p in sys.path
               if Path(p or ".").resolve() != Path(__file__).resolve().parent]

from mcfric import config, ensemble, run_file  # noqa: E402
from mcfric.distributed import Cluster  # noqa: E402


def spec_for(samples, n_freq, keep_response=True, scheduler="", threads=0):
    # the ensemble alone: the bounds, computed once on the client, are bench/bounds.py's
    return config.load({"model": {"preset": "eight-beam"}, "frequency": {"n": n_freq},
                        "sampling": {"samples": samples, "seed": 1},
                        "bounds": {"enabled": False},
                        "output": {"keep_response": keep_response},
                        "run": {"scheduler": scheduler, "threads": threads}}).spec


def timed_run(spec, path):
    t0 = time.perf_counter()
    s = ensemble.run(spec, path, force=True, progress=False)
    dt = time.perf_counter() - t0
    assert s.complete and s.samples_this_session == spec.samples
    path.unlink()
    return dt, s


def startup(workers, repeat):
    """Seconds from nothing to a ready ``local:N`` cluster (kernels loaded on every worker)."""
    spec = spec_for(1, 1000)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        c = Cluster.connect(f"local:{workers}", spec=spec, task=ensemble.solve_records,
                            fingerprint=run_file.fingerprint)
        times.append(time.perf_counter() - t0)
        c.close()
    return statistics.median(times)


MEM_SCRIPT = textwrap.dedent("""
    import sys
    from mcfric import cli
    rc = cli.main(sys.argv[1:])
    kb = next(int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM"))
    print("VMHWM", kb, rc)
""")


def client_memory(address, samples, n_freq, workdir):
    """VmHWM of a ``mcfric run --scheduler address`` client, MB."""
    path = workdir / f"mem-{samples}.h5"
    r = subprocess.run([sys.executable, "-c", MEM_SCRIPT, "run", "eight-beam", "-o",
                        str(path), "--samples", str(samples), "--n-freq", str(n_freq),
                        "--scheduler", address, "--no-bounds", "--no-progress", "--no-figure",
                        "--force"],
                       capture_output=True, text=True)
    line = [x for x in r.stdout.splitlines() if x.startswith("VMHWM")]
    if r.returncode != 0 or not line:
        raise SystemExit(f"client memory run failed: {r.stderr.strip()[-500:]}")
    _, kb, rc = line[0].split()
    size = path.stat().st_size
    path.unlink()
    return int(kb) / 1024, size


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, help="ensemble size (default 20000; quick 1000)")
    ap.add_argument("--n-freq", type=int, help="frequencies (default 1000; quick 200)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, help="alternated repeats (default 3; quick 1)")
    ap.add_argument("--memory",
                    help="ensemble sizes (100 frequencies) of the client-memory runs "
                         "(comma-separated, '' = skip; default 10000,100000; quick "
                         "1000,4000)")
    ap.add_argument("--dir", help="scratch directory (default: a temporary one)")
    ap.add_argument("--quick", action="store_true",
                    help="small sizes, a smoke test (flags given still apply)")
    a = ap.parse_args()
    # --quick fills in only what was not given
    for name, full, quick in (("samples", 20000, 1000), ("n_freq", 1000, 200),
                              ("repeat", 3, 1), ("memory", "10000,100000", "1000,4000")):
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
    import logging

    from distributed import LocalCluster

    w = a.workers
    print(f"eight-beam, {a.samples} samples x {a.n_freq} frequencies, peaks on, bounds off; "
          f"{w} worker processes x 1 thread against {w} numba threads in one process")
    timed_run(spec_for(8, a.n_freq), workdir / "warm.h5")     # kernels compiled or loaded
    t_start = startup(w, a.repeat)
    print(f"start-up of local:{w} (processes, imports, kernel load on every worker): "
          f"{t_start:.2f} s (median of {a.repeat})")

    with LocalCluster(n_workers=w, threads_per_worker=1, processes=True,
                      dashboard_address=None, silence_logs=logging.ERROR) as lc:
        address = lc.scheduler_address
        rows = []
        for keep in (True, False):
            specs = {"local": spec_for(a.samples, a.n_freq, keep, threads=w),
                     "cluster": spec_for(a.samples, a.n_freq, keep, scheduler=address)}
            times = {"local": [], "cluster": [], "connect": []}
            for _ in range(a.repeat):
                for name, spec in specs.items():           # alternated: drift hits both
                    dt, s = timed_run(spec, workdir / f"{name}.h5")
                    times[name].append(dt)
                    if name == "cluster":
                        times["connect"].append(s.startup_s)
            med = {k: statistics.median(v) for k, v in times.items()}
            up = med["cluster"] - med["connect"]
            mb = run_file.output_bytes(specs["local"]) / 1e6
            rows.append(("complex response" if keep else "metric only", med, up,
                         med["local"] / up, mb))
        print()
        print(f"{'output':<18} {'local s':>8} {'cluster s':>10} {'connect s':>10} "
              f"{'efficiency':>11} {'file MB':>8} {'writer MB/s':>12}")
        for name, med, up, eff, mb in rows:
            print(f"{name:<18} {med['local']:8.2f} {med['cluster']:10.2f} "
                  f"{med['connect']:10.2f} {eff:11.2f} {mb:8.0f} {mb / up:12.0f}")
        print("efficiency = local / (cluster - connect); medians of "
              f"{a.repeat} alternated runs")

        sizes = [int(x) for x in a.memory.split(",") if x]
        if sizes:
            print()
            print("client peak memory (VmHWM), mcfric run --scheduler, 100 frequencies:")
            for n in sizes:
                mb, size = client_memory(address, n, 100, workdir)
                print(f"  {n:>7} samples: {mb:7.0f} MB (results file {size / 1e6:.0f} MB)")


if __name__ == "__main__":
    main()
