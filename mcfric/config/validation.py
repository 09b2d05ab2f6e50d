"""Validation of a whole configuration: the schema's checks plus the cross-key rules.

:func:`validate` checks every key against :mod:`.schema`, then the rules that involve
several keys (table sizes, positions, the band, the bounds' limits), then builds the
model once to catch what only the model knows. The first problem raises a one-line
:class:`~mcfric.validators.InputError` naming the key (or the command-line flag that set
it).
"""

from __future__ import annotations

import json
import math

import numpy as np

from .. import sampling
from ..bounds.equivalent_linear import K_MAX_LIMIT, past_limits
from ..validators import SLIP_FORCE_MAX, InputError, choices, is_num, show
from . import configuration  # at call time: configuration imports this module
from .schema import BEAM, SPEC, TABLE, defaults


def _unknown(table, allowed, where):
    for k in table:
        if k not in allowed:
            names = ", ".join(allowed)
            raise InputError(f"{where}.{k}" if where else k,
                             f"unknown key; allowed in [{where}]: {names}" if where else
                             f"unknown section; allowed: {names}")


def _table(v, key):
    if not isinstance(v, dict):
        raise InputError(key, f"expected a table, got {show(v)}")
    return v


def _check_table(raw, spec, where):
    _table(raw, where)
    _unknown(raw, spec, where)
    return {k: spec[k][0](raw[k], f"{where}.{k}") for k in spec if k in raw}


def _missing(key, doc):
    raise InputError(key, f"missing ({doc})")


def _check_dist(raw, key):
    _table(raw, key)
    if "dist" not in raw:
        raise InputError(f"{key}.dist", "missing; expected one of "
                         + choices(sampling.DISTRIBUTIONS))
    dist = raw["dist"]
    if not isinstance(dist, str) or dist not in sampling.DISTRIBUTIONS:
        raise InputError(f"{key}.dist", f"expected one of {choices(sampling.DISTRIBUTIONS)}, "
                         f"got {show(dist)}")
    params = {k: v for k, v in raw.items() if k != "dist"}
    names = sampling.DISTRIBUTIONS[dist][1]
    for k, v in params.items():
        if k not in names:
            raise InputError(f"{key}.{k}", f"not a parameter of dist {json.dumps(dist)} "
                             f"(allowed: {', '.join(names)})")
        if isinstance(v, bool) or not is_num(v):
            raise InputError(f"{key}.{k}", f"expected a number, got {show(v)}")
    try:
        d = sampling.distribution(dist, **params)
    except ValueError as e:
        name, _, msg = str(e).partition(": ")
        raise InputError(f"{key}.{name}", msg) from None
    return sampling.as_dict(d)


