"""The package's one library of input checks: each failure is one line naming the input.

Every check raises :class:`InputError` (a ``ValueError``) whose message starts with the
name of the offending input: a dotted configuration key (``sampling.kc.high``), a
command-line flag (``--samples``) or a Python argument (``freq_hz``). The command line
prints that line and exits with code 2.

Two kinds of check live here:

* **value checks** for configuration keys, flags and scalar arguments. ``integer``,
  ``number``, ``choice``, ... build a check; the check is called as ``check(value, key)``
  and returns the canonical value (``number`` returns a float) or raises. Each check
  carries a ``what`` text where one exists (``"an integer in 1..10"``), used in messages;
* **array checks** for the Python API (:func:`finite_array`, :func:`frequencies`,
  :func:`per_damper`), which return contiguous float arrays.
"""

from __future__ import annotations

import datetime
import json
import math
import re

import numpy as np

from .scalars import is_bool, is_int


class InputError(ValueError):
    """Bad input: ``key`` (what was wrong) and ``message`` (what is allowed).

    ``alt`` is ``(key, message)``: the same problem blamed on another key, for a pair of
    keys that contradict each other (the command line blames the one the user set).
    """

    def __init__(self, key, message, alt=None):
        super().__init__(f"{key}: {message}")
        self.key = key
        self.message = message
        self.alt = alt


# ------------------------------------------------------------------ formatting

def show(v):
    """A value as the user wrote it (TOML spelling: ``true``, ``"text"``, ``inf``)."""
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "a table"
    if isinstance(v, float) and math.isinf(v):
        return "inf" if v > 0 else "-inf"
    if isinstance(v, list):
        s = "[" + ", ".join(show(x) for x in v) + "]"
        return s if len(s) <= 60 else s[:57] + "...]"
    if isinstance(v, (datetime.date, datetime.time)):    # TOML dates and times
        return f"the date or time {v.isoformat()}"
    return repr(v)


def choices(options):
    """``"a", "b", "c"``: the allowed words of a choice."""
    return ", ".join(json.dumps(o) for o in options)


def is_num(v):
    """True for a real number that is not a boolean."""
    return (isinstance(v, (int, float, np.integer, np.floating))
            and not is_bool(v))


# ------------------------------------------------------------------ value checks

def integer(lo=None, hi=None):
    """An integer in ``lo..hi`` (either end optional)."""
    if lo is not None and hi is not None:
        what = f"an integer in {lo}..{hi}"
    elif lo is not None:
        what = f"an integer >= {lo}"
    else:
        what = "an integer"

    def check(v, key):
        if not is_int(v) or (lo is not None and v < lo) or (hi is not None and v > hi):
            raise InputError(key, f"expected {what}, got {show(v)}")
        return int(v)
    check.what = what
    return check


def odd_integer(lo, hi):
    """An odd integer in ``lo..hi``."""
    what = f"an odd integer in {lo}..{hi}"

    def check(v, key):
        if not is_int(v) or v < lo or v > hi or v % 2 == 0:
            raise InputError(key, f"expected {what}, got {show(v)}")
        return int(v)
    check.what = what
    return check


def number(lo=None, hi=None, lo_open=False, hi_open=False, allow_inf=False):
    """A real number (finite unless ``allow_inf``) within optional limits; returns a float."""
    parts = []
    if lo is not None:
        parts.append(f"{'>' if lo_open else '>='} {lo:g}")
    if hi is not None:
        parts.append(f"{'<' if hi_open else '<='} {hi:g}")
    what = "a number" + (" " + " and ".join(parts) if parts else "")
    if not allow_inf:
        what = "a finite number" + what[len("a number"):]

    def check(v, key):
        ok = is_num(v) and not math.isnan(v) and (allow_inf or not math.isinf(v))
        if ok and lo is not None:
            ok = v > lo if lo_open else v >= lo
        if ok and hi is not None:
            ok = v < hi if hi_open else v <= hi
        if not ok:
            raise InputError(key, f"expected {what}, got {show(v)}")
        return float(v)
    check.what = what
    return check


def real(name, value, *, lo=None, lo_open=False, allow_inf=False):
    """A float argument, checked step by step; the message names the step that failed.

    Unlike :func:`number` (which states the whole requirement, as the configuration
    reference does), this says what is wrong: not a number, not finite, or below ``lo``.
    """
    if not is_num(value):
        raise InputError(name, f"expected a number, got {value!r}")
    v = float(value)
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise InputError(name, f"expected a finite number, got {value!r}")
    if lo is not None and (v <= lo if lo_open else v < lo):
        raise InputError(name, f"expected a number {'>' if lo_open else '>='} {lo:g}, "
                         f"got {value!r}")
    return v


