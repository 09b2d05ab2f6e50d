"""``mcfric`` command line: wires config, ensemble, store and plots together.

::

    mcfric                                   # = mcfric run: the embedded default
    mcfric run [PRESET|CONFIG.toml] [-o FILE] [--samples N] [--seed S] [--resume]
               [--force] [--threads T] [--chunk N] [--scheduler ADDRESS] [--peaks N]
               [--peak-rtol X] [--no-peaks] [--F0 N] [--f-min HZ] [--f-max HZ] [--n-freq N]
               [--no-certify] [--no-bounds] [--moments | --first-order] [--no-progress]
               [--no-figure] [--skip-space-check]
    mcfric config [PRESET|CONFIG.toml|FILE.h5]  # complete TOML on stdout (of a file: its run)
    mcfric info FILE                         # summary of a results file
    mcfric hbm [PRESET|CONFIG.toml] [--mu0 X] [--kc N_PER_M] [--N0 N] [--F0 N]
               [--f-min HZ] [--f-max HZ] [--n-freq N] [-o OUT.csv] [--no-figure]
    mcfric bounds [PRESET|CONFIG.toml] [-o FILE] [--F0 N] [--f-min HZ] [--f-max HZ]
               [--n-freq N] [--k-max N_PER_M] [--F-lim N] [--threads T] [--no-certify]
               [--moments | --first-order] [--no-progress] [--no-figure]
    mcfric plot FILE [-o FIG.png|pdf] [--quantity Q] [--f-min HZ] [--f-max HZ]
               [--member I] [--measured DATA ...] [--nodes N1,N2,...] [--normalise]
               [--measured-quantity Q] [--measured-force N] [--measured-direction D]
               [--no-indicator]
    mcfric verify [PRESET|CONFIG.toml] --f HZ [HZ ...] [--mu0 X] [--kc N_PER_M] [--N0 N]
               [--F0 N] [--harmonics H] [--start single|rest] [-o OUT.csv] [--no-figure]
               [--no-progress]
    mcfric verify FILE.h5 --member I --f HZ [HZ ...] [--harmonics H] ...

``run`` and ``hbm`` also take ``--harmonics H`` (multi-harmonic balance of the odd
harmonics 1..H) and ``--n-time N`` (AFT samples per period).

Exit codes: 0 done, 1 a run-time failure (disk full, I/O error, out of memory), 2 bad
configuration, arguments or input files, or a refused run (one line on stderr, nothing
written), 130 interrupted by Ctrl-C, SIGTERM or SIGHUP (the finished chunks are kept;
continue with ``--resume``).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from pathlib import Path

DEFAULT_DIR = Path("mcfric-results")
EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130
COMMANDS = ("run", "config", "info", "hbm", "bounds", "plot", "verify")
MOMENTS_HELP = ("the second-order moment relaxation of the certified upper bound, an "
                "error where it cannot run (default: where it applies, chains of 2-7 "
                "dampers with a force limit)")
FIRST_ORDER_HELP = ("certify with the first-order relaxation alone (about a third of "
                    "the time on eight beams; looser near some resonances)")


class UsageError(Exception):
    """Bad input from the user: one line on stderr, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)   # --sample must not mean --samples
        super().__init__(*args, **kwargs)

    def error(self, message):
        raise UsageError(f"{message} (see `{self.prog} --help`)")

    def parse_args(self, args=None, namespace=None):
        # the top-level parser reports a subcommand's unknown options: its help lists
        # the commands, not their options, so the pointer names the command's own help
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            cmd = getattr(ns, "command", None)
            prog = f"{self.prog} {cmd}" if cmd else self.prog
            raise UsageError(f"unrecognized arguments: {' '.join(extra)} (see `{prog} "
                             f"--help`)")
        return ns


def _source_help():
    return "a preset (two-beam, eight-beam, disk-24, disk-72) or a TOML configuration file"


