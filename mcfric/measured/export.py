"""Export of computed responses and ensemble percentiles as UFF dataset 58."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..metric import METRIC_UNITS as UNITS
from ..metric import QUANTITIES
from ..parsing import as_int
from ..uff import FRF, GENERAL, SPEC_TYPE, UFF_SUFFIXES, id_date, si_units_dataset, write_atomic
from ..uff import TAG as ID_TAGS
from ..validators import is_bool, is_num
from .measurement import KINDS, METRIC

#: Largest node number: a 32-bit integer, as UFF readers take the 10-character field
#: (10**12 was written cut to 1000000000).
MAX_NODE = 2**31 - 1


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
        Frequencies, Hz (> 0), in any order (an up-and-down sweep repeats them); two
        different ones must differ in 6 significant digits (how UFF 58 text prints them).
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
        Start of ID line 1: printable ASCII, without the tags above.
    overwrite : bool
        Replace an existing file.

    Returns
    -------
    dict
        ``{"records": int, "points": int, "dropped": int}`` (dropped: non-finite points).
    """
    path = Path(path)
    if path.suffix.lower() not in UFF_SUFFIXES:
        # read_measured tells the format by the suffix: another would not read back
        raise ValueError(f"{path}: expected a UFF file name ({', '.join(UFF_SUFFIXES)})")
    f = np.asarray(freq_hz, dtype=float)
    if f.ndim != 1 or f.size < 2 or not np.all(np.isfinite(f) & (f > 0)):
        raise ValueError(f"{path}: freq_hz: expected at least 2 finite frequencies > 0 Hz")
    # UFF 58 text prints an uneven abscissa as E13.5: two different frequencies that print
    # alike would read back as two points at one frequency (an up-and-down sweep's
    # repeated frequencies are the same number, and stay)
    distinct = np.unique(f)
    printed = np.array([float(f"{x:.5e}") for x in distinct])
    clash = np.flatnonzero(np.diff(printed) == 0)
    if clash.size:
        lo, hi = (float(x) for x in distinct[clash[0]:clash[0] + 2])
        raise ValueError(f"{path}: freq_hz: {lo:.10g} and {hi:.10g} Hz both print as "
                         f"{printed[clash[0]]:.5e} in UFF 58's 6 significant digits: "
                         f"expected frequencies that differ there")
    if not isinstance(description, str) or not (description.isascii()
                                                and description.isprintable()):
        # a line break or a non-ASCII character breaks UFF's fixed 80-column lines
        raise ValueError(f"{path}: description: expected printable ASCII text, got "
                         f"{description!r}")
    if ID_TAGS.search(description):
        # read back as the export's own kind=, force_n= or percentile= tags
        raise ValueError(f"{path}: description: {description!r} holds a tag that "
                         f"read_measured reads (kind=, force_n=, percentile=)")
    if not is_bool(overwrite):      # "no" is a true value: it replaced the file
        raise ValueError(f"{path}: overwrite: expected True or False, got {overwrite!r}")
    if is_bool(force_n) or not is_num(force_n):
        raise ValueError(f"{path}: force_n: expected a force > 0 N, got {force_n!r}")
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
    d = as_int(direction, "direction", path)
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
    beams = tuple(as_int(b, "beams", path) for b in beams)
    if len(beams) != nb or len(set(beams)) != nb or any(b < 0 for b in beams):
        raise ValueError(f"{path}: beams: expected {nb} distinct numbers >= 0, got {beams}")
    if nodes is None:
        node_of = {b: b for b in beams}
    elif isinstance(nodes, Mapping):
        node_of = {as_int(b, "nodes beam", path): as_int(n, "nodes", path)
                   for b, n in nodes.items()}
    else:
        if len(nodes) != nb:
            raise ValueError(f"{path}: nodes: expected {nb} node numbers (one per column), "
                             f"got {len(nodes)}")
        node_of = {b: as_int(n, "nodes", path) for b, n in zip(beams, nodes)}
    absent = [b for b in beams if b not in node_of]
    if absent:
        raise ValueError(f"{path}: nodes: no node for beam {absent[0]}")
    used = [node_of[b] for b in beams]
    # UFF 58 writes node numbers in 10-character fields; two beams on one node would not
    # read back apart
    if any(not 0 <= n <= MAX_NODE for n in used) or len(set(used)) != len(used):
        raise ValueError(f"{path}: nodes: expected distinct node numbers in 0..{MAX_NODE}, "
                         f"got {used}")
    ref_node = as_int(ref_node, "ref_node", path)
    if not 0 <= ref_node <= MAX_NODE:
        raise ValueError(f"{path}: ref_node: expected a node number in 0..{MAX_NODE}, got "
                         f"{ref_node}")
    cplx = np.iscomplexobj(y)
    frf = function == "frf" or (function == "auto" and cplx)
    if not cplx and np.any(y[np.isfinite(y)] < 0):
        raise ValueError(f"{path}: data: real data are amplitudes and must be >= 0")
    unit = UNITS[quantity]
    dsets, points, dropped = [si_units_dataset()], 0, 0
    date = id_date()
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
    write_atomic(path, dsets, overwrite)
    return {"records": len(dsets) - 1, "points": points, "dropped": dropped}
