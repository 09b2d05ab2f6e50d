"""Modal tables from files: UFF dataset 55, CSV and TOML -> :class:`mcfric.model.ModalTable`.

Users identify the beam modes of their rig by experimental modal analysis and keep them in
Universal File Format (UFF) files. This module reads such tables (and writes them, for
round trips and for other tools), with the conventions fixed here:

Positions and nodes
    A :class:`~mcfric.model.ModalTable` labels its shape columns with integer *positions*.
    A UFF file labels its values with *node numbers*, the natural labels. ``positions``
    says which nodes become which columns:

    * ``None``: every node of the file (in the order of the first mode), labels = nodes;
    * a sequence of node numbers, e.g. ``[101, 102, 103]``: those nodes, labels = nodes
      (the model then uses ``contact=101, output=102, drive=103``);
    * a mapping ``{label: node}``, e.g. ``{1: 101, 2: 102, 3: 103}``: relabelled, so the
      paper's numbering (1 contact, 2 output, 3 drive) and the model defaults still apply.

    In CSV and TOML tables the column labels play the role of the node numbers.

Modes (UFF 55)
    One dataset 55 per mode, analysis type 2 (normal mode): record 8 holds the frequency
    (Hz), the modal mass, the viscous damping ratio and the hysteretic damping ratio. The
    shapes must be **real** and, after this rule, **mass-normalised** in SI (kg^-1/2):

    * modal mass 0 (unknown, pyuff's default) or 1: the shapes are taken as they are;
    * modal mass m > 0: the shapes are divided by ``sqrt(m)`` (unit modal mass);
    * damping: the viscous ratio; if it is 0 and the hysteretic ratio eta > 0,
      ``zeta = eta / 2`` (equal at resonance);
    * a dataset 164 (units) in the file is honoured: file values are divided by its
      length/force factors (I-DEAS convention), so shapes scale by ``sqrt(F / L)``.

    The direction is one component of each node's values (1 = X, 2 = Y, 3 = Z, 4-6 the
    rotations): ``direction=None`` takes the only component that is non-zero at the chosen
    nodes and refuses to guess when there are several.

Rejected, each with one ``ValueError`` line naming the file
    complex-eigenvalue modes (analysis types 3, 7) and complex normal modes whose imaginary
    part exceeds ``max_imag`` of the largest component after the best real rotation;
    other analysis types; duplicated or missing mode numbers; nodes missing from a mode
    (UFF allows leaving out all-zero nodes: add them explicitly); modes that are zero at all
    chosen positions; zero or negative frequencies; truncated files and files without a
    dataset 55.

``pyuff`` is an optional dependency (``pip install "mcfric[uff]"``), imported only when a
UFF file is read or written.
"""

from __future__ import annotations

import math
import os
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .model import ModalTable
from .parsing import as_int, csv_rows, short
from .uff import DIRECTIONS, UFF_SUFFIXES, id_date, read_datasets, si_units_dataset, write_atomic
from .validators import existing_file

#: UFF 55 analysis types, for messages.
ANALYSIS_TYPES = {0: "unknown", 1: "static", 2: "normal mode",
                  3: "complex eigenvalue first order", 4: "transient",
                  5: "frequency response", 6: "buckling",
                  7: "complex eigenvalue second order"}
#: Relative rounding of UFF's E13.5 fields (6 significant digits).
UFF_RTOL = 5e-6


# ---------------------------------------------------------------- positions

def _position_map(positions, available, path, what="node"):
    """``[(label, key)]`` from the ``positions`` argument; ``key`` indexes the file.

    ``available``: the file's node numbers / column labels, in file order.
    """
    if positions is None:
        pairs = [(k, k) for k in available]
    elif isinstance(positions, Mapping):
        pairs = [(as_int(lab, "positions label", path), as_int(k, f"positions {what}", path))
                 for lab, k in positions.items()]
    else:
        try:
            if isinstance(positions, (str, bytes, set, frozenset)):    # "1" or no order
                raise TypeError
            keys = [as_int(k, f"positions {what}", path) for k in positions]
        except TypeError:
            raise ValueError(f"{path}: positions: expected None, a list of {what} numbers "
                             f"or a mapping {{label: {what}}}, got {positions!r}") from None
        pairs = [(k, k) for k in keys]
    if not pairs:
        raise ValueError(f"{path}: positions: no positions selected")
    keys = [k for _, k in pairs]
    if len(set(keys)) != len(keys):
        raise ValueError(f"{path}: positions: a {what} is used twice ({keys})")
    missing = [k for k in keys if k not in available]
    if missing:
        raise ValueError(f"{path}: {what} {missing[0]} not in the file "
                         f"({what}s: {short(available)})")
    return pairs