#: Accepted relative residuals of the harmonic balance: below ``RESIDUAL_TOL_MIN`` the
#: residual is at the rounding of double precision (about 1e-15 of the forces), where no
#: solver can tell converged from not.
RESIDUAL_TOL_MIN = 1e-14
RESIDUAL_TOL_MAX = 0.1


def residual_tol(name, value):
    """An accepted relative residual: a number in ``RESIDUAL_TOL_MIN .. RESIDUAL_TOL_MAX``."""
    if not (is_num(value) and RESIDUAL_TOL_MIN <= value <= RESIDUAL_TOL_MAX):
        raise InputError(name, f"expected a number in {RESIDUAL_TOL_MIN:g}..{RESIDUAL_TOL_MAX:g} "
                               f"(below {RESIDUAL_TOL_MIN:g} the residual is at the rounding "
                               f"of double precision), got {value!r}")
    return float(value)


def fraction(name, value):
    """A tolerance argument: a finite number strictly between 0 and 1, as a float."""
    if not (is_num(value) and math.isfinite(value) and 0 < value < 1):
        raise InputError(name, f"expected a number in (0, 1), got {value!r}")
    return float(value)


def choice(*options):
    """One of the words ``options``."""
    def check(v, key):
        if not isinstance(v, str) or v not in options:
            raise InputError(key, f"expected one of {choices(options)}, got {show(v)}")
        return v
    return check


def string(nonblank=False):
    """Text without control characters (a NUL or a newline would break files and the
    one-line outputs); ``nonblank``: not empty or spaces alone either."""
    def check(v, key):
        if not isinstance(v, str):
            raise InputError(key, f"expected a string, got {show(v)}")
        if any(ord(c) < 32 or ord(c) == 127 for c in v):
            raise InputError(key, f"expected text without control characters, got {v!r}")
        if nonblank and not v.strip():
            raise InputError(key, "expected a non-blank name, got "
                                  + ("an empty one" if not v else "spaces alone"))
        return v
    return check


def scheduler_address():
    """``""`` (this process), ``"local:N"`` (a local cluster of N worker processes) or a
    Dask scheduler address ``scheme://host:port``."""
    what = '"" (run here), "local:N" (N = 1..1024) or a scheduler address "tcp://host:port"'

    def check(v, key):
        if not isinstance(v, str):
            raise InputError(key, f"expected {what}, got {show(v)}")
        v = v.strip()
        if v == "":
            return v
        m = re.fullmatch(r"local:(\d+)", v)
        if m and 1 <= int(m.group(1)) <= 1024:
            return v
        # Dask's own schemes: others pass here and fail only when the run connects
        if not m and re.fullmatch(r"(tcp|tls|ucx|ws|wss|inproc)://[^\s/]+(/\S*)?", v):
            port = re.fullmatch(r"(tcp|tls|ws|wss)://[^\s/]+:(\d*)(/\S*)?", v)
            if port and not (port.group(2) and 1 <= int(port.group(2)) <= 65535):
                # found now, not after the connection's timeout
                raise InputError(key, f"expected a port in 1..65535, got "
                                 f"{port.group(2) or 'none'} in {show(v)}")
            return v
        raise InputError(key, f"expected {what}, got {show(v)}")
    check.what = what
    return check


def flag(name, value):
    """A Python argument that must be True or False (numpy's booleans too): a word such as
    ``"no"`` is a true value, so it is refused, not read; returns a Python bool."""
    if not is_bool(value):
        raise InputError(name, f"expected True or False, got {value!r}")
    return bool(value)


def boolean():
    """``true`` or ``false`` (numpy's booleans too); returns a Python bool."""
    def check(v, key):
        if not is_bool(v):
            raise InputError(key, f"expected true or false, got {show(v)}")
        return bool(v)
    return check


def numbers(lo=None, lo_open=False, nonempty=True, hi=None):
    """A list of finite numbers, each within the limits; returns a list of floats."""
    item = number(lo=lo, lo_open=lo_open, hi=hi)
    what = "a list of " + item.what.replace("a finite number", "finite numbers")

    def check(v, key):
        if not isinstance(v, list) or (nonempty and not v):
            raise InputError(key, f"expected {what}, got {show(v)}")
        try:
            return [item(x, key) for x in v]
        except InputError:
            raise InputError(key, f"expected {what}, got {show(v)}") from None
    return check


