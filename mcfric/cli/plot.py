"""``mcfric plot``: the figure of a results file, with measured data against the bounds."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from .errors import EXIT_OK, UsageError, reading
from .outputs import checked_file, file_name, no_such_file, not_replacing_hdf5, writable_dir


def cmd_plot(args):
    """``mcfric plot``: the figure of a results or bounds file, measured data on top."""
    from .. import plot
    from ..store import partial_path
    from ..validators import InputError

    path = Path(args.file)
    if not path.exists():
        if partial_path(path).exists():
            raise UsageError(f"{path}: the run is not complete ({partial_path(path).name} "
                             f"holds it; continue it with --resume)")
        raise UsageError(no_such_file(path))
    attrs = checked_file(path)[0]
    if attrs.get("complete") != 1:
        raise UsageError(f"{path}: the run is not complete (continue it with --resume)")
    # a results file reached through a link has its figure beside it, at the target
    out = (file_name(args.output) if args.output is not None
           else (Path(os.path.realpath(path)) if path.is_symlink() else path).with_suffix(".png"))
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise UsageError(f"-o: expected a .png, .pdf or .svg file, got {out.name}")
    if not out.parent.is_dir():
        raise UsageError(f"-o: directory {out.parent} does not exist")
    if out.is_dir():
        raise UsageError(f"-o: {out} is a directory")
    writable_dir(out)
    not_replacing_hdf5(out, "figure")
    window = None
    if args.f_min is not None or args.f_max is not None:
        from ..store import read
        f = read(path, "frequency")
        window = (args.f_min if args.f_min is not None else f.min(),
                  args.f_max if args.f_max is not None else f.max())
        for flag, v in (("--f-min", args.f_min), ("--f-max", args.f_max)):
            if v is not None and not (math.isfinite(v) and v >= 0):
                raise UsageError(f"{flag}: expected a frequency >= 0 Hz, got {v:g}")
        if not window[0] < window[1]:
            flag = "--f-min" if args.f_min is not None else "--f-max"
            raise UsageError(f"{flag}: expected f-min < f-max, got {window[0]:g} and "
                             f"{window[1]:g} Hz")
    n = int(attrs.get("samples", 0))
    if not n and args.member is not None and args.member >= 0:
        raise UsageError(f"--member: {path} holds no members (a bounds file)")
    args.member = 0 if args.member is None else args.member
    if n and not -1 <= args.member < n:
        raise UsageError(f"--member: expected -1 (none) or a member in 0..{n - 1}, "
                         f"got {args.member}")
    measured = _read_measured(args, attrs)

    def figure(*a, **k):
        try:
            return plot.results_figure(*a, **k)
        except InputError as e:
            # bad arguments, not a bad file; the Python arguments' names are the flags'
            flag = {"f_window": "--f-min/--f-max", "member": "--member"}.get(e.key, e.key)
            raise UsageError(f"{flag}: {e.message}") from None

    drawn = reading(path, figure, path, out, quantity=args.quantity, f_window=window,
                    member=None if args.member < 0 else args.member, measured=measured,
                    indicator=not args.no_indicator)
    gaps = drawn["n_not_converged"]
    grid = drawn["n_peaks_unrefined"]
    n, has_bounds = drawn["n_members"], drawn["has_bounds"]
    what = ("bounds only" if not n else f"{drawn['n_drawn']} of {n} members drawn"
            + (", bounds" if has_bounds else ", no bounds in the file"))
    print(f"figure: {out} ({what}"
          + (f"; {gaps:,} point{'s' if gaps > 1 else ''} not converged, left as gaps"
             if gaps else "")
          + (f"; {grid} member peak{'s' if grid > 1 else ''} not refined, drawn as circles"
             if grid else "")
          + (f"; {low} lower estimate{'s' if low > 1 else ''} beside a fold, drawn as "
             f"triangles" if (low := drawn["n_fold_lower"]) else "") + ")")
    if measured and has_bounds:
        _print_inside(path, measured, args.quantity, window)
    elif measured:
        print("measured data drawn; not compared (the file has no bounds)")
    return EXIT_OK


def _read_measured(args, attrs):
    """Measurements of ``--measured`` (normalised to the file's F0 with --normalise)."""
    if not args.measured:
        given = [flag for flag, v in (("--nodes", args.nodes), ("--normalise", args.normalise),
                                      ("--measured-quantity", args.measured_quantity),
                                      ("--measured-force", args.measured_force),
                                      ("--measured-direction", args.measured_direction))
                 # a flag given as 0 is given (and 0.0 == False: compare identity)
                 if v is not None and v is not False]
        if given:
            raise UsageError(f"{given[0]}: applies to --measured data, and none is given")
        return []
    from .. import measured as ms
    from ..uff import UFF_SUFFIXES

    if args.nodes and not any(Path(d).suffix.lower() in UFF_SUFFIXES
                              for d in args.measured):
        raise UsageError("--nodes: maps UFF response nodes to beams; no --measured file is "
                         "UFF (CSV columns name their beams)")
    if args.measured_force is not None and not (math.isfinite(args.measured_force)
                                                and args.measured_force > 0):
        raise UsageError(f"--measured-force: expected a force > 0 N, got "
                         f"{args.measured_force:g}")

    nodes = None
    if args.nodes:
        try:
            parts = args.nodes.split(",")
            if any(":" in x for x in parts):
                # NODE:BEAM pairs; beam 0 is the metric M (an exported percentile record)
                nodes = {int(n): int(b) for n, b in (x.split(":") for x in parts)}
            else:
                nodes = [int(x) for x in parts]
        except ValueError:
            raise UsageError(f"--nodes: expected comma-separated node numbers (beam 1, 2, "
                             f"...) or NODE:BEAM pairs (BEAM 0: the metric M), got "
                             f"{args.nodes!r}") from None
    cfg = json.loads(attrs.get("config_json", "{}"))
    F0 = cfg.get("excitation", {}).get("F0")
    n_beams = cfg.get("model", {}).get("n_beams")
    seen = set()
    for data in args.measured:
        key = Path(data).resolve()
        if key in seen:
            raise UsageError(f"--measured: {data} is given twice (its points would count "
                             f"twice)")
        seen.add(key)
    out, reports = [], []
    for data in args.measured:
        try:
            ms_list = ms.read_measured(data, nodes=nodes, quantity=args.measured_quantity,
                                       force_n=args.measured_force,
                                       direction=args.measured_direction)
        except (ValueError, ImportError) as e:
            msg = str(e).splitlines()[0]
            if nodes is None and "pass nodes=" in msg:
                # the API's words (nodes={102: 1}) said as the command line's flag
                found = msg[msg.find("(response nodes"):]
                msg = (f"{data}: give --nodes N1,N2,... (the UFF response node of beam 1, "
                       f"2, ...) {found}")
            raise UsageError(msg) from None
        for m in ms_list:
            extra = [b for b in m.beams if n_beams and b > n_beams]
            if extra:
                raise UsageError(f"{data}: beam {extra[0]} is measured, but the model has "
                                 f"{n_beams} beams")
            if args.normalise:
                if m.force_n is None:
                    raise UsageError(f"--normalise: {data} gives no force level (force_n)")
                try:
                    m, report = ms.normalise(m, F0)
                except ValueError as e:
                    msg = str(e) if m.source else f"{data}: {e}"    # the file named once
                    raise UsageError(f"--normalise: {msg}") from None
                # printed once all are read (a refusal prints nothing else), once each
                if report.text() not in reports:
                    reports.append(report.text())
            elif m.force_n is not None and F0 and abs(m.force_n - F0) > 1e-6 * F0:
                raise UsageError(f"--measured: {data} was measured at {m.force_n:g} N, the "
                                 f"file is for F0 = {F0:g} N: pass --normalise to rescale "
                                 f"it (docs: measured data)")
            elif m.force_n is None and F0:
                # nothing to check it against: said, not assumed silently
                note = (f"note: {data} gives no force level: compared as if measured at "
                        f"F0 = {F0:g} N (--measured-force N says at which)")
                if note not in reports:
                    reports.append(note)
            out.append(m)
    for text in reports:
        print(text)
    return out


def _print_inside(path, measured, quantity, window=None):
    """Fraction of measured points inside the bounds (within the plot's window): each of
    the metric's beams against the upper bound, the measured metric against both bounds
    where every beam of the metric is measured (the lower bound of M bounds the largest
    beam only), else against the upper one. The certified bounds where the file has them
    (the band the figure draws), else the searched ones; the first line says which, and
    that between grid frequencies the bounds are interpolated."""
    import numpy as np

    from .. import measured as ms
    from ..bounds import read_bounds
    from ..metric import omega_power
    from ..store import read_attrs

    B = read_bounds(path)
    q = quantity or B.quantity
    scale = omega_power(B.freq_hz, q, B.quantity)
    C = B.certificate
    lo, up = (C.lower, C.upper) if C is not None else (B.lower, B.upper)
    lo, up, g = lo * scale, up * scale, B.freq_hz
    if window is not None:
        # the grid inside the window and one frequency beyond each edge, so that every
        # measured point in the window lies between grid frequencies
        i0 = max(int(np.searchsorted(g, window[0], "right")) - 1, 0)
        i1 = min(int(np.searchsorted(g, window[1], "left")), len(g) - 1)
        lo, up, g = lo[i0:i1 + 1], up[i0:i1 + 1], g[i0:i1 + 1]
    n_beams = json.loads(read_attrs(path)["config_json"])["model"]["n_beams"]
    beams = tuple(b + 1 for b in B.beams) or tuple(range(1, n_beams + 1))
    step = float(np.median(np.diff(g)))
    print("measured data against the " + ("certified bounds (lower_certified, "
                                          "upper_certified)" if C is not None else
                                          "searched bounds (the file has no certified ones)")
          + f", which hold at the {g.size} grid frequencies ({step:.3g} Hz apart) and are "
          f"interpolated between them" + (f", {window[0]:g}-{window[1]:g} Hz"
                                          if window is not None else ""))
    if window is not None:
        kept = [_in_window(m, window) for m in measured]
        out = sum(n for _, n in kept)
        measured = [m for m, _ in kept if m is not None]
        if out:
            print(f"{out} measured points outside {window[0]:g}-{window[1]:g} Hz (not "
                  f"compared)")
    parts = ms.metric_parts([m.to_quantity(q) for m in measured], beams)
    if not (parts.single or parts.full):
        print(f"measured data drawn; not compared (no measured beam is one of the metric's "
              f"beams {', '.join(map(str, beams))})")
        return
    if parts.single:
        sk = parts.skipped
        print("each beam against the upper bound only (the lower bound of M bounds the "
              "largest beam, not every beam)"
              + (f"; beam{'s' if len(sk) > 1 else ''} {', '.join(map(str, sk))} "
                 f"{'are' if len(sk) > 1 else 'is'} not in the metric and not compared"
                 if sk else "") + ":")
        print(_inside_or_none(ms.fraction_inside(parts.single, g, lo, up, quantity=q,
                                                 check_lower=False)))
    if parts.full:
        print("the measured metric M (max over the beams) against both bounds:")
        print(_inside_or_none(ms.fraction_inside(parts.full, g, lo, up, quantity=q)))
    if parts.part:
        print(f"the largest measured beam against the upper bound only, where not every "
              f"beam of the metric ({', '.join(map(str, beams))}) is measured: M could be "
              f"larger; 'M' below is that largest beam:")
        print(_inside_or_none(ms.fraction_inside(parts.part, g, lo, up, quantity=q,
                                                 check_lower=False)))


def _in_window(m, window):
    """``m`` with only its points inside ``window`` (Hz), or None, and how many were cut."""
    from dataclasses import replace

    import numpy as np

    keep = (m.frequency_hz >= window[0]) & (m.frequency_hz <= window[1])
    cut = int(np.count_nonzero(~keep & ~np.all(np.isnan(np.abs(m.response)), axis=1)))
    if not keep.any():
        return None, cut
    return replace(m, frequency_hz=m.frequency_hz[keep], response=m.response[keep]), cut


def _inside_or_none(inside):
    """The line of an :class:`~mcfric.measured.Inside`, or a plain statement that no
    point was compared."""
    if not inside.compared():
        return ("no measured point compared (all outside the bounds' frequencies or "
                "without a value)")
    return inside.text()