def _select_modes(numbers, modes, path):
    """Indices into the file's modes for the ``modes`` argument (mode numbers)."""
    if len(set(numbers)) != len(numbers):
        dup = next(n for n in numbers if numbers.count(n) > 1)
        raise ValueError(f"{path}: mode {dup} appears twice")
    if modes is None:
        return sorted(range(len(numbers)), key=numbers.__getitem__)
    if isinstance(modes, (str, bytes, set, frozenset)) or not hasattr(modes, "__iter__"):
        # modes=1 failed iterating an int (TypeError); a set has no order
        raise ValueError(f"{path}: modes: expected a sequence of mode numbers, got {modes!r}")
    out = []
    for m in modes:
        m = as_int(m, "modes", path)
        if m not in numbers:
            raise ValueError(f"{path}: mode {m} not in the file (modes: {short(sorted(numbers))})")
        out.append(numbers.index(m))
    if not out:
        raise ValueError(f"{path}: modes: no modes selected")
    if len(set(out)) != len(out):
        raise ValueError(f"{path}: modes: a mode is selected twice")
    return out


def _table(path, freq, zeta, shapes, labels):
    try:
        return ModalTable(freq_hz=freq, zeta=zeta, shapes=shapes, positions=tuple(labels))
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None


def _check_modes(path, numbers, freq, zeta, mass, shapes, labels):
    for n, f, z, m, u in zip(numbers, freq, zeta, mass, shapes):
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"{path}: mode {n}: frequency must be > 0 Hz, got {float(f):g}")
        if not (math.isfinite(z) and z >= 0):
            raise ValueError(f"{path}: mode {n}: damping ratio must be >= 0, got {float(z):g}")
        if z > 1:
            # overdamped: no resonance; more often a damping in percent (2 for 0.02)
            raise ValueError(f"{path}: mode {n}: damping ratio must be <= 1 (0.02 for 2 %), "
                             f"got {float(z):g}")
        if not (math.isfinite(m) and m >= 0):
            raise ValueError(f"{path}: mode {n}: modal mass must be >= 0, got {float(m):g}")
        if not np.all(np.isfinite(u)):
            raise ValueError(f"{path}: mode {n}: shape values must be finite")
        if not np.any(u != 0):
            raise ValueError(f"{path}: mode {n} is zero at all positions "
                             f"({short(labels)}): leave it out with modes=")


def _mass_normalise(shape, m):
    # modal mass 0 means "not given" (pyuff's default) and 1 means already normalised
    return shape if m in (0.0, 1.0) else shape / math.sqrt(m)


# ---------------------------------------------------------------- reading

