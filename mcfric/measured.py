"""Measured responses: import (UFF 58, CSV), normalisation to a simulated force, the
fraction of measured points inside response bounds, and export of computed responses to
UFF 58 (physics.md section 8).

A :class:`Measurement` is one set of points taken in one way (``kind``: stepped-sine points
or a continuous sweep) at one force level: frequencies, and per beam an amplitude (real,
>= 0) or a complex response, in SI units of its quantity (displacement m, velocity m/s,
acceleration m/s^2). Readers return a list, one Measurement per (kind, force level,
percentile) found in the file, so stepped points and sweeps are never mixed.

Normalisation (paper Eq. 11-12): scaling the whole input by ``c`` scales the response and
the friction forces by ``c``, so a run at force ``F_meas`` with preload ``N0`` stands for
force ``c F_meas = F0`` with preload ``c N0``, ``c = F0 / F_meas``.

Tags in UFF ID lines: ``kind=stepped|sweep``, ``force_n=<N>``, ``percentile=<p>`` anywhere
in ID lines 1-5 are read (and written by :func:`export_uff58`); arguments fill in what a
file does not say and must agree with what it does.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .modal_io import (UFF_SUFFIXES, _as_int, _atomic_uff_write, _short, csv_rows,
                       uff_datasets, uff_date, uff_units_dataset)

KINDS = ("stepped", "sweep")
from .hbm import METRIC_UNITS as UNITS, QUANTITIES
#: UFF specific data types of the ordinate (record 9) for each quantity.
SPEC_TYPE = {"displacement": 8, "velocity": 11, "acceleration": 12}
QUANTITY_OF_SPEC = {v: k for k, v in SPEC_TYPE.items()}
#: UFF 58 function types, for messages.
FUNCTION_TYPES = {0: "general", 1: "time response", 2: "auto spectrum", 3: "cross spectrum",
                  4: "frequency response function", 5: "transmissibility", 6: "coherence",
                  7: "auto correlation", 8: "cross correlation", 9: "power spectral density",
                  10: "energy spectral density", 11: "probability density function",
                  12: "spectrum"}
FRF, GENERAL, SPECTRUM = 4, 0, 12
#: Label of the response metric ``M = max_b |y_b|`` where a beam number is expected.
METRIC = 0

_TAG = re.compile(r"\b(kind|force_n|percentile)\s*=\s*([^\s,;]+)", re.IGNORECASE)


# ---------------------------------------------------------------- the data

@dataclass(frozen=True, eq=False)
class Measurement:
    """Measured (or exported) responses of the beams at one force level.

    Parameters
    ----------
    frequency_hz : array_like, shape (n_f,)
        Excitation frequencies, Hz (> 0), in the order measured (an up-and-down sweep
        keeps its order).
    response : array_like, shape (n_f, n_beams)
        Per beam either the amplitude (real, >= 0) or the complex response
        (``x(t) = Re{X e^{i omega t}}``), in SI units of ``quantity``. NaN where a beam
        was not measured.
    beams : tuple of int
        Beam number (1-based) of each column; :data:`METRIC` (0) stands for the metric
        ``M``, the maximum over the beams.
    kind : {"stepped", "sweep"}
        Stepped-sine points (plotted as crosses) or a continuous sweep (a line).
    quantity : {"displacement", "velocity", "acceleration"}
    force_n : float, optional
        Force level ``F_meas`` of the run, N, if known.
    percentile : float, optional
        Set for ensemble percentiles exported by :func:`export_uff58`.
    source : str
        Where the data came from (used in messages).
    """

    frequency_hz: np.ndarray
    response: np.ndarray
    beams: tuple
    kind: str = "stepped"
    quantity: str = "displacement"
    force_n: float | None = None
    percentile: float | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self):
        who = f"{self.source}: " if self.source else ""
        f = np.array(self.frequency_hz, dtype=float)
        if f.ndim != 1 or f.size == 0:
            raise ValueError(f"{who}frequency_hz: expected a non-empty 1-d array, got shape "
                             f"{f.shape}")
        if not np.all(np.isfinite(f) & (f > 0)):
            raise ValueError(f"{who}frequency_hz: frequencies must be finite and > 0 Hz")
        r = np.array(self.response)
        if not (np.issubdtype(r.dtype, np.number) and not np.issubdtype(r.dtype, np.bool_)):
            raise ValueError(f"{who}response: expected numbers")
        r = r.astype(complex if np.iscomplexobj(r) else float)
        if r.ndim == 1:
            r = r[:, None]
        if r.ndim != 2 or r.shape[0] != f.size:
            raise ValueError(f"{who}response: expected shape ({f.size}, n_beams), got "
                             f"{r.shape}")
        finite = np.isfinite(r) | np.isnan(r)
        if not np.all(finite):
            raise ValueError(f"{who}response: values must be finite (NaN = not measured)")
        if not np.iscomplexobj(r) and np.any(r < 0):
            raise ValueError(f"{who}response: amplitudes must be >= 0")
        beams = tuple(int(b) for b in np.atleast_1d(self.beams))
        if len(beams) != r.shape[1]:
            raise ValueError(f"{who}beams: expected {r.shape[1]} beam numbers (one per "
                             f"column), got {len(beams)}")
        if len(set(beams)) != len(beams) or any(b < 0 for b in beams):
            raise ValueError(f"{who}beams: expected distinct beam numbers >= 1 (0 = metric), "
                             f"got {beams}")
        if self.kind not in KINDS:
            raise ValueError(f"{who}kind: expected one of {KINDS}, got {self.kind!r}")
        if self.quantity not in QUANTITIES:
            raise ValueError(f"{who}quantity: expected one of {QUANTITIES}, got "
                             f"{self.quantity!r}")
        F = self.force_n
        if F is not None:
            F = float(F)
            if not (math.isfinite(F) and F > 0):
                raise ValueError(f"{who}force_n: expected a force > 0 N, got {self.force_n!r}")
        f.setflags(write=False)
        r.setflags(write=False)
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "response", r)
        object.__setattr__(self, "beams", beams)
        object.__setattr__(self, "force_n", F)

    @property
    def is_complex(self):
        return np.iscomplexobj(self.response)

    @property
    def amplitude(self):
        """Amplitudes ``|response|``, shape (n_f, n_beams), SI units of ``quantity``."""
        return np.abs(self.response)

    @property
    def n_points(self):
        """Measured (non-NaN) values over all beams."""
        return int(np.count_nonzero(~np.isnan(self.response)))

    def column(self, beam):
        """Response of one beam (n_f,)."""
        try:
            return self.response[:, self.beams.index(int(beam))]
        except ValueError:
            raise ValueError(f"beam {beam} is not in the measurement (beams: "
                             f"{list(self.beams)})") from None

    def to_quantity(self, quantity):
        """The same data as ``quantity``: ``X = V / (i omega) = -A / omega^2``.

        Amplitudes convert by the powers of ``omega = 2 pi f``.
        """
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity: expected one of {QUANTITIES}, got {quantity!r}")
        k = QUANTITIES.index(quantity) - QUANTITIES.index(self.quantity)
        if k == 0:
            return self
        w = 2 * np.pi * self.frequency_hz[:, None]
        factor = (1j * w) ** k if self.is_complex else w ** k
        return replace(self, response=self.response * factor, quantity=quantity)

    def displacement(self):
        """The data as displacement (amplitude in m)."""
        return self.to_quantity("displacement")

    def metric(self):
        """``M = max_b |y_b|`` over this measurement's beams (physics.md 5), column 0.

        NaN at frequencies where a beam is missing: M needs every beam. Compare M, not
        single beams, with bounds on M: the lower bound of the maximum over beams is not
        a lower bound of each beam.
        """
        a = self.amplitude
        m = np.where(np.isnan(a).any(axis=1), np.nan,
                     np.max(np.where(np.isnan(a), -np.inf, a), axis=1))
        return replace(self, response=m[:, None], beams=(METRIC,))

    def scaled(self, c):
        """Response multiplied by ``c`` (> 0), force level too."""
        F = None if self.force_n is None else self.force_n * c
        return replace(self, response=self.response * c, force_n=F)

    def describe(self):
        F = "unknown force" if self.force_n is None else f"F = {self.force_n:g} N"
        p = "" if self.percentile is None else f", percentile {self.percentile:g}"
        cols = ", ".join("M" if b == METRIC else str(b) for b in self.beams)
        return (f"{self.kind}: {self.frequency_hz.size} frequencies "
                f"({self.frequency_hz.min():g}-{self.frequency_hz.max():g} Hz), beams {cols}, "
                f"{self.quantity}{' (complex)' if self.is_complex else ''}, {F}{p}")


# ---------------------------------------------------------------- reading

def read_measured(path, *, nodes=None, direction=None, quantity=None, force_n=None,
                  kind=None, scale=1.0, format=None):
    """Read measured responses from a UFF (dataset 58) or CSV file.

    Parameters
    ----------
    path : str or Path
        ``.uff``/``.unv``/``.uf`` (needs pyuff) or ``.csv``.
    nodes : mapping {node: beam} or sequence of int
        UFF only, required: response node of each beam, as ``{102: 1, 202: 2}`` or as a
        list ``[102, 202]`` (node of beam 1, beam 2, ...). Records at other nodes are
        ignored; every listed node must have a record.
    direction : int, optional
        UFF only: keep records with response direction ``+-direction`` (1=X, 2=Y, 3=Z);
        a ``-`` direction flips the sign of complex data. Default: any, one per node.
    quantity : {"displacement", "velocity", "acceleration"}, optional
        What the values are. UFF: taken from the ordinate's specific data type
        (8, 11, 12); needed when that is 0 (unknown) or 1 (general). CSV: default
        displacement.
    force_n : float, optional
        Force level of the run, N, when the file does not give one (UFF tag ``force_n=``
        in an ID line, CSV column ``force_n``). FRF records (function type 4) need it to
        give a response: ``X = H F``.
    kind : {"stepped", "sweep"}, optional
        When the file does not say (UFF tag ``kind=``, CSV column ``kind``); default
        ``"stepped"``.
    scale : float
        Factor applied to every value after unit conversion (e.g. ``sqrt(2)`` for RMS
        spectra, 9.81 for data in g).
    format : {"uff", "csv"}, optional
        Override the choice by suffix.

    Returns
    -------
    list of Measurement
        One per (kind, force level, percentile), in order of first appearance.

    Raises
    ------
    ValueError
        One line naming the file and the problem.
    ImportError
        A UFF file without pyuff installed.
    """
    path = Path(path)
    if format is None:
        suffix = path.suffix.lower()
        format = "uff" if suffix in UFF_SUFFIXES else "csv" if suffix == ".csv" else None
        if format is None:
            raise ValueError(f"{path}: unknown file type {suffix!r}: expected .uff/.unv "
                             f"(UFF 58) or .csv, or pass format=")
    elif format not in ("uff", "csv"):
        raise ValueError(f"{path}: format: expected 'uff' or 'csv', got {format!r}")
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"{path}: quantity: expected one of {QUANTITIES}, got {quantity!r}")
    if kind is not None and kind not in KINDS:
        raise ValueError(f"{path}: kind: expected one of {KINDS}, got {kind!r}")
    if force_n is not None and not (math.isfinite(float(force_n)) and float(force_n) > 0):
        raise ValueError(f"{path}: force_n: expected a force > 0 N, got {force_n!r}")
    if not (math.isfinite(float(scale)) and float(scale) > 0):
        raise ValueError(f"{path}: scale: expected a number > 0, got {scale!r}")
    if format == "uff":
        return _read_uff58(path, nodes, direction, quantity, force_n, kind, float(scale))
    return _read_csv(path, quantity or "displacement", force_n, kind, float(scale))


def _merge(path, what, file_value, arg_value, name):
    """The file's value, filled in by the argument; a disagreement is an error."""
    if file_value is None:
        return arg_value
    if arg_value is not None and not _same(file_value, arg_value):
        raise ValueError(f"{path}: {what} says {name}={file_value}, the argument says "
                         f"{name}={arg_value}")
    return file_value


