"""Multi-harmonic balance: solves per second against H, and against a scipy fsolve AFT loop.

Run: ``python bench/harmonics.py [--samples N] [--n-freq F] [--repeat R] [--threads T]
[--baseline-samples N] [--baseline-freq F]``.

Measured in this one run (absolute times drift on a shared machine; the ratios hold):

* solves per second of ``mcfric.solve`` for the two- and eight-beam presets (paper's
  distributions, 10-150 Hz) with the closed-form single-harmonic kernel, and with
  ``harmonics`` = 1 (through the AFT kernel), 3, 5, 7 and 9. The variants are timed in
  alternation, ``--repeat`` rounds, and the median of each is reported, with its ratio to
  the closed form. A multi-harmonic solve includes the single-harmonic solve that starts it.
* a plain baseline for eight beams at H = 7: ``scipy.optimize.fsolve`` per point on the
  same per-harmonic contact-space equations, the Jenkins force by a sampled AFT (numpy,
  256 samples per period, two passes of the return mapping, FFT), warm-started along
  frequency, on a subset of the points; three passes, each alternated with an mcfric
  H = 7 solve of the run's grid, the ratio the median of the three pairs' ratios.

Results are printed and saved to ``bench/out/harmonics.json``.
"""

import argparse
import json
import pathlib
import time

import numpy as np
from scipy import optimize

import mcfric
from mcfric.core.receptance import contact_space

N0 = 0.5
KC_MAX = 15000.0


def draw(model, n, seed):
    rng = np.random.default_rng(seed)
    nd = model.n_dampers
    return rng.uniform(0, 1, (n, nd)), rng.uniform(0, KC_MAX, (n, nd))


def variants():
    return [("closed form", dict()), ("H=1 via AFT", dict(aft=True))] + [
        (f"H={h}", dict(harmonics=h)) for h in (3, 5, 7, 9)]


def rates(model, f, n_samples, repeat, threads):
    mu0, kc = draw(model, n_samples, 1)
    for _, kw in variants():                      # compile / load, untimed
        mcfric.solve(model, f[:4], mu0[:2], kc[:2], N0, n_threads=threads, **kw)
    times = {name: [] for name, _ in variants()}
    nc = {}
    for _ in range(repeat):
        for name, kw in variants():
            t = time.perf_counter()
            r = mcfric.solve(model, f, mu0, kc, N0, n_threads=threads, **kw)
            times[name].append(time.perf_counter() - t)
            nc[name] = r.n_not_converged
    n = n_samples * len(f)
    return {name: dict(solves_per_s=n / float(np.median(t)), not_converged=nc[name],
                       points=n) for name, t in times.items()}


def sampled_aft(q, kc, fs, n_h, n=256):
    """Force harmonics of a Jenkins element by plain sampling (two passes, FFT)."""
    th = 2 * np.pi * np.arange(n) / n
    orders = np.arange(1, 2 * n_h, 2)
    x = np.real(np.exp(1j * np.outer(th, orders)) @ q)
    dx = np.diff(x, prepend=x[-1])
    f = np.empty(n)
    fc = 0.0
    for _ in range(2):
        for i in range(n):
            fc = min(max(fc + kc * dx[i], -fs), fs)
            f[i] = fc
    return 2 * np.fft.fft(f)[orders] / n


def fsolve_rate(model, f, n_samples, ours, n_h=4):
    """Points per second of a per-point fsolve on the per-harmonic equations, three
    passes, each after a call of ``ours()`` (solves/s of our code): the medians of both
    rates and of the pairs' ratios (ours over the baseline), and the converged count."""
    mu0, kc = draw(model, n_samples, 1)
    a, b = model.dampers
    nd = model.n_dampers
    orders = np.arange(1, 2 * n_h, 2)
    cs = [contact_space(model.receptances(k * 2 * np.pi * f)[0], model.force, a, b)
          for k in orders]
    pairs = []
    for _ in range(3):
        mine = ours()
        t = time.perf_counter()
        n_ok = 0
        for i in range(n_samples):
            x = np.zeros(2 * nd * n_h)
            fs = mu0[i] * N0
            for k in range(len(f)):
                def residual(x):
                    Q = (x[0::2] + 1j * x[1::2]).reshape(nd, n_h)
                    Fh = np.array([sampled_aft(Q[j], kc[i, j], fs[j], n_h) for j in range(nd)])
                    R = Q.copy()
                    for h in range(n_h):
                        R[:, h] += cs[h][0][k] @ Fh[:, h]
                    R[:, 0] -= cs[0][1][k]
                    return np.column_stack([R.real.ravel(), R.imag.ravel()]).ravel()
                x, _, ier, _ = optimize.fsolve(residual, x, full_output=True)
                n_ok += ier == 1
        pairs.append((mine, n_samples * len(f) / (time.perf_counter() - t)))
    return (float(np.median([b for _, b in pairs])), float(np.median([m for m, _ in pairs])),
            float(np.median([m / b for m, b in pairs])), n_ok)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=40)
    p.add_argument("--n-freq", type=int, default=200)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--baseline-samples", type=int, default=1)
    p.add_argument("--baseline-freq", type=int, default=20)
    args = p.parse_args()
    f = np.linspace(10.0, 150.0, args.n_freq)
    out = {}
    for name in ("two-beam", "eight-beam"):
        model = mcfric.preset(name)
        r = rates(model, f, args.samples, args.repeat, args.threads)
        out[name] = r
        base = r["closed form"]["solves_per_s"]
        print(f"{name}: {args.samples} samples x {args.n_freq} frequencies, median of "
              f"{args.repeat} alternated rounds")
        for v, d in r.items():
            print(f"  {v:<13} {d['solves_per_s']:>12,.0f} solves/s   "
                  f"closed form / this {base / d['solves_per_s']:8.1f}   "
                  f"not converged {d['not_converged']}")
    model = mcfric.eight_beam()
    fb = np.linspace(10.0, 150.0, args.baseline_freq)
    mu0, kc = draw(model, args.samples, 1)

    def ours():
        t = time.perf_counter()
        mcfric.solve(model, f, mu0, kc, N0, n_threads=args.threads, harmonics=7)
        return mu0.shape[0] * len(f) / (time.perf_counter() - t)
    rate, mine, ratio, ok = fsolve_rate(model, fb, args.baseline_samples, ours)
    out["fsolve_baseline"] = dict(solves_per_s=rate, converged=int(ok),
                                  points=args.baseline_samples * len(fb),
                                  ours_solves_per_s=mine, ours_over_baseline=ratio)
    print(f"eight-beam H=7 baseline (fsolve, sampled AFT): {rate:,.1f} solves/s "
          f"({ok} of {args.baseline_samples * len(fb)} converged); mcfric H=7 "
          f"{mine:,.0f} solves/s; mcfric / baseline {ratio:,.0f} (median of 3 pairs)")
    path = pathlib.Path(__file__).parent / "out" / "harmonics.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"saved: {path}")


if __name__ == "__main__":
    main()