def read_modal_table(path, *, positions=None, direction=None, modes=None, max_imag=0.05,
                     format=None):
    """Read one beam's modal table from a UFF (dataset 55), CSV or TOML file.

    Parameters
    ----------
    path : str or Path
        ``.uff``/``.unv``/``.uf`` (UFF, needs pyuff), ``.csv`` or ``.toml``.
    positions : None, sequence of int or mapping {int: int}, optional
        Which nodes (UFF) or column labels (CSV/TOML) become the table's positions, and
        their labels (module docstring). Default: all, labels = node numbers.
    direction : int, optional
        UFF only: component of the node values, 1..6 (X, Y, Z, RX, RY, RZ); default the
        only non-zero one.
    modes : sequence of int, optional
        Mode numbers to keep, in this order; default all, by mode number.
    max_imag : float
        UFF only: largest accepted ``max |Im| / max |u|`` of a complex-valued normal mode
        after its best real rotation (default 0.05); the real part is used.
    format : {"uff", "csv", "toml"}, optional
        Override the choice by file suffix.

    Returns
    -------
    ModalTable
        Frequencies in Hz, damping ratios, mass-normalised shapes in kg^-1/2.

    Raises
    ------
    ValueError
        One line naming the file and the problem.
    ImportError
        A UFF file without pyuff installed.
    """
    if not isinstance(path, (str, os.PathLike)):      # Path(None): a TypeError from os
        raise ValueError(f"path: expected a file's path, got {path!r}")
    path = Path(path)
    fmt = _format(path, format)
    if fmt != "uff":
        existing_file(path)
    if fmt == "uff":
        return _read_uff55(path, positions, direction, modes, max_imag)
    if fmt == "csv":
        numbers, freq, zeta, mass, shapes, labels = _parse_csv_table(path)
    else:
        numbers, freq, zeta, mass, shapes, labels = _parse_toml_table(path)
    pairs = _position_map(positions, labels, path, what="column")
    cols = [labels.index(k) for _, k in pairs]
    out_labels = [lab for lab, _ in pairs]
    order = _select_modes(numbers, modes, path)
    shapes = shapes[:, cols]
    _check_modes(path, [numbers[i] for i in order], freq[order], zeta[order], mass[order],
                 shapes[order], out_labels)
    u = np.array([_mass_normalise(shapes[i], mass[i]) for i in order])
    return _table(path, freq[order], zeta[order], u, out_labels)


def _format(path, fmt):
    if fmt is not None:
        if fmt not in ("uff", "csv", "toml"):
            raise ValueError(f"{path}: format: expected 'uff', 'csv' or 'toml', got {fmt!r}")
        return fmt
    suffix = path.suffix.lower()
    if suffix in UFF_SUFFIXES:
        return "uff"
    if suffix in (".csv", ".toml"):
        return suffix[1:]
    raise ValueError(f"{path}: unknown file type {suffix!r}: expected .uff/.unv (UFF 55), "
                     f".csv or .toml, or pass format=")


def _read_uff55(path, positions, direction, modes, max_imag):
    sets, (Lf, Ff) = read_datasets(path, (55,))
    if not (math.isfinite(max_imag) and max_imag >= 0):
        raise ValueError(f"{path}: max_imag: expected a number >= 0, got {max_imag!r}")
    parsed = [_uff55_mode(path, k, d) for k, d in enumerate(sets)]
    numbers = [p["mode"] for p in parsed]
    order = _select_modes(numbers, modes, path)
    parsed = [parsed[i] for i in order]
    pairs = _position_map(positions, list(parsed[0]["nodes"]), path)
    labels = [lab for lab, _ in pairs]
    nodes = [n for _, n in pairs]
    ndv = parsed[0]["values"].shape[1]
    # (n_modes, n_positions, ndv) values at the chosen nodes
    vals = []
    for p in parsed:
        if p["values"].shape[1] != ndv:
            raise ValueError(f"{path}: mode {p['mode']} has {p['values'].shape[1]} values "
                             f"per node, mode {parsed[0]['mode']} has {ndv}")
        rows = []
        for n in nodes:
            if n not in p["nodes"]:
                raise ValueError(f"{path}: node {n} missing from mode {p['mode']} "
                                 f"(nodes: {short(p['nodes'])})")
            rows.append(p["values"][p["nodes"][n]])
        vals.append(rows)
    vals = np.array(vals)
    comp = _direction(path, vals, direction, nodes)
    shapes = vals[:, :, comp]
    if np.iscomplexobj(shapes):
        shapes = np.array([_realise(path, p["mode"], s, max_imag)
                           for p, s in zip(parsed, shapes)])
    shapes = shapes.astype(float) * math.sqrt(Ff / Lf)  # dataset 164: file units -> SI
    freq = np.array([p["freq"] for p in parsed])
    zeta = np.array([p["zeta"] for p in parsed])
    mass = np.array([p["mass"] for p in parsed])
    _check_modes(path, [p["mode"] for p in parsed], freq, zeta, mass, shapes, nodes)
    u = np.array([_mass_normalise(s, m) for s, m in zip(shapes, mass)])
    return _table(path, freq, zeta, u, labels)