def _same(a, b):
    if isinstance(a, str) or isinstance(b, str):
        return a == b
    return math.isclose(float(a), float(b), rel_tol=1e-6)


def _node_map(path, nodes, found):
    if nodes is None:
        raise ValueError(f"{path}: pass nodes= to map response nodes to beams, e.g. "
                         f"nodes={{{found[0]}: 1}} (response nodes in the file: "
                         f"{_short(found)})")
    if isinstance(nodes, Mapping):
        pairs = {_as_int(n, "nodes", path): _as_int(b, "nodes beam", path)
                 for n, b in nodes.items()}
    elif isinstance(nodes, Sequence) and not isinstance(nodes, str):
        pairs = {_as_int(n, "nodes", path): b + 1 for b, n in enumerate(nodes)}
        if len(pairs) != len(nodes):
            raise ValueError(f"{path}: nodes: a node is listed twice ({list(nodes)})")
    else:
        raise ValueError(f"{path}: nodes: expected {{node: beam}} or a list of nodes "
                         f"(beam 1, 2, ...), got {nodes!r}")
    beams = list(pairs.values())
    if len(set(beams)) != len(beams) or any(b < 0 for b in beams):
        raise ValueError(f"{path}: nodes: beams must be distinct numbers >= 1, got {beams}")
    return pairs


