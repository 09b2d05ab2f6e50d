"""Run configuration: a TOML file or a preset, command-line overrides, validated once.

A configuration is resolved in three layers, later ones winning:

1. the defaults of a preset (``model.preset``: ``two-beam`` or ``eight-beam``; the rig
   itself comes from :mod:`mcfric.presets`), plus the paper's ensemble (physics.md 6);
2. the TOML file, key by key (a ``[sampling.<param>]`` distribution table and the
   ``[[model.beam]]`` list are replaced whole, not merged);
3. command-line overrides (``--samples``, ``--F0``, ...).

The result is validated once (:func:`validate`): an unknown key, a wrong type or a value
out of range raises :class:`ConfigError`, whose one-line message names the key (or the
command-line flag that set it) and what is allowed. A valid configuration is complete:
:meth:`Config.toml` renders every key, with comments, and parses back to the same
configuration (``mcfric config PRESET`` prints it).

Sections (units SI: Hz, N, N/m): ``[model]`` (+ ``[model.table]``, ``[[model.beam]]``),
``[excitation]``, ``[frequency]``, ``[sampling]`` (+ ``[sampling.mu0|kc|N0]``), ``[metric]``,
``[solver]``, ``[output]``, ``[run]`` and ``[bounds]``. ``[run]`` says how to compute
(threads, chunk size, checkpoints), never what: it is excluded from :meth:`Config.identity`,
the part that must match for ``--resume``. ``[bounds]`` configures the response bounds
that ``run`` computes before the ensemble (and ``mcfric bounds`` alone); it does not
change the ensemble and is excluded too.
"""

from __future__ import annotations

import copy
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import sampling
from .model import PATTERNS, TOPOLOGIES, Excitation, ModalTable, Model
from .presets import PRESETS, preset as make_preset

DEFAULT_PRESET = "eight-beam"
QUANTITIES = ("displacement", "velocity", "acceleration")
SPACINGS = ("linear", "log")
#: Sections that do not change the results (ignored when comparing runs for --resume).
NOT_IDENTITY = ("run", "bounds")
MAX_SAMPLES = 10 ** 10
MAX_FREQ = 10 ** 7


class ConfigError(ValueError):
    """A configuration problem: ``key`` (dotted TOML path or CLI flag) and a message."""

    def __init__(self, key, message, alt=None):
        super().__init__(f"{key}: {message}")
        self.key = key
        self.message = message
        self.alt = alt   # (key, message): the same problem blamed on the other key


# ----------------------------------------------------------------------------- defaults

def defaults(preset=DEFAULT_PRESET):
    """The complete default configuration of a preset, as a nested dict."""
    if preset not in PRESETS:
        raise ConfigError("model.preset", f"expected one of {_choices(PRESETS)}, "
                          f"got {_show(preset)}")
    m = make_preset(preset)
    t = m.beams[0]
    ex = m.excitation
    return {
        "model": {
            "preset": preset, "name": m.name, "n_beams": m.n_beams,
            "topology": m.topology, "contact": m.contact, "output": m.output,
            "drive": m.drive,
            "table": {"freq_hz": t.freq_hz.tolist(), "zeta": t.zeta.tolist(),
                      "shapes": t.shapes.tolist(), "positions": list(t.positions)},
            "beam": [],
        },
        "excitation": {"pattern": ex.pattern, "F0": ex.F0, "beam": ex.beam,
                       "mode": ex.mode, "engine_order": ex.engine_order},
        "frequency": {"f_min": 10.0, "f_max": 150.0, "n": 1000, "spacing": "linear"},
        "sampling": {"samples": 2000, "seed": 0, "mistuning": 0.0, "mistuning_per": "beam",
                     **{k: sampling.as_dict(d) for k, d in sampling.PAPER.items()}},
        "metric": {"quantity": "displacement", "beams": "all"},
        "solver": {"tol": 1e-10, "max_iter": 50},
        "output": {"keep_response": True},
        "run": {"threads": 0, "chunk": 0, "checkpoint_s": 0.0},
        "bounds": {"enabled": True, "k_max": "auto", "k_max_im": "auto", "F_lim": "auto",
                   "n_starts": 3},
    }


# ----------------------------------------------------------------------------- schema
# One entry per key: (check, comment). The comment is what `mcfric config` prints.
# Checks take (value, key) and return the canonical value or raise ConfigError.

