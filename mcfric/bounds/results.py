"""The bounds in results files: the ``bounds/`` group, and files holding only bounds.

This module says what is stored (names, units, attributes); the store writes and reads
it (:mod:`mcfric.store`), as it does every HDF5 file.
"""

from __future__ import annotations

import numpy as np

from ..metric import METRIC_UNITS
from ..results_check import check_bounds
from .certified import Certificate
from .equivalent_linear import Bounds

#: The bounds group's datasets at most (18 with a certificate), and its values per
#: frequency at most: 16 of 8 bytes and 4 complex ones per damper (:func:`to_group`).
_DATASETS, _PER_FREQ, _PER_DAMPER = 32, 16 * 8, 4 * 16


def group_bytes(n_freq, n_dampers):
    """Bytes the ``bounds/`` group of :func:`to_group` needs in a file at most (its data,
    4 kB of HDF5 metadata per dataset, 8 kB of attributes), known before the bounds are
    computed: a run checks its disk for them first (tests compare it with the group's
    own size).

    Parameters
    ----------
    n_freq, n_dampers : int

    Returns
    -------
    int
        Bytes.
    """
    return (_DATASETS * 4096 + 8192
            + n_freq * (_PER_FREQ + _PER_DAMPER * n_dampers))


def to_group(B):
    """The ``bounds/`` group of a results file: ``{var: (dims, array, attrs)}, attrs``."""
    unit = METRIC_UNITS[B.quantity]
    variables = {
        "upper": (("frequency",), B.upper, {
            "units": unit, "long_name": "searched upper bound of M (the paper's: the largest "
                                        "box value found or the force bound, the smaller), "
                                        "not certified (upper_certified, where computed, "
                                        "is); NaN where the search failed"}),
        "lower": (("frequency",), B.lower, {
            "units": unit, "long_name": "searched lower bound of M (the smallest box value "
                                        "found), not certified (lower_certified, where "
                                        "computed, is)"}),
        "limited_by": (("frequency",), B.limited_by, {
            "long_name": "constraint that sets the upper bound", "flag_values": [0, 1],
            "flag_meanings": "box force"}),
        "upper_box": (("frequency",), B.upper_box, {
            "units": unit, "long_name": "largest box value found (at least the force bound "
                                        "where the force limit sets the upper bound)"}),
        "upper_force": (("frequency",), B.upper_force, {
            "units": unit, "long_name": "force-saturation bound of M (Eq. 10)"}),
        "K_upper": (("frequency", "damper"), B.K_upper, {
            "units": "N/m", "long_name": "describing functions at the box maximum"}),
        "K_lower": (("frequency", "damper"), B.K_lower, {
            "units": "N/m", "long_name": "describing functions at the box minimum"}),
    }
    attrs = {"k_max_re": B.k_max_re, "k_max_im": B.k_max_im, "F_lim": B.F_lim,
             "quantity": B.quantity, "beams": np.asarray(B.beams, dtype=np.int64) + 1,
             "method": "equivalent-linear bounds (paper Section 3; docs: bounds): upper and "
                       "lower are extremes found by a search, not certified (the "
                       "certified ones, where computed: upper_certified, lower_certified): "
                       "coordinate search exact per "
                       "damper, multistart, continuation along frequency, projected "
                       "gradient and minimax search for the minimum (mcfric.bounds)",
             "n_failed": np.int64(B.n_failed)}
    C = B.certificate
    if C is not None:
        variables.update({
            "upper_certified": (("frequency",), C.upper, {
                "units": unit, "long_name": "certified upper bound: >= M for every admissible "
                                            "set of describing functions (box and force "
                                            "limit together); inf where not proved"}),
            "lower_certified": (("frequency",), C.lower, {
                "units": unit, "long_name": "certified lower bound: <= M for every admissible "
                                            "set of describing functions"}),
            "upper_witness": (("frequency",), C.upper_witness, {
                "units": unit, "long_name": "M at an admissible point (K_upper_witness): "
                                            "the largest M lies in [upper_witness, "
                                            "upper_certified]"}),
            "lower_witness": (("frequency",), C.lower_witness, {
                "units": unit, "long_name": "M at an admissible point (K_lower_witness)"}),
            "upper_gap": (("frequency",), C.upper_gap, {
                "units": "1", "long_name": "upper_certified / upper_witness - 1"}),
            "lower_gap": (("frequency",), C.lower_gap, {
                "units": "1", "long_name": "1 - lower_certified / lower_witness"}),
            "K_upper_witness": (("frequency", "damper"), C.K_upper, {
                "units": "N/m", "long_name": "describing functions of the upper witness"}),
            "K_lower_witness": (("frequency", "damper"), C.K_lower, {
                "units": "N/m", "long_name": "describing functions of the lower witness"}),
            "certified_converged": (("frequency",), (C.converged[0] + 2 * C.converged[1]
                                                     ).astype(np.int8), {
                "long_name": "certification met its tolerance certify_rtol (within the "
                             "budget, or after the relaxation)",
                "flag_masks": [1, 2], "flag_meanings": "upper lower"}),
        })
        for row, name in enumerate(("upper", "lower")):
            variables[f"{name}_evaluations"] = (("frequency",), C.evaluations[row], {
                "long_name": f"enclosures evaluated by the certification of the {name} bound"})
        attrs["certify_budget"] = np.int64(C.budget)
        attrs["certify_relaxation"] = np.int8(C.relaxed)
        attrs["certify_second_order"] = np.asarray(C.second_order, np.int64)
        attrs["certify_moments"] = np.int8(C.moments)
        attrs["certify_rtol"] = np.float64(C.rtol)
        attrs["certify_split"] = np.int64(C.split)
        attrs["certify_split_relaxations"] = np.asarray(C.split_used, np.int64)
        attrs["certify_first_order"] = np.asarray(C.first_order, np.int64)
    return variables, attrs


