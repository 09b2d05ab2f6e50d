"""The configuration a command runs: the source, the flags that override it, and notes
about it."""

from __future__ import annotations

from .errors import UsageError

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


def load_config(args, fixed=None):
    """The validated configuration of ``args``; ``fixed``: ``{dotted key: value}`` that
    the command itself sets."""
    from .. import config

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


def check_friction_flag(name, v):
    """``--mu0``, ``--kc`` or ``--N0`` (``name`` without dashes): finite and >= 0, ``kc``
    at most :data:`mcfric.validators.KC_MAX`; a UsageError naming the flag otherwise."""
    from ..validators import InputError, check_kc, number

    try:
        number(lo=0)(v, f"--{name}")
        if name == "kc":
            check_kc("--kc", v)
    except InputError as e:
        raise UsageError(str(e)) from None


def check_slip_flags(mu0, N0):
    """``--mu0`` times ``--N0`` at most :data:`mcfric.validators.SLIP_FORCE_MAX` (N); a
    UsageError naming both flags otherwise."""
    from ..validators import InputError, check_slip_force

    try:
        check_slip_force("--mu0 x --N0", mu0, N0)
    except InputError as e:
        raise UsageError(str(e)) from None


def settings_notes(cfg, sections=None):
    """The notes on a configuration before the work: where ``[bounds]``' constraints
    leave out friction the sampling draws (a limit given in kN/m, say: the bounds then
    need not hold for every member), then each setting that does nothing under the
    others, of the tables ``sections`` or all
    (:meth:`~mcfric.config.Config.idle_settings`)."""
    short = cfg.bounds_shortfalls()
    if short:
        print(f"note: the bounds' constraints leave out members the sampling draws "
              f"({'; '.join(short)}): the bounds need not hold for them, and the check "
              f"against the members leaves them out", flush=True)
    for phrase in cfg.idle_settings(sections):
        print(f"note: {phrase}", flush=True)
