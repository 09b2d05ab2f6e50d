"""``mcfric`` command line: wires config, ensemble, store and plots together.

::

    mcfric                                   # = mcfric run: the embedded default
    mcfric run [PRESET|CONFIG.toml] [-o FILE] [--samples N] [--seed S] [--resume]
               [--force] [--threads T] [--chunk N] [--F0 N] [--f-min HZ] [--f-max HZ]
               [--n-freq N] [--no-progress] [--no-figure]
    mcfric config [PRESET|CONFIG.toml]       # complete, commented TOML on stdout
    mcfric info FILE                         # summary of a results file
    mcfric hbm [PRESET|CONFIG.toml] [--mu0 X] [--kc N_PER_M] [--N0 N] [--F0 N]
               [--f-min HZ] [--f-max HZ] [--n-freq N] [-o OUT.csv] [--no-figure]

Exit codes: 0 done, 1 a run-time failure (e.g. disk full, unreadable file), 2 bad
configuration or arguments (one line on stderr, nothing written), 130 interrupted (the
finished chunks are kept; continue with ``--resume``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

DEFAULT_DIR = Path("mcfric-results")
EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
COMMANDS = ("run", "config", "info", "hbm")


class UsageError(Exception):
    """Bad input from the user: one line on stderr, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)   # --sample must not mean --samples
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise UsageError(f"{message} (see `{self.prog} --help`)")


def _source_help():
    return "a preset (two-beam, eight-beam) or a TOML configuration file"


def _parser():
    from . import __version__

    p = _Parser(prog="mcfric", description="Friction-damped beam arrays: harmonic balance, "
                "Monte Carlo ensembles. `mcfric` alone runs the default ensemble.")
    p.add_argument("--version", action="version", version=f"mcfric {__version__}")
    sub = p.add_subparsers(dest="command", metavar="{run,config,info,hbm}")

    r = sub.add_parser("run", help="run (or resume) a Monte Carlo ensemble",
                       description="Run a Monte Carlo ensemble into an HDF5 results file "
                       "(written as FILE.partial, renamed when complete) and draw its figure.")
    r.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")
    r.add_argument("-o", "--output", metavar="FILE",
                   help="results file (default: mcfric-results/<name>.h5)")
    r.add_argument("--samples", type=int, metavar="N", help="ensemble size")
    r.add_argument("--seed", type=int, metavar="S", help="root seed (>= 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue FILE.partial left by an interrupted run")
    r.add_argument("--force", action="store_true",
                   help="replace an existing FILE or FILE.partial holding another run")
    r.add_argument("--threads", type=int, metavar="T", help="numba threads (0 = all)")
    r.add_argument("--chunk", type=int, metavar="N", help="samples per chunk (0 = auto)")
    _model_flags(r)
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    r.add_argument("--no-figure", action="store_true", help="do not draw the figure")

    c = sub.add_parser("config", help="print a complete, commented configuration",
                       description="Print the complete, commented TOML configuration of a "
                       "preset (or the validated, complete form of a configuration file).")
    c.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")

    i = sub.add_parser("info", help="summarise a results file")
    i.add_argument("file", help="results file (FILE or FILE.partial)")

    h = sub.add_parser("hbm", help="one deterministic parameter set (like the paper's Fig. 5)",
                       description="Harmonic balance of one parameter set (the same for every "
                       "damper): writes a CSV and a PNG next to it.")
    h.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")
    h.add_argument("--mu0", type=float, default=0.5, help="friction coefficient (default 0.5)")
    h.add_argument("--kc", type=float, default=6000.0, metavar="N_PER_M",
                   help="tangential stiffness, N/m (default 6000)")
    h.add_argument("--N0", type=float, default=0.5, metavar="N",
                   help="normal preload, N (default 0.5)")
    _model_flags(h)
    h.add_argument("-o", "--output", metavar="OUT.csv",
                   help="CSV file (default: mcfric-results/hbm-<name>.csv); the PNG goes "
                        "next to it")
    h.add_argument("--no-figure", action="store_true", help="do not draw the figure")
    return p


def _model_flags(p):
    p.add_argument("--F0", type=float, metavar="NEWTONS",
                   help="excitation amplitude of the preset's pattern, N")
    p.add_argument("--f-min", type=float, metavar="HZ", help="lowest frequency, Hz")
    p.add_argument("--f-max", type=float, metavar="HZ", help="highest frequency, Hz")
    p.add_argument("--n-freq", type=int, metavar="N", help="number of frequencies")