def _uff55_mode(path, k, d):
    """One dataset 55 as {mode, freq, zeta, mass, nodes: {node: row}, values (n, ndv)}."""
    at = d.get("analysis_type")
    where = f"dataset 55 #{k + 1}"
    if at in (3, 7):
        raise ValueError(f"{path}: {where} holds complex-eigenvalue modes (analysis type {at}); "
                         f"mcfric needs real normal modes (analysis type 2), mass-normalised")
    if at != 2:
        raise ValueError(f"{path}: {where} has analysis type {at} "
                         f"({ANALYSIS_TYPES.get(at, 'unknown')}); mcfric needs normal modes "
                         f"(analysis type 2)")
    node_nums = [int(n) for n in np.atleast_1d(d.get("node_nums", []))]
    values = _uff55_values(path, where, d, len(node_nums))
    nodes = {}
    for i, n in enumerate(node_nums):
        if n in nodes:
            raise ValueError(f"{path}: {where}: node {n} appears twice")
        nodes[n] = i
    if not nodes:
        raise ValueError(f"{path}: {where} (mode {d.get('mode_n')}) has no node values")
    zeta = float(d.get("modal_damp_vis", 0.0))
    eta = float(d.get("modal_damp_his", 0.0))
    if zeta == 0.0 and eta > 0.0:
        zeta = eta / 2  # hysteretic loss factor -> equivalent viscous ratio at resonance
    return dict(mode=int(d["mode_n"]), freq=float(d["freq"]), zeta=zeta,
                mass=float(d.get("modal_m", 0.0)), nodes=nodes, values=values)


def _uff55_values(path, where, d, n_nodes):
    ndv = int(d.get("n_data_per_node", 3))
    keys = [f"r{i}" for i in range(1, 7) if f"r{i}" in d]
    cols = [np.atleast_1d(d[k]) for k in keys]
    if len(cols) == ndv and all(len(c) == n_nodes for c in cols):
        return np.column_stack(cols)
    if len(cols) == 6 and ndv not in (3, 6) and not any(np.iscomplexobj(c) for c in cols):
        # pyuff splits any NDV other than 3 with a stride of 6: undo it
        flat = np.empty(sum(len(c) for c in cols))
        for i, c in enumerate(cols):
            flat[i::6] = c
        if flat.size == n_nodes * ndv:
            return flat.reshape(n_nodes, ndv)
    raise ValueError(f"{path}: {where}: cannot split the node values ({ndv} per node, "
                     f"{n_nodes} nodes)")


def _direction(path, vals, direction, nodes):
    ndv = vals.shape[2]
    if direction is not None:
        d = as_int(direction, "direction", path)
        if not 1 <= d <= ndv:
            raise ValueError(f"{path}: direction: expected 1..{ndv} (values per node), got {d}")
        return d - 1
    nonzero = [c for c in range(ndv) if np.any(vals[:, :, c] != 0)]
    if len(nonzero) == 1 or ndv == 1:
        return nonzero[0] if nonzero else 0
    if not nonzero:
        return 0  # all zero: reported as zero modes
    names = ", ".join(DIRECTIONS.get(c + 1, str(c + 1)) for c in nonzero)
    raise ValueError(f"{path}: the modes have non-zero {names} components at nodes "
                     f"{short(nodes)}: pass direction= (1=X, 2=Y, 3=Z)")


def _realise(path, mode, v, max_imag):
    """Real shape from a complex one: best rotation, imaginary rest must be small."""
    # theta maximising sum Re(v e^{-i theta})^2 is half the angle of sum v^2
    w = v * np.exp(-0.5j * np.angle(np.sum(v * v)))
    scale = np.max(np.abs(w))
    ratio = np.max(np.abs(w.imag)) / scale if scale > 0 else 0.0
    if ratio > max_imag:
        raise ValueError(f"{path}: mode {mode} is complex (imaginary part {ratio:.3g} of the "
                         f"largest component after the best real rotation, limit "
                         f"max_imag={max_imag:g}); mcfric needs real normal modes")
    return w.real