def _show(v):
    """A value as the user wrote it in TOML."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if isinstance(v, list):
        s = "[" + ", ".join(_show(x) for x in v) + "]"
        return s if len(s) <= 60 else s[:57] + "...]"
    return repr(v)


def _choices(options):
    return ", ".join(json.dumps(o) for o in options)


def _is_int(v):
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def integer(lo=None, hi=None):
    if lo is not None and hi is not None:
        what = f"an integer in {lo}..{hi}"
    elif lo is not None:
        what = f"an integer >= {lo}"
    else:
        what = "an integer"

    def check(v, key):
        if not _is_int(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
            raise ConfigError(key, f"expected {what}, got {_show(v)}")
        return v
    check.what = what
    return check


def number(lo=None, hi=None, lo_open=False, hi_open=False, allow_inf=False):
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    what = "a number" + (" " + " and ".join(parts) if parts else "")
    if not allow_inf:
        what = "a finite number" + what[len("a number"):]

    def check(v, key):
        ok = _is_num(v) and not math.isnan(v) and (allow_inf or not math.isinf(v))
        if ok and lo is not None:
            ok = v > lo if lo_open else v >= lo
        if ok and hi is not None:
            ok = v < hi if hi_open else v <= hi
        if not ok:
            raise ConfigError(key, f"expected {what}, got {_show(v)}")
        return float(v)
    check.what = what
    return check


def choice(*options):
    def check(v, key):
        if not isinstance(v, str) or v not in options:
            raise ConfigError(key, f"expected one of {_choices(options)}, got {_show(v)}")
        return v
    return check


def string():
    def check(v, key):
        if not isinstance(v, str):
            raise ConfigError(key, f"expected a string, got {_show(v)}")
        return v
    return check


def boolean():
    def check(v, key):
        if not isinstance(v, bool):
            raise ConfigError(key, f"expected true or false, got {_show(v)}")
        return v
    return check


def numbers(lo=None, lo_open=False, nonempty=True):
    item = number(lo=lo, lo_open=lo_open)
    what = "a list of " + item.what.replace("a finite number", "finite numbers")

    def check(v, key):
        if not isinstance(v, list) or (nonempty and not v):
            raise ConfigError(key, f"expected {what}, got {_show(v)}")
        try:
            return [item(x, key) for x in v]
        except ConfigError:
            raise ConfigError(key, f"expected {what}, got {_show(v)}") from None
    return check


def matrix():
    def check(v, key):
        what = "a list of rows (lists of finite numbers) of equal length"
        if (not isinstance(v, list) or not v or not all(isinstance(r, list) and r for r in v)
                or len({len(r) for r in v}) != 1
                or not all(_is_num(x) and math.isfinite(x) for r in v for x in r)):
            raise ConfigError(key, f"expected {what}, got {_show(v)}")
        return [[float(x) for x in r] for r in v]
    return check


def integers():
    def check(v, key):
        if not isinstance(v, list) or not v or not all(_is_int(x) for x in v):
            raise ConfigError(key, f"expected a non-empty list of integers, got {_show(v)}")
        if len(set(v)) != len(v):
            raise ConfigError(key, f"expected distinct integers, got {_show(v)}")
        return list(v)
    return check


def auto_or_number(lo=0, words=("auto",)):
    """``"auto"`` (or another of ``words``) or a number > ``lo``."""
    num = number(lo=lo, lo_open=True)

    def check(v, key):
        if isinstance(v, str):
            if v in words:
                return v
            raise ConfigError(key, f"expected {_choices(words)} or a number > {lo:g}, "
                              f"got {_show(v)}")
        return num(v, key)
    return check


def beams_or_all():
    ints = integers()

    def check(v, key):
        if v == "all":
            return v
        if isinstance(v, list):
            return ints(v, key)
        raise ConfigError(key, f'expected "all" or a list of beam numbers, got {_show(v)}')
    return check


TABLE = {
    "freq_hz": (numbers(lo=0, lo_open=True), "natural frequencies, Hz, one per mode"),
    "zeta": (numbers(lo=0), "modal damping ratios (-), one per mode"),
    "shapes": (matrix(), "mass-normalised mode shapes, kg^-1/2: one row per mode, "
                         "one column per position"),
    "positions": (integers(), "position label of each column of shapes"),
}
BEAM = {
    "beam": (integer(1), "which beam (1-based) this entry overrides"),
    "freq_hz": TABLE["freq_hz"],
    "zeta": TABLE["zeta"],
    "shapes": TABLE["shapes"],
}
DIST_DOC = {
    "mu0": "friction coefficient (-), per damper",
    "kc": "tangential contact stiffness, N/m, per damper",
    "N0": "normal preload, N, per damper",
}

SPEC = {
    "model": {
        "preset": (choice(*PRESETS), "base rig; every other key overrides it"),
        "name": (string(), "free text, shown in plots and in `mcfric info`"),
        "n_beams": (integer(2, 100000), "number of beams (>= 2)"),
        "topology": (choice(*TOPOLOGIES), '"linear": n_beams - 1 dampers between '
                                          'neighbours; "circular": also last-first'),
        "contact": (integer(), "position label of the friction contacts"),
        "output": (integer(), "position label of the response output"),
        "drive": (integer(), "position label of the drive force"),
        "table": TABLE,
        "beam": BEAM,
    },
    "excitation": {
        "pattern": (choice(*PATTERNS), '"single": one beam; "mode": F0 cos(m pi (b - 1/2) / n); '
                                       '"travelling": F0 exp(-2 pi i E (b - 1) / n)'),
        "F0": (number(lo=0, lo_open=True), "force amplitude, N"),
        "beam": (integer(1), 'driven beam for "single" (1-based)'),
        "mode": (integer(0), 'chain mode m for "mode"'),
        "engine_order": (integer(), 'engine order E for "travelling"'),
    },
    "frequency": {
        "f_min": (number(lo=0, lo_open=True), "lowest frequency, Hz"),
        "f_max": (number(lo=0, lo_open=True), "highest frequency, Hz (> f_min)"),
        "n": (integer(2, MAX_FREQ), "number of frequencies (each sample sweeps them upward)"),
        "spacing": (choice(*SPACINGS), '"linear" or "log" spacing'),
    },
    "sampling": {
        "samples": (integer(1, MAX_SAMPLES), "ensemble size"),
        "seed": (integer(0, 2 ** 63 - 1), "root seed; sample i uses SeedSequence(seed, "
                                          "spawn_key=(i,))"),
        "mistuning": (number(lo=0, hi=sampling.MISTUNING_MAX),
                      "relative std of the modal frequencies (0 = none, max 0.1)"),
        "mistuning_per": (choice(*sampling.MISTUNING_PER),
                          '"beam": one factor per beam for all its modes; "mode": '
                          'one per beam and mode'),
        "mu0": "dist",
        "kc": "dist",
        "N0": "dist",
    },
    "metric": {
        "quantity": (choice(*QUANTITIES), "M = max over beams of omega^k |y| at the output "
                                          "position (k = 0, 1, 2)"),
        "beams": (beams_or_all(), '"all" or a list of beam numbers (1-based) to take the '
                                  'maximum over'),
    },
    "solver": {
        "tol": (number(lo=0, hi=0.1, lo_open=True),
                "accepted relative friction-force residual"),
        "max_iter": (integer(1, 10000), "Newton iterations per attempt"),
    },
    "output": {
        "keep_response": (boolean(), "store the complex response per beam; false keeps only "
                                     "the metric (for very large runs)"),
    },
    "run": {
        "threads": (integer(0), "numba threads (0 = all); never changes the results"),
        "chunk": (integer(0, 10 ** 7), "samples per chunk (0 = auto, ~32 MB of kernel output); "
                                       "never changes the results"),
        "checkpoint_s": (number(lo=0), "min seconds between crash-safe checkpoints "
                                       "(0 = after every chunk)"),
    },
    "bounds": {
        "enabled": (boolean(), "compute the equivalent-linear response bounds (physics.md 7) "
                               "before the ensemble, stored in bounds/"),
        "k_max": (auto_or_number(), 'largest stiffness Re K of a damper, N/m; "auto": the '
                                    'upper limit of the kc distribution'),
        "k_max_im": (auto_or_number(), 'largest dissipation Im K, N/m; "auto": k_max'),
        "F_lim": (auto_or_number(words=("auto", "none")),
                  'friction force limit (first harmonic), N; "auto": 4/pi mu0_max N0_max '
                  'from the sampling; "none": no force constraint'),
        "n_starts": (integer(1, 10000), "starts of the box search per frequency"),
    },
}
SECTION_DOC = {
    "model": "the beam array (physics.md 1-2)",
    "model.table": "modal table of every beam (paper Table 1)",
    "model.beam": "per-beam overrides of the table (mistuned or measured beams)",
    "excitation": "harmonic drive at the drive position (physics.md 4)",
    "frequency": "the frequency grid",
    "sampling": "the Monte Carlo ensemble (physics.md 6)",
    "metric": "response metric M stored per sample and frequency (physics.md 5)",
    "solver": "harmonic-balance solver",
    "output": "what the results file keeps",
    "run": "how to compute: never changes the results, not compared on --resume",
    "bounds": "equivalent-linear response bounds (physics.md 7): do not change the ensemble",
}


def _unknown(table, allowed, where):
    for k in table:
        if k not in allowed:
            names = ", ".join(allowed)
            raise ConfigError(f"{where}.{k}" if where else k,
                              f"unknown key; allowed in [{where}]: {names}" if where else
                              f"unknown section; allowed: {names}")


def _table(v, key):
    if not isinstance(v, dict):
        raise ConfigError(key, f"expected a table, got {_show(v)}")
    return v


def _check_table(raw, spec, where):
    _table(raw, where)
    _unknown(raw, spec, where)
    return {k: spec[k][0](raw[k], f"{where}.{k}") for k in spec if k in raw}


def _missing(key, doc):
    raise ConfigError(key, f"missing ({doc})")


def _check_dist(raw, key):
    _table(raw, key)
    if "dist" not in raw:
        raise ConfigError(f"{key}.dist", "missing; expected one of "
                          + _choices(sampling.DISTRIBUTIONS))
    dist = raw["dist"]
    if not isinstance(dist, str) or dist not in sampling.DISTRIBUTIONS:
        raise ConfigError(f"{key}.dist", f"expected one of {_choices(sampling.DISTRIBUTIONS)}, "
                          f"got {_show(dist)}")
    params = {k: v for k, v in raw.items() if k != "dist"}
    names = sampling.DISTRIBUTIONS[dist][1]
    for k, v in params.items():
        if k not in names:
            raise ConfigError(f"{key}.{k}", f"not a parameter of dist {json.dumps(dist)} "
                              f"(allowed: {', '.join(names)})")
        if isinstance(v, bool) or not _is_num(v):
            raise ConfigError(f"{key}.{k}", f"expected a number, got {_show(v)}")
    try:
        d = sampling.distribution(dist, **params)
    except ValueError as e:
        name, _, msg = str(e).partition(": ")
        raise ConfigError(f"{key}.{name}", msg) from None
    return sampling.as_dict(d)


def validate(raw, labels=None):
    """Validate a complete raw configuration (defaults + file + overrides).

    Parameters
    ----------
    raw : dict
        Nested dict as from ``tomllib`` merged over :func:`defaults`.
    labels : dict, optional
        Dotted key -> label used in messages instead (the CLI flag that set the key).

    Returns
    -------
    Config

    Raises
    ------
    ConfigError
        The first problem found, naming the key (or its label) and what is allowed.
    """
    labels = labels or {}
    try:
        return _validate(raw)
    except ConfigError as e:
        if e.alt and e.key not in labels and e.alt[0] in labels:
            e = ConfigError(*e.alt)    # blame the key the user changed on the command line
        if e.key in labels:
            raise ConfigError(labels[e.key], e.message) from None
        raise e from None


def _validate(raw):
    _table(raw, "config")
    _unknown(raw, SPEC, "")
    out = {}
    for sec, spec in SPEC.items():
        src = _table(raw.get(sec, {}), sec)
        _unknown(src, spec, sec)
        res = {}
        for k, entry in spec.items():
            key = f"{sec}.{k}"
            if k not in src:
                if sec == "model" and k == "beam":
                    res[k] = []
                    continue
                _missing(key, "every key must be given when validating without defaults")
            v = src[k]
            if entry == "dist":
                res[k] = _check_dist(v, key)
            elif k == "table" and sec == "model":
                res[k] = _check_table(v, TABLE, key)
                for t in TABLE:
                    if t not in res[k]:
                        _missing(f"{key}.{t}", TABLE[t][1])
            elif k == "beam" and sec == "model":
                if not isinstance(v, list):
                    raise ConfigError(key, f"expected an array of tables [[model.beam]], "
                                      f"got {_show(v)}")
                res[k] = []
                for n, item in enumerate(v, 1):
                    b = _check_table(item, BEAM, f"{key}[{n}]")
                    if "beam" not in b:
                        _missing(f"{key}[{n}].beam", BEAM["beam"][1])
                    res[k].append(b)
            else:
                res[k] = entry[0](v, key)
        out[sec] = res
    _cross_checks(out)
    cfg = Config(out)
    try:
        cfg.model()
    except ValueError as e:   # a rule of the Model itself that the checks above missed
        raise ConfigError("model", str(e)) from None
    return cfg


def _cross_checks(c):
    m, t = c["model"], c["model"]["table"]
    nb = m["n_beams"]
    n_modes = len(t["freq_hz"])
    if len(t["zeta"]) != n_modes:
        raise ConfigError("model.table.zeta", f"expected {n_modes} values (one per mode in "
                          f"freq_hz), got {len(t['zeta'])}")
    if len(t["shapes"]) != n_modes:
        raise ConfigError("model.table.shapes", f"expected {n_modes} rows (one per mode in "
                          f"freq_hz), got {len(t['shapes'])}")
    if len(t["shapes"][0]) != len(t["positions"]):
        raise ConfigError("model.table.positions", f"expected {len(t['shapes'][0])} labels "
                          f"(one per column of shapes), got {len(t['positions'])}")
    for k in ("contact", "output", "drive"):
        if m[k] not in t["positions"]:
            raise ConfigError(f"model.{k}", f"expected one of the table positions "
                              f"{t['positions']}, got {m[k]}")
    if m["topology"] == "circular" and nb < 3:
        raise ConfigError("model.topology", f'"circular" needs n_beams >= 3, got n_beams = {nb}')
    seen = set()
    for n, b in enumerate(m["beam"], 1):
        key = f"model.beam[{n}]"
        if not 1 <= b["beam"] <= nb:
            raise ConfigError(f"{key}.beam", f"expected an integer in 1..{nb} (n_beams), "
                              f"got {b['beam']}")
        if b["beam"] in seen:
            raise ConfigError(f"{key}.beam", f"beam {b['beam']} is overridden twice")
        seen.add(b["beam"])
        nm = len(b.get("freq_hz", t["freq_hz"]))
        for k in ("freq_hz", "zeta", "shapes"):
            got = len(b.get(k, t[k]))
            if got != nm:
                raise ConfigError(f"{key}.{k}", f"expected {nm} entries (one per mode), "
                                  f"got {got}; give freq_hz, zeta and shapes together to "
                                  f"change the number of modes")
        if "shapes" in b and len(b["shapes"][0]) != len(t["positions"]):
            raise ConfigError(f"{key}.shapes", f"expected {len(t['positions'])} columns "
                              f"(model.table.positions), got {len(b['shapes'][0])}")
    ex = c["excitation"]
    if not 1 <= ex["beam"] <= nb:
        raise ConfigError("excitation.beam", f"expected an integer in 1..{nb} (n_beams), "
                          f"got {ex['beam']}")
    fr = c["frequency"]
    if not fr["f_max"] > fr["f_min"]:
        raise ConfigError("frequency.f_max", f"expected a number > f_min ({fr['f_min']:g}), "
                          f"got {fr['f_max']:g}",
                          alt=("frequency.f_min", f"expected a number < f_max "
                                                  f"({fr['f_max']:g}), got {fr['f_min']:g}"))
    beams = c["metric"]["beams"]
    if beams != "all":
        for b in beams:
            if not 1 <= b <= nb:
                raise ConfigError("metric.beams", f"expected beam numbers in 1..{nb} "
                                  f"(n_beams), got {_show(beams)}")
    if c["bounds"]["enabled"]:
        _bounds_limits(c)      # unbounded distributions need explicit limits
    import numba
    nt = numba.config.NUMBA_NUM_THREADS
    if c["run"]["threads"] > nt:
        raise ConfigError("run.threads", f"expected an integer in 0..{nt} (0 = all {nt}), "
                          f"got {c['run']['threads']}")


def _dist_max(t):
    """Upper limit of a distribution table (inf where it has none)."""
    d = t["dist"]
    if d == "fixed":
        return float(t["value"])
    if d in ("uniform", "truncnormal"):
        return float(t["high"])
    return math.inf


def _bounds_limits(c):
    """(k_max_re, k_max_im, F_lim) in N/m, N/m, N from ``[bounds]`` and ``[sampling]``."""
    b, s = c["bounds"], c["sampling"]
    k_max = b["k_max"]
    if k_max == "auto":
        k_max = _dist_max(s["kc"])
        if not math.isfinite(k_max):
            raise ConfigError("bounds.k_max", f'"auto" needs a kc distribution with an upper '
                              f'limit ({s["kc"]["dist"]} has none): give k_max in N/m')
        if not k_max > 0:
            raise ConfigError("bounds.k_max", '"auto" needs kc > 0 somewhere: give k_max '
                              "in N/m or set bounds.enabled = false")
    k_im = k_max if b["k_max_im"] == "auto" else b["k_max_im"]
    F_lim = b["F_lim"]
    if F_lim == "none":
        F_lim = math.inf
    elif F_lim == "auto":
        mu, n0 = _dist_max(s["mu0"]), _dist_max(s["N0"])
        if not (math.isfinite(mu) and math.isfinite(n0)):
            which = "mu0" if not math.isfinite(mu) else "N0"
            raise ConfigError("bounds.F_lim", f'"auto" needs {which} with an upper limit '
                              f'({s[which]["dist"]} has none): give F_lim in N or "none"')
        F_lim = 4.0 / math.pi * mu * n0
        if not F_lim > 0:
            F_lim = math.inf      # no friction anywhere: the force constraint is void
    return float(k_max), float(k_im), float(F_lim)


# ----------------------------------------------------------------------------- loading

def _merge(base, top, path=""):
    """``top`` over ``base``; distribution tables and [[model.beam]] replace whole."""
    out = dict(base)
    for k, v in top.items():
        key = f"{path}.{k}" if path else k
        whole = key in ("sampling.mu0", "sampling.kc", "sampling.N0", "model.beam")
        if isinstance(v, dict) and isinstance(out.get(k), dict) and not whole:
            out[k] = _merge(out[k], v, key)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _set(tree, dotted, value):
    *head, last = dotted.split(".")
    for h in head:
        tree = tree.setdefault(h, {})
    tree[last] = value


def read_toml(path):
    """Parse a TOML file; problems become a one-line :class:`ConfigError` naming the file."""
    p = Path(path)
    try:
        text = p.read_bytes().decode("utf-8")
    except FileNotFoundError:
        raise ConfigError(str(path), "no such file (and not a preset: "
                          f"{_choices(PRESETS)})") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(str(path), f"cannot read: {e}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(str(path), f"invalid TOML: {e}") from None


def load(source=None, overrides=None):
    """Resolve and validate a configuration.

    Parameters
    ----------
    source : str, Path, dict or None
        A preset name, a TOML file path, an already-parsed dict (as from a TOML file), or
        None (the default preset, eight-beam).
    overrides : dict, optional
        ``{dotted key: (value, label)}``, e.g. ``{"sampling.samples": (500, "--samples")}``;
        errors in an override name its label. A None value is ignored.

    Returns
    -------
    Config
    """
    if source is None:
        user = {}
    elif isinstance(source, dict):
        user = copy.deepcopy(source)
    elif isinstance(source, str) and source in PRESETS:
        user = {"model": {"preset": source}}
    else:
        user = read_toml(source)
        _expand_modal_files(user, Path(source).parent)
    model = user.get("model", {})
    base_name = model.get("preset", DEFAULT_PRESET) if isinstance(model, dict) else DEFAULT_PRESET
    if not isinstance(base_name, str) or base_name not in PRESETS:
        raise ConfigError("model.preset", f"expected one of {_choices(PRESETS)}, "
                          f"got {_show(base_name)}")
    raw = _merge(defaults(base_name), user)
    labels = {}
    for key, (value, label) in (overrides or {}).items():
        if value is None:
            continue
        _set(raw, key, value)
        labels[key] = label
    return validate(raw, labels)


MODAL_FILE_KEYS = ("file", "nodes", "direction", "modes", "max_imag")


def _expand_modal_files(user, base):
    """Replace ``[model.table] file = ...`` (and per-beam ``file``) by the table read.

    The file (UFF 55, CSV or TOML; :func:`mcfric.modal_io.read_modal_table`) is read
    once, here: the validated configuration holds the numbers, so a results file records
    the modal data it was computed with. ``nodes = {contact, output, drive}`` maps the
    file's node numbers (CSV/TOML: position labels) to positions 1, 2, 3.
    """
    m = user.get("model")
    if not isinstance(m, dict):
        return
    beams = m.get("beam") if isinstance(m.get("beam"), list) else []
    items = [("model.table", m.get("table"))] + [(f"model.beam[{n}]", b)
                                                  for n, b in enumerate(beams, 1)]
    for key, t in items:
        if not isinstance(t, dict) or "file" not in t:
            continue
        extra = set(t) - set(MODAL_FILE_KEYS) - ({"beam"} if key != "model.table" else set())
        if extra:
            raise ConfigError(f"{key}.{sorted(extra)[0]}", "cannot be given together with "
                              "file (the file holds the whole table)")
        nodes = t.get("nodes")
        if (not isinstance(nodes, dict) or set(nodes) != {"contact", "output", "drive"}
                or not all(_is_int(v) for v in nodes.values())):
            raise ConfigError(f"{key}.nodes", "expected {contact = N, output = N, drive = N} "
                              f"(node numbers in the file), got {_show(nodes)}")
        if not isinstance(t["file"], str):
            raise ConfigError(f"{key}.file", f"expected a file name, got {_show(t['file'])}")
        path = Path(t["file"])
        if not path.is_absolute():
            path = base / path
        from .modal_io import read_modal_table
        try:
            table = read_modal_table(
                path, positions={1: nodes["contact"], 2: nodes["output"], 3: nodes["drive"]},
                direction=t.get("direction"), modes=t.get("modes"),
                max_imag=t.get("max_imag", 0.05))
        except (ValueError, ImportError, OSError) as e:
            raise ConfigError(f"{key}.file", str(e).splitlines()[0]) from None
        new = {"freq_hz": table.freq_hz.tolist(), "zeta": table.zeta.tolist(),
               "shapes": table.shapes.tolist()}
        if key == "model.table":
            new["positions"] = list(table.positions)
        else:
            new["beam"] = t.get("beam")
        t.clear()
        t.update(new)
        if key == "model.table":
            for role, label in (("contact", 1), ("output", 2), ("drive", 3)):
                if m.get(role, label) != label:
                    raise ConfigError(f"model.{role}", "is set by model.table.nodes when the "
                                      "table comes from a file; remove it")


# ----------------------------------------------------------------------------- Config

@dataclass(frozen=True)
class Config:
    """A validated, complete configuration (``data``: nested dict of canonical values)."""

    data: dict

    def __getitem__(self, section):
        return self.data[section]

    def model(self):
        """The :class:`~mcfric.model.Model` described by ``[model]`` and ``[excitation]``."""
        m, t = self.data["model"], self.data["model"]["table"]
        table = ModalTable(t["freq_hz"], t["zeta"], t["shapes"], tuple(t["positions"]))
        beams = [table] * m["n_beams"]
        for b in m["beam"]:
            beams[b["beam"] - 1] = ModalTable(b.get("freq_hz", t["freq_hz"]),
                                              b.get("zeta", t["zeta"]),
                                              b.get("shapes", t["shapes"]),
                                              tuple(t["positions"]))
        ex = Excitation(**self.data["excitation"])
        return Model(beams=tuple(beams), excitation=ex, topology=m["topology"],
                     contact=m["contact"], output=m["output"], drive=m["drive"],
                     name=m["name"])

    def frequencies(self):
        """The frequency grid, Hz, shape (n,), increasing."""
        f = self.data["frequency"]
        space = np.linspace if f["spacing"] == "linear" else np.geomspace
        return space(f["f_min"], f["f_max"], f["n"])

    def sampler(self, model=None):
        """The :class:`~mcfric.sampling.Sampler` of ``[sampling]``."""
        s = self.data["sampling"]
        model = model or self.model()
        dists = {k: sampling.distribution(s[k]["dist"],
                                          **{p: v for p, v in s[k].items() if p != "dist"})
                 for k in ("mu0", "kc", "N0")}
        return sampling.Sampler(seed=s["seed"], n_dampers=model.n_dampers,
                                modal_freq_hz=model.modal_arrays()[0],
                                mistuning=s["mistuning"], mistuning_per=s["mistuning_per"],
                                **dists)

    def bounds_limits(self):
        """(k_max_re, k_max_im, F_lim): the admissible region of the bounds, N/m, N/m, N
        (``F_lim`` inf: no force constraint)."""
        return _bounds_limits(self.data)

    def metric_beams(self):
        """0-based beams of the metric, or None for all."""
        b = self.data["metric"]["beams"]
        return None if b == "all" else [x - 1 for x in b]

    @property
    def samples(self):
        return self.data["sampling"]["samples"]

    @property
    def seed(self):
        return self.data["sampling"]["seed"]

    def identity(self):
        """The part of the configuration that determines the results (no [run], [bounds])."""
        return {k: v for k, v in self.data.items() if k not in NOT_IDENTITY}

    def json(self, identity=False):
        """Canonical JSON (sorted keys; floats round-trip exactly)."""
        return json.dumps(self.identity() if identity else self.data, sort_keys=True)

    def toml(self, comments=True):
        """The complete configuration as TOML (parses back to the same configuration)."""
        return render(self.data, comments)

    def replace(self, dotted, value):
        """A validated copy with one key changed (e.g. ``"sampling.samples"``)."""
        raw = copy.deepcopy(self.data)
        _set(raw, dotted, value)
        return validate(raw)


def first_difference(a, b, path=""):
    """Dotted key of the first difference between two nested dicts, or None."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            d = first_difference(a.get(k), b.get(k), f"{path}.{k}" if path else k)
            if d:
                return d
        return None
    return None if a == b else path