def _tags(d):
    tags = {}
    for k in ("id1", "id2", "id3", "id4", "id5"):
        for name, value in _TAG.findall(str(d.get(k, ""))):
            tags[name.lower()] = value
    return tags


def _read_uff58(path, nodes, direction, quantity, force_n, kind, scale):
    sets, (Lf, Ff) = uff_datasets(path, (58,))
    node_of = _node_map(path, nodes, sorted({int(d.get("rsp_node", 0)) for d in sets}))
    if direction is not None:
        direction = _as_int(direction, "direction", path)
        if not 1 <= abs(direction) <= 6:
            raise ValueError(f"{path}: direction: expected 1..6 (X, Y, Z, RX, RY, RZ), got "
                             f"{direction}")
    groups = {}
    for k, d in enumerate(sets):
        node, rdir = int(d.get("rsp_node", 0)), int(d.get("rsp_dir", 0))
        if node not in node_of:
            continue
        if direction is not None and abs(rdir) != abs(direction):
            continue
        where = f"record {k + 1} (node {node}, direction {rdir})"
        key, q, x, y = _uff58_record(path, where, d, quantity, force_n, kind, Lf, Ff)
        if direction is not None and rdir * direction < 0 and np.iscomplexobj(y):
            y = -y
        g = groups.setdefault(key, {"quantity": q, "beams": {}})
        if g["quantity"] != q:
            raise ValueError(f"{path}: {where} is {q}, other records of the same run are "
                             f"{g['quantity']}: pass quantity= or split the file")
        beam = node_of[node]
        if beam in g["beams"]:
            raise ValueError(f"{path}: two records for beam {beam} (node {node}) in the same "
                             f"run: pass direction= or split the file")
        g["beams"][beam] = (x, y)
    if not groups:
        raise ValueError(f"{path}: no dataset 58 record at the mapped nodes "
                         f"{_short(sorted(node_of))}" +
                         ("" if direction is None else f" in direction {direction}"))
    out = []
    for (knd, F, pct), g in groups.items():
        missing = [n for n, b in node_of.items() if b not in g["beams"]]
        if missing:
            raise ValueError(f"{path}: no record for node {missing[0]} (beam "
                             f"{node_of[missing[0]]})" +
                             ("" if F is None else f" at force_n={F:g}") +
                             ("" if direction is None else f" in direction {direction}"))
        beams = sorted(g["beams"])
        freq, resp = _align(path, [g["beams"][b] for b in beams])
        out.append(Measurement(freq, resp * scale, tuple(beams), kind=knd,
                               quantity=g["quantity"], force_n=F, percentile=pct,
                               source=str(path)))
    return out