def _parser():
    from . import __version__

    p = _Parser(prog="mcfric", description="Friction-damped beam arrays: harmonic balance, "
                "Monte Carlo ensembles. `mcfric` alone runs the default ensemble; options "
                "given without a command are run's (`mcfric --samples 10` is `mcfric run "
                "--samples 10`).")
    p.add_argument("--version", action="version", version=f"mcfric {__version__}")
    sub = p.add_subparsers(dest="command",
                           metavar="{run,config,info,hbm,bounds,plot,verify}")

    r = sub.add_parser("run", help="run (or resume) a Monte Carlo ensemble",
                       description="Run a Monte Carlo ensemble into an HDF5 results file "
                       "(written as FILE.partial, renamed when complete) and draw its figure.")
    r.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")
    r.add_argument("-o", "--output", metavar="FILE",
                   help="results file (default: mcfric-results/<name>.h5, <name> the preset or "
                        "the TOML file's name, default without a source)")
    r.add_argument("--samples", type=int, metavar="N", help="ensemble size")
    r.add_argument("--seed", type=int, metavar="S", help="root seed (>= 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue FILE.partial left by an interrupted run")
    r.add_argument("--force", action="store_true",
                   help="replace an existing FILE or FILE.partial holding another run")
    r.add_argument("--threads", type=int, metavar="T", help="numba threads (0 = all)")
    r.add_argument("--chunk", type=int, metavar="N", help="samples per chunk (0 = auto)")
    r.add_argument("--scheduler", metavar="ADDRESS",
                   help='solve the chunks on a Dask cluster: "local:N" (N worker processes '
                        'on this machine) or "tcp://host:port" (needs mcfric[dask])')
    r.add_argument("--peaks", type=int, metavar="N",
                   help="resolved peaks kept per member (default: one per mode)")
    r.add_argument("--peak-rtol", type=float, metavar="X",
                   help="relative tolerance of a refined peak (default 1e-4)")
    r.add_argument("--no-peaks", action="store_true",
                   help="do not refine peaks or look for folds")
    r.add_argument("--no-certify", action="store_true",
                   help="skip the certification of the bounds (searched bounds only)")
    r.add_argument("--no-bounds", action="store_true",
                   help="skip the response bounds altogether (bounds.enabled = false)")
    _order_flags(r)
    _model_flags(r)
    _harmonic_flags(r)
    r.add_argument("--no-progress", action="store_true",
                   help="no progress bars (the run's and the certification's)")
    r.add_argument("--skip-space-check", action="store_true",
                   help="start even if the results file looks too large for the free disk "
                        "space")
    r.add_argument("--no-figure", action="store_true", help="do not draw the figure")

    c = sub.add_parser("config", help="print a complete, commented configuration",
                       description="Print the complete, commented TOML configuration of a "
                       "preset (or the validated, complete form of a configuration file), "
                       "or the configuration a results file was run with.")
    c.add_argument("source", nargs="?", help=_source_help() + ", or a results file "
                   "(FILE or FILE.partial) (default: eight-beam)")

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
    _harmonic_flags(h)
    h.add_argument("-o", "--output", metavar="OUT.csv",
                   help="CSV file (default: mcfric-results/hbm-<name>.csv, <name> as in run); "
                        "the PNG goes next to it")
    h.add_argument("--no-figure", action="store_true", help="do not draw the figure")

    b = sub.add_parser("bounds", help="response bounds alone (no ensemble)",
                       description="Equivalent-linear response bounds (paper Section 3) of a "
                       "preset or configuration: an HDF5 file with frequency and bounds/, "
                       "and a figure next to it.")
    b.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")
    b.add_argument("-o", "--output", metavar="FILE",
                   help="bounds file (default: mcfric-results/bounds-<name>.h5, <name> as in run)")
    _model_flags(b)
    b.add_argument("--k-max", type=float, metavar="N_PER_M",
                   help="largest Re K of a damper, N/m, and Im K unless k_max_im is "
                        "set (default: from kc)")
    b.add_argument("--F-lim", type=_number_or_none, metavar="N",
                   help='friction force limit, N, or "none" (default: 4/pi mu0_max N0_max)')
    b.add_argument("--threads", type=int, metavar="T", help="numba threads (0 = all)")
    b.add_argument("--no-certify", action="store_true",
                   help="skip the certification of the bounds (a quick look: the searched "
                        "bounds alone)")
    _order_flags(b)
    b.add_argument("--no-progress", action="store_true",
                   help="no progress bars (the certification's, shown on a terminal)")
    b.add_argument("--no-figure", action="store_true", help="do not draw the figure")

    pl = sub.add_parser("plot", help="figure of a results or bounds file",
                        description="Bounds band over the ensemble cloud (log amplitude vs "
                        "frequency), optionally with measured data; prints the fraction of "
                        "measured points inside the bounds.")
    pl.add_argument("file", help="results file (mcfric run) or bounds file (mcfric bounds)")
    pl.add_argument("-o", "--output", metavar="FIG",
                    help="figure file, .png/.pdf/.svg (default: FILE with .png)")
    pl.add_argument("--quantity", choices=("displacement", "velocity", "acceleration"),
                    help="plotted quantity (default: the stored one)")
    pl.add_argument("--f-min", type=float, metavar="HZ", help="lower end of the window, Hz")
    pl.add_argument("--f-max", type=float, metavar="HZ", help="upper end of the window, Hz")
    pl.add_argument("--member", type=int, default=None, metavar="I",
                    help="ensemble member drawn in black (default 0; -1: none; a bounds "
                         "file has none)")
    pl.add_argument("--measured", nargs="+", metavar="DATA", default=[],
                    help="measured responses (CSV, or UFF dataset 58 with --nodes)")
    pl.add_argument("--nodes", metavar="N1,N2,...",
                    help="UFF response node of beam 1, 2, ... (for --measured UFF files), "
                         "or NODE:BEAM pairs, BEAM 0 for the metric M (an exported "
                         "percentile record)")
    pl.add_argument("--measured-quantity", choices=("displacement", "velocity",
                                                    "acceleration"),
                    help="what the measured values are, when the file does not say")
    pl.add_argument("--measured-force", type=float, metavar="N",
                    help="force level of the measured run, N, when the file does not give "
                         "one (UFF FRFs need it)")
    pl.add_argument("--measured-direction", type=int, choices=(1, 2, 3), metavar="D",
                    help="UFF: keep the records of response direction D (1 X, 2 Y, 3 Z), "
                         "for files with several per node")
    pl.add_argument("--normalise", action="store_true",
                    help="rescale measured data taken at force F_meas to the file's F0 "
                         "(Eq. 11-12; needs the force level in the data)")
    pl.add_argument("--no-indicator", action="store_true",
                    help="do not mark the points flagged by harmonic_indicator")
    _verify_parser(sub)
    return p


def _verify_parser(sub):
    v = sub.add_parser("verify", help="time-domain check of harmonic-balance points",
                       usage="mcfric verify [SOURCE] --f HZ [HZ ...] [options]",
                       description="Integrate the modal equations with exact Jenkins contacts "
                       "to a periodic state at each frequency; print and save, per beam, the "
                       "harmonics, the full-period peak, and the single- and multi-harmonic "
                       "results at the same point. SOURCE may also be a results file, with "
                       "--member I taking that member's parameters.")
    v.add_argument("source", nargs="?", help=_source_help() + ", or a results file "
                   "(default: eight-beam)")
    v.add_argument("--f", type=_hz, nargs="+", required=True, metavar="HZ",
                   help="drive frequencies, Hz")
    v.add_argument("--member", type=int, metavar="I",
                   help="member of a results file (0-based) whose parameters to take")
    v.add_argument("--mu0", type=float, help="friction coefficient (default 0.5)")
    v.add_argument("--kc", type=float, metavar="N_PER_M",
                   help="tangential stiffness, N/m (default 6000)")
    v.add_argument("--N0", type=float, metavar="N", help="normal preload, N (default 0.5)")
    v.add_argument("--F0", type=float, metavar="NEWTONS",
                   help="excitation amplitude of the preset's pattern, N")
    v.add_argument("--harmonics", type=int, metavar="H",
                   help="highest odd harmonic (>= 3) of the multi-harmonic solution "
                        "compared beside the single-harmonic one (default: the run's or "
                        "configuration's solver.harmonics where it is > 1, else 9)")
    v.add_argument("--start", choices=("single", "rest"), default="single",
                   help="initial state: the single-harmonic solution (default) or rest")
    v.add_argument("--max-periods", type=int, default=20000, metavar="N",
                   help="periods after which a response counts as not periodic "
                        "(default %(default)s)")
    v.add_argument("-o", "--output", metavar="OUT.csv",
                   help="CSV file (default: mcfric-results/verify-<name>.csv, <name> as in "
                        "run); the PNG goes next to it")
    v.add_argument("--no-figure", action="store_true", help="do not draw the figure")
    v.add_argument("--no-progress", action="store_true", help="no progress bar")


