"""Cost and effect of resolving every member's peaks, on the default ensemble.

Run: ``python bench/peaks.py [--members N] [--repeat R] [--threads T] [--figures DIR]``.

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


def strict(x):
    """``x`` with every non-finite float (an open end of an interval) as None: strict JSON
    has no Infinity or NaN."""
    if isinstance(x, dict):
        return {k: strict(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [strict(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if np.isfinite(x) else None
    return x


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--members", type=int, default=2000)
    p.add_argument("--repeat", type=int, default=5)
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--figures", metavar="DIR",
                   help="also draw the two figures of docs/peaks.md into DIR")
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
    folds = int(np.count_nonzero((r.peaks.fold >= 1).any(axis=1)))
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
    (out / "peaks.json").write_text(json.dumps(strict(res), indent=2, allow_nan=False))
    print(f"saved {out / 'peaks.json'}")
    if args.figures:
        figures(pathlib.Path(args.figures), model, f, mu0, kc, r)


def figures(where, model, f, mu0, kc, r):
    """docs/peaks.md's figures: the grid's share of each member's peak, and a zoom."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    grid = r.metric().max(axis=1)
    best = r.peaks.largest()
    fig = Figure(figsize=(6.4, 3.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.hist(grid / best, bins=50, range=(0.4, 1.0), color="0.4")
    ax.set_xlabel("largest value on the 1000-point grid / refined peak")
    ax.set_ylabel("members")
    ax.set_title(f"default ensemble ({len(best)} members, eight beams, 1.1 N)", fontsize=9)
    fig.savefig(where / "peaks-ratio.png", dpi=110)

    fig = Figure(figsize=(6.4, 3.4), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    fine = np.arange(16.0, 16.5, 0.0005)
    ratio = grid / best
    # the members whose grid value is the worst, the median and the best share of the peak
    first = (r.peaks.freq_hz[np.arange(len(best)), np.nanargmax(r.peaks.metric, axis=1)]
             < fine[-1])                         # members whose largest peak is in view
    ratio_in = np.where(first, ratio, np.nan)
    order = np.argsort(np.where(first, ratio, np.inf))
    picks = [int(np.nanargmin(ratio_in)), int(order[np.count_nonzero(first) // 2]),
             int(np.nanargmax(ratio_in))]
    for i, colour in zip(picks, ("tab:blue", "tab:orange", "tab:green")):
        m = mcfric.solve(model, fine, mu0[i], kc[i], 0.5).metric()[0]
        ax.plot(fine, m, color=colour, lw=1.0,
                label=f"member {i}: grid / peak {ratio[i]:.2f} (0.0005 Hz sweep)")
        keep = (f >= fine[0]) & (f <= fine[-1])
        ax.plot(f[keep], r.metric()[i, keep], "o", color=colour, ms=4, mfc="none")
        j = int(np.nanargmax(r.peaks.metric[i]))
        ax.plot(r.peaks.freq_hz[i, j], r.peaks.metric[i, j], "*", color=colour, ms=11)
    ax.set_yscale("log")
    ax.set_xlim(fine[0], fine[-1])
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("displacement amplitude M [m]")
    ax.set_title("first resonance: grid points (circles) and refined peaks (stars)",
                 fontsize=9)
    ax.legend(fontsize=7)
    fig.savefig(where / "peaks-zoom.png", dpi=110)
    print(f"figures: {where / 'peaks-ratio.png'}, {where / 'peaks-zoom.png'}")


if __name__ == "__main__":
    main()
