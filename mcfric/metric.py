"""The response metric ``M``: the quantities it can be in, their units, how it is formed.

``M = max_b omega^k |y_b|`` over the chosen beams at the output position, with ``k = 0,
1, 2`` for displacement (m), velocity (m/s) and acceleration (m/s^2); see the theory
page of the docs, section "Response metric".
"""

from __future__ import annotations

import numpy as np

from .validators import InputError, choice, is_int

#: The quantities a metric can be in; the index is the power k of omega.
QUANTITIES = ("displacement", "velocity", "acceleration")
#: SI units of the metric for each quantity.
METRIC_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}

check_quantity = choice(*QUANTITIES)


def omega_power(freq_hz, to_quantity, from_quantity="displacement"):
    """``omega^k`` that turns an amplitude in ``from_quantity`` into ``to_quantity``.

    Parameters
    ----------
    freq_hz : array_like
        Frequencies, Hz.
    to_quantity, from_quantity : {"displacement", "velocity", "acceleration"}

    Returns
    -------
    ndarray
        ``(2 pi f)^k``, ``k = index(to) - index(from)`` (s^-k).
    """
    k = QUANTITIES.index(check_quantity(to_quantity, "quantity")) \
        - QUANTITIES.index(check_quantity(from_quantity, "quantity"))
    return (2 * np.pi * np.asarray(freq_hz, dtype=float)) ** k


def check_beams(beams, n_beams, name="beams"):
    """``beams`` (0-based beam indices, one or more, each in ``0..n_beams - 1``; any
    ``>= 0`` where ``n_beams`` is None) as a tuple of int; an ``InputError`` (a
    ``ValueError``) naming ``name`` otherwise (a float, a bool or a string is not an
    index: numpy would truncate or parse it)."""
    top = np.iinfo(np.int64).max if n_beams is None else n_beams
    if is_int(beams):
        beams = (beams,)
    if isinstance(beams, (str, bytes)):        # "all" was read as 'a', 'l', 'l'
        raise InputError(name, f"expected 0-based beam indices, got {beams!r}")
    try:
        beams = list(beams)
    except TypeError:
        raise InputError(name, f"expected 0-based beam indices, got {beams!r}") from None
    bad = [b for b in beams if not is_int(b) or not 0 <= b < top]
    if bad or not beams:
        within = "" if n_beams is None else f" in 0..{n_beams - 1}"
        raise InputError(name, f"expected 0-based beam indices{within} (the Python API "
                               f"counts from 0), got {bad[0] if bad else beams!r}")
    return tuple(int(b) for b in beams)


def response_metric(response, freq_hz, quantity="displacement", beams=None):
    """``max_b |y_b| omega^k`` over the chosen beams (NaN propagates).

    Parameters
    ----------
    response : ndarray of complex, shape (..., n_f, n_beams)
        Displacement amplitudes, m.
    freq_hz : ndarray, shape (n_f,)
        Frequencies, Hz.
    quantity : {"displacement", "velocity", "acceleration"}
    beams : sequence of int, optional
        Beams to take the maximum over, **0-based** like the arrays (the configuration
        and the command line count beams from 1, like the rig); default all.

    Returns
    -------
    ndarray, shape (..., n_f)
        ``M`` in m, m/s or m/s^2.
    """
    check_quantity(quantity, "quantity")
    if beams is not None:
        beams = list(check_beams(beams, response.shape[-1]))
    amp = np.abs(response if beams is None else response[..., beams])
    # the maximum over beams slice by slice: numpy reduces a short last axis slowly, and
    # np.maximum propagates NaN like ndarray.max
    m = amp[..., 0].copy()
    for b in range(1, amp.shape[-1]):
        np.maximum(m, amp[..., b], out=m)
    power = QUANTITIES.index(quantity)
    if power:
        m *= (2 * np.pi * np.asarray(freq_hz)) ** power
    return m
