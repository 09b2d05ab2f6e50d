"""The argument parser of ``mcfric`` and its subcommands."""

from __future__ import annotations

import argparse
import os
import re

from .errors import UsageError

COMMANDS = ("run", "config", "info", "hbm", "bounds", "plot", "verify")


MOMENTS_HELP = ("the second-order moment relaxation of the certified upper bound, an "
                "error where it cannot run (default: where it applies, chains of 2-7 "
                "dampers with a force limit)")


FIRST_ORDER_HELP = ("certify with the first-order relaxation alone (about a third of "
                    "the time on eight beams; looser near some resonances)")


class _NegativeNumber:
    """argparse's test of whether a token starting with "-" is a value, not an option.

    argparse's own test knows ``-1`` and ``-0.5`` only: ``--F0 -1e-3`` or ``--F0 -inf``
    gave "expected one argument", ``--f -1e-3 10`` "expected at least one argument",
    instead of the option's own check of the value. Any token that ``float`` reads is a
    value here.
    """

    @staticmethod
    def match(token):
        try:
            float(token)
        except ValueError:
            return False
        return token.startswith("-")


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("allow_abbrev", False)   # --sample must not mean --samples
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NegativeNumber()

    def error(self, message):
        raise UsageError(f"{message} (see `{self.prog} --help`)")

    def parse_args(self, args=None, namespace=None):
        # the top-level parser reports a subcommand's unknown options: its help lists
        # the commands, not their options, so the pointer names the command's own help
        ns, extra = self.parse_known_args(args, namespace)
        if extra:
            cmd = getattr(ns, "command", None)
            prog = f"{self.prog} {cmd}" if cmd else self.prog
            hint = _option_typo(extra, cmd, self._command_parsers())
            raise UsageError(f"unrecognized arguments: {' '.join(extra)} ({hint}see `{prog} "
                             f"--help`)")
        return ns

    def _command_parsers(self):
        """The subcommands' parsers by name ({None: this one} where there are none)."""
        for action in self._actions:
            if isinstance(action, argparse._SubParsersAction):
                return dict(action.choices)
        return {None: self}


def _long_options(parser):
    return [o for o in parser._option_string_actions if o.startswith("--")]


def _option_typo(extra, cmd, parsers):
    """A hint for the first unknown long option in ``extra``: the commands it belongs to
    (``run --N0``: "--N0 is an option of `mcfric hbm`"), or the option of ``cmd``'s it is
    close to (``--nfreq``, ``--f0``: "did you mean --n-freq?"), else ``""``."""
    import difflib

    word = next((t.split("=", 1)[0] for t in extra if t.startswith("--") and t != "--"),
                None)
    if word is None or cmd not in parsers:
        return ""
    # an option of another command: a close option of this one would be another quantity
    owners = [f"`mcfric {c}`" for c, p in parsers.items() if word in _long_options(p)]
    if owners:
        return f"{word} is an option of {' and '.join(owners)}; "
    close = difflib.get_close_matches(word, _long_options(parsers[cmd]), n=1, cutoff=0.75)
    return f"did you mean {close[0]}? " if close else ""


def _source_help():
    return "a preset (two-beam, eight-beam, disk-24, disk-72) or a TOML configuration file"