def matrix():
    """A non-empty list of rows of finite numbers, all rows of one length."""
    def check(v, key):
        what = "a list of rows (lists of finite numbers) of equal length"
        if (not isinstance(v, list) or not v or not all(isinstance(r, list) and r for r in v)
                or len({len(r) for r in v}) != 1
                or not all(is_num(x) and math.isfinite(x) for r in v for x in r)):
            raise InputError(key, f"expected {what}, got {show(v)}")
        return [[float(x) for x in r] for r in v]
    return check


def integers():
    """A non-empty list of distinct integers."""
    def check(v, key):
        if not isinstance(v, list) or not v or not all(is_int(x) for x in v):
            raise InputError(key, f"expected a non-empty list of integers, got {show(v)}")
        if len(set(v)) != len(v):
            raise InputError(key, f"expected distinct integers, got {show(v)}")
        return list(v)
    return check


def integer_list(lo=0):
    """A list of distinct integers >= ``lo``, possibly empty."""
    def check(v, key):
        if not isinstance(v, list) or not all(is_int(x) and x >= lo for x in v):
            raise InputError(key, f"expected a list of integers >= {lo}, got {show(v)}")
        if len(set(v)) != len(v):
            raise InputError(key, f"expected distinct integers, got {show(v)}")
        return [int(x) for x in v]
    return check


def auto_or_number(lo=0, words=("auto",)):
    """``"auto"`` (or another of ``words``) or a number > ``lo``."""
    num = number(lo=lo, lo_open=True)

    def check(v, key):
        if isinstance(v, str):
            if v in words:
                return v
            raise InputError(key, f"expected {choices(words)} or a number > {lo:g}, "
                             f"got {show(v)}")
        return num(v, key)
    return check


def auto_or_boolean():
    """``"auto"``, ``true`` or ``false``."""
    def check(v, key):
        if v == "auto":
            return v
        if is_bool(v):
            return bool(v)
        raise InputError(key, f'expected "auto", true or false, got {show(v)}')
    return check


def auto_or_integer(lo, hi):
    """``"auto"`` or an integer in ``lo..hi``."""
    whole = integer(lo, hi)

    def check(v, key):
        if v == "auto":
            return v
        if isinstance(v, str):
            raise InputError(key, f'expected "auto" or {whole.what}, got {show(v)}')
        return whole(v, key)
    return check


def beams_or_all():
    """``"all"`` or a list of beam numbers."""
    ints = integers()

    def check(v, key):
        if v == "all":
            return v
        if isinstance(v, list):
            return ints(v, key)
        raise InputError(key, f'expected "all" or a list of beam numbers, got {show(v)}')
    return check


# ------------------------------------------------------------------ array checks

