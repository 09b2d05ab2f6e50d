"""Kernel throughput against a per-point scipy fsolve loop, and numba compile times.

Run: ``python bench/kernel.py [--samples N] [--threads T] [--repeat R] [--skip-compile]``.

Everything is measured in this one run, so the ratios hold even though absolute times
drift on a shared machine:

* solves per second of ``mcfric.solve`` for the two- and eight-beam presets (paper's
  distributions, 10-150 Hz, 1000 frequencies), after compilation and one untimed
  full-size call;
* the same solves done the paper's way, ``scipy.optimize.fsolve`` per point on
  ``s - s_out(s) = 0`` (warm-started along frequency, contact-space reduction so the
  baseline is not handicapped), timed on a subset;
* the two alternated ``--repeat`` times (default 5): the speed-up is the median of each
  pair's ratio, the rates the medians (a shared machine's speed drifts within minutes);
* compile time of the first call in a fresh process with an empty numba cache, and the
  first call of a second process that finds the cache warm.

Results are printed and saved to ``bench/out/kernel.json``.
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
from scipy import optimize

import mcfric
from mcfric.core.friction import describing_function
from mcfric.core.receptance import contact_space

F = np.linspace(10.0, 150.0, 1000)
N0 = 0.5
KC_MAX = 15000.0


def draw(model, n, seed):
    rng = np.random.default_rng(seed)
    nd = model.n_dampers
    return rng.uniform(0, 1, (n, nd)), rng.uniform(0, KC_MAX, (n, nd))


def kernel_rate(model, n_samples, threads):
    """A callable timing one full ``mcfric.solve``: returns (solves/s, result)."""
    mu0, kc = draw(model, n_samples, 1)
    mcfric.solve(model, F[:8], mu0[:4], kc[:4], N0, n_threads=threads)  # compile / load
    # one untimed full-size call: the first large allocations of a fresh process land on
    # memory the (virtual) machine has not backed yet, which measured 13e6 -> 25e6 solves/s
    # over the first calls for two beams; the timed calls then see a process in steady state
    mcfric.solve(model, F, mu0, kc, N0, n_threads=threads)

    def once():
        t = time.perf_counter()
        r = mcfric.solve(model, F, mu0, kc, N0, n_threads=threads)
        return r.status.size / (time.perf_counter() - t), r
    return once


def fsolve_rate(model, n_samples, n_freq):
    """The paper's approach: fsolve per point on s_trial - s_out(s_trial)."""
    mu0, kc = draw(model, n_samples, 1)
    f = F[:: len(F) // n_freq][:n_freq]
    rec = model.receptances(2 * np.pi * f)[0]
    a, b = model.dampers
    G, q0, _, _ = contact_space(rec, model.force, a, b)
    nd = model.n_dampers
    n_bad = 0
    t = time.perf_counter()
    for i in range(n_samples):
        fl = mu0[i] * N0
        s = np.ones(nd)
        for k in range(len(f)):
            def residual(s_trial, k=k):
                s_abs = np.abs(s_trial)
                K = np.array([describing_function(np.array([s_abs[j]]), kc[i, j])[0]
                              for j in range(nd)])
                q = np.linalg.solve(np.eye(nd) + G[k] * K[None, :], q0[k])
                return s_trial - fl / (kc[i] * np.abs(q))
            s, info, ier, msg = optimize.fsolve(residual, s, full_output=True)
            n_bad += ier != 1
    dt = time.perf_counter() - t
    return n_samples * len(f) / dt, n_bad


def compile_times(preset):
    """First-call time with an empty cache (fresh process), then with the cache warm."""
    code = ("import time; t0 = time.perf_counter(); import mcfric; t1 = time.perf_counter(); "
            f"mcfric.solve(mcfric.preset({preset!r}), [20.0, 30.0], 0.5, 6000.0, 0.5); "
            "t2 = time.perf_counter(); print(t1 - t0, t2 - t1)")
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("cold", "warm"):
            res = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True)
            imp, call = map(float, res.stdout.split())
            out[label] = {"import_s": imp, "first_call_s": call}
    return out


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=2000, help="ensemble size (default 2000)")
    p.add_argument("--threads", type=int, default=None, help="numba threads (default all)")
    p.add_argument("--repeat", type=int, default=5,
                   help="alternated kernel / fsolve pairs per preset, medians count (default "
                        "5; a two-beam call takes ~0.1 s, so one slice of other load on "
                        "this shared machine can halve a single measurement)")
    p.add_argument("--skip-compile", action="store_true", help="do not time compilation")
    args = p.parse_args(argv)
    import numba
    threads = args.threads or numba.config.NUMBA_NUM_THREADS
    results = {"threads": threads, "samples": args.samples, "frequencies": len(F)}
    print(f"mcfric {mcfric.__version__}, numba {numba.__version__}, {threads} thread(s), "
          f"{args.samples} samples x {len(F)} frequencies, 10-150 Hz")
    for preset, (n_fs, f_fs) in (("two-beam", (20, 50)), ("eight-beam", (5, 40))):
        model = mcfric.preset(preset)
        kernel_once = kernel_rate(model, args.samples, threads)
        pairs = []
        for _ in range(args.repeat):
            # alternated, so that each pair sees the same machine speed (single fsolve
            # passes measured 670-5200 solves/s in runs the same hour)
            k_rate, r = kernel_once()
            b_rate, bad = fsolve_rate(model, n_fs, f_fs)
            pairs.append((k_rate, b_rate))
        rate = float(np.median([k for k, _ in pairs]))
        base = float(np.median([b for _, b in pairs]))
        speedup = float(np.median([k / b for k, b in pairs]))
        results[preset] = {"kernel_solves_per_s": rate, "fsolve_solves_per_s": base,
                           "speedup": speedup, "speedup_pairs": [k / b for k, b in pairs],
                           "not_converged": r.n_not_converged,
                           "mean_iterations": float(r.iterations.mean()),
                           "fsolve_flagged": int(bad), "fsolve_points": n_fs * f_fs}
        print(f"{preset:>10}: kernel {rate / 1e6:7.2f} M solves/s | fsolve loop "
              f"{base:8.0f} solves/s ({bad} of {n_fs * f_fs} flagged ier != 1) | "
              f"speed-up {speedup:8.0f}x (median of pairs) | not converged {r.n_not_converged} | "
              f"mean iterations {r.iterations.mean():.2f}")
    if not args.skip_compile:
        for preset in ("two-beam", "eight-beam"):
            c = compile_times(preset)
            results[f"compile_{preset}"] = c
            print(f"{preset:>10}: first call, empty cache {c['cold']['first_call_s']:5.1f} s; "
                  f"warm cache {c['warm']['first_call_s']:5.2f} s "
                  f"(+ import {c['warm']['import_s']:.2f} s)")
    out = pathlib.Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    (out / "kernel.json").write_text(json.dumps(results, indent=2))
    print(f"saved {out / 'kernel.json'}")


if __name__ == "__main__":
    main()