def _uff58_record(path, where, d, quantity, force_n, kind, Lf, Ff):
    """Group key, quantity, abscissa (Hz) and SI response of one dataset 58."""
    ft = int(d.get("func_type", 0))
    if ft not in (GENERAL, FRF, SPECTRUM):
        raise ValueError(f"{path}: {where} is function type {ft} "
                         f"({FUNCTION_TYPES.get(ft, 'unknown')}); expected a response "
                         f"(0 general, 12 spectrum) or an FRF (4)")
    xt = int(d.get("abscissa_spec_data_type", 0))
    if xt not in (0, 18):
        raise ValueError(f"{path}: {where}: abscissa specific data type {xt} is not "
                         f"frequency (18)")
    x = np.asarray(d.get("x"), dtype=float)
    y = np.asarray(d.get("data"))
    n = int(d.get("num_pts", len(y)))
    if len(x) != n or len(y) != n:
        raise ValueError(f"{path}: {where}: the header announces {n} points, the data has "
                         f"{len(y)} (truncated record?)")
    if n == 0:
        raise ValueError(f"{path}: {where} has no data points")
    spec = int(d.get("ordinate_spec_data_type", 0))
    q = QUANTITY_OF_SPEC.get(spec)
    if q is None and spec not in (0, 1):
        raise ValueError(f"{path}: {where}: ordinate specific data type {spec} is not a "
                         f"displacement (8), velocity (11) or acceleration (12)")
    q = _merge(path, where, q, quantity, "quantity")
    if q is None:
        raise ValueError(f"{path}: {where}: the ordinate's type is not given "
                         f"(specific data type {spec}): pass quantity=")
    tags = _tags(d)
    try:
        F_file = float(tags["force_n"]) if "force_n" in tags else None
        pct = float(tags["percentile"]) if "percentile" in tags else None
    except ValueError:
        raise ValueError(f"{path}: {where}: bad tag in the ID lines {tags}") from None
    F = _merge(path, where, F_file, force_n, "force_n")
    knd = _merge(path, where, tags.get("kind", "").lower() or None, kind, "kind") or "stepped"
    if knd not in KINDS:
        raise ValueError(f"{path}: {where}: kind={knd!r}, expected one of {KINDS}")
    y = y / Lf  # dataset 164: file length unit -> m
    if ft == FRF:
        den = int(d.get("orddenom_spec_data_type", 0))
        if den not in (0, 1, 13):
            raise ValueError(f"{path}: {where}: FRF denominator type {den} is not a force "
                             f"(13)")
        if F is None:
            raise ValueError(f"{path}: {where} is an FRF (response/force): pass force_n= "
                             f"(the force level of the run, N) to get the response")
        y = y * Ff * F  # X = H F, force in N
    elif not np.iscomplexobj(y) and np.any(y < 0):
        raise ValueError(f"{path}: {where}: negative amplitudes in a real-valued record")
    if not np.all(np.isfinite(x) & (x > 0)):
        raise ValueError(f"{path}: {where}: frequencies must be finite and > 0 Hz")
    return (knd, F, pct), q, x, y


def _align(path, records):
    """Common frequency axis of per-beam records: identical, or merged (NaN fill)."""
    x0 = records[0][0]
    cplx = any(np.iscomplexobj(y) for _, y in records)
    if all(len(x) == len(x0) and np.array_equal(x, x0) for x, _ in records):
        return x0, np.column_stack([y for _, y in records]).astype(complex if cplx else float)
    if not all(np.all(np.diff(x) > 0) for x, _ in records):
        raise ValueError(f"{path}: the beams' records have different frequencies and are "
                         f"not increasing: cannot merge them")
    grid = np.unique(np.concatenate([x for x, _ in records]))
    out = np.full((grid.size, len(records)), np.nan, dtype=complex if cplx else float)
    for j, (x, y) in enumerate(records):
        out[np.searchsorted(grid, x), j] = y
    return grid, out


_CSV_BEAM = re.compile(r"^(re_|im_)?beam_?(\d+)$")