def _hz(text):
    """One value of ``verify --f``; a word there is most likely SOURCE given after it."""
    from .presets import PRESETS

    try:
        return float(text)
    except ValueError:
        source = (text in PRESETS or text.endswith((".toml", ".h5", ".partial"))
                  or os.path.exists(text))
        hint = f" (SOURCE goes before --f: mcfric verify {text} --f HZ ...)" if source else ""
        raise argparse.ArgumentTypeError(f"expected a frequency in Hz, got {text!r}"
                                         + hint) from None


def _harmonic_flags(p):
    p.add_argument("--harmonics", type=int, metavar="H",
                   help="balance the odd harmonics 1, 3, ..., H (default 1: the "
                        "single-harmonic describing function)")
    p.add_argument("--n-time", type=int, metavar="N",
                   help="AFT samples per period (default max(32, 8 H))")


def _order_flags(p):
    """``--moments`` and ``--first-order``: the order of the certification's relaxation
    (one or the other)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--moments", action="store_true", help=MOMENTS_HELP)
    g.add_argument("--first-order", action="store_true", help=FIRST_ORDER_HELP)


def _model_flags(p):
    p.add_argument("--F0", type=float, metavar="NEWTONS",
                   help="excitation amplitude of the preset's pattern, N")
    p.add_argument("--f-min", type=float, metavar="HZ", help="lowest frequency, Hz")
    p.add_argument("--f-max", type=float, metavar="HZ", help="highest frequency, Hz")
    p.add_argument("--n-freq", type=int, metavar="N", help="number of frequencies")


def _number_or_none(text):
    """``--F-lim``: a number, or ``none`` as in the configuration file."""
    if text.strip().lower() == "none":
        return "none"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number or "none", got {text!r}') from None


#: The peak refinement's settings on the command line: (argument, flag).
_PEAK_FLAGS = (("peaks", "--peaks"), ("peak_rtol", "--peak-rtol"))


def _overrides(args):
    o = {}
    for key, attr, flag in (("excitation.F0", "F0", "--F0"),
                            ("frequency.f_min", "f_min", "--f-min"),
                            ("frequency.f_max", "f_max", "--f-max"),
                            ("frequency.n", "n_freq", "--n-freq"),
                            ("sampling.samples", "samples", "--samples"),
                            ("sampling.seed", "seed", "--seed"),
                            ("run.threads", "threads", "--threads"),
                            ("run.chunk", "chunk", "--chunk"),
                            ("run.scheduler", "scheduler", "--scheduler"),
                            ("bounds.k_max", "k_max", "--k-max"),
                            ("bounds.F_lim", "F_lim", "--F-lim"),
                            ("peaks.count", "peaks", "--peaks"),
                            ("peaks.rtol", "peak_rtol", "--peak-rtol"),
                            ("solver.harmonics", "harmonics", "--harmonics"),
                            ("solver.n_time", "n_time", "--n-time")):
        if hasattr(args, attr):
            o[key] = (getattr(args, attr), flag)
    if getattr(args, "no_peaks", False):
        for attr, flag in _PEAK_FLAGS:
            if getattr(args, attr, None) is not None:
                raise UsageError(f"{flag}: a setting of the peak refinement; not with "
                                 f"--no-peaks")
        o["peaks.enabled"] = (False, "--no-peaks")
    for skip, key in (("no_certify", "bounds.certify"), ("no_bounds", "bounds.enabled")):
        if not getattr(args, skip, False):
            continue
        o[key] = (False, f"--{skip.replace('_', '-')}")
        for flag in ("moments", "first_order"):
            if getattr(args, flag, False):
                raise UsageError(f"--{flag.replace('_', '-')}: the order of the "
                                 f"certification; not with --{skip.replace('_', '-')}")
    if getattr(args, "moments", False):
        o["bounds.certify_moments"] = (True, "--moments")
    if getattr(args, "first_order", False):
        o["bounds.certify_moments"] = (False, "--first-order")
    return o


def _load(args, fixed=None):
    """The validated configuration of ``args``; ``fixed``: ``{dotted key: value}`` that
    the command itself sets."""
    from . import config

    overrides = _overrides(args)
    overrides.update({k: (v, k) for k, v in (fixed or {}).items()})
    try:
        cfg = config.load(args.source, overrides)
    except config.ConfigError as e:
        raise UsageError(str(e)) from None
    H = cfg.data["solver"]["harmonics"]
    if H > 1:
        for attr, flag in _PEAK_FLAGS:
            if getattr(args, attr, None) is not None:
                raise UsageError(f"{flag}: peaks are refined in single-harmonic runs only "
                                 f"(this one balances the odd harmonics up to {H})")
    if cfg.data["excitation"]["engine_orders"] and args.command not in ("run", "config"):
        raise UsageError(f"excitation.engine_orders: a sweep of engine orders is for "
                         f"mcfric run; mcfric {args.command} takes one engine_order")
    return cfg


def _default_output(args, suffix, prefix=""):
    from .presets import PRESETS

    if args.source is None:
        stem = "default"
    elif args.source in PRESETS:
        stem = args.source
    else:
        stem = Path(args.source).stem
    return DEFAULT_DIR / f"{prefix}{stem}{suffix}"


#: Default output directories this invocation made: removed at exit if still empty (a
#: run refused after its output path was chosen leaves nothing behind).
_MADE_DIRS = []


def _output_path(args, suffix, prefix="", figure=False):
    """The output path; the default directory is created, a given one must exist.

    ``figure``: the command also writes ``FILE.png`` next to it; the two must differ.
    Neither may replace an HDF5 file unless the command writes HDF5 itself (``suffix``
    ``.h5``, whose own checks decide), nor the command's own input, nor be a directory,
    nor end in the other format's suffix (found now, not after the work).
    """
    if args.output is not None:
        if not str(args.output).strip():
            raise UsageError('-o: expected a file name, got ""')
        out = Path(args.output)
        if not out.parent.is_dir():
            raise UsageError(f"-o: directory {out.parent} does not exist")
        if out.is_dir():
            raise UsageError(f"-o: {out} is a directory")
        if out.exists() and not out.is_file():
            # --force would replace a device (/dev/null) with a results file; a pipe hangs
            raise UsageError(f"-o: {out} is not a regular file (a device or a pipe)")
    else:
        out = _default_output(args, suffix, prefix)
        if not out.parent.is_dir():
            out.parent.mkdir(parents=True, exist_ok=True)
            _MADE_DIRS.append(out.parent)
    _writable_dir(out)
    what = "results file" if suffix == ".h5" else f"{suffix[1:].upper()} output"
    if suffix == ".h5" and out.name.endswith(".partial"):
        raise UsageError(f"-o: {out.name} ends in .partial, the name of an interrupted "
                         f"run's file; give the final name ({out.name[:-8]})")
    if out.name.endswith(".lock"):
        # a run on the name without .lock takes FILE.lock as its lock and removes it
        raise UsageError(f"-o: {out.name} ends in .lock, the name of a run's lock file; "
                         f"choose another name")
    if suffix != ".h5":
        _not_replacing_hdf5(out, what)
    _not_replacing_input(args, out, what)
    if figure:
        png = out.with_suffix(".png")
        if png == out:
            raise UsageError(f"-o: the {what} and its figure would both be {out}; give the "
                             f"{what} another suffix (e.g. {out.with_suffix(suffix).name})")
        if png.is_dir():
            raise UsageError(f"-o: the figure {png} is a directory; choose another -o")
        _not_replacing_hdf5(png, "figure")
        _not_replacing_input(args, png, "figure")
    # a name that promises the other format (the reader would then fail on it)
    other = {".h5": (".csv", ".png", ".txt", ".toml"),
             ".csv": (".h5", ".hdf5", ".hdf", ".nc", ".png", ".toml")}[suffix]
    if out.suffix.lower() in other:
        fmt = "an HDF5 results file" if suffix == ".h5" else "CSV"
        raise UsageError(f"-o: {out.name}: this command writes {fmt}; give a name ending "
                         f"in {suffix}")
    return out


def _writable_dir(out):
    """An output is renamed into its directory when complete: one that cannot be written
    is refused now, not after the work."""
    if not os.access(out.parent, os.W_OK | os.X_OK):
        raise UsageError(f"-o: directory {out.parent} is not writable")


def _not_replacing_input(args, path, what):
    """No output replaces the configuration (or file) the command reads."""
    src = getattr(args, "source", None)
    if src and Path(src).is_file() and path.exists() and path.samefile(src):
        raise UsageError(f"-o: the {what} would replace the input {src}; choose another -o")


def _not_replacing_hdf5(path, what):
    """No CSV or figure silently replaces a results file (HDF5)."""
    if path.is_file() and _is_hdf5(path):
        raise UsageError(f"{path} is an HDF5 file (results?); the {what} would replace it: "
                         f"choose another -o")


def _no_such_file(path):
    """The line for a results file that does not exist; it names the files an
    engine-order sweep writes for that ``-o`` (``FILE-eoE.h5``), where there are any."""
    import glob

    p = Path(path)
    # order_path's names, any order (its "-eo" and then digits: engine orders are >= 0)
    pattern = order_path(Path(glob.escape(str(p))), "*")
    names = sorted(Path(q).name for q in glob.glob(str(pattern))
                   if Path(q).stem[len(p.stem) + 3:].isdigit()) if p.suffix else []
    if not names:
        return f"{path}: no such file"
    shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
    return (f"{path}: no such file; an engine-order sweep wrote {shown} (one file per "
            f"order): give one of them")


def _checked_file(path):
    """:func:`~mcfric.results_check.check_file` of ``path``, then the keys of its stored
    configuration that the readers use (an edited file: one line, exit 2)."""
    from . import config
    from .results_check import CONFIG_KEYS, check_file
    from .store import StoreError

    if Path(path).is_dir():
        raise UsageError(f"{path}: a directory, not a results file")
    if not Path(path).exists():
        raise UsageError(_no_such_file(path))
    try:
        attrs, cfg = check_file(path)
    except StoreError as e:
        raise UsageError(str(e)) from None
    try:
        config.check_keys(cfg, CONFIG_KEYS)
    except config.ConfigError as e:
        raise UsageError(f"{path}: stored configuration: {e}") from None
    return attrs, cfg


def _only_replacing_bounds(out):
    """``mcfric bounds`` replaces a bounds file of its own, nothing else (an ensemble's
    results file, its ``.partial``, or a file of another kind)."""
    from .store import StoreError, partial_path, read_attrs

    part = partial_path(out)
    if part.exists():
        raise UsageError(f"{part} exists (an interrupted run?); the bounds would replace "
                         f"it: choose another -o")
    if not out.exists():
        return
    try:
        attrs = read_attrs(out)
    except StoreError:
        attrs = {}
    if "layout_version" not in attrs or int(attrs.get("samples", -1)) != 0:
        kind = "an ensemble's results file" if "layout_version" in attrs else \
            "not an mcfric bounds file"
        raise UsageError(f"{out} exists and is {kind}; the bounds would replace it: "
                         f"choose another -o")


def _check_members(path):
    """Count converged ensemble points outside the stored bounds (a validity check), on
    the members the bounds' constraints admit (:meth:`Bounds.admits`): ``(outside, total,
    outside_certified, left_out)``, ``outside_certified`` None if not certified,
    ``left_out`` the members not admitted (not checked)."""
    import numpy as np

    from .bounds import read_bounds
    from .store import iter_records

    B = read_bounds(path)
    if B is None:
        return None
    C = B.certificate
    outside = total = outside_cert = left_out = 0
    for _, arr in iter_records(path, ["metric", "converged", "mu0", "kc", "N0"]):
        admitted = B.admits(arr["mu0"], arr["kc"], arr["N0"])
        left_out += int(np.count_nonzero(~admitted))
        ok = arr["converged"] & admitted[:, None]
        outside += int(np.count_nonzero(~B.contains(arr["metric"]) & ok))
        if C is not None:
            outside_cert += int(np.count_nonzero(~C.contains(arr["metric"]) & ok))
        total += int(np.count_nonzero(ok))
    return outside, total, None if C is None else outside_cert, left_out


def _shortfall_note(cfg):
    """A note where ``[bounds]``' constraints leave out friction the sampling draws (a
    limit given in kN/m, say): the bounds then need not hold for every member."""
    short = cfg.bounds_shortfalls()
    if short:
        print(f"note: the bounds' constraints leave out members the sampling draws "
              f"({'; '.join(short)}): the bounds need not hold for them, and the check "
              f"against the members leaves them out", flush=True)


def _kept_bounds_note(cfg, out):
    """A note where ``out`` (resumed, or complete already) keeps bounds made with other
    ``[bounds]`` settings than ``cfg``'s (they are not part of a run's identity), else
    None."""
    import json

    from .config.configuration import first_difference
    from .store import read_attrs

    try:
        stored = json.loads(read_attrs(out)["config_json"]).get("bounds", {})
    except (KeyError, ValueError, TypeError):
        return None
    diff = first_difference(cfg.data["bounds"], stored, "bounds")
    if diff is None:
        return None
    kept = (f"{out} has no bounds (the session that created it had [bounds] enabled = "
            f"false)" if not stored.get("enabled", True) else
            f"{out} keeps the bounds of the session that created it, whose [bounds] differ "
            f"from this configuration's (first difference: {diff})")
    return (f"note: {kept}; `mcfric bounds` computes this configuration's into a file of "
            f"their own, --force recomputes the run")


def _outside_note(n, H, fault, mistuned=False):
    """What ``n`` member points outside the bounds mean in a run balancing ``H``
    harmonics: a ``fault`` to report where ``H = 1``; with ``H > 1`` none, as the bounds
    rest on the describing function's constraints (the single-harmonic model) and a
    multi-harmonic fundamental need not keep to them; with random mistuning none, as the
    bounds are the nominal rig's."""
    if mistuned:
        return (" (the bounds are the nominal rig's, the members mistuned: not a fault)"
                if n else "")
    if H > 1:
        return (f" (the bounds are the single-harmonic model's, these points the "
                f"fundamentals of H = {H}: not a fault)")
    return f" ({fault}: please report)" if n else ""