# ----------------------------------------------------------------------------- rendering

def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)       # a TOML basic string for printable text
    if isinstance(v, float):
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot render {v!r}")


def _lines(table, spec, comments, pad=28):
    out = []
    for k, v in table.items():
        if isinstance(v, dict) or isinstance(spec.get(k), dict):
            continue   # sub-tables ([model.table], [[model.beam]], [sampling.mu0]) follow
        line = f"{k} = {_toml_value(v)}"
        doc = spec.get(k, (None, ""))[1] if isinstance(spec.get(k), tuple) else ""
        if comments and doc:
            line = f"{line:<{pad}} # {doc}"
        out.append(line)
    return out


def render(data, comments=True):
    """A configuration dict as TOML text, sections in schema order, with comments."""
    out = []
    if comments:
        out += ["# mcfric run configuration (TOML). Units: Hz, N, N/m, m.",
                "# Start from `mcfric config PRESET`; run with `mcfric run THIS.toml -o out.h5`.",
                ""]

    def header(name, array=False):
        h = f"[[{name}]]" if array else f"[{name}]"
        if comments and name in SECTION_DOC:
            h = f"{h:<28} # {SECTION_DOC[name]}"
        out.append(h)

    for sec, spec in SPEC.items():
        table = data[sec]
        header(sec)
        out.extend(_lines(table, spec, comments))
        out.append("")
        if sec == "model":
            header("model.table")
            out.extend(_lines(table["table"], TABLE, comments))
            out.append("")
            if table["beam"]:
                for b in table["beam"]:
                    header("model.beam", array=True)
                    out.extend(_lines(b, BEAM, comments))
                    out.append("")
            elif comments:
                out += ["# [[model.beam]]            # e.g. the paper's Fig. 10b: beam 2 "
                        "with f2 = 108 Hz",
                        "# beam = 2", "# freq_hz = [16.2, 108.0]", ""]
        if sec == "sampling":
            for k in ("mu0", "kc", "N0"):
                h = f"[sampling.{k}]"
                if comments:
                    h = f"{h:<28} # {DIST_DOC[k]}"
                out.append(h)
                out.extend(_lines(table[k], {}, comments))
                out.append("")
    if comments:
        out += ["# distributions: fixed(value), uniform(low, high), normal(mean, std; "
                "mean >= 3 std),",
                "#   truncnormal(mean, std, low, high; high may be inf), "
                "lognormal(median, sigma = std of ln)"]
    return "\n".join(out).rstrip() + "\n"


def template(preset=DEFAULT_PRESET):
    """The complete, commented configuration of a preset (``mcfric config PRESET``)."""
    return render(validate(defaults(preset)).data)
