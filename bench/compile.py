"""Where the first run's compile time goes, kernel by kernel.

Run: ``python bench/compile.py [--samples N] [--n-freq F]``.

A small ``mcfric run two-beam`` (the ensemble, refined peaks, the harmonic indicator,
searched and certified bounds, the file and the figure) runs twice in fresh processes
that share a new, empty numba cache (``NUMBA_CACHE_DIR``, so the project's own cache is
left alone): the first compiles every kernel of a run, the second loads them. Printed: the
two wall times and their ratio, each kernel compiled from Python with the time of its
compile (callees included: numba compiles a kernel's callees first, then links their code
into the caller's module and optimises and translates that module again, so a long call
chain pays for its deepest kernels once per level), and the chain under the costliest
one. Saved to ``bench/out/compile.json``.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time


def _child(samples, n_freq, out):
    """Run the small ``mcfric run`` and write the compile events to ``out``."""
    from numba.core import event

    # events in start order; ``parent`` is the index of the compile that asked for this one
    stack, starts, events = [], [], []

    class _Listener(event.Listener):
        def on_start(self, ev):
            events.append(dict(kernel=ev.data["dispatcher"].py_func.__qualname__,
                               parent=stack[-1] if stack else None, depth=len(stack)))
            stack.append(len(events) - 1)
            starts.append(time.perf_counter())

        def on_end(self, ev):
            events[stack.pop()]["seconds"] = time.perf_counter() - starts.pop()

    event.register("numba:compile", _Listener())
    from mcfric import cli

    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        rc = cli.main(["run", "two-beam", "--samples", str(samples), "--n-freq", str(n_freq),
                       "--seed", "3", "-o", f"{d}/r.h5", "--no-progress"])
    wall = time.perf_counter() - t
    pathlib.Path(out).write_text(json.dumps(dict(rc=rc, wall=wall, events=events)))


def _chain(events, top):
    """The costliest path of compiles down from the event at index ``top``."""
    path = [top]
    while True:
        kids = [i for i, e in enumerate(events) if e["parent"] == path[-1]]
        if not kids:
            return [events[i] for i in path]
        path.append(max(kids, key=lambda i: events[i]["seconds"]))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=8)
    p.add_argument("--n-freq", type=int, default=5)
    p.add_argument("--child", metavar="OUT", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        return _child(args.samples, args.n_freq, args.child)
    if args.samples < 1 or args.n_freq < 2:
        p.error("expected --samples >= 1 and --n-freq >= 2")
    runs = []
    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, NUMBA_CACHE_DIR=f"{d}/numba", MPLBACKEND="Agg")
        for k in range(2):
            out = f"{d}/events{k}.json"
            subprocess.run([sys.executable, __file__, "--child", out, "--samples",
                            str(args.samples), "--n-freq", str(args.n_freq)],
                           env=env, check=True, stdout=subprocess.DEVNULL)
            runs.append(json.loads(pathlib.Path(out).read_text()))
    cold, warm = runs
    if cold["rc"] or warm["rc"]:
        sys.exit(f"bench/compile.py: mcfric run exited with {cold['rc']} / {warm['rc']}")
    ev = cold["events"]
    roots = sorted((i for i, e in enumerate(ev) if e["parent"] is None),
                   key=lambda i: -ev[i]["seconds"])
    top = [ev[i] for i in roots]
    total = sum(e["seconds"] for e in top)
    print(f"mcfric run two-beam, {args.samples} samples x {args.n_freq} frequencies")
    print(f"empty cache {cold['wall']:.1f} s, loaded cache {warm['wall']:.1f} s: "
          f"ratio {cold['wall'] / warm['wall']:.0f}; compiling {total:.1f} s "
          f"({len(cold['events'])} compiles, {len(warm['events'])} in the second run)")
    print("kernels compiled from Python (callees included):")
    for e in top:
        print(f"  {e['seconds']:7.1f} s  {100 * e['seconds'] / total:5.1f} %  {e['kernel']}")
    chain = _chain(ev, roots[0])
    print(f"the costliest chain, under {top[0]['kernel']} (each level's compile, callees "
          "included):")
    for e in chain:
        print(f"  {'  ' * e['depth']}{e['kernel']}: {e['seconds']:.1f} s")
    outdir = pathlib.Path(__file__).parent / "out"
    outdir.mkdir(exist_ok=True)
    (outdir / "compile.json").write_text(json.dumps(dict(
        samples=args.samples, n_freq=args.n_freq, cold_wall=cold["wall"],
        warm_wall=warm["wall"], compile_total=total, top=top, chain=chain), indent=1))


if __name__ == "__main__":
    main()