def order_path(out, E):
    """The results file of engine order ``E`` in a sweep written to ``out``."""
    return out.with_name(f"{out.stem}-eo{E}{out.suffix}")


def cmd_run(args):
    """``mcfric run``: run (or resume) an ensemble, check it against its bounds, draw it;
    with ``excitation.engine_orders``, one such run and file per engine order."""
    from . import ensemble
    from .store.lock import LockError, OutputLock

    if args.resume and args.force:
        # --force won silently and threw a resumable partial away
        raise UsageError("--force: discards FILE.partial, --resume continues it; give one")
    cfg = _load(args)
    out = _output_path(args, ".h5", figure=not args.no_figure)
    orders = cfg.data["excitation"]["engine_orders"]
    if not orders:
        return _run_one(args, cfg, out)
    runs = [(cfg.replace("excitation.engine_order", E).replace("excitation.engine_orders",
                                                                 []), order_path(out, E))
            for E in orders]
    # the refusals of every order's files before the first order starts (with --resume
    # too: a later order's file of another run was found only after the earlier orders)
    for c, o in runs:
        if not args.no_figure:
            _not_replacing_hdf5(o.with_suffix(".png"), "figure")
        try:
            # under the order's lock: a writer of it is named, as for one run
            with OutputLock(o, "mcfric run (checking an engine order's files)"):
                kind, got = ensemble.prepare(c.spec, o, resume=args.resume,
                                             force=args.force)
                if kind == "resume":
                    got[0].close()          # reopened in its turn
        except (ensemble.RunError, LockError) as e:
            raise UsageError(str(e)) from None
    print(f"mcfric run: engine orders {', '.join(map(str, orders))}: one results file "
          f"each ({', '.join(o.name for _, o in runs)})", flush=True)
    for c, o in runs:
        print(f"== engine order {c.data['excitation']['engine_order']}: {o}", flush=True)
        rc = _run_one(args, c, o, resume_as=out)
        if rc != EXIT_OK:
            return rc
    return EXIT_OK


