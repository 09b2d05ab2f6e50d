"""Cost of the bound's peak: its refinement and the certified bound around it.

Run: ``python bench/bound_peak.py [--preset P ...] [--repeat R] [--threads T]``.

Measured in this one run, per preset (default ``eight-beam`` and ``disk-24``, F0 = 1.1 N,
1000 frequencies over 10-150 Hz, the presets' bounds settings), the variants timed
alternately ``--repeat`` times (default 3) and reported as medians and the median of the
pairs' ratios (a shared machine's speed drifts by tens of percent within minutes):

* the refinement of the searched upper bound's peak
  (:func:`mcfric.bounds.peak.refine_upper_peak`) against the searched bounds on the
  whole grid (``compute_bounds(certified=False)``), its baseline;
* the certification of the refinement's 33-point sub-grid as the run does it
  (:func:`mcfric.bounds.peak.certified_near_peak`: first order, the second order only
  where it can change the largest value) against certifying every sub-grid frequency as
  the grid is certified (``compute_bounds`` with the grid's settings), its baseline; and
  whether both give the same largest certified value and witness.

The certificate's settings come from certifying the three grid frequencies around the
peak (the grid's own certification takes minutes and is not what is measured here).
Printed and saved to ``bench/out/bound_peak.json``.
"""

import argparse
import json
import pathlib
import time

import numpy as np

from mcfric import config
from mcfric.bounds import compute_bounds
from mcfric.bounds.peak import SUB_GRID, certified_near_peak, refine_upper_peak


def timed(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def measure(preset, repeat, threads):
    spec = config.load(preset, {"run.threads": (threads, "--threads")}).spec
    model, f, b = spec.model, spec.freq_hz, spec.bounds
    kw = {"k_max_im": b.k_max_im, "F_lim": None if np.isinf(b.F_lim) else b.F_lim,
          "quantity": spec.metric.quantity, "beams": spec.metric.beams,
          "n_threads": threads, "progress": False}
    B = compute_bounds(model, f, b.k_max_re, certified=False, **kw)
    k = int(np.nanargmax(B.upper))
    near = compute_bounds(model, f[k - 1:k + 2], b.k_max_re, **kw)   # certified, default
    C = near.certificate
    sub = np.linspace(f[k - 1], f[k + 1], SUB_GRID)
    how = {"budget": C.budget if C.budget >= 1 else None, "split": C.split,
           "moments": C.moments}
    # compile and warm everything once, outside the timings
    refine_upper_peak(model, B)
    certified_near_peak(model, near, sub)
    times = {"search": [], "refine": [], "near": [], "all": []}
    for _ in range(repeat):
        for name, fn in (
                ("search", lambda: compute_bounds(model, f, b.k_max_re, certified=False,
                                                  **kw)),
                ("refine", lambda: refine_upper_peak(model, B)),
                ("near", lambda: certified_near_peak(model, near, sub)),
                ("all", lambda: compute_bounds(model, sub, b.k_max_re, certified=True,
                                               **how, **kw))):
            t, out = timed(fn)
            times[name].append(t)
            if name == "near":
                up, wit = out
            if name == "all":
                full = out.certificate
    ratio = {"refine / search": float(np.median(np.divide(times["refine"], times["search"]))),
             "near / all": float(np.median(np.divide(times["near"], times["all"])))}
    return {"preset": preset, "median_s": {k: float(np.median(v)) for k, v in times.items()},
            "ratio": ratio,
            "largest_certified": {"near": float(np.max(up)), "all": float(np.max(full.upper))},
            "largest_witness": {"near": float(np.nanmax(wit)),
                                "all": float(np.nanmax(full.upper_witness))},
            "second_order": bool(C.moments)}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", nargs="+", default=["eight-beam", "disk-24"])
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--threads", type=int, default=None)
    args = p.parse_args(argv)
    if args.repeat < 1:
        p.error(f"--repeat: expected an integer >= 1, got {args.repeat}")
    rows = [measure(name, args.repeat, args.threads) for name in args.preset]
    for r in rows:
        s, q = r["median_s"], r["ratio"]
        print(f"{r['preset']}: refinement {s['refine']:.2f} s / searched bounds "
              f"{s['search']:.2f} s = {q['refine / search']:.2f}; sub-grid certified as the "
              f"run does {s['near']:.2f} s / as the grid is {s['all']:.2f} s = "
              f"{q['near / all']:.3f} (second order on the grid: {r['second_order']})")
        print(f"  largest certified {r['largest_certified']['near']:.6g} m (as the grid: "
              f"{r['largest_certified']['all']:.6g}); largest witness "
              f"{r['largest_witness']['near']:.6g} m ({r['largest_witness']['all']:.6g})")
    out = pathlib.Path(__file__).parent / "out"
    out.mkdir(exist_ok=True)
    (out / "bound_peak.json").write_text(json.dumps(rows, indent=2))
    print(f"saved {out / 'bound_peak.json'}")


if __name__ == "__main__":
    main()
