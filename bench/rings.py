"""Rings against chains: solves per second and per damper, from 8 to 128 blades.

Run: ``python bench/rings.py [--blades 8 16 32 64 128] [--repeat R] [--threads T]
[--dense-max N] [--bounds 8 24 32] [--bounds-frequencies N] [--search-only] [--storage]
[--memory 10000 100000] [--skip-rates] [--harmonics H]``.

For each blade count, in one run and alternating the variants (absolute times drift on a
shared machine by tens of percent within minutes; ratios measured side by side do not):

* ``chain``: identical Table-1 blades in a line, the lockstep O(n_dampers) kernel;
* ``ring``: the same blades closed into a ring, the same kernel with the ring bordered;
* ``dense``: the ring sent through the dense-LU kernel (every ring's path before the ring
  kernel existed), up to ``--dense-max`` blades (it costs O(n^3)).

``--harmonics H`` (odd, > 1): the same table for the multi-harmonic balance of the odd
harmonics up to ``H`` (its Newton step by block Thomas on a chain, bordered on a ring),
``dense`` then the ring with its dampers numbered from the second, which the kernel takes
for a graph of no known layout (the dense LU), on the ring's samples; 256 samples x blades
per call (at least 2 samples).

Every variant solves the same travelling-wave drive (engine order 1, 1.1 N), the paper's
friction distributions (mu0 ~ U(0, 1), kc ~ U(0, 15000) N/m, N0 = 0.5 N) and 200
frequencies over 10-150 Hz; the sample count shrinks with the blade count so that every
call does about the same work. Reported: medians over ``--repeat`` (default 5) rounds of
solves/s and damper-solves/s (solves/s times the damper count), the ring's cost per damper
relative to the chain's (chain damper-solves/s over the ring's), and the ring's
damper-solves/s relative to the smallest ring (1 = linear cost).

``--bounds``: for tuned rings (engine order 1) of these sizes, the time of the searched
bounds and of the certified ones (1000 frequencies, the paper's limits) against that of
the 2000-member ensemble's solves (2000 x 1000), alternated, medians of three rounds
(``--repeat``), each ratio the median of the rounds' own ratios.
``--bounds-frequencies N``: N frequencies instead of 1000 (bounds and ensemble alike).
``--search-only``: the searched bounds alone (large rings, whose certificate is mostly
Eq. 10: the search is what costs there).

``--storage``: a 128-blade ring, ``mcfric`` end to end (solve and write) with the response
stored complex and as float32 amplitudes: seconds, file size, alternated, medians of
three (200 samples x 1000 frequencies, so about 2 % of a 2000-member run).

``--memory`` (Linux): peak resident memory of whole 128-blade runs (amplitudes stored, 20
frequencies, bounds off) at these sample counts, each in a fresh process.

Results are printed and saved to ``bench/out/rings.json`` (the parts run replace theirs;
the others stay).
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time

import numpy as np

import mcfric
from mcfric.core import multi_harmonic as _multi_harmonic
from mcfric.core import sweep as _sweep
from mcfric.model import TABLE_1, Excitation, Model

F = np.linspace(10.0, 150.0, 200)
N0 = 0.5
WORK = 32000            # samples x blades per call
WORK_HARMONICS = 256    # the same with --harmonics


def model_for(n, topology):
    return Model.identical(TABLE_1, n, topology=topology,
                           excitation=Excitation("travelling", 1.1, engine_order=1))


def draw(model, n_s, seed):
    rng = np.random.default_rng(seed)
    nd = model.n_dampers
    return rng.uniform(0, 1, (n_s, nd)), rng.uniform(0, 15000.0, (n_s, nd))


def _renumbered(kernel):
    """``kernel`` (the multi-harmonic sweep) on the dampers numbered from the second: the
    same ring, which the kernel no longer recognises as one (damper 0 not on beams 0, 1)."""
    def call(rech, force, a, b, orders, omega, mu0, N0, kc, n_time, s1, *rest):
        def roll(x, axis):
            return np.ascontiguousarray(np.roll(x, -1, axis=axis))
        s = rest[-4]
        s_rolled = np.empty_like(s)
        kernel(rech, force, roll(a, 0), roll(b, 0), orders, omega, roll(mu0, 1), roll(N0, 1),
               roll(kc, 1), n_time, roll(s1, 2), *rest[:-4], s_rolled, *rest[-3:])
        s[...] = np.roll(s_rolled, 1, axis=2)
    return call


def solve(variant, model, mu0, kc, threads, harmonics=1):
    chain = _sweep.sweep_chain
    multi = _multi_harmonic.sweep_multi_harmonic
    if variant == "dense" and harmonics > 1:
        _multi_harmonic.sweep_multi_harmonic = _renumbered(multi)
    elif variant == "dense":
        _sweep.sweep_chain = lambda *a: _sweep.sweep_dense(*a, np.int64(0))
    try:
        t = time.perf_counter()
        r = mcfric.solve(model, F, mu0, kc, N0, n_threads=threads, harmonics=harmonics)
        dt = time.perf_counter() - t
    finally:
        _sweep.sweep_chain = chain
        _multi_harmonic.sweep_multi_harmonic = multi
    assert r.n_not_converged == 0, (variant, model.n_beams, r.n_not_converged)
    return r.status.size / dt


def bounds_vs_ensemble(sizes, repeat, threads, n_f, search_only):
    from mcfric.bounds import compute_bounds, force_limit

    F_lim = force_limit(1.0, N0)
    f = np.linspace(10.0, 150.0, n_f)
    rows = []
    for n in sizes:
        model = model_for(n, "circular")
        mu0, kc = draw(model, 2000, n)
        mcfric.solve(model, f[:8], mu0[:4], kc[:4], N0, n_threads=threads)
        compute_bounds(model, f[:8], 15000.0, F_lim=F_lim, n_threads=threads)
        tb, tc, te = [], [], []
        for _ in range(repeat):
            # the searched bounds alone, then with their certificate, then the ensemble
            t = time.perf_counter()
            compute_bounds(model, f, 15000.0, F_lim=F_lim, n_threads=threads,
                           certified=False)
            tb.append(time.perf_counter() - t)
            if not search_only:
                t = time.perf_counter()
                compute_bounds(model, f, 15000.0, F_lim=F_lim, n_threads=threads)
                tc.append(time.perf_counter() - t)
            t = time.perf_counter()
            mcfric.solve(model, f, mu0, kc, N0, n_threads=threads)
            te.append(time.perf_counter() - t)
        # ratios: the median of each round's own ratio (a round sees one machine speed)
        b, e = statistics.median(tb), statistics.median(te)
        rb = statistics.median(x / y for x, y in zip(tb, te))
        row = dict(blades=n, frequencies=n_f, bounds_s=b, ensemble_s=e, ratio=rb)
        line = f"bounds, {n:>3} blades: searched {b:7.1f} s"
        if not search_only:
            c = statistics.median(tc)
            rc = statistics.median(x / y for x, y in zip(tc, te))
            row.update(certified_s=c, certified_ratio=rc)
            line += f", certified {c:7.1f} s"
        line += f"; 2000 x {n_f} ensemble solves {e:7.1f} s; searched / ensemble {rb:.2f}"
        if not search_only:
            line += f", certified / ensemble {rc:.2f}"
        rows.append(row)
        print(line)
    return rows


def storage(repeat, threads, workdir):
    from mcfric import config, ensemble

    raw = {"model": {"preset": "disk-72", "n_beams": 128},
           "sampling": {"samples": 200, "seed": 1}, "bounds": {"enabled": False},
           "peaks": {"enabled": False}, "run": {"threads": threads or 0}}
    rows = {}
    for fmt in ("complex", "amplitude"):
        cfg = config.load(raw).replace("output.response", fmt)
        ensemble.run(cfg.replace("sampling.samples", 8), workdir / "warm.h5", force=True,
                     progress=False)
        rows[fmt] = (cfg, [])
    for _ in range(repeat):
        for fmt, (cfg, times) in rows.items():
            path = workdir / f"{fmt}.h5"
            t = time.perf_counter()
            ensemble.run(cfg, path, force=True, progress=False)
            times.append(time.perf_counter() - t)
    out = []
    for fmt, (cfg, times) in rows.items():
        size = (workdir / f"{fmt}.h5").stat().st_size
        out.append(dict(format=fmt, seconds=statistics.median(times), bytes=size))
        print(f"storage, 128 blades, 200 x 1000, {fmt:>9}: {statistics.median(times):6.1f} s, "
              f"{size / 1e6:8.1f} MB (x10 for 2000 members)")
    return out


MEM_SCRIPT = textwrap.dedent("""
    import sys, time
    from mcfric import config, ensemble
    samples, path = int(sys.argv[1]), sys.argv[2]
    cfg = config.load({"model": {"preset": "disk-72", "n_beams": 128},
                       "frequency": {"n": 20}, "sampling": {"samples": samples, "seed": 1},
                       "bounds": {"enabled": False}, "peaks": {"enabled": False}})
    t0 = time.perf_counter()
    s = ensemble.run(cfg, path, force=True, progress=False)
    # VmHWM: this process's own peak (ru_maxrss would carry the parent's across the spawn)
    kb = next(int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM"))
    print(kb, time.perf_counter() - t0, s.complete)
""")


def memory(sizes, workdir):
    out = []
    for n in sizes:
        path = workdir / f"mem-{n}.h5"
        r = subprocess.run([sys.executable, "-c", MEM_SCRIPT, str(n), str(path)],
                           capture_output=True, text=True, check=True)
        kb, dt, _ = r.stdout.split()
        out.append(dict(samples=n, peak_rss_mb=int(kb) / 1024, seconds=float(dt),
                        bytes=path.stat().st_size))
        path.unlink()
        print(f"memory, 128 blades, {n:>7} samples x 20: peak RSS {int(kb) / 1024:7.0f} MB, "
              f"{float(dt):6.1f} s")
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--blades", type=int, nargs="+", default=[8, 16, 32, 64, 128])
    p.add_argument("--repeat", type=int, default=None,
                   help="rounds (default 5 for the rates, 3 for --bounds and --storage)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default all)")
    p.add_argument("--dense-max", type=int, default=32,
                   help="largest ring also timed on the dense kernel (default 32)")
    p.add_argument("--bounds", type=int, nargs="*", default=[],
                   help="tuned ring sizes whose bounds are timed against the ensemble")
    p.add_argument("--bounds-frequencies", type=int, default=1000,
                   help="frequencies of --bounds (default 1000)")
    p.add_argument("--search-only", action="store_true",
                   help="--bounds: time the searched bounds only, not the certified ones")
    p.add_argument("--storage", action="store_true",
                   help="time 128-blade runs storing complex responses and amplitudes")
    p.add_argument("--memory", type=int, nargs="*", default=[],
                   help="sample counts of 128-blade runs whose peak memory is measured")
    p.add_argument("--skip-rates", action="store_true", help="skip the solves/s table")
    p.add_argument("--harmonics", type=int, default=1,
                   help="odd harmonics balanced in the solves/s table (default 1)")
    args = p.parse_args()
    results = {}
    slow = args.repeat or 3             # minutes per round at the larger rings
    if args.bounds:
        results["bounds"] = bounds_vs_ensemble(args.bounds, slow, args.threads,
                                               args.bounds_frequencies, args.search_only)
    with tempfile.TemporaryDirectory(prefix="mcfric-rings-") as tmp:
        if args.storage:
            results["storage"] = storage(slow, args.threads, pathlib.Path(tmp))
        if args.memory:
            results["memory"] = memory(args.memory, pathlib.Path(tmp))
    if not args.skip_rates:
        args.repeat = args.repeat or 5
        key = "rates" if args.harmonics == 1 else f"rates_H{args.harmonics}"
        results[key] = rates(args)
    out = pathlib.Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    path = out / "rings.json"
    # the parts of this run replace theirs; the others (an earlier --bounds run) stay
    kept = json.loads(path.read_text()) if path.exists() else {}
    path.write_text(json.dumps({**kept, **results}, indent=2))
    print(f"saved {path}")


def rates(args):
    cases = {}
    for n in args.blades:
        n_s = max(8, WORK // n) if args.harmonics == 1 else max(2, WORK_HARMONICS // n)
        variants = ["chain", "ring"] + (["dense"] if n <= args.dense_max else [])
        for v in variants:
            model = model_for(n, "linear" if v == "chain" else "circular")
            mu0, kc = draw(model, n_s, n)
            if v == "dense" and args.harmonics == 1:    # slow: fewer samples
                mu0, kc = mu0[:max(4, n_s // n)], kc[:max(4, n_s // n)]
            # compile or load the cache
            solve(v, model, mu0[:4], kc[:4], args.threads, args.harmonics)
            cases[n, v] = (model, mu0, kc, [])
    for _ in range(args.repeat):
        for (n, v), (model, mu0, kc, rates) in cases.items():
            rates.append(solve(v, model, mu0, kc, args.threads, args.harmonics))

    rows = []
    base = None
    print(f"{'blades':>6} {'variant':>7} {'solves/s':>11} {'damper-solves/s':>16} "
          f"{'per damper vs chain':>20} {'vs ' + str(args.blades[0]) + ' blades':>12} "
          f"{'ring vs dense':>14}")
    for n in args.blades:
        chain_rate = statistics.median(cases[n, "chain"][3])
        for v in ("chain", "ring", "dense"):
            if (n, v) not in cases:
                continue
            model = cases[n, v][0]
            rate = statistics.median(cases[n, v][3])
            per_damper = rate * model.n_dampers
            if v == "ring" and base is None:
                base = per_damper
            row = dict(blades=n, variant=v, solves_per_s=rate, damper_solves_per_s=per_damper,
                       rates=cases[n, v][3])
            line = f"{n:>6} {v:>7} {rate:>11.4g} {per_damper:>16.4g}"
            if v != "chain":
                ratio = (chain_rate * (n - 1)) / per_damper
                row["chain_over_ring_per_damper"] = ratio
                line += f" {ratio:>20.2f}"
            else:
                line += f" {'':>20}"
            if v == "ring":
                row["vs_smallest"] = per_damper / base
                line += f" {per_damper / base:>12.2f}"
                if (n, "dense") in cases:
                    sp = rate / statistics.median(cases[n, "dense"][3])
                    row["ring_over_dense"] = sp
                    line += f" {sp:>14.1f}"
            print(line)
            rows.append(row)
    return rows


if __name__ == "__main__":
    main()