def _run_one(args, cfg, out, resume_as=None):
    """One ensemble run into ``out``; ``resume_as``: the -o to give ``--resume``."""
    from . import ensemble
    from .distributed import ClusterError
    from .memory import MemoryRefused
    from .store import partial_path

    spec = cfg.spec
    resume = f"`mcfric run ... -o {resume_as or out} --resume`"
    # every refusal (bad config, existing files) happens before anything is written
    try:
        model = spec.model
        print(f"mcfric run: {model.name}, {spec.samples} samples x {len(spec.freq_hz)} "
              f"frequencies, {model.n_beams} beams, F0 = {model.excitation.F0:g} N, "
              f"seed {spec.seed}", flush=True)
        if args.force or not (out.exists() or partial_path(out).exists()):
            # only where this run computes its bounds: a file resumed or complete keeps
            # the bounds it was made with ([bounds] is no part of a run's identity)
            _shortfall_note(cfg)
        summary = ensemble.run(cfg, out, resume=args.resume, force=args.force,
                               progress=not args.no_progress,
                               space_check=not args.skip_space_check)
    except ensemble.RunError as e:
        raise UsageError(str(e)) from None
    except ensemble.Interrupted as e:
        s = e.summary
        print(f"interrupted: {s.samples_done} of {s.samples} samples saved in {s.path}; "
              f"continue with {resume}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except ClusterError as e:
        # the committed chunks are in the partial file (the writer commits before stopping)
        print(f"mcfric: error: {e}; the finished chunks are kept: continue with {resume}",
              file=sys.stderr)
        return EXIT_FAIL
    except MemoryRefused as e:
        # a chunk's solve found too little free memory (after --skip-space-check, or as
        # the machine's free memory fell): what was committed stays, to resume
        kept = (f"; the finished chunks are kept: continue with {resume} when memory is "
                f"free" if partial_path(out).exists() else "")
        print(f"mcfric: error: {_one_line(e)}{kept}", file=sys.stderr)
        return EXIT_FAIL
    try:
        _report_run(args, cfg, out, summary)
    except KeyboardInterrupt:
        if not summary.complete:
            raise
        # the file is whole: only the summary's checks or the figure were cut short
        rest = f"; the sweep's other engine orders: {resume}" if resume_as else ""
        print(f"interrupted: {out} is complete; the checks or the figure after it were "
              f"cut short (`mcfric info {out}`, `mcfric plot {out}`){rest}",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_OK


def _report_run(args, cfg, out, summary):
    """What ``mcfric run`` prints and draws once the run is over: the summary, the bounds'
    lines, the members' check against them, the figure."""
    from . import plot

    if summary.already_complete:
        print(f"{out} already holds this run (same configuration, [run] and [bounds] "
              f"aside, and seed): nothing to do; --force recomputes it")
    print(summary.text())
    if summary.complete and not summary.bounds_computed:
        note = _kept_bounds_note(cfg, out)
        if note:
            print(note)
    if summary.complete and (args.no_progress or not summary.bounds_computed):
        # the bounds' summary was printed as they were computed only with progress on,
        # and not at all where they came from an earlier session's file
        from .bounds import read_bounds

        B = read_bounds(out)
        if B is not None:
            print(B.summary())
    if summary.complete:
        check = _check_members(out)
        if check is not None:
            outside, total, outside_cert, left_out = check
            from .store import read_attrs

            H = int(read_attrs(out).get("harmonics", 1))
            mis = cfg.data["sampling"]["mistuning"] > 0
            if left_out:
                print(f"bounds check: {left_out:,} of {summary.samples:,} members have "
                      f"friction outside the bounds' constraints ([bounds] k_max, k_max_im, "
                      f"F_lim), for which the bounds need not hold: left out of the checks")
            # a search may miss extremes; with certified bounds that hold, no fault
            held = outside_cert == 0
            note = (" (the search missed them; the certified bounds hold them)"
                    if outside and held and H == 1 and not mis else
                    _outside_note(outside, H, "the bounds search missed them", mis))
            print(f"searched bounds check: {outside} of {total:,} converged member points "
                  f"outside [lower, upper]" + note)
            if outside_cert is not None:
                print(f"certified bounds check: {outside_cert} outside [lower_certified, "
                      f"upper_certified]" + _outside_note(outside_cert, H,
                                                          "a broken certificate", mis))
    if summary.complete and not args.no_figure:
        png = out.with_suffix(".png")
        plot.results_figure(out, png)
        print(f"figure: {png}")


def cmd_bounds(args):
    """``mcfric bounds``: the response bounds alone, into a bounds file, and a figure."""
    import time

    from . import bounds, plot
    from .store.lock import LockError, OutputLock

    cfg = _load(args, {"bounds.enabled": True})
    spec = cfg.spec
    out = _output_path(args, ".h5", prefix="bounds-", figure=not args.no_figure)
    model, f, lim = spec.model, spec.freq_hz, spec.bounds
    lock = OutputLock(out, "mcfric bounds")
    try:
        lock.acquire()
    except LockError as e:
        raise UsageError(str(e)) from None
    try:
        _only_replacing_bounds(out)
        print(f"mcfric bounds: {model.name}, {len(f)} frequencies {f[0]:g}-{f[-1]:g} Hz, "
              f"F0 = {model.excitation.F0:g} N; box 0 <= Re K <= {lim.k_max_re:g} N/m, "
              f"0 <= Im K <= {lim.k_max_im:g} N/m, F_lim = {lim.F_lim:g} N", flush=True)
        _shortfall_note(cfg)
        t = time.perf_counter()
        B = bounds.from_spec(spec, progress=False if args.no_progress else None)
        print(f"{B.summary()} ({time.perf_counter() - t:.1f} s)")
        peak = None
        if spec.peaks:
            # as a run's bounds group has it: the upper bound's peak between grid points
            from .bounds.peak import peak_attrs

            peak = peak_attrs(model, B, spec.peaks.rtol)
        bounds.write_bounds_file(out, cfg, B, peak=peak)
        from .metric import METRIC_UNITS
        from .peaks import bound_peak, bound_peak_lines

        for line in bound_peak_lines(bound_peak(out), METRIC_UNITS[spec.metric.quantity]):
            print(line)
    finally:
        lock.release()
    print(f"bounds: {out}")
    if not args.no_figure:
        png = out.with_suffix(".png")
        plot.results_figure(out, png)
        print(f"figure: {png}")
    return EXIT_OK


def cmd_plot(args):
    """``mcfric plot``: the figure of a results or bounds file, measured data on top."""
    from . import plot
    from .store import partial_path

    path = Path(args.file)
    if not path.exists():
        if partial_path(path).exists():
            raise UsageError(f"{path}: the run is not complete ({partial_path(path).name} "
                             f"holds it; continue it with --resume)")
        raise UsageError(_no_such_file(path))
    attrs = _checked_file(path)[0]
    if attrs.get("complete") != 1:
        raise UsageError(f"{path}: the run is not complete (continue it with --resume)")
    if args.output is not None and not str(args.output).strip():
        raise UsageError('-o: expected a file name, got ""')
    out = Path(args.output) if args.output else path.with_suffix(".png")
    if out.suffix.lower() not in (".png", ".pdf", ".svg"):
        raise UsageError(f"-o: expected a .png, .pdf or .svg file, got {out.name}")
    if not out.parent.is_dir():
        raise UsageError(f"-o: directory {out.parent} does not exist")
    if out.is_dir():
        raise UsageError(f"-o: {out} is a directory")
    _writable_dir(out)
    _not_replacing_hdf5(out, "figure")
    window = None
    if args.f_min is not None or args.f_max is not None:
        from .store import read
        f = read(path, "frequency")
        window = (args.f_min if args.f_min is not None else f.min(),
                  args.f_max if args.f_max is not None else f.max())
        for flag, v in (("--f-min", args.f_min), ("--f-max", args.f_max)):
            if v is not None and not math.isfinite(v):
                raise UsageError(f"{flag}: expected a frequency in Hz, got {v}")
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
    try:
        drawn = plot.results_figure(path, out, quantity=args.quantity, f_window=window,
                                    member=None if args.member < 0 else args.member,
                                    measured=measured, indicator=not args.no_indicator)
    except ValueError as e:
        raise UsageError(str(e)) from None
    gaps = drawn["n_not_converged"]
    grid = drawn["n_peaks_unrefined"]
    print(f"figure: {out} ({drawn['n_drawn']} of {drawn['n_members']} members drawn"
          f"{', bounds' if drawn['has_bounds'] else ', no bounds in the file'}"
          + (f"; {gaps:,} point{'s' if gaps > 1 else ''} not converged, left as gaps"
             if gaps else "")
          + (f"; {grid} member peak{'s' if grid > 1 else ''} not refined, drawn as circles"
             if grid else "") + ")")
    if measured and drawn["has_bounds"]:
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
                 if v]
        if given:
            raise UsageError(f"{given[0]}: applies to --measured data, and none is given")
        return []
    from . import measured as ms
    from .uff import UFF_SUFFIXES

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
                m, report = ms.normalise(m, F0)
                # printed once all are read (a refusal prints nothing else), once each
                if report.text() not in reports:
                    reports.append(report.text())
            elif m.force_n is not None and F0 and abs(m.force_n - F0) > 1e-6 * F0:
                raise UsageError(f"--measured: {data} was measured at {m.force_n:g} N, the "
                                 f"file is for F0 = {F0:g} N: pass --normalise to rescale "
                                 f"it (docs: measured data)")
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

    from . import measured as ms
    from .bounds import read_bounds
    from .metric import omega_power
    from .store import read_attrs

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
        print(f"the largest measured beam against the upper bound only (the metric's beams "
              f"{', '.join(map(str, beams))} are not all measured: M could be larger; "
              f"'M' below is that largest beam):")
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


def cmd_config(args):
    """``mcfric config``: the complete, commented configuration on stdout; of a results
    file (complete or partial), the configuration it was run with."""
    from .store import partial_path

    path = Path(args.source) if args.source is not None else None
    if path is not None and not path.exists() and partial_path(path).exists():
        path = partial_path(path)
    if path is not None and path.is_file() and _is_hdf5(path):
        a, _ = _checked_file(path)
        out = str(path).removesuffix(".partial")
        how = (f"mcfric run THIS.toml -o {out} --resume continues an interrupted one"
               if int(a.get("samples", 0)) else
               "a bounds file: mcfric bounds THIS.toml computes it again")
        text = a.get("config")
        if not isinstance(text, str):
            from . import config

            # the TOML copy lost (an edited file): the JSON record is the one runs resume by
            try:
                text = config.validate(json.loads(a["config_json"])).toml(comments=False)
            except config.ConfigError as e:
                raise UsageError(f"{path}: stored configuration: {e}") from None
        sys.stdout.write(f"# the configuration of the run in {path}\n# ({how})\n\n{text}")
        return EXIT_OK
    cfg = _load(args)
    sys.stdout.write(cfg.toml())
    return EXIT_OK


def _is_hdf5(path):
    import h5py

    try:
        return h5py.is_hdf5(path)
    except OSError:
        return False


def cmd_info(args):
    """``mcfric info``: a summary of a results file (complete or partial)."""
    from .indicator import file_report as indicator_report
    from .metric import METRIC_UNITS
    from .peaks import file_report as peak_report
    from .peaks import report_text
    from .store import StoreError, describe, iter_records, partial_path
    from .store.lock import holder

    path = Path(args.file)
    if not path.exists() and partial_path(path).exists():
        path = partial_path(path)
    a, cfg = _checked_file(path)
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
    state = ("complete" if a.get("complete") == 1 else
             f"INCOMPLETE: {done} of {n} samples done; being written now by {writer}"
             if writer else
             f"INCOMPLETE: {done} of {n} samples done; continue it with the command "
             f"that started it and --resume, or with `mcfric config {path} > run.toml` "
             f"and `mcfric run run.toml -o {final} --resume`")

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
    report = peak_report(path)
    if report is not None:
        lines += report_text(report, METRIC_UNITS[q])
    else:
        # a bounds file: the bound's peak alone, when it was refined
        from .peaks import bound_peak, bound_peak_lines

        lines += bound_peak_lines(bound_peak(path), METRIC_UNITS[q])
    lines += indicator_report(path)
    from .bounds import read_bounds
    B = read_bounds(path)
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
        from .store import read_group

        names = sorted(read_group(path, "bounds")[0])
        lines.append(f"  bounds/ (group)      {len(names)} datasets per frequency: "
                     + ", ".join(names))
    print("\n".join(lines))
    return EXIT_OK


def _check_friction_flag(name, v):
    """``--mu0``, ``--kc`` or ``--N0`` (``name`` without dashes): finite and >= 0, ``kc``
    at most :data:`mcfric.validators.KC_MAX`; a UsageError naming the flag otherwise."""
    from .validators import InputError, check_kc, number

    try:
        number(lo=0)(v, f"--{name}")
        if name == "kc":
            check_kc("--kc", v)
    except InputError as e:
        raise UsageError(str(e)) from None


def cmd_hbm(args):
    """``mcfric hbm``: one deterministic parameter set, to a CSV file and a figure."""
    import numpy as np

    from . import hbm, plot
    from .metric import METRIC_UNITS, omega_power
    from .threads import interruptible

    spec = _load(args).spec
    for flag, v in (("mu0", args.mu0), ("kc", args.kc), ("N0", args.N0)):
        _check_friction_flag(flag, v)
    out = _output_path(args, ".csv", prefix="hbm-", figure=not args.no_figure)
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
    from .store import replacing

    with replacing(out, "CSV") as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(header), comments="", fmt=fmt)
    bad = int(np.count_nonzero(~conv))
    print(f"mcfric hbm: {model.name}, mu0 = {args.mu0:g}, kc = {args.kc:g} N/m, "
          f"N0 = {args.N0:g} N, F0 = {model.excitation.F0:g} N; {len(f)} frequencies "
          f"{f[0]:g}-{f[-1]:g} Hz; " + ("single-harmonic" if H == 1 else
                                          f"odd harmonics 1..{H} (abs_y: the fundamental)"))
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