def _read_csv(path, quantity, force_n, kind, scale):
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    rows = csv_rows(path)
    _, header = rows[0]
    names = [h.strip().lower().replace(" ", "_") for h in header]
    amp, re_, im_, special = {}, {}, {}, {}
    for j, name in enumerate(names):
        m = _CSV_BEAM.match(name)
        if m:
            b = int(m.group(2))
            target = {None: amp, "re_": re_, "im_": im_}[m.group(1)]
            if b in target or b < 1:
                raise ValueError(f"{path}: column {header[j].strip()!r}: beam {b} twice or "
                                 f"< 1")
            target[b] = j
        elif name in ("frequency_hz", "force_n", "kind"):
            if name in special:
                raise ValueError(f"{path}: column {name!r} appears twice")
            special[name] = j
        else:
            raise ValueError(f"{path}: unknown column {header[j].strip()!r} (expected "
                             f"frequency_hz, beam<k> or re_beam<k>/im_beam<k>, force_n, kind)")
    missing = [] if "frequency_hz" in special else ["frequency_hz"]
    if not (amp or re_ or im_):
        missing.append("beam<k> (amplitude) or re_beam<k> and im_beam<k> (complex)")
    unpaired = sorted(set(re_) ^ set(im_))
    if unpaired:
        missing.append(f"{'im' if unpaired[0] in re_ else 're'}_beam{unpaired[0]}")
    if missing:
        raise ValueError(f"{path}: missing column(s): {'; '.join(missing)}")
    both = sorted(set(amp) & set(re_))
    if both:
        raise ValueError(f"{path}: beam {both[0]} has both an amplitude and complex columns")
    if amp and re_:
        raise ValueError(f"{path}: mix of amplitude (beam<k>) and complex (re_/im_beam<k>) "
                         f"columns: use one form for all beams")
    beams = sorted(amp) if amp else sorted(re_)

    def number(line, j, c):
        c = c.strip()
        if c == "" or c.lower() == "nan":
            return math.nan
        try:
            return float(c)
        except ValueError:
            raise ValueError(f"{path}: line {line}, column {names[j]}: not a number: "
                             f"{c!r}") from None

    groups = {}
    for line, r in rows[1:]:
        if len(r) != len(names):
            raise ValueError(f"{path}: line {line}: {len(r)} fields, the header has "
                             f"{len(names)}")
        f = number(line, special["frequency_hz"], r[special["frequency_hz"]])
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"{path}: line {line}: frequency_hz must be > 0, got "
                             f"{r[special['frequency_hz']].strip()!r}")
        F_file = None
        if "force_n" in special:
            F_file = number(line, special["force_n"], r[special["force_n"]])
            if math.isnan(F_file):
                F_file = None
            elif not F_file > 0:
                raise ValueError(f"{path}: line {line}: force_n must be > 0 N")
        F = _merge(path, f"line {line}", F_file, force_n, "force_n")
        k_file = r[special["kind"]].strip().lower() or None if "kind" in special else None
        knd = _merge(path, f"line {line}", k_file, kind, "kind") or "stepped"
        if knd not in KINDS:
            raise ValueError(f"{path}: line {line}: kind {knd!r}, expected one of {KINDS}")
        if amp:
            vals = [number(line, amp[b], r[amp[b]]) for b in beams]
            if any(v < 0 for v in vals):
                raise ValueError(f"{path}: line {line}: amplitudes must be >= 0")
        else:
            vals = [complex(number(line, re_[b], r[re_[b]]), number(line, im_[b], r[im_[b]]))
                    for b in beams]
        g = groups.setdefault((knd, F), ([], []))
        g[0].append(f)
        g[1].append(vals)
    if not groups:
        raise ValueError(f"{path}: no data rows (only a header)")
    return [Measurement(np.array(fs), np.array(vs) * scale, tuple(beams), kind=knd,
                        quantity=quantity, force_n=F, source=str(path))
            for (knd, F), (fs, vs) in groups.items()]


# ---------------------------------------------------------------- normalisation

@dataclass(frozen=True)
class Normalisation:
    """What :func:`normalise` did (paper Eq. 11-12).

    Attributes
    ----------
    F_meas, F0 : float
        Force level of the measurement and the simulated force, N.
    c : float
        ``F0 / F_meas``: factor applied to the response, and to the preload that the
        measurement stands for.
    N0_meas, N0_equivalent : float or None
        The run's preload (if given) and ``c N0_meas``, N.
    """

    F_meas: float
    F0: float
    c: float
    N0_meas: float | None = None
    N0_equivalent: float | None = None

    def text(self):
        s = (f"normalised to F0 = {self.F0:g} N: c = F0/F_meas = {self.F0:g}/{self.F_meas:g} "
             f"= {self.c:.6g}; responses x c. A run at force {self.F_meas:g} N with preload "
             f"N0 stands for force {self.F0:g} N with preload {self.c:.6g} N0")
        if self.N0_meas is not None:
            s += (f" (N0 = {self.N0_meas:g} N -> {self.N0_equivalent:.6g} N: compare with "
                  f"bounds for that preload)")
        return s

    __str__ = text


def normalise(measurement, F0, *, N0_meas=None):
    """Rescale a measurement taken at ``F_meas`` to the simulated force ``F0``.

    The friction law is homogeneous: force ``cF`` with preload ``cN0`` gives ``c`` times
    the response of force ``F`` with preload ``N0``. So the rescaled data, ``c`` times the
    measured response with ``c = F0 / F_meas``, is what the rig would do at ``F0`` with
    preload ``c N0``: compare it with results for that preload.

    Parameters
    ----------
    measurement : Measurement
        With a known ``force_n`` (F_meas, N).
    F0 : float
        Simulated force amplitude, N (> 0).
    N0_meas : float, optional
        Preload of the measured run, N; the report then gives ``c N0_meas``.

    Returns
    -------
    Measurement
        Response times ``c``, ``force_n = F0``.
    Normalisation
        ``c`` and the implied preload scaling (``.text()`` for a printable line).
    """
    if not isinstance(measurement, Measurement):
        raise ValueError(f"measurement: expected a Measurement, got "
                         f"{type(measurement).__name__}")
    F0 = float(F0)
    if not (math.isfinite(F0) and F0 > 0):
        raise ValueError(f"F0: expected a force > 0 N, got {F0!r}")
    if measurement.force_n is None:
        who = f"{measurement.source}: " if measurement.source else ""
        raise ValueError(f"{who}force level unknown: normalising needs the measurement's "
                         f"force_n (pass force_n= when reading)")
    c = F0 / measurement.force_n
    N0_eq = None
    if N0_meas is not None:
        N0_meas = float(N0_meas)
        if not (math.isfinite(N0_meas) and N0_meas >= 0):
            raise ValueError(f"N0_meas: expected a preload >= 0 N, got {N0_meas!r}")
        N0_eq = c * N0_meas
    out = replace(measurement.scaled(c), force_n=F0)
    return out, Normalisation(measurement.force_n, F0, c, N0_meas, N0_eq)


# ---------------------------------------------------------------- inside the bounds

