"""``mcfric bounds``: the response bounds alone, into a bounds file."""

from __future__ import annotations

from .errors import EXIT_OK, UsageError, interrupted_after
from .inputs import load_config, settings_notes
from .outputs import only_replacing_bounds, output_path


def cmd_bounds(args):
    """``mcfric bounds``: the response bounds alone, into a bounds file, and a figure."""
    import time

    from .. import bounds, plot
    from ..store.lock import LockError, OutputLock

    cfg = load_config(args, {"bounds.enabled": True})
    spec = cfg.spec
    out = output_path(args, ".h5", prefix="bounds-", figure=not args.no_figure)
    model, f, lim = spec.model, spec.freq_hz, spec.bounds
    lock = OutputLock(out, "mcfric bounds")
    try:
        lock.acquire()
    except LockError as e:
        raise UsageError(str(e)) from None
    written = False
    try:
        try:
            only_replacing_bounds(out)
            print(f"mcfric bounds: {model.name}, {len(f)} frequencies {f[0]:g}-{f[-1]:g} Hz, "
                  f"F0 = {model.excitation.F0:g} N; box 0 <= Re K <= {lim.k_max_re:g} N/m, "
                  f"0 <= Im K <= {lim.k_max_im:g} N/m, F_lim = {lim.F_lim:g} N", flush=True)
            # the tables this command reads: the ensemble's settings are not its business
            settings_notes(cfg, ("bounds", "peaks", "excitation"))
            t = time.perf_counter()
            B = bounds.from_spec(spec, progress=False if args.no_progress else None)
            print(f"{B.summary()} ({time.perf_counter() - t:.1f} s)")
            peak = None
            if spec.peaks:
                # as a run's bounds group has it: the upper bound's peak between grid points
                from ..bounds.peak import peak_attrs

                peak = peak_attrs(model, B, spec.peaks.rtol)
            bounds.write_bounds_file(out, cfg, B, peak=peak)
            written = True
            from ..metric import METRIC_UNITS
            from ..peaks import bound_peak, bound_peak_lines

            for line in bound_peak_lines(bound_peak(out), METRIC_UNITS[spec.metric.quantity]):
                print(line)
        finally:
            lock.release()
        print(f"bounds: {out}")
        if not args.no_figure:
            png = out.with_suffix(".png")
            plot.results_figure(out, png)
            print(f"figure: {png}")
    except KeyboardInterrupt:
        if not written:
            raise
        return interrupted_after(out, "the lines or the figure")
    return EXIT_OK
