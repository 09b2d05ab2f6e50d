"""``mcfric hbm``: one harmonic-balance sweep into a CSV file and its figure."""

from __future__ import annotations

from .errors import EXIT_OK, UsageError
from .inputs import check_friction_flag, check_slip_flags, load_config
from .outputs import output_path


def cmd_hbm(args):
    """``mcfric hbm``: one deterministic parameter set, to a CSV file and a figure."""
    import numpy as np

    from .. import hbm, plot
    from ..metric import METRIC_UNITS, omega_power
    from ..threads import interruptible

    spec = load_config(args).spec
    for flag, v in (("mu0", args.mu0), ("kc", args.kc), ("N0", args.N0)):
        check_friction_flag(flag, v)
    check_slip_flags(args.mu0, args.N0)
    out = output_path(args, ".csv", prefix="hbm-", figure=not args.no_figure)
    model, f = spec.model, spec.freq_hz
    H = spec.solver.harmonics
    try:
        res = interruptible(hbm.solve, model, f, args.mu0, args.kc, args.N0,
                            tol=spec.solver.tol, max_iter=spec.solver.max_iter,
                            n_threads=spec.execution.threads, harmonics=H,
                            n_time=spec.solver.n_time)
    except ValueError as e:
        raise UsageError(str(e).splitlines()[0]) from None
    q = spec.metric.quantity
    unit = METRIC_UNITS[q]
    amp = np.abs(res.response[0])                       # (n_f, n_beams), m
    metric = res.metric(q, spec.metric.beams)[0]
    conv = res.converged[0]
    s = res.s[0]
    header = (["frequency_hz"] + [f"abs_y{b + 1}_m" for b in range(model.n_beams)]
              + [f"metric_{unit.replace('/', '_per_').replace('^', '')}", "converged"]
              + [f"s{j + 1}" for j in range(model.n_dampers)])
    table = np.column_stack([f, amp, metric, conv.astype(float), s])
    fmt = ["%.10g"] + ["%.10e"] * (model.n_beams + 1) + ["%d"] + ["%.10e"] * model.n_dampers
    if H > 1:
        # the fundamental above; the full-period peak (all harmonics) after
        header += ([f"peak_y{b + 1}_m" for b in range(model.n_beams)]
                   + ["from_above", "from_rest"])
        table = np.column_stack([table, res.response_peak[0],
                                 res.from_above[0].astype(float),
                                 res.from_rest[0].astype(float)])
        fmt += ["%.10e"] * model.n_beams + ["%d", "%d"]
    from ..store import replacing

    with replacing(out, "CSV") as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    bad = int(np.count_nonzero(~conv))
    print(f"mcfric hbm: {model.name}, mu0 = {args.mu0:g}, kc = {args.kc:g} N/m, "
          f"N0 = {args.N0:g} N, F0 = {model.excitation.F0:g} N; {len(f)} frequencies "
          f"{f[0]:g}-{f[-1]:g} Hz; " + ("single-harmonic" if H == 1 else
                                          f"odd harmonics 1..{H} (abs_y: the fundamental)")
          + _tables_note(model, spec.mistuned))
    print(f"not converged: {bad} of {len(f)} points"
          + (f" (at {', '.join(f'{x:.4g}' for x in f[~conv][:10])} Hz"
             f"{', ...' if bad > 10 else ''}; not drawn)" if bad else ""))
    up = int(np.count_nonzero(res.from_above[0]))
    if up:
        print(f"from above: {up} points converged only from the next frequency's solution "
              f"(column from_above)")
    rest = int(np.count_nonzero(res.from_rest[0]))
    if rest:
        print(f"from rest: {rest} points converged only from rest, raising the drive at "
              f"their frequency (column from_rest)")
    print(f"csv: {out}")
    if not args.no_figure:
        png = out.with_suffix(".png")
        # the beams in the metric's quantity: one axis, one unit (the CSV keeps metres)
        plot.hbm_figure(f, amp * omega_power(f, q)[:, None], metric, conv, png,
                        title=f"{model.name}: mu0 = {args.mu0:g}, kc = {args.kc:g} N/m, "
                              f"N0 = {args.N0:g} N, F0 = {model.excitation.F0:g} N"
                              + (f" ({bad} non-converged points not drawn)" if bad else ""),
                        metric_label=f"M [{unit}]",
                        ylabel=f"{q} amplitude at the output [{unit}]"
                               + (" (fundamental)" if H > 1 else ""))
        print(f"figure: {png}")
    return EXIT_OK


def _tables_note(model, mistuned):
    """What the header line adds where the beams are not all alike: the name is free text
    (often the preset's), so it does not say so itself."""
    import numpy as np

    first = model.beams[0]

    def same(t):
        return (t.positions == first.positions and np.array_equal(t.freq_hz, first.freq_hz)
                and np.array_equal(t.zeta, first.zeta)
                and np.array_equal(t.shapes, first.shapes))

    own = [b + 1 for b, t in enumerate(model.beams) if not same(t)]
    note = ""
    if own:
        shown = ", ".join(map(str, own[:8])) + (", ..." if len(own) > 8 else "")
        note = (f"; beam{'s' if len(own) > 1 else ''} {shown} with a modal table unlike "
                f"beam 1's")
    if mistuned:
        # hbm solves the nominal tables; the drawn frequencies belong to a run's members
        note += "; sampling.mistuning not applied (the nominal tables)"
    return note