def _overrides(args):
    o = {}
    for key, attr, flag in (("excitation.F0", "F0", "--F0"),
                            ("frequency.f_min", "f_min", "--f-min"),
                            ("frequency.f_max", "f_max", "--f-max"),
                            ("frequency.n", "n_freq", "--n-freq"),
                            ("sampling.samples", "samples", "--samples"),
                            ("sampling.seed", "seed", "--seed"),
                            ("run.threads", "threads", "--threads"),
                            ("run.chunk", "chunk", "--chunk")):
        if hasattr(args, attr):
            o[key] = (getattr(args, attr), flag)
    return o


def _load(args):
    from . import config

    try:
        return config.load(args.source, _overrides(args))
    except config.ConfigError as e:
        raise UsageError(str(e)) from None


def _default_output(args, suffix, prefix=""):
    from .presets import PRESETS

    if args.source is None:
        stem = "default"
    elif args.source in PRESETS:
        stem = args.source
    else:
        stem = Path(args.source).stem
    return DEFAULT_DIR / f"{prefix}{stem}{suffix}"


def _output_path(args, suffix, prefix=""):
    """The output path; the default directory is created, a given one must exist."""
    if args.output:
        out = Path(args.output)
        if not out.parent.is_dir():
            raise UsageError(f"-o: directory {out.parent} does not exist")
        if out.is_dir():
            raise UsageError(f"-o: {out} is a directory")
        return out
    out = _default_output(args, suffix, prefix)
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def cmd_run(args):
    from . import ensemble, plot

    cfg = _load(args)
    out = _output_path(args, ".h5")
    # every refusal (bad config, existing files) happens before anything is written
    try:
        model = cfg.model()
        print(f"mcfric run: {model.name}, {cfg.samples} samples x {cfg['frequency']['n']} "
              f"frequencies, {model.n_beams} beams, F0 = {model.excitation.F0:g} N, "
              f"seed {cfg.seed}", flush=True)
        summary = ensemble.run(cfg, out, resume=args.resume, force=args.force,
                               progress=not args.no_progress)
    except ensemble.RunError as e:
        raise UsageError(str(e)) from None
    except ensemble.Interrupted as e:
        s = e.summary
        print(f"interrupted: {s.samples_done} of {s.samples} samples saved in {s.path}; "
              f"continue with `mcfric run ... -o {out} --resume`", file=sys.stderr)
        return EXIT_INTERRUPTED
    if summary.already_complete:
        print(f"{out} already holds this run (same configuration and seed): nothing to do; "
              f"--force recomputes it")
    print(summary.text())
    if summary.complete and not args.no_figure:
        fig = getattr(plot, "ensemble_figure", None)   # the plotting stage may replace it
        if fig is not None:
            png = out.with_suffix(".png")
            fig(out, png)
            print(f"figure: {png}")
    return EXIT_OK


def cmd_config(args):
    cfg = _load(args)
    sys.stdout.write(cfg.toml())
    return EXIT_OK


def cmd_info(args):
    from . import ensemble
    from .store import StoreError, describe, iter_records, partial_path

    path = Path(args.file)
    if not path.exists() and partial_path(path).exists():
        path = partial_path(path)
    try:
        d = describe(path)
        a = d["attrs"]
        if "layout_version" not in a:
            raise UsageError(f"{path}: not an mcfric results file")
        cfg = json.loads(a["config_json"])
        import numpy as np
        lo, hi, bad = np.inf, -np.inf, 0
        for _, arr in iter_records(path, ["metric", "converged"]):
            m = arr["metric"][arr["converged"]]
            if m.size:
                lo, hi = min(lo, m.min()), max(hi, m.max())
            bad += int(np.count_nonzero(~arr["converged"]))
    except StoreError as e:
        raise UsageError(str(e)) from None
    n = int(a.get("samples", 0))
    done = d.get("done", 0)
    m, ex, fr, sa = cfg["model"], cfg["excitation"], cfg["frequency"], cfg["sampling"]
    nd = m["n_beams"] - (1 if m["topology"] == "linear" else 0)
    state = ("complete" if a.get("complete") == 1 else
             f"INCOMPLETE: {done} of {n} samples done; continue it with "
             f"`mcfric run CONFIG -o {str(path).removesuffix('.partial')} --resume`")

    def dist(t):
        from .sampling import DISTRIBUTIONS
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
        f"sampling:    {n} samples, seed {sa['seed']}; mu0 ~ {dist(sa['mu0'])}, "
        f"kc ~ {dist(sa['kc'])} N/m, N0 ~ {dist(sa['N0'])} N"
        + (f", mistuning {sa['mistuning']:g} per {sa['mistuning_per']}"
           if sa["mistuning"] else ""),
        f"converged:   {pts - bad:,} of {pts:,} points ({bad:,} not converged)",
        (f"metric:      {q} {ensemble.METRIC_UNITS[q]}, {lo:.4g} to {hi:.4g}" if pts - bad
         else f"metric:      {q}, no converged points"),
    ]
    if a.get("complete") == 1:
        lines.append(f"run time:    {a.get('wall_time_s', float('nan')):.1f} s "
                     f"(kernel {a.get('kernel_time_s', float('nan')):.1f} s) in the session "
                     f"that completed it")
    lines.append(f"written by:  mcfric {a.get('mcfric_version')}, numba "
                 f"{a.get('numba_version')}, numpy {a.get('numpy_version')}, HDF5 "
                 f"{a.get('hdf5_version')}; created {a.get('created_utc')}")
    lines.append("datasets:")
    for name, (dims, shape, dtype) in d["datasets"].items():
        lines.append(f"  {name:<14} {'(' + ', '.join(dims) + ')':<30} "
                     f"{' x '.join(map(str, shape)):<18} {dtype}")
    print("\n".join(lines))
    return EXIT_OK


