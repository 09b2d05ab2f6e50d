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

    stack, events = [], []

    class _Listener(event.Listener):
        def on_start(self, ev):
            stack.append((ev.data["dispatcher"].py_func.__qualname__, time.perf_counter()))

        def on_end(self, ev):
            name, t0 = stack.pop()
            parent = stack[-1][0] if stack else None
            events.append(dict(kernel=name, parent=parent, depth=len(stack),
                               seconds=time.perf_counter() - t0))

    event.register("numba:compile", _Listener())
    import matplotlib

    matplotlib.use("Agg")
    from mcfric import cli

    t = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        rc = cli.main(["run", "two-beam", "--samples", str(samples), "--n-freq", str(n_freq),
                       "--seed", "3", "-o", f"{d}/r.h5", "--no-progress"])
    wall = time.perf_counter() - t
    pathlib.Path(out).write_text(json.dumps(dict(rc=rc, wall=wall, events=events)))


def _chain(events, top):
    """The costliest path of compiles under the top-level kernel ``top``."""
    path, name, depth = [], top, 0
    while name is not None:
        mine = [e for e in events if e["kernel"] == name and e["depth"] == depth]
        if not mine:
            break
        path.append(max(mine, key=lambda e: e["seconds"]))
        kids = [e for e in events if e["parent"] == name and e["depth"] == depth + 1]
        name = max(kids, key=lambda e: e["seconds"])["kernel"] if kids else None
        depth += 1
    return path


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
    top = sorted((e for e in cold["events"] if e["depth"] == 0), key=lambda e: -e["seconds"])
    total = sum(e["seconds"] for e in top)
    print(f"mcfric run two-beam, {args.samples} samples x {args.n_freq} frequencies")
    print(f"empty cache {cold['wall']:.1f} s, loaded cache {warm['wall']:.1f} s: "
          f"ratio {cold['wall'] / warm['wall']:.0f}; compiling {total:.1f} s "
          f"({len(cold['events'])} compiles, {len(warm['events'])} in the second run)")
    print("kernels compiled from Python (callees included):")
    for e in top:
        print(f"  {e['seconds']:7.1f} s  {100 * e['seconds'] / total:5.1f} %  {e['kernel']}")
    chain = _chain(cold["events"], top[0]["kernel"])
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