_CSV_SHAPE = re.compile(r"^u_?(-?\d+)$")


def _parse_csv_table(path):
    rows = csv_rows(path, "CSV table")
    line0, header = rows[0]
    names = [h.strip().lower() for h in header]
    labels, shape_cols = [], []
    known = {}
    for j, name in enumerate(names):
        m = _CSV_SHAPE.match(name)
        if m:
            labels.append(int(m.group(1)))
            shape_cols.append(j)
        elif name in ("mode", "freq_hz", "zeta", "modal_mass"):
            if name in known:
                raise ValueError(f"{path}: column {name!r} appears twice")
            known[name] = j
        else:
            raise ValueError(f"{path}: unknown column {header[j].strip()!r} (expected mode, "
                             f"freq_hz, zeta, modal_mass, u<position>)")
    missing = [c for c in ("freq_hz", "zeta") if c not in known]
    if not shape_cols:
        missing.append("u<position> (mode shape columns, e.g. u1, u2, u3)")
    if missing:
        raise ValueError(f"{path}: missing column(s): {', '.join(missing)}")
    if len(set(labels)) != len(labels):
        raise ValueError(f"{path}: a shape column label appears twice ({labels})")
    data = []
    for line, r in rows[1:]:
        if len(r) != len(names):
            raise ValueError(f"{path}: line {line}: {len(r)} fields, the header has "
                             f"{len(names)}")
        vals = []
        for j, c in enumerate(r):
            try:
                vals.append(float(c))
            except ValueError:
                raise ValueError(f"{path}: line {line}, column {names[j]}: not a number: "
                                 f"{c.strip()!r}") from None
        data.append(vals)
    if not data:
        raise ValueError(f"{path}: no modes (only a header)")
    a = np.array(data)
    n = len(a)
    numbers = ([as_int(x, "mode", path) for x in a[:, known["mode"]]] if "mode" in known
               else list(range(1, n + 1)))
    mass = a[:, known["modal_mass"]] if "modal_mass" in known else np.zeros(n)
    return (numbers, a[:, known["freq_hz"]], a[:, known["zeta"]], mass,
            a[:, shape_cols], labels)


_TOML_KEYS = ("freq_hz", "zeta", "shapes", "positions", "modes", "modal_mass")


