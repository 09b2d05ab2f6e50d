"""Accuracy of the harmonic balance: convergence in H, and the indicator's quality.

Run: ``python bench/harmonic_accuracy.py [--members N] [--n-freq F]``.

* Convergence in H: at the 3:1 and 5:1 points of the second bending mode (105.8 / 3 and
  105.8 / 5 Hz) for both presets, and at 17.5 Hz (3rd harmonic in the eight-beam chain's
  passband), the metric M (largest fundamental amplitude over the beams) for H = 1 ... 15,
  against ``mcfric verify``'s time integration (parameters in ``POINTS``, N0 = 0.5 N).
* The indicator on an eight-beam ensemble (paper's distributions, 10-150 Hz): among the
  points it does not flag, the share whose H = 1 metric differs by more than 1 % from
  H = 9; among the points it flags, the share that really do.

Prints markdown tables (the docs' harmonics page quotes them) and saves
``bench/out/harmonic_accuracy.json``.
"""

import argparse
import json
import pathlib

import numpy as np

import mcfric
from mcfric.hbm import INDICATOR_THRESHOLD
from mcfric.verify import verify

#: preset: (mu0, kc N/m, frequencies Hz); the two-beam pair needs less friction to slip
POINTS = {"two-beam": (0.03, 15000.0, [105.8 / 5, 105.8 / 3]),
          "eight-beam": (0.5, 6000.0, [17.5, 105.8 / 5, 105.8 / 3])}
HS = (1, 3, 5, 7, 9, 11, 15)


def convergence():
    rows = []
    for name, (mu0, kc, freqs) in POINTS.items():
        model = mcfric.preset(name)
        vs = verify(model, freqs, mu0, kc, 0.5, harmonics=9)
        for k, f in enumerate(freqs):
            td = np.max(np.abs(vs[k].harmonics[0]))
            Ms = []
            for H in HS:
                r = mcfric.solve(model, [f], mu0, kc, 0.5, harmonics=H)
                Ms.append(float(np.max(np.abs(r.response[0, 0]))))
            rows.append(dict(preset=name, mu0=mu0, kc=kc, f_hz=f, periodic=vs[k].periodic,
                             time=float(td), M=Ms))
    print("| preset (mu0, kc) | f (Hz) | " + " | ".join(f"H = {h}" for h in HS)
          + " | time integration |")
    print("|---|---|" + "---|" * (len(HS) + 1))
    for r in rows:
        cells = [f"{(m / r['time'] - 1):+.2%}" for m in r["M"]]
        print(f"| {r['preset']} ({r['mu0']:g}, {r['kc']:g}) | {r['f_hz']:.2f} | "
              + " | ".join(cells)
              + f" | {r['time']:.4e} m{'' if r['periodic'] else ' (not periodic)'} |")
    return rows


def indicator_quality(members, n_freq):
    model = mcfric.eight_beam()
    rng = np.random.default_rng(11)
    mu0 = rng.uniform(0, 1, (members, model.n_dampers))
    kc = rng.uniform(0, 15000, (members, model.n_dampers))
    f = np.linspace(10, 150, n_freq)
    r1 = mcfric.solve(model, f, mu0, kc, 0.5, indicator=True)
    r9 = mcfric.solve(model, f, mu0, kc, 0.5, harmonics=9)
    ok = r1.converged & r9.converged
    M1 = np.abs(r1.response).max(-1)
    M9 = np.abs(r9.response).max(-1)
    bad = np.abs(M1 / M9 - 1) > 0.01
    flag = r1.harmonic_indicator > INDICATOR_THRESHOLD
    out = dict(points=int(ok.sum()), not_converged_h9=int(r9.n_not_converged),
               flagged=float(np.mean(flag[ok])), differ=float(np.mean(bad[ok])),
               unflagged_differ=float(np.mean(bad[ok & ~flag])),
               flagged_differ=float(np.mean(bad[ok & flag])))
    print(f"\nindicator on {members} eight-beam members x {n_freq} frequencies "
          f"({out['points']:,} points converged at H = 1 and H = 9; "
          f"{out['not_converged_h9']} not converged at H = 9):")
    print(f"  flagged (> {INDICATOR_THRESHOLD:g}): {out['flagged']:.2%} of points; "
          f"H = 1 differs from H = 9 by > 1 % at {out['differ']:.2%}")
    print(f"  unflagged points that differ by > 1 %: {out['unflagged_differ']:.3%} "
          f"(target < 1 %)")
    print(f"  flagged points that differ by > 1 %: {out['flagged_differ']:.1%}")
    print("  other thresholds: | threshold | flagged | unflagged that differ | flagged that "
          "differ |")
    out["thresholds"] = {}
    for th in (0.001, 0.002, 0.003, 0.005, 0.01, 0.02):
        fl = r1.harmonic_indicator > th
        row = (float(np.mean(fl[ok])), float(np.mean(bad[ok & ~fl])),
               float(np.mean(bad[ok & fl])))
        out["thresholds"][th] = row
        print(f"  | {th:g} | {row[0]:.1%} | {row[1]:.3%} | {row[2]:.1%} |")
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--members", type=int, default=400)
    p.add_argument("--n-freq", type=int, default=250)
    args = p.parse_args()
    out = dict(convergence=convergence(),
               indicator=indicator_quality(args.members, args.n_freq))
    path = pathlib.Path(__file__).parent / "out" / "harmonic_accuracy.json"
    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(out, indent=1))
    print(f"saved: {path}")


if __name__ == "__main__":
    main()