def build_parser():
    """The ``mcfric`` argument parser with every command's options."""
    from .. import __version__

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
    r.add_argument("--samples", type=_int, metavar="N", help="ensemble size")
    r.add_argument("--seed", type=_int, metavar="S", help="root seed (>= 0)")
    r.add_argument("--resume", action="store_true",
                   help="continue FILE.partial left by an interrupted run")
    r.add_argument("--force", action="store_true",
                   help="replace an existing FILE or FILE.partial holding another run")
    r.add_argument("--threads", type=_int, metavar="T", help="numba threads (0 = all)")
    r.add_argument("--chunk", type=_int, metavar="N", help="samples per chunk (0 = auto)")
    r.add_argument("--scheduler", metavar="ADDRESS",
                   help='solve the chunks on a Dask cluster: "local:N" (N worker processes '
                        'on this machine) or "tcp://host:port" (needs mcfric[dask])')
    r.add_argument("--peaks", type=_int, metavar="N",
                   help="resolved peaks kept per member (default: one per mode)")
    r.add_argument("--peak-rtol", type=_float, metavar="X",
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
                        "space, or the run's arrays for the free memory")
    r.add_argument("--no-figure", action="store_true", help="do not draw the figure")

    c = sub.add_parser("config", help="print a complete configuration (a preset's commented)",
                       description="Print the complete, commented TOML configuration of a "
                       "preset (or the validated, complete form of a configuration file), "
                       "or the configuration a results file was run with, as the file "
                       "stores it (without the comments).")
    c.add_argument("source", nargs="?", help=_source_help() + ", or a results file "
                   "(FILE or FILE.partial) (default: eight-beam)")

    i = sub.add_parser("info", help="summarise a results file")
    i.add_argument("file", type=_file_name, help="results file (FILE or FILE.partial)")

    h = sub.add_parser("hbm", help="one deterministic parameter set (like the paper's Fig. 5)",
                       description="Harmonic balance of one parameter set (the same for every "
                       "damper): writes a CSV and a PNG next to it.")
    h.add_argument("source", nargs="?", help=_source_help() + " (default: eight-beam)")
    h.add_argument("--mu0", type=_float, default=0.5, help="friction coefficient (default 0.5)")
    h.add_argument("--kc", type=_float, default=6000.0, metavar="N_PER_M",
                   help="tangential stiffness, N/m (default 6000)")
    h.add_argument("--N0", type=_float, default=0.5, metavar="N",
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
    b.add_argument("--k-max", type=_float, metavar="N_PER_M",
                   help="largest Re K of a damper, N/m, and Im K unless k_max_im is "
                        "set (default: from kc)")
    b.add_argument("--F-lim", type=_number_or_none, metavar="N",
                   help='friction force limit, N, or "none" (default: 4/pi mu0_max N0_max)')
    b.add_argument("--threads", type=_int, metavar="T", help="numba threads (0 = all)")
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
    pl.add_argument("file", type=_file_name,
                    help="results file (mcfric run) or bounds file (mcfric bounds)")
    pl.add_argument("-o", "--output", metavar="FIG",
                    help="figure file, .png/.pdf/.svg (default: FILE with .png)")
    pl.add_argument("--quantity", choices=("displacement", "velocity", "acceleration"),
                    help="plotted quantity (default: the stored one)")
    pl.add_argument("--f-min", type=_float, metavar="HZ", help="lower end of the window, Hz")
    pl.add_argument("--f-max", type=_float, metavar="HZ", help="upper end of the window, Hz")
    pl.add_argument("--member", type=_int, default=None, metavar="I",
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
    pl.add_argument("--measured-force", type=_float, metavar="N",
                    help="force level of the measured run, N, when the file does not give "
                         "one (UFF FRFs need it)")
    pl.add_argument("--measured-direction", type=_int, choices=(1, 2, 3), metavar="D",
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
    v.add_argument("--f", type=_hz, nargs="+", action="extend", required=True, metavar="HZ",
                   help="drive frequencies, Hz (repeated --f add to the list)")
    v.add_argument("--member", type=_int, metavar="I",
                   help="member of a results file (0-based) whose parameters to take")
    v.add_argument("--mu0", type=_float, help="friction coefficient (default 0.5)")
    v.add_argument("--kc", type=_float, metavar="N_PER_M",
                   help="tangential stiffness, N/m (default 6000)")
    v.add_argument("--N0", type=_float, metavar="N", help="normal preload, N (default 0.5)")
    v.add_argument("--F0", type=_float, metavar="NEWTONS",
                   help="excitation amplitude of the preset's pattern, N")
    v.add_argument("--harmonics", type=_int, metavar="H",
                   help="highest odd harmonic (>= 3) of the multi-harmonic solution "
                        "compared beside the single-harmonic one (default: the run's or "
                        "configuration's solver.harmonics where it is > 1, else 9)")
    v.add_argument("--start", choices=("single", "rest"), default="single",
                   help="initial state: the single-harmonic solution (default) or rest")
    v.add_argument("--max-periods", type=_int, default=20000, metavar="N",
                   help="periods after which a response counts as not periodic "
                        "(default %(default)s)")
    v.add_argument("-o", "--output", metavar="OUT.csv",
                   help="CSV file (default: mcfric-results/verify-<name>.csv, <name> the "
                        "model's name, or a results file's stem); the PNG goes next to it")
    v.add_argument("--no-figure", action="store_true", help="do not draw the figure")
    v.add_argument("--no-progress", action="store_true", help="no progress bar")


# int() and float() also take "3_0" (30) and other scripts' digits ("٣"): a typo
# read as a number
_INTEGER = re.compile(r"\s*[+-]?[0-9]+\s*")
_REAL = re.compile(r"\s*[+-]?(([0-9]+\.?[0-9]*|\.[0-9]+)([eE][+-]?[0-9]+)?|nan|inf|infinity)\s*",
                   re.IGNORECASE)


def _int(text):
    """An integer flag's value: ASCII digits with an optional sign."""
    if not _INTEGER.fullmatch(text):
        raise ValueError(text)
    return int(text)


def _float(text):
    """A real flag's value: a decimal number, as Python writes it without ``_`` (nan and
    inf pass, for the checks after to name)."""
    if not _REAL.fullmatch(text):
        raise ValueError(text)
    return float(text)


_int.__name__, _float.__name__ = "int", "float"       # argparse: "invalid int value"


def _file_name(text):
    """A file argument: an empty one ("" from an unset shell variable) named as such, not
    read as the current directory."""
    if not text.strip():
        raise argparse.ArgumentTypeError(f"expected a file name, got {text!r}")
    return text


def _hz(text):
    """One value of ``verify --f``; a word there is most likely SOURCE given after it."""
    from ..presets import PRESETS

    try:
        return _float(text)
    except ValueError:
        source = (text in PRESETS or text.endswith((".toml", ".h5", ".partial"))
                  or os.path.exists(text))
        hint = f" (SOURCE goes before --f: mcfric verify {text} --f HZ ...)" if source else ""
        raise argparse.ArgumentTypeError(f"expected a frequency in Hz, got {text!r}"
                                         + hint) from None


def _harmonic_flags(p):
    p.add_argument("--harmonics", type=_int, metavar="H",
                   help="balance the odd harmonics 1, 3, ..., H (default 1: the "
                        "single-harmonic describing function)")
    p.add_argument("--n-time", type=_int, metavar="N",
                   help="AFT samples per period (default max(32, 8 H))")


def _order_flags(p):
    """``--moments`` and ``--first-order``: the order of the certification's relaxation
    (one or the other)."""
    g = p.add_mutually_exclusive_group()
    g.add_argument("--moments", action="store_true", help=MOMENTS_HELP)
    g.add_argument("--first-order", action="store_true", help=FIRST_ORDER_HELP)


def _model_flags(p):
    p.add_argument("--F0", type=_float, metavar="NEWTONS",
                   help="excitation amplitude of the preset's pattern, N")
    p.add_argument("--f-min", type=_float, metavar="HZ", help="lowest frequency, Hz")
    p.add_argument("--f-max", type=_float, metavar="HZ", help="highest frequency, Hz")
    p.add_argument("--n-freq", type=_int, metavar="N", help="number of frequencies")


def _number_or_none(text):
    """``--F-lim``: a number, or ``none`` as in the configuration file."""
    if text.strip().lower() == "none":
        return "none"
    try:
        return _float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number or "none", got {text!r}') from None