@dataclass(frozen=True)
class Inside:
    """Measured points against bounds, per beam (label :data:`METRIC` = 0 for M).

    Attributes
    ----------
    beams : tuple of int
    inside, below, above : dict {beam: int}
        Points with ``lower <= a <= upper``, ``a < lower``, ``a > upper``.
    outside_range : dict {beam: int}
        Points at frequencies outside the bounds' grid: excluded.
    missing : dict {beam: int}
        Points without a value (NaN data or NaN bound): excluded.
    """

    beams: tuple
    inside: dict
    below: dict
    above: dict
    outside_range: dict
    missing: dict

    def compared(self, beam=None):
        """Points compared (inside + below + above), one beam or all."""
        bs = self.beams if beam is None else (beam,)
        return sum(self.inside[b] + self.below[b] + self.above[b] for b in bs)

    def fraction(self, beam=None):
        """Fraction of compared points inside, one beam or overall (NaN if none)."""
        bs = self.beams if beam is None else (beam,)
        n = self.compared(beam)
        return sum(self.inside[b] for b in bs) / n if n else math.nan

    @property
    def per_beam(self):
        """``{beam: fraction inside}``."""
        return {b: self.fraction(b) for b in self.beams}

    @property
    def overall(self):
        return self.fraction()

    def text(self):
        parts = [f"{'M' if b == METRIC else f'beam {b}'} {_percent(self.fraction(b))} % "
                 f"({self.inside[b]}/{self.compared(b)})" for b in self.beams]
        excl = sum(self.outside_range.values())
        miss = sum(self.missing.values())
        s = (f"measured points inside the bounds: {_percent(self.overall)} % "
             f"({sum(self.inside.values())}/{self.compared()}); " + ", ".join(parts))
        if excl:
            s += f"; {excl} outside the bounds' frequency range (excluded)"
        if miss:
            s += f"; {miss} without data or bound (excluded)"
        return s

    __str__ = text


