"""``mcfric info`` and ``mcfric config``: what a results file holds, and the
configuration (of a preset, a file, or a results file's run)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from .errors import EXIT_OK, UsageError, reading
from .inputs import load_config
from .outputs import checked_file, is_hdf5


def cmd_config(args):
    """``mcfric config``: the complete, commented configuration on stdout; of a results
    file (complete or partial), the configuration it was run with, as stored (no
    comments)."""
    from ..store import partial_path

    path = Path(args.source) if args.source is not None else None
    if path is not None and not path.exists() and partial_path(path).exists():
        path = partial_path(path)
    if path is not None and path.is_file() and is_hdf5(path):
        a, _ = checked_file(path)
        out = str(path).removesuffix(".partial")
        how = (f"mcfric run THIS.toml -o {out} --resume continues an interrupted one"
               if int(a.get("samples", 0)) else
               "a bounds file: mcfric bounds THIS.toml computes it again")
        text = a.get("config")
        if not isinstance(text, str):
            from .. import config

            # the TOML copy lost (an edited file): the JSON record is the one runs resume by
            try:
                text = config.validate(json.loads(a["config_json"])).toml(comments=False)
            except config.ConfigError as e:
                raise UsageError(f"{path}: stored configuration: {e}") from None
        sys.stdout.write(f"# the configuration of the run in {path}\n# ({how})\n\n{text}")
        return EXIT_OK
    cfg = load_config(args)
    sys.stdout.write(cfg.toml())
    return EXIT_OK


def cmd_info(args):
    """``mcfric info``: a summary of a results file (complete or partial)."""
    from ..indicator import file_report as indicator_report
    from ..metric import METRIC_UNITS
    from ..peaks import file_report as peak_report
    from ..peaks import report_text, unrefined_lines
    from ..store import StoreError, describe, iter_records, partial_path
    from ..store.lock import holder

    path = Path(args.file)
    if not path.exists() and partial_path(path).exists():
        path = partial_path(path)
    a, cfg = checked_file(path)
    try:
        d = describe(path)
        import numpy as np
        lo, hi, bad, nan, number = np.inf, -np.inf, 0, 0, 0
        if int(a.get("samples", 0)):
            for _, arr in iter_records(path, ["metric", "converged"]):
                m = arr["metric"][arr["converged"]]
                ok = np.isfinite(m)
                nan += int(np.count_nonzero(~ok))
                if ok.any():
                    lo, hi = min(lo, m[ok].min()), max(hi, m[ok].max())
                bad += int(np.count_nonzero(~arr["converged"]))
                number += int(np.count_nonzero(np.isfinite(arr["metric"][~arr["converged"]])))
    except StoreError as e:
        raise UsageError(str(e)) from None
    n = int(a.get("samples", 0))
    done = d.get("done", 0)
    m, ex, fr, sa = cfg["model"], cfg["excitation"], cfg["frequency"], cfg["sampling"]
    nd = m["n_beams"] - (1 if m["topology"] == "linear" else 0)
    final = str(path).removesuffix(".partial")
    writer = None if a.get("complete") == 1 else holder(final)
    state = (f"complete, but not renamed to {final}: stopped as it finished ("
             + ("the command that started it with --resume renames it)" if "done" in d
                else f"rename it to {Path(final).name})")
             if a.get("complete") == 1 and str(path).endswith(".partial") else
             "complete" if a.get("complete") == 1 else
             f"INCOMPLETE: {done} of {n} samples done; being written now by {writer}"
             if writer else
             f"INCOMPLETE: {done} of {n} samples done; continue it with the command "
             f"that started it and --resume, or with `mcfric config {path} > run.toml` "
             f"and `mcfric run run.toml -o {final} --resume`")

    def dist(t):
        from ..sampling import DISTRIBUTIONS
        names = DISTRIBUTIONS[t["dist"]][1]
        return f"{t['dist']}(" + ", ".join(f"{k}={t[k]:g}" for k in names) + ")"
    q = cfg["metric"]["quantity"]
    pts = done * fr["n"]
    lines = [
        f"file:        {path} ({state})",
        f"model:       {m['name']}: {m['n_beams']} beams, {nd} damper{'s' * (nd != 1)}, "
        f"{m['topology']}; "
        f"excitation {ex['pattern']}, F0 = {ex['F0']:g} N",
        f"frequencies: {fr['n']}, {fr['f_min']:g} to {fr['f_max']:g} Hz ({fr['spacing']})",
        (f"sampling:    {n} samples, seed {sa['seed']}; " if n else
         "sampling:    none (a bounds file: no members); the bounds' limits from ")
        + f"mu0 ~ {dist(sa['mu0'])}, kc ~ {dist(sa['kc'])} N/m, N0 ~ {dist(sa['N0'])} N"
        + (f", mistuning {sa['mistuning']:g} per {sa['mistuning_per']}"
           if sa["mistuning"] else ""),
    ]
    if n:
        lines += [f"converged:   {pts - bad:,} of {pts:,} points ({bad:,} not converged)",
                  (f"metric:      {q} {METRIC_UNITS[q]}, {lo:.4g} to {hi:.4g}" if lo <= hi
                   else f"metric:      {q}, no converged points")]
    else:
        lines.append(f"metric:      {q} {METRIC_UNITS[q]}")
    if nan:
        lines.append(f"WARNING:     {nan:,} points marked converged hold no finite metric "
                     "(the file was edited or damaged; they are left out above)")
    if number:
        lines.append(f"WARNING:     {number:,} points marked not converged hold a number (the "
                     "file was edited or damaged; left out above, as not converged)")
    stored = a.get("n_not_converged", -1)
    if a.get("complete") == 1 and n and int(stored) >= 0 and int(stored) != bad:
        lines.append(f"WARNING:     the file's attribute n_not_converged = {int(stored):,}, "
                     f"but {bad:,} points are marked not converged (the file was edited "
                     f"or damaged)")
    report = reading(path, peak_report, path)
    if report is not None:
        lines += report_text(report, METRIC_UNITS[q])
    else:
        # members without refined peaks, or a bounds file: the bound's peak alone, when
        # it was refined
        from ..peaks import bound_peak, bound_peak_lines

        if n:
            lines += unrefined_lines(int(cfg["solver"]["harmonics"]))
        lines += bound_peak_lines(reading(path, bound_peak, path), METRIC_UNITS[q])
    lines += reading(path, indicator_report, path)
    from ..bounds import read_bounds
    B = reading(path, read_bounds, path)
    if B is not None:
        # what run and bounds printed: the searched line, witnesses past it, the certificate
        text = B.summary() + ("" if B.certificate is not None else
                              "\nnot certified (--no-certify)")
        lines += [("bounds:      " if n == 0 else " " * 13) + t
                  for n, t in enumerate(text.splitlines())]
    if a.get("complete") == 1 and "wall_time_s" in a:
        b = float(a.get("bounds_time_s", 0.0))    # files before 2026-11-30 have none
        of = f"bounds {b:.1f} s, " if b > 0 else ""
        lines.append(f"run time:    {a['wall_time_s']:.1f} s ({of}kernel "
                     f"{a.get('kernel_time_s', float('nan')):.1f} s) in the session "
                     f"that completed it")
    # what wrote the file (bounds files before 2026-11-30 record the mcfric version only)
    lines.append(f"written by:  mcfric {a.get('mcfric_version')}" + "".join(
        f", {name} {a[key]}" for name, key in (("numba", "numba_version"),
                                              ("numpy", "numpy_version"),
                                              ("HDF5", "hdf5_version")) if key in a)
        + (f"; created {a['created_utc']}" if "created_utc" in a else ""))
    lines.append("datasets:")
    for name, (dims, shape, dtype) in d["datasets"].items():
        lines.append(f"  {name:<20} {'(' + ', '.join(dims) + ')':<26} "
                     f"{' x '.join(map(str, shape)):<18} {dtype}")
    if B is not None:
        from ..store import read_group

        names = sorted(reading(path, read_group, path, "bounds")[0])
        lines.append(f"  bounds/ (group)      {len(names)} datasets per frequency: "
                     + ", ".join(names))
    print("\n".join(lines))
    return EXIT_OK
