"""``mcfric verify``: harmonic balance against time integration, at given frequencies."""

from __future__ import annotations

import json
import math
from pathlib import Path

from .errors import EXIT_OK, UsageError
from .inputs import check_friction_flag, check_slip_flags, load_config
from .outputs import checked_file, is_hdf5, output_path


def _verify_source(args):
    """Model and parameters of ``mcfric verify``: a preset/config and the flags, or a
    results file's configuration and one member's parameters. Returns ``(model, params,
    stem, spec)``: ``stem`` only for a file; ``spec`` the validated run specification (a
    file's stored one)."""
    import numpy as np

    from .. import config

    src = args.source
    # by content: run writes any -o name (out.H5, x)
    if src is not None and (src.endswith((".h5", ".h5.partial"))
                            or (Path(src).is_file() and is_hdf5(src))):
        from ..store import partial_path, read
        if not Path(src).exists() and partial_path(src).exists():
            raise UsageError(f"{src}: no such file; {partial_path(src).name} holds the "
                             f"interrupted run (give that name to verify its members done)")
        attrs = checked_file(src)[0]       # a damaged or foreign file: one line, exit 2
        n = int(attrs.get("samples", 0))
        if n == 0:
            # said first: asking for --member would send the user to a second refusal
            raise UsageError(f"{src}: no members (a bounds file); give a results file of a run")
        if args.member is None:
            raise UsageError("--member: a results file needs --member I (0-based)")
        for flag in ("mu0", "kc", "N0", "F0"):
            if getattr(args, flag) is not None:
                raise UsageError(f"--{flag}: taken from the results file; not with a FILE")
        try:
            spec = config.validate(json.loads(attrs["config_json"])).spec
        except config.ConfigError as e:
            raise UsageError(f"{src}: stored configuration: {e}") from None
        if spec.mistuned:
            raise UsageError(f"{src}: verify does not take mistuned members yet")
        if not 0 <= args.member < n:
            raise UsageError(f"--member: expected an integer in 0..{n - 1}, got {args.member}")
        # a member not done holds the fill value (0), not NaN: ``done`` says which are
        params = [read(src, k)[args.member] for k in ("mu0", "kc", "N0")]
        if (read(src, "done")[args.member] != 1
                or not all(np.all(np.isfinite(p)) for p in params)):
            raise UsageError(f"--member: member {args.member} is not in the file (not done)")
        return spec.model, params, Path(src).stem, spec
    if args.member is not None:
        given = f"; {args.source} is not one" if args.source else ""
        raise UsageError(f"--member: only with a results file (FILE.h5){given}")
    spec = load_config(args).spec
    params = []
    for flag, default in (("mu0", 0.5), ("kc", 6000.0), ("N0", 0.5)):
        v = getattr(args, flag)
        v = default if v is None else v
        check_friction_flag(flag, v)
        params.append(v)
    check_slip_flags(params[0], params[2])
    return spec.model, params, None, spec


#: ``verify FILE --f HZ``: a frequency this close (relative) to one of the run's grid
#: frequencies is taken as that one (the run summary prints them to 4 digits)
GRID_MATCH = 1e-3