def _parse_toml_table(path):
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8-sig"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: not valid TOML ({e})") from None
    for keys in ((), ("table",), ("model", "table")):
        t = doc
        for k in keys:
            t = t.get(k, {}) if isinstance(t, dict) else {}
        if isinstance(t, dict) and "freq_hz" in t:
            break
    else:
        raise ValueError(f"{path}: no modal table (key freq_hz at the top level, in [table] "
                         f"or in [model.table])")
    unknown = [k for k in t if k not in _TOML_KEYS]
    if unknown:
        raise ValueError(f"{path}: unknown key {unknown[0]!r} in the modal table (expected "
                         f"{', '.join(_TOML_KEYS)})")
    missing = [k for k in ("zeta", "shapes") if k not in t]
    if missing:
        raise ValueError(f"{path}: missing key(s): {', '.join(missing)}")
    try:
        freq = np.array(t["freq_hz"], dtype=float)
        zeta = np.array(t["zeta"], dtype=float)
        shapes = np.array(t["shapes"], dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: freq_hz, zeta and shapes must be numbers (shapes: one "
                         f"row of equal length per mode)") from None
    n = freq.size
    if freq.ndim != 1 or zeta.shape != freq.shape or shapes.ndim != 2 or len(shapes) != n:
        raise ValueError(f"{path}: expected freq_hz and zeta of one value per mode and "
                         f"shapes of one row per mode, got {freq.size}, {zeta.size} and "
                         f"shape {shapes.shape}")
    labels = [as_int(p, "positions", path) for p in t.get("positions",
                                                          range(1, shapes.shape[1] + 1))]
    if len(labels) != shapes.shape[1]:
        raise ValueError(f"{path}: positions: {len(labels)} labels for {shapes.shape[1]} "
                         f"shape columns")
    numbers = [as_int(m, "modes", path) for m in t.get("modes", range(1, n + 1))]
    if len(numbers) != n:
        raise ValueError(f"{path}: modes: {len(numbers)} numbers for {n} modes")
    mass = np.array(t.get("modal_mass", np.zeros(n)), dtype=float)
    if mass.shape != (n,):
        raise ValueError(f"{path}: modal_mass: expected {n} values")
    return numbers, freq, zeta, mass, shapes, labels


# ---------------------------------------------------------------- writing

def write_modal_table_uff55(path, table, *, nodes=None, direction=3, modes=None,
                            description="mcfric modal table", overwrite=False):
    """Write a modal table as UFF: a dataset 164 (SI) and one dataset 55 per mode.

    Each mode is a normal mode (analysis type 2), 3-DOF translation vectors (data
    characteristic 2, displacement), the shape in component ``direction`` and zeros in the
    others, modal mass 1 (the shapes are mass-normalised, kg^-1/2), the viscous damping
    ratio. UFF prints 6 significant digits (E13.5): frequencies, damping ratios and shapes
    come back rounded to that.

    Parameters
    ----------
    path : str or Path
        Output file (``.uff``), written atomically.
    table : ModalTable
    nodes : mapping {position label: node number}, optional
        Node number of each position; default the labels themselves (must be > 0).
    direction : {1, 2, 3}
        Component that holds the shape (X, Y, Z).
    modes : sequence of int, optional
        Mode numbers written to the file (default 1..n_modes).
    description : str
        ID line 1.
    overwrite : bool
        Replace an existing file.
    """
    path = Path(path)
    if not isinstance(table, ModalTable):
        raise ValueError(f"{path}: table: expected a ModalTable, got {type(table).__name__}")
    d = as_int(direction, "direction", path)
    if d not in (1, 2, 3):
        raise ValueError(f"{path}: direction: expected 1, 2 or 3 (X, Y, Z), got {direction!r}")
    nodes = dict(nodes) if nodes is not None else {p: p for p in table.positions}
    node_nums = []
    for p in table.positions:
        if p not in nodes:
            raise ValueError(f"{path}: nodes: no node number for position {p}")
        n = as_int(nodes[p], "nodes", path)
        if n <= 0:
            raise ValueError(f"{path}: nodes: node numbers must be > 0, got {n} for "
                             f"position {p}")
        node_nums.append(n)
    if len(set(node_nums)) != len(node_nums):
        raise ValueError(f"{path}: nodes: node numbers must be distinct, got {node_nums}")
    numbers = (list(range(1, table.n_modes + 1)) if modes is None
               else [as_int(m, "modes", path) for m in modes])
    if len(numbers) != table.n_modes or len(set(numbers)) != len(numbers):
        raise ValueError(f"{path}: modes: expected {table.n_modes} distinct mode numbers")
    zero = np.zeros(len(node_nums))
    dsets = [si_units_dataset()]
    for k, number in enumerate(numbers):
        r = [zero, zero, zero]
        r[d - 1] = np.array(table.shapes[k], dtype=float)
        f = float(table.freq_hz[k])
        dsets.append({
            "type": 55, "id1": description[:80],
            "id2": "mass-normalised real normal modes, SI (kg^-1/2)",
            "id3": id_date(), "id4": f"mode {number}",
            "id5": f"Mode {number:10d} Frequency {f:13.5e}",
            "model_type": 1, "analysis_type": 2, "data_ch": 2, "spec_data_type": 8,
            "data_type": 2, "n_data_per_node": 3, "load_case": 1, "mode_n": number,
            "freq": f, "modal_m": 1.0, "modal_damp_vis": float(table.zeta[k]),
            "modal_damp_his": 0.0, "node_nums": np.array(node_nums),
            "r1": r[0], "r2": r[1], "r3": r[2]})
    write_atomic(path, dsets, overwrite)
    return path