def cmd_hbm(args):
    import numpy as np

    from . import config, hbm, plot

    cfg = _load(args)
    for flag, v in (("--mu0", args.mu0), ("--kc", args.kc), ("--N0", args.N0)):
        try:
            config.number(lo=0)(v, flag)
        except config.ConfigError as e:
            raise UsageError(str(e)) from None
    out = _output_path(args, ".csv", prefix="hbm-")
    model = cfg.model()
    f = cfg.frequencies()
    res = hbm.solve(model, f, args.mu0, args.kc, args.N0, tol=cfg["solver"]["tol"],
                    max_iter=cfg["solver"]["max_iter"],
                    n_threads=cfg["run"]["threads"] or None)
    q = cfg["metric"]["quantity"]
    from .ensemble import METRIC_UNITS
    unit = METRIC_UNITS[q]
    amp = np.abs(res.response[0])                       # (n_f, n_beams), m
    metric = res.metric(q, cfg.metric_beams())[0]
    conv = res.converged[0]
    s = res.s[0]
    header = (["frequency_hz"] + [f"abs_y{b + 1}_m" for b in range(model.n_beams)]
              + [f"metric_{unit.replace('/', '_per_').replace('^', '')}", "converged"]
              + [f"s{j + 1}" for j in range(model.n_dampers)])
    table = np.column_stack([f, amp, metric, conv.astype(float), s])
    fmt = ["%.10g"] + ["%.10e"] * (model.n_beams + 1) + ["%d"] + ["%.10e"] * model.n_dampers
    np.savetxt(out, table, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    bad = int(np.count_nonzero(~conv))
    print(f"mcfric hbm: {model.name}, mu0 = {args.mu0:g}, kc = {args.kc:g} N/m, "
          f"N0 = {args.N0:g} N, F0 = {model.excitation.F0:g} N; {len(f)} frequencies "
          f"{f[0]:g}-{f[-1]:g} Hz")
    print(f"not converged: {bad} of {len(f)} points"
          + (f" (at {', '.join(f'{x:.4g}' for x in f[~conv][:10])} Hz"
             f"{', ...' if bad > 10 else ''}; not drawn)" if bad else ""))
    print(f"csv: {out}")
    if not args.no_figure:
        png = out.with_suffix(".png")
        plot.hbm_figure(f, amp, metric, conv, png,
                        title=f"{model.name}: mu0 = {args.mu0:g}, kc = {args.kc:g} N/m, "
                              f"N0 = {args.N0:g} N, F0 = {model.excitation.F0:g} N"
                              + (f" ({bad} non-converged points not drawn)" if bad else ""),
                        metric_label=f"M ({q}) [{unit}]")
        print(f"figure: {png}")
    return EXIT_OK


def main(argv=None):
    """Entry point of ``mcfric``; returns the exit code."""
    from .store import StoreError

    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or (argv[0] not in COMMANDS and argv[0] not in ("-h", "--help", "--version")):
        argv = ["run"] + argv        # `mcfric` alone (or `mcfric two-beam`) means `mcfric run`
    try:
        args = _parser().parse_args(argv)
        return {"run": cmd_run, "config": cmd_config, "info": cmd_info,
                "hbm": cmd_hbm}[args.command](args)
    except UsageError as e:
        print(f"mcfric: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("mcfric: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except (OSError, StoreError) as e:   # disk full, unreadable file: one line, no traceback
        print(f"mcfric: error: {e}", file=sys.stderr)
        return EXIT_FAIL


if __name__ == "__main__":   # pragma: no cover
    sys.exit(main())