def read_bounds(path):
    """The bounds stored in a results (or bounds) file.

    Parameters
    ----------
    path : str or Path
        A results file of ``mcfric run`` (complete or partial) or a bounds file of
        ``mcfric bounds``.

    Returns
    -------
    Bounds or None
        The searched bounds and, where the file has them, the certified ones
        (``certificate``), in the metric's unit; None if the file has no ``bounds/``
        group.
    """
    from ..store import StoreError, read, read_group

    found = read_group(path, "bounds")
    if found is None:
        return None
    g, a = found
    f = read(path, "frequency")
    # a damaged group: one line naming what is missing, not a KeyError
    check_bounds(path, g, a, len(f))
    try:
        return _bounds(f, g, a)
    except (TypeError, ValueError) as e:
        raise StoreError(f"{path}: bounds/ is not readable ({e})") from None


def _bounds(f, g, a):
    """:class:`Bounds` from the frequencies ``f`` and the checked group ``g``, ``a``."""
    cert = None
    if "upper_certified" in g:
        conv = np.asarray(g["certified_converged"])
        cert = Certificate(g["upper_certified"], g["lower_certified"], g["upper_witness"],
                           g["lower_witness"], g["K_upper_witness"], g["K_lower_witness"],
                           np.stack([(conv & 1) > 0, (conv & 2) > 0]),
                           np.stack([g["upper_evaluations"], g["lower_evaluations"]]),
                           int(a["certify_budget"]), bool(a.get("certify_relaxation", 0)),
                           np.asarray(a.get("certify_second_order", [0, 0]), np.int64),
                           int(a.get("certify_split", 0)),
                           np.asarray(a.get("certify_split_relaxations", [0, 0]), np.int64),
                           bool(a.get("certify_moments", 0)),
                           # files before it was stored: 0.5 % then for every model
                           float(a.get("certify_rtol", 5e-3)),
                           np.asarray(a.get("certify_first_order", [0, 0]), np.int64))
    return Bounds(f, g["upper"], g["lower"], g["upper_box"],
                  g["upper_force"], g["limited_by"], g["K_upper"], g["K_lower"],
                  float(a["k_max_re"]), float(a["k_max_im"]), float(a["F_lim"]),
                  str(a["quantity"]), tuple(int(b) - 1 for b in np.atleast_1d(a["beams"])),
                  cert)


def write_bounds_file(path, cfg, B, peak=None):
    """A bounds-only results file: ``frequency``, ``damper`` and ``bounds/``, root
    attributes as a run's (configuration, versions), written atomically by the store;
    ``peak`` (:func:`mcfric.bounds.peak.peak_attrs`), when given, joins the group's
    attributes as in a run's file."""
    from ..provenance import software_attrs
    from ..store import write_file

    spec = getattr(cfg, "spec", cfg)
    model = spec.model
    if not np.array_equal(np.asarray(B.freq_hz), np.asarray(spec.freq_hz)):
        # the file's record would describe another grid (info and plot refuse such a file)
        raise ValueError(f"B: bounds on {len(B.freq_hz)} frequencies, not on the "
                         f"configuration's grid ({len(spec.freq_hz)}): compute them on "
                         f"cfg.spec.freq_hz")
    a, b = model.dampers
    coords = {
        "frequency": (B.freq_hz, {"units": "Hz", "long_name": "excitation frequency"}),
        "damper": (np.arange(1, model.n_dampers + 1),
                   {"long_name": "damper number (1-based); couples beam_a and beam_b",
                    "beam_a": a + 1, "beam_b": b + 1}),
    }
    attrs = {"title": f"mcfric response bounds: {model.name}", "model_name": model.name,
             "config": spec.config_toml, "config_json": spec.config_json,
             "samples": np.int64(0), **software_attrs()}
    variables, group_attrs = to_group(B)
    group_attrs.update(peak or {})
    return write_file(path, coords, {"bounds": (variables, group_attrs)}, attrs)