def _stored_points(path, member, freqs, quantity):
    """What a results file holds for ``member`` at each verified frequency: verify solves
    its harmonic balance afresh (the run's tolerance and iterations, a short sweep over the
    frequencies given, each started from the one before), so the lines say what that is
    compared with, or that there is nothing.

    Returns the frequencies to verify (a typed one within ``GRID_MATCH`` of a grid
    frequency, and nearer to it than to its neighbours, becomes that grid frequency), the
    lines to print, and the stored metric at each of them where the run converged there
    (a dict, frequency -> M).
    """
    import numpy as np

    from ..metric import METRIC_UNITS
    from ..store import dataset_names, read

    f = read(path, "frequency")
    conv = read(path, "converged", member)
    metric = read(path, "metric", member)
    names = dataset_names(path)
    above, rest = (read(path, name, member) if name in names else np.zeros(len(f), bool)
                   for name in ("from_above", "from_rest"))
    lines = [f"file: member {member}'s harmonic balance here is solved afresh (the run's "
             f"tolerance and iterations, a short sweep over the frequencies given, each "
             f"started from the one before, a failed one again from its neighbours: near "
             f"a fold it may reach another branch than the run's sweep over its grid)"]

    def snap(fk):
        """The nearest grid frequency's index, and whether ``fk`` is that frequency
        (``"exact"``), is taken as it (``"near"``), or neither (None)."""
        k = int(np.argmin(np.abs(f - fk)))
        step = np.min(np.abs(np.diff(f)[max(k - 1, 0):k + 1])) if len(f) > 1 else np.inf
        if abs(f[k] - fk) <= 1e-12 * fk:
            return k, "exact"
        near = abs(f[k] - fk) <= GRID_MATCH * fk and abs(f[k] - fk) < step / 2
        return k, ("near" if near else None)

    # refused with their own message before any work: not snapped
    snapped = [snap(fk) if math.isfinite(fk) and fk > 0 else (None, None) for fk in freqs]
    on_grid = {k for k, how in snapped if how}
    out = []
    stored = {}
    for fk, (k, how) in zip(freqs, snapped):
        if k is None:
            out.append(fk)
            continue
        if how == "exact":
            fk = float(f[k])
        elif how == "near":
            lines.append(f"file: --f {fk:g} Hz taken as the run's grid frequency "
                         f"{f[k]:.10g} Hz")
            fk = float(f[k])
        else:
            lines.append(f"file: {fk:g} Hz is not a grid frequency of the run (nearest "
                         f"{f[k]:.10g} Hz)")
            out.append(fk)
            continue
        out.append(fk)
        if not conv[k]:
            lines.append(f"file: at {fk:.10g} Hz the run did not converge (no value stored)")
        else:
            lines.append(f"file: at {fk:.10g} Hz the run stored M = {metric[k]:.6g} "
                         f"{METRIC_UNITS[quantity]} ({quantity}, the run's metric)")
            stored[fk] = float(metric[k])
            if above[k]:
                nxt = (f"; add its next grid frequency, --f {fk:.10g} {f[k + 1]:.10g}, to "
                       f"start there too" if k + 1 < len(f) and k + 1 not in on_grid
                       else "")
                lines.append(f"file: the run reached {fk:.10g} Hz only from its solution at "
                             f"the next grid frequency (from_above){nxt}")
            if rest[k]:
                lines.append(f"file: the run reached {fk:.10g} Hz only from rest, raising "
                             f"the drive there (from_rest): on the branch connected to rest")
    return out, lines, stored


def _compared_with_stored(vs, stored, spec, harmonics):
    """Lines comparing the metric of the balance verify solved with the value the run
    stored, at each verified grid frequency where the run converged: whether verify's
    table shows the file's solution (the same to the solver's tolerance), another branch
    of the same equations, or (``harmonics`` not the run's) another truncation."""
    import numpy as np

    from ..metric import response_metric

    H_run = spec.solver.harmonics
    if H_run > 1 and harmonics != H_run:
        return [f"file: the run balanced H = {H_run}, verify H = {harmonics} (--harmonics): "
                f"its multi-harmonic columns are another truncation, not the file's values"]
    lines = []
    for v in vs:
        if v.freq_hz not in stored:
            continue
        y = v.single if H_run == 1 else v.multi[0]
        m = float(response_metric(y[None, :], np.array([v.freq_hz]), spec.metric.quantity,
                                  spec.metric.beams)[0])
        what = "single-harmonic" if H_run == 1 else f"H = {H_run}"
        if not np.isfinite(m):
            lines.append(f"file: at {v.freq_hz:.10g} Hz the {what} balance solved here did "
                         f"not converge: the stored value is not checked against it")
            continue
        ref = stored[v.freq_hz]
        rel = abs(m - ref) / max(abs(ref), abs(m)) if max(abs(ref), abs(m)) > 0 else 0.0
        # both solve the equations to the solver's tolerance: closer than that (with a
        # floor for rounding) is one solution
        same = (f"the stored value's solution ({rel:.1e} from it)"
                if rel <= max(1e-6, 10 * spec.solver.tol) else
                f"{100 * rel:.3g} % from the stored value: a solution (branch) of the same "
                f"equations other than the run's")
        lines.append(f"file: at {v.freq_hz:.10g} Hz the {what} balance solved here gives "
                     f"M = {m:.6g}, {same}")
    return lines


