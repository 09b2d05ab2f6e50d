"""Cost and effect of resolving every member's peaks, on the default ensemble.

Run: ``python bench/peaks.py [--members N] [--repeat R] [--threads T]``.

Measured in this one run, on the default ensemble (eight beams, F0 = 1.1 N, the paper's
distributions, 1000 frequencies over 10-150 Hz): the plain sweep (``mcfric.solve``) and
the sweep with refined peaks and fold checks (``peaks=`` the default settings), timed
alternately ``--repeat`` times (default 5); the ratio is the median of the pairs' ratios,
since a shared machine's speed drifts by tens of percent within minutes. Then what the
refinement changes: each member's largest peak on the grid against the refined one (the
median ratio, the 95th percentile and the maximum before and after), and the members
with a fold. Printed and saved to ``bench/out/peaks.json``.
"""

import argparse
import json
import pathlib
import time

import numpy as np

import mcfric
from mcfric.peaks import PeakSettings, statistics


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--members", type=int, default=2000)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--threads", type=int, default=None)
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error(f"--repeat: expected an integer >= 1, got {args.repeat}")
    model = mcfric.eight_beam(1.1)
    f = np.linspace(10.0, 150.0, 1000)
    rng = np.random.default_rng(0)
    nd = model.n_dampers
    mu0 = rng.uniform(0, 1, (args.members, nd))
    kc = rng.uniform(0, 15000.0, (args.members, nd))
    settings = PeakSettings(count=2)

    def plain():
        return mcfric.solve(model, f, mu0, kc, 0.5, n_threads=args.threads)

    def refined():
        return mcfric.solve(model, f, mu0, kc, 0.5, n_threads=args.threads, peaks=settings)

    plain(), refined()                          # compile, and fault the pages in
    ratios, t_plain, t_refined = [], [], []
    for _ in range(args.repeat):
        t = time.perf_counter()
        plain()
        a = time.perf_counter() - t
        t = time.perf_counter()
        r = refined()
        b = time.perf_counter() - t
        t_plain.append(a)
        t_refined.append(b)
        ratios.append(b / a)
    grid = r.metric().max(axis=1)
    best = r.peaks.largest()
    before, after = statistics(grid), statistics(best)
    folds = int(np.count_nonzero((r.peaks.fold == 1).any(axis=1)))
    res = {"members": args.members, "frequencies": len(f),
           "ratio_median": float(np.median(ratios)), "ratios": ratios,
           "plain_best_s": min(t_plain), "refined_best_s": min(t_refined),
           "grid_over_refined_median": float(np.median(grid / best)),
           "grid_over_refined_min": float(np.min(grid / best)),
           "before": before, "after": after, "members_with_folds": folds}
    print(f"{args.members} members x {len(f)} frequencies, eight beams, F0 = 1.1 N")
    print(f"refined / plain sweep: {res['ratio_median']:.2f} (median of {args.repeat} "
          f"pairs, {min(ratios):.2f}-{max(ratios):.2f}); best times {min(t_plain):.2f} s "
          f"and {min(t_refined):.2f} s")
    print(f"grid peak / refined peak: median {res['grid_over_refined_median']:.3f}, "
          f"worst {res['grid_over_refined_min']:.3f}")
    for name in ("median", "p95", "max"):
        print(f"  {name:>6} of the members' largest peak: grid {before[name]:.4g} m, "
              f"refined {after[name]:.4g} m ({after[name] / before[name] - 1:+.1%})")
    print(f"members with a fold: {folds} of {args.members}")
    out = pathlib.Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    (out / "peaks.json").write_text(json.dumps(res, indent=2))
    print(f"saved {out / 'peaks.json'}")


if __name__ == "__main__":
    main()