def real_array(name, value):
    """``value`` as a float array, refusing strings, booleans and complex numbers (numpy
    would convert the first two, and drop the imaginary part with only a warning)."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(name, f"expected numbers, got {value!r}") from None
    if raw.dtype.kind not in "iuf":
        raise InputError(name, f"expected real numbers, got {_kind_word(raw.dtype)}")
    return raw.astype(float)


def _kind_word(dtype):
    return {"b": "booleans", "c": "complex numbers", "U": "text", "S": "bytes",
            "O": "mixed or non-numeric values"}.get(dtype.kind, f"{dtype} values")


def finite_array(name, value, ndim, positive=False, nonnegative=False):
    """A read-only float array of ``ndim`` dimensions, finite, optionally > 0 or >= 0."""
    arr = np.array(real_array(name, value))
    if arr.ndim != ndim:
        raise InputError(name, f"expected a {ndim}-d array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(name, "values must be finite (no NaN or inf)")
    if positive and not np.all(arr > 0):
        raise InputError(name, "values must be > 0")
    if nonnegative and not np.all(arr >= 0):
        raise InputError(name, "values must be >= 0")
    arr.setflags(write=False)
    return arr


#: Highest frequency accepted, Hz (as the configuration's ``f_max``): far above any blade
#: mode; beyond it the receptances overflow to zero responses that look converged.
MAX_FREQ_HZ = 1e6


def frequencies(freq_hz, name="freq_hz"):
    """Frequencies as a contiguous 1-d float array, Hz: non-empty, finite, in
    ``(0, MAX_FREQ_HZ]``."""
    f = np.ascontiguousarray(real_array(name, freq_hz))
    if f.ndim == 0:
        f = f[None]
    if f.ndim != 1 or f.size == 0:
        raise InputError(name, f"expected a non-empty 1-d array, got shape {f.shape}")
    if not np.all(np.isfinite(f)):
        raise InputError(name, "frequencies must be finite (no NaN or inf)")
    if not np.all(f > 0):
        raise InputError(name, "frequencies must be > 0 Hz")
    if not np.all(f <= MAX_FREQ_HZ):
        raise InputError(name, f"frequencies must be at most {MAX_FREQ_HZ:g} Hz, got "
                         f"{f.max():g}")
    return f


#: Force amplitudes accepted, N (``F0``): below 1e-12 N the squared responses head for
#: underflow (at 1e-150 N a fifth of the members fell outside their bounds); above 1e6 N
#: no blade array of this kind stays linear.
F0_RANGE = (1e-12, 1e6)

#: Stiffest contact accepted, N/m (``kc``, and the bounds' ``k_max``): far stiffer than
#: any real contact (a stuck damper). Far beyond it (~1e155) the slip ratio overflows and
#: a stuck damper came back as a free one, marked converged.
KC_MAX = 1e12


#: Largest slip force ``mu0 N0`` accepted, N: far beyond any damper (a stuck one; forces
#: above F0_RANGE's top are stuck for every F0). Near 1e308 the force limit 4/pi mu0 N0
#: overflowed to inf and a response came back as inf.
SLIP_FORCE_MAX = 1e12


def check_slip_force(name, mu0, N0):
    """Raise :class:`InputError` under ``name`` where ``mu0 N0`` (N, broadcast) exceeds
    :data:`SLIP_FORCE_MAX`."""
    with np.errstate(over="ignore"):
        top = float(np.max(np.asarray(mu0, dtype=float) * np.asarray(N0, dtype=float)))
    if top > SLIP_FORCE_MAX:
        raise InputError(name, f"expected mu0 N0 of at most {SLIP_FORCE_MAX:g} N (a stuck "
                         f"damper), got {top:g}")


def existing_file(path):
    """Raise ``ValueError`` naming ``path`` (a Path) where it is no regular file: missing,
    a directory (``beam.csv/``), or a device or pipe."""
    if path.is_dir():
        raise ValueError(f"{path}: a directory, not a file")
    if not path.exists():
        raise ValueError(f"{path}: file not found")
    if not path.is_file():
        raise ValueError(f"{path}: not a regular file (a device or a pipe)")


def check_kc(name, kc):
    """Raise :class:`InputError` under ``name`` where a contact stiffness ``kc`` (N/m,
    any shape) exceeds :data:`KC_MAX`."""
    if np.any(np.asarray(kc) > KC_MAX):
        raise InputError(name, f"expected at most {KC_MAX:g} N/m (a stuck contact), got "
                         f"{float(np.max(kc)):g}")


def per_damper(nd, **params):
    """Broadcast per-damper parameters to a common (n_s, nd) float array each.

    Each parameter may be a scalar (all samples and dampers), shape (nd,) (one sample),
    shape (n_s, 1) (same for every damper of a sample) or (n_s, nd). Values must be
    finite and >= 0; ``kc`` at most :data:`KC_MAX`, ``mu0 N0`` at most
    :data:`SLIP_FORCE_MAX`.
    """
    out = {}
    n_s = 1
    for name, value in params.items():
        arr = real_array(name, value)
        if arr.ndim == 0:
            arr = np.full((1, nd), float(arr))
        elif arr.ndim == 1:
            if arr.shape[0] != nd:
                raise InputError(name, f"a 1-d array must have one value per damper "
                                 f"({nd}), got {arr.shape[0]}")
            arr = arr[None, :]
        elif arr.ndim == 2:
            if arr.shape[1] not in (1, nd):
                raise InputError(name, f"expected shape (n_samples, {nd}), got {arr.shape}")
            if arr.shape[0] == 0:
                raise InputError(name, f"expected at least one sample, got shape {arr.shape}")
            arr = np.broadcast_to(arr, (arr.shape[0], nd))
        else:
            raise InputError(name, f"expected at most 2 dimensions, got shape {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise InputError(name, "values must be finite (no NaN or inf)")
        if np.any(arr < 0):
            raise InputError(name, "values must be >= 0")
        if name == "kc":
            check_kc(name, arr)
        if arr.shape[0] != 1:
            if n_s not in (1, arr.shape[0]):
                raise InputError(name, f"{arr.shape[0]} samples do not match the "
                                 f"{n_s} samples of the other parameters")
            n_s = arr.shape[0]
        out[name] = arr
    if "mu0" in out and "N0" in out:
        check_slip_force("mu0 x N0", out["mu0"], out["N0"])
    return {k: np.ascontiguousarray(np.broadcast_to(v, (n_s, nd))) for k, v in out.items()}