def cmd_verify(args):
    """``mcfric verify``: time integration against harmonic balance at a few points."""
    import numpy as np

    from .. import plot
    from ..verify import MAX_PERIODS_CAP, time_steps, verify

    if not 1 <= args.max_periods <= MAX_PERIODS_CAP:
        raise UsageError(f"--max-periods: expected an integer in 1..{MAX_PERIODS_CAP}, got "
                         f"{args.max_periods}")
    from ..hbm import MAX_HARMONICS

    if args.harmonics is not None and (not 3 <= args.harmonics <= MAX_HARMONICS
                                       or args.harmonics % 2 == 0):
        # the single-harmonic solution is compared in any case
        raise UsageError(f"--harmonics: expected an odd integer in 3..{MAX_HARMONICS} (the "
                         f"odd harmonics 1, 3, ..., H are balanced beside the "
                         f"single-harmonic solution), got {args.harmonics}")
    model, (mu0, kc, N0), stem, spec = _verify_source(args)
    H_run = spec.solver.harmonics
    # by default the run's own balance, so that the table shows the file's values
    harmonics = args.harmonics or (H_run if H_run > 1 else 9)
    lines, stored = [], {}
    if stem is not None:
        args.f, lines, stored = _stored_points(args.source, args.member, args.f,
                                               spec.metric.quantity)

    def usage(e):
        msg = str(e).splitlines()[0]
        if msg.startswith("kc:") and stem is None:      # typed as --kc, not from a file
            return UsageError("--" + msg)
        return UsageError("--f:" + msg[8:] if msg.startswith("freq_hz:") else msg)
    try:
        time_steps(model, args.f, kc)           # before any output is made
    except ValueError as e:
        raise usage(e) from None
    # the default name of a file's member too goes through the checks (an HDF5 file at
    # mcfric-results/verify-NAME.csv was overwritten)
    out = output_path(args, ".csv", prefix="verify-", figure=not args.no_figure)
    try:
        # the harmonic balance with the run's tolerance, iterations and (its H) AFT samples
        vs = verify(model, args.f, mu0, kc, N0, harmonics=harmonics, start=args.start,
                    max_periods=args.max_periods, progress=not args.no_progress,
                    hb_tol=spec.solver.tol, hb_max_iter=spec.solver.max_iter,
                    hb_n_time=spec.solver.n_time if harmonics == H_run else None)
    except ValueError as e:
        raise usage(e) from None
    label = (f"mu0 = {np.ravel(mu0)[0]:g}, kc = {np.ravel(kc)[0]:g} N/m, "
             f"N0 = {np.ravel(N0)[0]:g} N" if np.size(mu0) == 1 or np.ptp(mu0) == 0 else
             "parameters per damper")
    if stem is not None:        # the figure's title named no member (nor the file)
        label = f"member {args.member} of {Path(args.source).name}, {label}"
    print(f"mcfric verify: {model.name}, {label}, F0 = {model.excitation.F0:g} N; "
          f"time integration against harmonic balance (H = 1 and H = {harmonics})")
    if stem is not None:
        lines += _compared_with_stored(vs, stored, spec, harmonics)
    for line in lines:
        print(line)
    rows = []
    for v in vs:
        print(v.table())
        d1, dm, d3 = v.differences()       # NaN where not periodic
        for bb in range(model.n_beams):
            rows.append([v.freq_hz, bb + 1, int(v.periodic), v.periods,
                         *np.abs(v.harmonics[:, bb]), v.even[bb], v.peak[bb],
                         abs(v.single[bb]),
                         abs(v.multi[0, bb]), v.multi_peak[bb], d1[bb], dm[bb], d3[bb]])
    orders = vs[0].orders
    # one row per beam: columns named by harmonic (hbm's CSV names its beams y1, y2, ...)
    header = (["frequency_hz", "beam", "periodic", "periods"]
              + [f"time_harmonic{n}_m" for n in orders]
              + ["time_even_m", "time_peak_m", "h1_fundamental_m", "mhb_fundamental_m",
                 "mhb_peak_m", "diff_h1", "diff_mhb", "diff_mhb_harmonic3"])
    from ..store import replacing

    with replacing(out, "CSV") as tmp:
        np.savetxt(tmp, np.array(rows), delimiter=",", header=",".join(header),
                   comments="", fmt="%.10g")
    bad = sum(not v.periodic for v in vs)
    if bad:
        print(f"not periodic: {bad} of {len(vs)} frequencies (reported, not averaged)")
    # a harmonic-balance solve that did not converge is NaN in the table and the CSV
    h1 = sum(bool(np.isnan(v.single).any()) for v in vs)
    hm = sum(bool(np.isnan(v.multi).any()) for v in vs)
    if h1 or hm:
        print(f"harmonic balance not converged: H = 1 at {h1}, H = {harmonics} at {hm} "
              f"of {len(vs)} frequencies (NaN in the table and the CSV, no difference)")
    print(f"csv: {out}")
    if not args.no_figure:
        png = out.with_suffix(".png")
        plot.verify_figure(vs, png, title=f"{model.name}: {label}, "
                                          f"F0 = {model.excitation.F0:g} N")
        print(f"figure: {png}")
    return EXIT_OK
