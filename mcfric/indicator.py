"""Where one harmonic is not enough: the indicator's report for a results file.

A single-harmonic run stores ``harmonic_indicator`` per point
(:mod:`mcfric.core.harmonic_indicator`); points above
:data:`mcfric.hbm.INDICATOR_THRESHOLD` are flagged. A multi-harmonic run says which
harmonics it balanced. ``mcfric info`` and the run summary print these lines.
"""

from __future__ import annotations

import json

import numpy as np

from .hbm import INDICATOR_THRESHOLD

#: Flagged points listed by name in the report, the largest indicators first.
SHOWN = 3


def file_report(path):
    """Lines on the harmonic content of a results file (empty if it has none).

    Parameters
    ----------
    path : str or Path
        A results file, complete or partial.

    Returns
    -------
    list of str
    """
    from .store import dataset_names, iter_records, read, read_attrs

    attrs = read_attrs(path)
    H = int(attrs.get("harmonics", 1))
    names = dataset_names(path)
    if H > 1:
        stored = next((n for n in ("response", "amplitude") if n in names), None)
        what = [f"metric and {stored} hold the fundamental" if stored else
                "metric holds the fundamental"]
        if "response_peak" in names:
            what.append("response_peak the full-period peak")
        lines = [f"harmonics:   odd harmonics 1..{H} balanced (multi-harmonic); "
                 + ", ".join(what)]
        if "from_above" in names:
            n = sum(int(np.count_nonzero(arr["from_above"]))
                    for _, arr in iter_records(path, ["from_above"]))
            if n:
                lines.append(f"from above:  {n:,} points converged only from the next "
                             "frequency's solution, sweeping down (dataset from_above)")
        if "from_rest" in names:        # files before 2026-11-30 have none
            n = sum(int(np.count_nonzero(arr["from_rest"]))
                    for _, arr in iter_records(path, ["from_rest"]))
            if n:
                lines.append(f"from rest:   {n:,} points converged only from rest, raising "
                             "the drive at their frequency (dataset from_rest)")
        return lines
    if "harmonic_indicator" not in names:
        return []
    flagged = total = 0
    worst = []          # (indicator, member, frequency index)
    # blocks of ~128 kB of indicator (a few temporaries each): memory stays flat in the
    # number of members
    block = max(1, (1 << 15) // max(1, len(read(path, "frequency"))))
    for start, arr in iter_records(path, ["harmonic_indicator", "converged"], block=block):
        ind = np.where(arr["converged"], arr["harmonic_indicator"], np.nan)
        ok = ~np.isnan(ind)         # inf: harmonics without a fundamental, flagged
        total += int(np.count_nonzero(ok))
        hit = ok & (ind > INDICATOR_THRESHOLD)
        flagged += int(np.count_nonzero(hit))
        if hit.any():
            flat = np.where(hit, ind, -np.inf).ravel()
            top = np.argsort(flat)[::-1][:SHOWN]
            worst += [(flat[t], start + t // ind.shape[1], t % ind.shape[1]) for t in top
                      if flat[t] > -np.inf]
    if not total:
        return []
    # a displacement ratio over every beam's output, whatever the metric: in velocity
    # or acceleration the k-th harmonic weighs k or k^2 times more
    q = json.loads(attrs.get("config_json", "{}")).get("metric", {}).get("quantity",
                                                                         "displacement")
    weigh = {"velocity": "; in velocity the 3rd and 5th weigh 3 and 5 times more",
             "acceleration": "; in acceleration the 3rd and 5th weigh 9 and 25 times more"}
    lines = [f"harmonics:   single-harmonic; {flagged:,} of {total:,} converged points "
             f"({100.0 * flagged / total:.3g} %) may have higher harmonics above "
             f"{INDICATOR_THRESHOLD:g} of the fundamental (harmonic_indicator: displacements "
             f"at every beam's output, an estimate, not a bound{weigh.get(q, '')})"]
    if flagged and attrs.get("complete") == 1:   # member numbers need every row done
        freq = read(path, "frequency")
        worst = sorted(worst, reverse=True)[:SHOWN]
        pts = ", ".join(f"member {m} at {freq[k]:.4g} Hz ({v:.2g})" for v, m, k in worst)
        lines.append(f"             largest: {pts}; check one with `mcfric verify FILE "
                     "--member I --f HZ`, or rerun with --harmonics 9")
    return lines