def interpolate_log(freq_hz, values, at_hz):
    """Log-linear interpolation: ``log(values)`` linear in frequency.

    Parameters
    ----------
    freq_hz : ndarray, shape (n_g,)
        Increasing grid, Hz.
    values : ndarray, shape (n_g, ...)
        Values >= 0 (NaN allowed: propagates to the neighbouring intervals).
    at_hz : ndarray, shape (n,)
        Frequencies inside ``[freq_hz[0], freq_hz[-1]]``, Hz.

    Returns
    -------
    ndarray, shape (n, ...)
        Exactly the grid value at a grid frequency; 0 on an interval with a zero end.
    """
    i = np.clip(np.searchsorted(freq_hz, at_hz, side="right") - 1, 0, len(freq_hz) - 2)
    f0, f1 = freq_hz[i], freq_hz[i + 1]
    t = ((at_hz - f0) / (f1 - f0)).reshape((-1,) + (1,) * (values.ndim - 1))
    v0, v1 = values[i], values[i + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.exp((1 - t) * np.log(v0) + t * np.log(v1))
    out = np.where((v0 == 0) | (v1 == 0), 0.0, out)
    out = np.where(np.isnan(v0) | np.isnan(v1), np.nan, out)
    # exp(log(v)) may be off by an ulp: grid points get their own value exactly
    return np.where(t == 0, v0, np.where(t == 1, v1, out))


def _percent(x):
    """One decimal, rounded down: 9999 of 10000 must not read 100.0 %."""
    return "nan" if math.isnan(x) else f"{math.floor(1000 * x) / 10:.1f}"


def fraction_inside(measurement, freq_hz, lower, upper, beams=None, *,
                    quantity="displacement", check_lower=True, rtol=1e-9):
    """Fraction of measured points between lower and upper bounds, per beam and overall.

    The bounds are interpolated log-linearly (log amplitude linear in frequency) to the
    measured frequencies; points outside the bounds' frequency range are excluded and
    counted in ``outside_range``; NaN values (no data, failed bound) in ``missing``.

    Parameters
    ----------
    measurement : Measurement or sequence of Measurement
        Compared as amplitudes of ``quantity`` (converted if needed); several
        measurements are pooled.
    freq_hz : array_like, shape (n_g,)
        Frequency grid of the bounds, Hz, strictly increasing.
    lower, upper : array_like, shape (n_g,) or (n_g, n_beams)
        Bounds in SI units of ``quantity`` (>= 0). One column applies to every beam (e.g.
        bounds of the metric M; note that the lower bound of M is a lower bound of the
        largest beam only: compare ``measurement.metric()`` with it). Several columns:
        column ``b - 1`` for beam ``b``.
    beams : sequence of int, optional
        Beams (labels of the measurement) to count; default all.
    quantity : {"displacement", "velocity", "acceleration"}
        Quantity of the bounds.
    check_lower : bool
        False: test single beams against the upper bound only (the valid test of a beam
        against bounds of M); ``below`` stays 0.
    rtol : float
        Relative tolerance of the comparison (rounding).

    Returns
    -------
    Inside
        ``.per_beam``, ``.overall``, counts, ``.text()``.
    """
    ms = [measurement] if isinstance(measurement, Measurement) else list(measurement)
    if not ms or not all(isinstance(m, Measurement) for m in ms):
        raise ValueError("measurement: expected a Measurement or a list of them")
    g = np.asarray(freq_hz, dtype=float)
    lo = np.asarray(lower, dtype=float)
    up = np.asarray(upper, dtype=float)
    if g.ndim != 1 or g.size < 2 or not np.all(np.isfinite(g)) or not np.all(np.diff(g) > 0):
        raise ValueError("freq_hz: expected at least 2 finite, strictly increasing "
                         "frequencies")
    if lo.shape != up.shape or lo.shape[:1] != g.shape or lo.ndim not in (1, 2):
        raise ValueError(f"lower, upper: expected shape ({g.size},) or ({g.size}, n_beams), "
                         f"got {lo.shape} and {up.shape}")
    if np.any(lo < 0) or np.any(up < 0):
        raise ValueError("lower, upper: bounds must be >= 0 (NaN allowed)")
    wanted = None if beams is None else tuple(int(b) for b in beams)
    counts = {k: {} for k in ("inside", "below", "above", "outside_range", "missing")}
    order = []
    for m in ms:
        m = m.to_quantity(quantity)
        for j, b in enumerate(m.beams):
            if wanted is not None and b not in wanted:
                continue
            if lo.ndim == 2:
                if b == METRIC or not 1 <= b <= lo.shape[1]:
                    raise ValueError(f"lower, upper: no bound column for beam {b} "
                                     f"({lo.shape[1]} columns)")
                lo_b, up_b = lo[:, b - 1], up[:, b - 1]
            else:
                lo_b, up_b = lo, up
            if b not in order:
                order.append(b)
                for c in counts.values():
                    c[b] = 0
            a = np.abs(m.response[:, j])
            f = m.frequency_hz
            has = ~np.isnan(a)
            in_range = has & (f >= g[0]) & (f <= g[-1])
            counts["outside_range"][b] += int(np.count_nonzero(has & ~in_range))
            L = interpolate_log(g, lo_b, f[in_range])
            U = interpolate_log(g, up_b, f[in_range])
            a = a[in_range]
            ok = ~(np.isnan(L) | np.isnan(U))
            counts["missing"][b] += int(np.count_nonzero(~has) + np.count_nonzero(~ok))
            a, L, U = a[ok], L[ok], U[ok]
            below = (a < L * (1 - rtol)) if check_lower else np.zeros(a.shape, bool)
            above = a > U * (1 + rtol)
            counts["below"][b] += int(np.count_nonzero(below))
            counts["above"][b] += int(np.count_nonzero(above))
            counts["inside"][b] += int(np.count_nonzero(~below & ~above))
    if wanted is not None:
        absent = [b for b in wanted if b not in order]
        if absent:
            raise ValueError(f"beams: beam {absent[0]} is not in the measurement")
    return Inside(beams=tuple(order), **counts)


# ---------------------------------------------------------------- export

def export_uff58(path, freq_hz, data, *, force_n, beams=None, nodes=None, percentiles=None,
                 quantity="displacement", kind="sweep", function="auto", direction=3,
                 ref_node=0, description="mcfric", overwrite=False):
    """Write computed responses or ensemble percentiles as UFF dataset 58 records.

    One record per beam (and percentile), preceded by a dataset 164 declaring SI units.
    The abscissa is frequency (Hz, uneven spacing, each value printed to 6 significant
    digits by pyuff), the ordinate double precision. Non-finite values (non-converged
    points) are left out of their record: pyuff would write them as 0.

    Function types:

    * ``"frf"`` (default for complex data): function type 4, ``H = X / force_n`` in
      m/N (or m/s/N, m/s^2/N), numerator the quantity, denominator excitation force (13):
      the response per unit force amplitude of the excitation pattern, at that force.
    * ``"response"`` (default for real amplitudes and percentiles): function type 0
      (general), the amplitude itself in m (m/s, m/s^2).

    ID line 4 carries the tags ``kind=``, ``force_n=`` and ``percentile=`` that
    :func:`read_measured` reads back, so an export is read as a measurement at
    ``force_n``.

    Parameters
    ----------
    path : str or Path
        Output file, written atomically.
    freq_hz : array_like, shape (n_f,)
        Frequencies, Hz (> 0).
    data : array_like
        ``(n_f, n_beams)`` complex responses or real amplitudes of one member; with
        ``percentiles``, ``(n_p, n_f, n_beams)`` or ``(n_p, n_f)`` (percentiles of the
        metric M: one column, label 0 unless ``beams`` says otherwise).
    force_n : float
        Force amplitude F0 of the computation, N.
    beams : sequence of int, optional
        Beam number of each column (default 1..n_beams; 0 stands for the metric).
    nodes : mapping {beam: node} or sequence of int, optional
        Response node of each beam, or a list with the node of each column (in the order
        of ``beams``); default the beam numbers.
    percentiles : sequence of float, optional
        The percentiles (0..100) of the first axis of ``data``.
    quantity : {"displacement", "velocity", "acceleration"}
    kind : {"stepped", "sweep"}
        How the points should be shown when read back (default ``"sweep"``).
    function : {"auto", "frf", "response"}
    direction : {1, 2, 3}
        Response direction (X, Y, Z); the reference direction of FRFs too.
    ref_node : int
        Reference (drive) node written to FRF records (default 0: the excitation is a
        pattern over the beams, not one node).
    description : str
        Start of ID line 1.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    dict
        ``{"records": int, "points": int, "dropped": int}`` (dropped: non-finite points).
    """
    path = Path(path)
    f = np.asarray(freq_hz, dtype=float)
    if f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f) & (f > 0)):
        raise ValueError(f"{path}: freq_hz: expected at least 2 finite frequencies > 0 Hz")
    F = float(force_n)
    if not (math.isfinite(F) and F > 0):
        raise ValueError(f"{path}: force_n: expected a force > 0 N, got {force_n!r}")
    if quantity not in QUANTITIES:
        raise ValueError(f"{path}: quantity: expected one of {QUANTITIES}, got {quantity!r}")
    if kind not in KINDS:
        raise ValueError(f"{path}: kind: expected one of {KINDS}, got {kind!r}")
    if function not in ("auto", "frf", "response"):
        raise ValueError(f"{path}: function: expected 'auto', 'frf' or 'response', got "
                         f"{function!r}")
    d = _as_int(direction, "direction", path)
    if d not in (1, 2, 3):
        raise ValueError(f"{path}: direction: expected 1, 2 or 3, got {direction!r}")
    y = np.asarray(data)
    if not np.issubdtype(y.dtype, np.number):
        raise ValueError(f"{path}: data: expected numbers")
    if percentiles is None:
        if y.ndim == 1:
            y = y[:, None]
        if y.ndim != 2:
            raise ValueError(f"{path}: data: expected shape (n_f, n_beams), got {y.shape}")
        y = y[None]
        pcts = [None]
    else:
        pcts = [float(p) for p in np.atleast_1d(percentiles)]
        if not all(0 <= p <= 100 for p in pcts):
            raise ValueError(f"{path}: percentiles: expected values in 0..100")
        if y.ndim == 2:
            y = y[:, :, None]
        if y.ndim != 3 or y.shape[0] != len(pcts):
            raise ValueError(f"{path}: data: expected shape ({len(pcts)}, n_f[, n_beams]) "
                             f"for {len(pcts)} percentiles, got {y.shape}")
        if np.iscomplexobj(y):
            raise ValueError(f"{path}: data: percentiles are real amplitudes, got complex")
    if y.shape[1] != f.size:
        raise ValueError(f"{path}: data: {y.shape[1]} frequencies, freq_hz has {f.size}")
    nb = y.shape[2]
    if beams is None:
        beams = (METRIC,) if percentiles is not None and np.ndim(data) == 2 else \
            tuple(range(1, nb + 1))
    beams = tuple(_as_int(b, "beams", path) for b in beams)
    if len(beams) != nb or len(set(beams)) != nb or any(b < 0 for b in beams):
        raise ValueError(f"{path}: beams: expected {nb} distinct numbers >= 0, got {beams}")
    if nodes is None:
        node_of = {b: b for b in beams}
    elif isinstance(nodes, Mapping):
        node_of = {_as_int(b, "nodes beam", path): _as_int(n, "nodes", path)
                   for b, n in nodes.items()}
    else:
        if len(nodes) != nb:
            raise ValueError(f"{path}: nodes: expected {nb} node numbers (one per column), "
                             f"got {len(nodes)}")
        node_of = {b: _as_int(n, "nodes", path) for b, n in zip(beams, nodes)}
    absent = [b for b in beams if b not in node_of]
    if absent:
        raise ValueError(f"{path}: nodes: no node for beam {absent[0]}")
    cplx = np.iscomplexobj(y)
    frf = function == "frf" or (function == "auto" and cplx)
    if not cplx and np.any(y[np.isfinite(y)] < 0):
        raise ValueError(f"{path}: data: real data are amplitudes and must be >= 0")
    unit = UNITS[quantity]
    dsets, points, dropped = [uff_units_dataset()], 0, 0
    date = uff_date()
    for p, block in zip(pcts, y):
        for j, b in enumerate(beams):
            col = block[:, j]
            ok = np.isfinite(col)
            dropped += int(np.count_nonzero(~ok))
            what = "M (max over beams)" if b == METRIC else f"beam {b}"
            if np.count_nonzero(ok) < 2:  # pyuff cannot write a record of < 2 points
                raise ValueError(f"{path}: {what}: fewer than 2 finite points to write")
            vals = col[ok] / F if frf else col[ok]
            tags = f"mcfric kind={kind} force_n={F:.10g}"
            if p is not None:
                tags += f" percentile={p:g}"
            label = f" p{p:g}" if p is not None else ""
            dsets.append({
                "type": 58, "binary": 0,
                "id1": f"{description} {what}{label}"[:80],
                "id2": (f"{quantity} / force, per unit F0, at F0 = {F:g} N" if frf else
                        f"{quantity} amplitude at F0 = {F:g} N")[:80],
                "id3": date, "id4": tags[:80], "id5": "NONE",
                "func_type": FRF if frf else GENERAL, "func_id": len(dsets), "ver_num": 0,
                "load_case_id": 0,
                "rsp_ent_name": "BEAM", "rsp_node": node_of[b], "rsp_dir": d,
                "ref_ent_name": "DRIVE" if frf else "NONE",
                "ref_node": int(ref_node) if frf else 0, "ref_dir": d if frf else 0,
                "abscissa_spacing": 0,
                "abscissa_spec_data_type": 18, "abscissa_axis_lab": "Frequency",
                "abscissa_axis_units_lab": "Hz",
                "ordinate_spec_data_type": SPEC_TYPE[quantity],
                "ordinate_axis_lab": quantity.capitalize(),
                "ordinate_axis_units_lab": f"{unit}/N" if frf else unit,
                "orddenom_spec_data_type": 13 if frf else 0,
                "orddenom_axis_lab": "Force" if frf else "NONE",
                "orddenom_axis_units_lab": "N" if frf else "NONE",
                "z_axis_spec_data_type": 0, "z_axis_value": 0.0,
                "x": f[ok].copy(), "data": vals.copy()})
            points += int(np.count_nonzero(ok))
    _atomic_uff_write(path, dsets, overwrite)
    return {"records": len(dsets) - 1, "points": points, "dropped": dropped}