def _verify_source(args):
    """Model and parameters of ``mcfric verify``: a preset/config and the flags, or a
    results file's configuration and one member's parameters. Returns ``(model, params,
    stem, spec)``: ``stem`` only for a file; ``spec`` the validated run specification (a
    file's stored one)."""
    import numpy as np

    from . import config

    src = args.source
    # by content: run writes any -o name (out.H5, x)
    if src is not None and (src.endswith((".h5", ".h5.partial"))
                            or (Path(src).is_file() and _is_hdf5(src))):
        from .store import partial_path, read
        if not Path(src).exists() and partial_path(src).exists():
            raise UsageError(f"{src}: no such file; {partial_path(src).name} holds the "
                             f"interrupted run (give that name to verify its members done)")
        attrs = _checked_file(src)[0]       # a damaged or foreign file: one line, exit 2
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
        raise UsageError("--member: only with a results file")
    spec = _load(args).spec
    params = []
    for flag, default in (("mu0", 0.5), ("kc", 6000.0), ("N0", 0.5)):
        v = getattr(args, flag)
        v = default if v is None else v
        _check_friction_flag(flag, v)
        params.append(v)
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

    from .metric import METRIC_UNITS
    from .store import dataset_names, read

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

    from .metric import response_metric

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

    from . import plot
    from .verify import time_steps, verify

    if args.max_periods < 1:
        raise UsageError(f"--max-periods: expected an integer >= 1, got {args.max_periods}")
    from .hbm import MAX_HARMONICS

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
    out = _output_path(args, ".csv", prefix="verify-", figure=not args.no_figure)
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
             "member parameters")
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
    from .store import replacing

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


