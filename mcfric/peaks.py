"""Resolved peaks of every member, and folds: settings, the call into the kernel, results.

After a sweep, each member's largest local maxima of the metric are refined in frequency
(to a relative tolerance in amplitude) and the sweep is repeated downward around each
of them to find where the member has more than one steady state. The algorithm is in
:mod:`mcfric.core.peaks`; the docs' page on resolution and branches
(``docs/peaks.md``) explains it and shows what it changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .core import peaks as _kernel
from .metric import QUANTITIES, check_quantity
from .validators import integer, real

#: Default relative tolerance of a refined peak's amplitude.
RTOL = 1e-4
#: Default number of grid points swept downward on each side of a peak.
WINDOW = 4
#: Status and fold codes (see :mod:`mcfric.core.peaks`).
REFINED, AT_EDGE, GRID, NONE = (_kernel.PEAK_REFINED, _kernel.PEAK_AT_EDGE,
                                _kernel.PEAK_GRID, _kernel.PEAK_NONE)
FOLD_NONE, FOLD_FOUND, FOLD_UNCHECKED = (_kernel.FOLD_NONE, _kernel.FOLD_FOUND,
                                         _kernel.FOLD_UNCHECKED)


@dataclass(frozen=True)
class PeakSettings:
    """What to refine.

    Attributes
    ----------
    count : int
        Largest local maxima of the metric kept per member (>= 1).
    rtol : float
        Relative tolerance of the refined amplitude, 0 < rtol <= 0.1.
    window : int
        Grid points on each side of a peak swept downward to look for folds (>= 1).
    quantity : {"displacement", "velocity", "acceleration"}
        Quantity of the metric whose peaks are refined.
    beams : tuple of int or None
        0-based beams of the metric; None for all.
    """

    count: int = 2
    rtol: float = RTOL
    window: int = WINDOW
    quantity: str = "displacement"
    beams: tuple | None = None

    def __post_init__(self):
        integer(1, 10_000)(self.count, "peaks.count")
        r = real("peaks.rtol", self.rtol, lo=0, lo_open=True)
        if r > 0.1:
            raise ValueError(f"peaks.rtol: expected a number in (0, 0.1], got {self.rtol!r}")
        integer(1, 10_000)(self.window, "peaks.window")
        check_quantity(self.quantity, "peaks.quantity")


@dataclass
class Peaks:
    """Refined peaks of ``n_s`` members, ``count`` per member, largest first.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_s, count)
        Frequency of each peak, Hz (NaN where a member has fewer local maxima).
    metric : ndarray, shape (n_s, count)
        The metric at the peak (m, m/s or m/s^2), on the branch the upward sweep
        follows.
    response : ndarray of complex, shape (n_s, count, n_beams)
        Every beam's output amplitude at the peak, m.
    status : ndarray of int8, shape (n_s, count)
        0 refined to ``rtol``; 1 the maximum is at an end of the band (refined there);
        2 not refined (a solver failed): the grid value; -1 no such peak (NaN).
    fold : ndarray of int8, shape (n_s, count)
        1 where the downward sweep around the peak reached another steady state, 0 where
        it reproduced the upward one, -1 where it could not be checked.
    freq_hz_down, metric_down : ndarray, shape (n_s, count)
        The peak of the branch reached from above (equal to the above without a fold).
    """

    freq_hz: np.ndarray
    metric: np.ndarray
    response: np.ndarray
    status: np.ndarray
    fold: np.ndarray
    freq_hz_down: np.ndarray
    metric_down: np.ndarray

    def largest(self):
        """Each member's largest peak of the metric over both branches, shape (n_s,)."""
        both = np.concatenate([self.metric, self.metric_down], axis=1)
        with np.errstate(invalid="ignore"):
            return np.nanmax(np.where(np.isnan(both), -np.inf, both), axis=1)


def refine(model, result, omega, modal_freq_hz, settings, mu0, N0, kc, tol, max_iter):
    """Refine the peaks of a sweep (the kernel's outputs in ``result``).

    Parameters
    ----------
    model : Model
    result : HBMResult
        The sweep: ``response``, ``s`` and ``status`` of every member.
    omega : ndarray, shape (n_f,)
        The sweep's frequencies, rad/s (increasing).
    modal_freq_hz : ndarray, shape (n_r, n_beams, n_modes)
        Modal frequencies, Hz (one rig, or one per member).
    settings : PeakSettings
    mu0, N0, kc : ndarray, shape (n_s, nd)
        Writable, contiguous parameters of the members.
    tol, max_iter :
        The sweep's solver settings.

    Returns
    -------
    Peaks
    """
    if np.any(np.diff(omega) <= 0):
        raise ValueError("freq_hz: peaks are refined on increasing frequencies only")
    n_s, _, n_beams = result.response.shape
    n = settings.count
    _, zeta, u = model.modal_arrays()
    a, b = model.dampers
    beams = np.arange(n_beams) if settings.beams is None else np.asarray(settings.beams)
    out_w = np.empty((n_s, n))
    out_m = np.empty((n_s, n))
    out_y = np.empty((n_s, n, n_beams), np.complex128)
    out_st = np.empty((n_s, n), np.int8)
    out_fold = np.empty((n_s, n), np.int8)
    out_wd = np.empty((n_s, n))
    out_md = np.empty((n_s, n))
    _kernel.refine_peaks(
        np.ascontiguousarray(omega, dtype=np.float64),
        np.array(modal_freq_hz, dtype=np.float64, order="C"),
        np.array(zeta, dtype=np.float64, order="C"), np.array(u, dtype=np.float64, order="C"),
        np.array(model.force, dtype=np.complex128), a.astype(np.int64), b.astype(np.int64),
        mu0, N0, kc, float(tol), int(max_iter), result.response, result.s, result.status,
        beams.astype(np.int64), np.int64(QUANTITIES.index(settings.quantity)), np.int64(n),
        float(settings.rtol), np.int64(settings.window),
        out_w, out_m, out_y, out_st, out_fold, out_wd, out_md)
    to_hz = 1.0 / (2.0 * np.pi)
    return Peaks(out_w * to_hz, out_m, out_y, out_st, out_fold, out_wd * to_hz, out_md)
