"""Reading measured responses: UFF dataset 58 and CSV files -> :class:`.Measurement`.

Readers return a list, one Measurement per (kind, force level, percentile) found in the
file, so stepped points and sweeps are never mixed. Tags in UFF ID lines
(``kind=stepped|sweep``, ``force_n=<N>``, ``percentile=<p>``) are read; arguments fill in
what a file does not say and must agree with what it does.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from ..metric import QUANTITIES
from ..parsing import as_int, csv_rows, short
from ..uff import (
    FRF,
    FUNCTION_TYPES,
    GENERAL,
    QUANTITY_OF_SPEC,
    SPECTRUM,
    TAG,
    UFF_SUFFIXES,
    read_datasets,
)
from ..validators import existing_file, is_num
from .measurement import KINDS, Measurement


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
    if not isinstance(path, (str, os.PathLike)):
        raise ValueError(f"path: expected a UFF or CSV file's path, got {type(path).__name__}")
    path = Path(path)
    if format is None:
        suffix = path.suffix.lower()
        format = "uff" if suffix in UFF_SUFFIXES else "csv" if suffix == ".csv" else None
        if format is None:
            raise ValueError(f"{path}: unknown file type {suffix!r}: expected .uff/.unv "
                             f"(UFF 58) or .csv (from Python, or format=)")
    elif format not in ("uff", "csv"):
        raise ValueError(f"{path}: format: expected 'uff' or 'csv', got {format!r}")
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"{path}: quantity: expected one of {QUANTITIES}, got {quantity!r}")
    if kind is not None and kind not in KINDS:
        raise ValueError(f"{path}: kind: expected one of {KINDS}, got {kind!r}")
    # is_num: float() took "2" and True as numbers, and "x" failed naming nothing
    if force_n is not None and not (is_num(force_n) and math.isfinite(float(force_n))
                                    and float(force_n) > 0):
        raise ValueError(f"{path}: force_n: expected a force > 0 N, got {force_n!r}")
    if not (is_num(scale) and math.isfinite(float(scale)) and float(scale) > 0):
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
                         f"{short(found)})")
    if isinstance(nodes, Mapping):
        pairs = {as_int(n, "nodes", path): as_int(b, "nodes beam", path)
                 for n, b in nodes.items()}
    elif isinstance(nodes, Sequence) and not isinstance(nodes, str):
        pairs = {as_int(n, "nodes", path): b + 1 for b, n in enumerate(nodes)}
        if len(pairs) != len(nodes):
            raise ValueError(f"{path}: nodes: a node is listed twice ({list(nodes)})")
    else:
        raise ValueError(f"{path}: nodes: expected {{node: beam}} or a list of nodes "
                         f"(beam 1, 2, ...), got {nodes!r}")
    beams = list(pairs.values())
    if len(set(beams)) != len(beams) or any(b < 0 for b in beams):
        raise ValueError(f"{path}: nodes: beams must be distinct numbers >= 0 (0: the "
                         f"metric M), got {beams}")
    return pairs


def _tags(d):
    tags = {}
    for k in ("id1", "id2", "id3", "id4", "id5"):
        for name, value in TAG.findall(str(d.get(k, ""))):
            tags[name.lower()] = value
    return tags


def _read_uff58(path, nodes, direction, quantity, force_n, kind, scale):
    sets, (Lf, Ff) = read_datasets(path, (58,))
    node_of = _node_map(path, nodes, sorted({int(d.get("rsp_node", 0)) for d in sets}))
    if direction is not None:
        direction = as_int(direction, "direction", path)
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
                             f"{g['quantity']}: pass quantity= (mcfric plot: "
                             f"--measured-quantity) or split the file")
        beam = node_of[node]
        if beam in g["beams"]:
            # with a direction given, +Z and -Z records are both in it: the file must go
            hint = ("pass direction= (mcfric plot: --measured-direction) or split the file"
                    if direction is None else
                    f"both in direction +-{abs(direction)}: split the file")
            raise ValueError(f"{path}: two records for beam {beam} (node {node}) in the same "
                             f"run: {hint}")
        g["beams"][beam] = (x, y)
    if not groups:
        raise ValueError(f"{path}: no dataset 58 record at the mapped nodes "
                         f"{short(sorted(node_of))}" +
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
                         f"(specific data type {spec}): pass quantity= (mcfric plot: "
                         f"--measured-quantity)")
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
                             f"(mcfric plot: --measured-force), the force level of the run "
                             f"in N, to get the response")
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
    existing_file(path)
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