def _stop_signals_interrupt():
    """SIGTERM and SIGHUP stop a run as Ctrl-C does: the finished chunks are committed, a
    message says how to resume, exit 130 (main thread only; elsewhere a no-op)."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}

    from . import ensemble

    def handler(signum, frame):
        # also noted: raised inside a ctypes callback (numba compiling) the exception is
        # printed and dropped, and the run checks the note between chunks
        ensemble.STOP_SIGNALS.append(signal.Signals(signum).name)
        raise KeyboardInterrupt(signal.Signals(signum).name)

    ensemble.STOP_SIGNALS.clear()
    previous = {}
    for name in ("SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            sig = getattr(signal, name)
            previous[sig] = signal.signal(sig, handler)
    return previous


def _one_line(e):
    """An error's text on one line: a key or a library's message may hold line breaks
    (a quoted TOML key with a line break in it, HDF5's own errors)."""
    return " ".join(str(e).split())


def _command_typo(word):
    """A message where ``word``, the first argument, is no command, preset or file but
    close to a command's name (``runn``: read as ``mcfric run runn`` it failed on the
    arguments after it, or as a missing file), else None."""
    import difflib

    from .presets import PRESETS

    if (word in COMMANDS or word.startswith("-") or word in PRESETS or os.path.exists(word)
            or any(c in word for c in "./\\")):       # a file's name: "no such file" says it
        return None
    close = difflib.get_close_matches(word, COMMANDS, n=1, cutoff=0.6)
    return (f"unknown command {word!r} (did you mean {close[0]!r}? commands: "
            f"{', '.join(COMMANDS)})" if close else None)


def main(argv=None):
    """Entry point of ``mcfric``; returns the exit code."""
    from .store import StoreError

    argv = list(sys.argv[1:] if argv is None else argv)
    typo = _command_typo(argv[0]) if argv else None
    if typo:
        print(f"mcfric: error: {typo}", file=sys.stderr)
        return EXIT_USAGE
    if not argv or (argv[0] not in COMMANDS and argv[0] not in ("-h", "--help", "--version")):
        argv = ["run"] + argv        # `mcfric` alone (or `mcfric two-beam`) means `mcfric run`
    import signal

    previous = {}
    try:
        # inside: Ctrl-C while the solver's modules load is an interrupt like any other
        previous = _stop_signals_interrupt()
        args = _parser().parse_args(argv)
        from .threads import leaving_on_interrupt

        # the process ends after an interrupt: a chunk's kernel may be left running
        with leaving_on_interrupt():
            rc = {"run": cmd_run, "config": cmd_config, "info": cmd_info, "hbm": cmd_hbm,
                  "bounds": cmd_bounds, "plot": cmd_plot,
                  "verify": cmd_verify}[args.command](args)
        sys.stdout.flush()           # a closed pipe shows here, not at interpreter exit
        return rc
    except UsageError as e:
        print(f"mcfric: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("mcfric: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # the reader of stdout went away (`mcfric info FILE | head -1`): stop quietly
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_OK
    except (OSError, StoreError) as e:   # disk full, unreadable file: one line, no traceback
        print(f"mcfric: error: {_one_line(e)}", file=sys.stderr)
        return EXIT_FAIL
    except MemoryError:
        print("mcfric: error: out of memory (a model or ensemble this large needs more RAM "
              "than is free: fewer beams, frequencies or samples per chunk)", file=sys.stderr)
        return EXIT_FAIL
    finally:
        for sig, h in previous.items():
            signal.signal(sig, h)
        while _MADE_DIRS:
            try:
                _MADE_DIRS.pop().rmdir()         # only an empty one
            except OSError:
                pass


if __name__ == "__main__":   # pragma: no cover
    sys.exit(main())