def check_keys(raw, keys):
    """Check only ``keys`` (``{section: (key, ...)}``) of ``raw`` against the schema.

    For a configuration stored in a results file, of which a reader uses a few keys: the
    record may predate keys added since (so :func:`validate` would refuse it), but a value
    a reader formats or looks up must be what the schema allows (an edited file: one
    line, not a traceback). Raises :class:`~mcfric.validators.InputError`.
    """
    _table(raw, "configuration")
    for section, names in keys.items():
        table = _table(raw.get(section), section)
        for k in names:
            if k not in table:
                _missing(f"{section}.{k}", "a reader of the file uses it")
            check = SPEC[section][k]
            if check == "dist":
                _check_dist(table[k], f"{section}.{k}")
            else:
                check[0](table[k], f"{section}.{k}")


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
    InputError
        The first problem found, naming the key (or its label) and what is allowed.
    """
    labels = labels or {}
    try:
        return _validate(raw)
    except InputError as e:
        if e.alt and e.key not in labels and e.alt[0] in labels:
            e = InputError(*e.alt)    # blame the key the user changed on the command line
        if e.key in labels:
            raise InputError(labels[e.key], e.message) from None
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
                    raise InputError(key, f"expected an array of tables [[model.beam]], "
                                     f"got {show(v)}")
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
    cfg = configuration.Config(out)
    try:
        cfg.spec            # resolved once, here: the model, sampler and grid are built
    except InputError as e:
        if e.key.startswith(("model.", "sampling.", "bounds.")):
            raise                 # already names its key
        raise InputError("model", str(e)) from None
    except ValueError as e:   # a rule of the Model itself that the checks above missed
        key, _, message = str(e).partition(": ")
        if key in ("drive", "output"):      # shapes all zero there
            raise InputError(_zero_shapes_key(out["model"], key),
                             f"{message} (or model.{key} names the wrong position)") from None
        raise InputError("model", str(e)) from None
    return cfg


def _zero_shapes_key(m, label):
    """The shapes to blame for a column of zeros at position ``m[label]``: the table's if
    its column is zero, else the first per-beam override whose column is."""
    col = m["table"]["positions"].index(m[label])
    if not any(row[col] for row in m["table"]["shapes"]):
        return "model.table.shapes"
    for n, b in enumerate(m["beam"], 1):
        if "shapes" in b and not any(row[col] for row in b["shapes"]):
            return f"model.beam[{n}].shapes"
    return "model.table.shapes"


def _cross_checks(c):
    m, t = c["model"], c["model"]["table"]
    nb = m["n_beams"]
    n_modes = len(t["freq_hz"])
    if len(t["zeta"]) != n_modes:
        raise InputError("model.table.zeta", f"expected {n_modes} values (one per mode in "
                         f"freq_hz), got {len(t['zeta'])}")
    if len(t["shapes"]) != n_modes:
        raise InputError("model.table.shapes", f"expected {n_modes} rows (one per mode in "
                         f"freq_hz), got {len(t['shapes'])}")
    if len(t["shapes"][0]) != len(t["positions"]):
        raise InputError("model.table.positions", f"expected {len(t['shapes'][0])} labels "
                         f"(one per column of shapes), got {len(t['positions'])}")
    for k in ("contact", "output", "drive"):
        if m[k] not in t["positions"]:
            raise InputError(f"model.{k}", f"expected one of the table positions "
                             f"{t['positions']}, got {m[k]}")
    if m["topology"] == "circular" and nb < 3:
        raise InputError("model.topology", f'"circular" needs n_beams >= 3, got n_beams = {nb}')
    seen = set()
    for n, b in enumerate(m["beam"], 1):
        key = f"model.beam[{n}]"
        if not 1 <= b["beam"] <= nb:
            raise InputError(f"{key}.beam", f"expected an integer in 1..{nb} (n_beams), "
                             f"got {b['beam']}")
        if b["beam"] in seen:
            raise InputError(f"{key}.beam", f"beam {b['beam']} is overridden twice")
        seen.add(b["beam"])
        nm = len(b.get("freq_hz", t["freq_hz"]))
        for k in ("freq_hz", "zeta", "shapes"):
            got = len(b.get(k, t[k]))
            if got != nm:
                raise InputError(f"{key}.{k}", f"expected {nm} entries (one per mode), "
                                 f"got {got}; give freq_hz, zeta and shapes together to "
                                 f"change the number of modes")
        if "shapes" in b and len(b["shapes"][0]) != len(t["positions"]):
            raise InputError(f"{key}.shapes", f"expected {len(t['positions'])} columns "
                             f"(model.table.positions), got {len(b['shapes'][0])}")
    ex = c["excitation"]
    if ex["engine_orders"] and ex["pattern"] != "travelling":
        raise InputError("excitation.engine_orders", f'a list of engine orders needs '
                         f'pattern = "travelling", got pattern = "{ex["pattern"]}"')
    if ex["pattern"] == "travelling":
        # a sweep replaces engine_order (the preset's may not fit the beams: two-beam's 2)
        key = "excitation.engine_orders" if ex["engine_orders"] else "excitation.engine_order"
        for E in ex["engine_orders"] or [ex["engine_order"]]:
            if not 0 <= E < nb:
                raise InputError(key, f"expected engine orders in 0..{nb - 1} (n_beams - 1; "
                                 f"E and E + n_beams are the same wave), got {E}")
    if ex["pattern"] == "mode" and not ex["mode"] < nb:
        raise InputError("excitation.mode", f"expected a chain mode in 0..{nb - 1} (n_beams "
                         f"- 1; m = n_beams drives no beam), got {ex['mode']}")
    if not 1 <= ex["beam"] <= nb:
        raise InputError("excitation.beam", f"expected an integer in 1..{nb} (n_beams), "
                         f"got {ex['beam']}")
    fr = c["frequency"]
    if not fr["f_max"] > fr["f_min"]:
        raise InputError("frequency.f_max", f"expected a number > f_min ({fr['f_min']:g}), "
                         f"got {fr['f_max']:g}",
                         alt=("frequency.f_min", f"expected a number < f_max "
                                                  f"({fr['f_max']:g}), got {fr['f_min']:g}"))
    space = np.linspace if fr["spacing"] == "linear" else np.geomspace
    if not np.all(np.diff(2.0 * np.pi * space(fr["f_min"], fr["f_max"], fr["n"])) > 0):
        # a band narrower than rounding repeats frequencies (the peaks need them rising,
        # in rad/s as the kernels take them)
        raise InputError("frequency.n", f"{fr['n']} points between f_min = {fr['f_min']!r} "
                         f"and f_max = {fr['f_max']!r} Hz repeat frequencies in floating "
                         f"point; widen the band or use fewer points")
    beams = c["metric"]["beams"]
    if beams != "all":
        for b in beams:
            if not 1 <= b <= nb:
                raise InputError("metric.beams", f"expected beam numbers in 1..{nb} "
                                 f"(n_beams), got {show(beams)}")
    kc = c["sampling"]["kc"]
    top = _draw_max(kc)
    if top > K_MAX_LIMIT:
        # the solver refuses such a draw: found here, not in the middle of the run
        key = "sampling.kc." + {"fixed": "value", "normal": "std",
                                "lognormal": "sigma"}.get(kc["dist"], "high")
        raise InputError(key, f"expected draws of at most {K_MAX_LIMIT:g} N/m (a stuck "
                         f"contact); this distribution reaches {top:.3g}" +
                         (" (8.3 standard deviations: the draws' reach)"
                          if kc["dist"] in ("normal", "lognormal") else ""))
    s = c["sampling"]
    top = _reach(s["mu0"]) * _reach(s["N0"])
    if top > SLIP_FORCE_MAX:
        # as for kc: the solvers refuse such draws, so they are refused before the run
        raise InputError("sampling.mu0 x sampling.N0", f"expected draws with mu0 N0 of at "
                         f"most {SLIP_FORCE_MAX:g} N (a stuck damper); the two "
                         f"distributions reach {top:.3g}")
    if c["bounds"]["enabled"]:
        bounds_limits(c)      # unbounded distributions need explicit limits
    sv = c["solver"]
    if sv["n_time"] and sv["n_time"] < 4 * sv["harmonics"] + 4:
        raise InputError("solver.n_time", f"expected 0 (auto) or an integer >= "
                         f"{4 * sv['harmonics'] + 4} (4 H + 4 for harmonics = "
                         f"{sv['harmonics']}), got {sv['n_time']}")
    import numba
    nt = numba.config.NUMBA_NUM_THREADS
    if c["run"]["threads"] > nt:
        raise InputError("run.threads", f"expected an integer in 0..{nt} (0 = all {nt}), "
                         f"got {c['run']['threads']}")


def _dist_max(t):
    """Upper limit of a distribution table (inf where it has none)."""
    d = t["dist"]
    if d == "fixed":
        return float(t["value"])
    if d in ("uniform", "truncnormal"):
        return float(t["high"])
    return math.inf


def _draw_max(t):
    """The largest value a distribution table can draw: its upper limit, or for the
    unbounded ones 8.3 standard deviations (the uniforms' reach, ``ndtri(2^-53)`` = -8.2)."""
    d = t["dist"]
    if d == "normal":
        return float(t["mean"]) + 8.3 * float(t["std"])
    if d == "lognormal":
        return float(t["median"]) * math.exp(min(8.3 * float(t["sigma"]), 700.0))
    return _dist_max(t)


def _reach(t):
    """:func:`_draw_max`, with a truncated normal open above (``high = inf``, allowed for
    mu0 and N0) taken to reach 8.3 standard deviations above ``max(low, mean)``."""
    if t["dist"] == "truncnormal" and math.isinf(float(t["high"])):
        return max(float(t["low"]), float(t["mean"])) + 8.3 * float(t["std"])
    return _draw_max(t)


def _single_harmonic(c):
    return c["solver"]["harmonics"] == 1


#: Settings that do nothing under others: ``(dotted key, whether it is idle in a
#: configuration, why)``.
_IDLE = (
    ("solver.n_time", _single_harmonic, "solver.harmonics = 1 (the describing function "
                                        "is exact there; AFT is multi-harmonic)"),
    ("output.keep_harmonics", _single_harmonic, "solver.harmonics = 1 (single-harmonic "
                                                "balance)"),
    ("output.keep_harmonics", lambda c: not c["output"]["keep_response"],
     "output.keep_response = false"),
    *((f"peaks.{k}", lambda c: not c["peaks"]["enabled"], "peaks.enabled = false")
      for k in ("count", "rtol", "window")),
    *((f"peaks.{k}", lambda c: not _single_harmonic(c), "peaks are refined in "
                                                         "single-harmonic runs only")
      for k in ("count", "rtol", "window")),
    *((f"bounds.{k}", lambda c: not c["bounds"]["enabled"], "bounds.enabled = false")
      for k in ("k_max", "k_max_im", "F_lim", "n_starts", "certify", "certify_budget",
                "certify_split", "certify_moments")),
    *((f"bounds.{k}", lambda c: c["bounds"]["enabled"] and not c["bounds"]["certify"],
       "bounds.certify = false") for k in ("certify_budget", "certify_split",
                                            "certify_moments")),
    ("sampling.mistuning_per", lambda c: c["sampling"]["mistuning"] == 0,
     "sampling.mistuning = 0"),
    ("excitation.beam", lambda c: c["excitation"]["pattern"] != "single",
     'excitation.pattern is not "single"'),
    ("excitation.mode", lambda c: c["excitation"]["pattern"] != "mode",
     'excitation.pattern is not "mode"'),
    ("excitation.engine_order", lambda c: c["excitation"]["pattern"] != "travelling",
     'excitation.pattern is not "travelling"'),
    ("excitation.engine_order", lambda c: bool(c["excitation"]["engine_orders"]),
     "excitation.engine_orders lists the orders"),
)


def idle_settings(c, sections=None):
    """The settings changed from the preset's defaults that do nothing in configuration
    ``c`` (a peak setting with the peaks off, ``solver.n_time`` with one harmonic, ...):
    one phrase each, ``"KEY = VALUE does nothing: WHY"``; empty where there are none.

    A value equal to the default is not named: a complete file (``mcfric config``)
    holds every key. ``sections``: only the settings of these tables (``mcfric bounds``
    reads ``[bounds]``, ``[peaks]`` and ``[excitation]``, not the ensemble's), or all.
    """
    base = defaults(c["model"]["preset"])
    out = []
    for key, idle, why in _IDLE:
        section, name = key.split(".")
        if sections is not None and section not in sections:
            continue
        value = c[section][name]
        if value != base[section][name] and idle(c) and not any(o.startswith(f"{key} =")
                                                                for o in out):
            out.append(f"{key} = {_toml_value(value)} does nothing: {why}")
    return out


def _toml_value(v):
    return json.dumps(v) if isinstance(v, (bool, str)) else f"{v:g}" if is_num(v) else show(v)


def bounds_shortfalls(c):
    """Where ``[bounds]``' constraints leave out friction the sampling draws: one phrase
    per constraint (empty where they cover every member, or the bounds are off).

    The bounds hold for the members whose dampers keep inside their constraints
    (:func:`~mcfric.bounds.equivalent_linear.past_limits`, as :meth:`Bounds.admits
    <mcfric.bounds.Bounds.admits>` checks members); ``"auto"`` limits cover the sampling by
    construction, given ones may not (a unit slip: 15 for 15 kN/m). Unbounded
    distributions (normal, lognormal) are not looked at: their tails are counted after
    the run.
    """
    if not c["bounds"]["enabled"]:
        return []
    k_max, k_im, F_lim = bounds_limits(c)
    s = c["sampling"]
    # upper limits only: an unbounded distribution's tail past a given limit is left to
    # the check after the run, which counts the members it left out
    kc, mu, n0 = (_dist_max(s[k]) for k in ("kc", "mu0", "N0"))
    kc, mu, n0 = (x if math.isfinite(x) else 0.0 for x in (kc, mu, n0))
    re, im, force = past_limits(mu, kc, n0, k_max, k_im, F_lim)
    out = []
    if re:
        out.append(f"k_max = {k_max:g} N/m is below the largest kc drawn, {kc:g} N/m")
    if im:
        out.append(f"k_max_im = {k_im:g} N/m is below the largest kc / pi drawn, "
                   f"{kc / math.pi:g} N/m")
    if force:
        out.append(f"F_lim = {F_lim:g} N is below the largest 4/pi mu0 N0 drawn, "
                   f"{4.0 / math.pi * mu * n0:g} N")
    return out


def bounds_limits(c):
    """(k_max_re, k_max_im, F_lim) in N/m, N/m, N from ``[bounds]`` and ``[sampling]``."""
    b, s = c["bounds"], c["sampling"]
    k_max = b["k_max"]
    if k_max == "auto":
        k_max = _dist_max(s["kc"])
        if not math.isfinite(k_max):
            raise InputError("bounds.k_max", f'"auto" needs a kc distribution with an upper '
                             f'limit ({s["kc"]["dist"]} has none): give k_max in N/m')
        if not k_max > 0:
            raise InputError("bounds.k_max", '"auto" needs kc > 0 somewhere: give k_max '
                             "in N/m or set bounds.enabled = false")
    k_im = k_max if b["k_max_im"] == "auto" else b["k_max_im"]
    for key, k in (("bounds.k_max", k_max), ("bounds.k_max_im", k_im)):
        # far stiffer than any contact (a stuck damper); beyond it the search overflows
        if k > K_MAX_LIMIT:
            raise InputError(key, f"expected at most {K_MAX_LIMIT:g} N/m (a stuck damper), "
                             f"got {k:g}" + (" from the kc distribution's upper limit"
                                             if b[key.split('.')[1]] == "auto" else ""))
    F_lim = b["F_lim"]
    if F_lim == "none":
        F_lim = math.inf
    elif F_lim == "auto":
        mu, n0 = _dist_max(s["mu0"]), _dist_max(s["N0"])
        if not (math.isfinite(mu) and math.isfinite(n0)):
            which = "mu0" if not math.isfinite(mu) else "N0"
            raise InputError("bounds.F_lim", f'"auto" needs {which} with an upper limit '
                             f'({s[which]["dist"]} has none): give F_lim in N or "none"')
        F_lim = 4.0 / math.pi * mu * n0
        if not F_lim > 0:
            # no friction anywhere: a force limit of 0 is no bound the certificate can
            # take, and "none" (the box alone) would hide that: the user decides
            raise InputError("bounds.F_lim", f'"auto" gives 4/pi x {mu:g} x {n0:g} = 0 N '
                             f"(mu0 or N0 is 0 for every member): give F_lim in N, "
                             f'"none", or set bounds.enabled = false')
    return float(k_max), float(k_im), float(F_lim)
