"""The peak of the upper bound over frequency, refined like the members' peaks.

The largest value of the upper bound on a frequency grid misses a lightly damped
resonance as the members' grid peaks do. Here the bracket between its grid neighbours
is searched again on a sub-grid (the same search as on the grid, continuation along
the sub-grid included), and the best sub-interval refined by
:func:`mcfric.peaks.maximize`, the bound at each new frequency searched from the
uniform corners and the optima of the two nearest frequencies already searched. Where
the force limit takes over from the box beside the best sub-grid point (a kink, which
misleads the parabolic steps), a golden-section search of the bracket is kept where it
finds more. Like the bound itself, the refined peak is the result of a search.

Where the bounds were certified, the sub-grid and the refined peak's frequency are
certified too (:func:`certified_near_peak`): the largest certified upper bound there and
the largest witness (attained by an admissible set of describing functions) bracket the
worst case near the peak, as far as these frequencies sample it; the grid alone can miss
much of it (measured: the docs' peaks page).
"""

from __future__ import annotations

import numpy as np

from ..core.peaks import N_FLANK_MAX
from ..core.receptance import contact_space
from ..metric import QUANTITIES
from ..peaks import at_band_end, golden_maximize, maximize
from .equivalent_linear import MAX_SWEEPS, MAX_SWEEPS_FRACTION_MAX, compute_bounds, upper_bound

_CORNERS = np.array([0, 1, 1 + 1j, 1j])
#: Frequencies of the sub-grid searched between the grid neighbours of the bound's peak.
SUB_GRID = 33


def refine_upper_peak(model, B, rtol=1e-4):
    """Frequency and value of the largest upper bound, refined to ``rtol``.

    Parameters
    ----------
    model : Model
        The model the bounds ``B`` were computed for.
    B : Bounds
        Bounds on an increasing frequency grid.
    rtol : float
        Relative tolerance of the refined value.

    Returns
    -------
    (float, float, bool)
        Frequency (Hz) and value (the metric's unit) of the refined peak, and whether the
        refinement converged (False: the best value found, or the grid's where every
        evaluation failed).
    """
    return _refine(model, B, rtol)[:3]


def _refine(model, B, rtol):
    """:func:`refine_upper_peak`'s result and the frequencies of its sub-grid (None where
    the grid gives no bracket)."""
    f = B.freq_hz
    up = np.where(np.isfinite(B.upper), B.upper, -np.inf)
    k = int(np.argmax(up))
    if not np.isfinite(up[k]):
        return float("nan"), float("nan"), False, None
    lo, hi = max(k - 1, 0), min(k + 1, len(f) - 1)
    if lo == hi:
        return float(f[k]), float(up[k]), False, None
    # a sub-grid of the bracket searched as the grid was (with continuation along it)
    sub_f = np.linspace(f[lo], f[hi], SUB_GRID)
    S = compute_bounds(model, sub_f, B.k_max_re, **_limits(B), certified=False)
    s_up = np.where(np.isfinite(S.upper), S.upper, -np.inf)
    j = int(np.argmax(s_up))
    if s_up[j] < up[k]:                  # never below what the grid found
        return float(f[k]), float(up[k]), False, sub_f
    j_lo, j_hi = max(j - 1, 0), min(j + 1, SUB_GRID - 1)
    a, b = model.dampers
    beams = list(B.beams) if B.beams else list(range(model.n_beams))
    power = QUANTITIES.index(B.quantity)
    solved = {float(sub_f[i]): S.K_upper[i] for i in range(SUB_GRID)}

    def upper_at(f_hz):
        # starts: the uniform corners and the optima of the two nearest frequencies
        near = sorted(solved, key=lambda x: abs(x - f_hz))[:2]
        K = np.array([solved[x] for x in near])
        start = np.concatenate([np.broadcast_to(_CORNERS[:, None], (4, K.shape[1])),
                                K.real / B.k_max_re + 1j * K.imag / B.k_max_im])
        omega = 2.0 * np.pi * np.array([f_hz])
        G, q0, ylin, H = contact_space(model.receptances(omega)[0], model.force, a, b)
        ylin = np.ascontiguousarray(ylin[:, beams])
        H = np.ascontiguousarray(H[:, beams, :])
        upper, _, _, _, K_upper = upper_bound(
            np.ascontiguousarray(G), np.ascontiguousarray(q0), ylin, H, B.k_max_re,
            B.k_max_im, B.F_lim, np.ascontiguousarray(start[None], dtype=complex),
            max(1, round(MAX_SWEEPS_FRACTION_MAX * MAX_SWEEPS)))
        solved[f_hz] = K_upper[0]
        return float(upper[0] * omega[0] ** power), None

    x, m, _, ok = maximize(upper_at, float(sub_f[j_lo]), float(sub_f[j_hi]),
                           float(s_up[j_lo]), float(s_up[j_hi]), rtol)
    if not np.isfinite(m) or m < s_up[j]:
        x, m, ok = float(sub_f[j]), float(s_up[j]), False
    # where the force limit takes over from the box beside the best sub-grid point, the
    # bound has a kink there, which misleads parabolic steps: a golden-section search of
    # the same bracket (unimodal functions, kinks included) is kept where it finds more
    if len(set(S.limited_by[[j_lo, j, j_hi]].tolist())) > 1:
        xg, mg, okg = golden_maximize(upper_at, float(sub_f[j_lo]), float(sub_f[j_hi]), rtol)
        if np.isfinite(mg) and mg > m:
            x, m, ok = xg, mg, okg
    return float(x), float(m), ok, sub_f


def _limits(B):
    """:func:`compute_bounds`' keywords for the constraints and metric of ``B``."""
    return {"k_max_im": B.k_max_im, "F_lim": None if np.isinf(B.F_lim) else B.F_lim,
            "quantity": B.quantity, "beams": B.beams or None}


def certified_near_peak(model, B, sub_f):
    """The certified upper bound and its witness at the frequencies ``sub_f`` (Hz), as
    ``B`` was certified (its certificate's budget, split and order).

    Only the largest value matters near the peak: the first-order relaxation certifies
    every frequency, and where ``B`` used the second order, it runs again only where
    the first order leaves the bound above the largest witness by more than the
    certificate's tolerance (nowhere near the first resonance of the presets: the
    docs' peaks page).

    Parameters
    ----------
    model : Model
        The model the bounds ``B`` were computed for.
    B : Bounds
        Certified bounds (their certificate's settings are reused).
    sub_f : ndarray, shape (n,)
        Frequencies, Hz.

    Returns
    -------
    (ndarray, ndarray)
        The certified upper bound and the witness's value per frequency (the metric's
        unit; inf where a frequency was not certified, NaN where it has no witness).
    """
    C = B.certificate
    how = {"budget": C.budget if C.budget >= 1 else None, "split": C.split,
           "progress": False, **_limits(B)}
    S = compute_bounds(model, sub_f, B.k_max_re, certified=True, moments=False, **how)
    up = np.where(np.isnan(S.certificate.upper), np.inf, S.certificate.upper)
    wit = np.where(np.isfinite(S.certificate.upper_witness), S.certificate.upper_witness,
                   np.nan)
    if C.moments and np.isfinite(wit).any():
        again = np.flatnonzero(up > np.nanmax(wit) * (1 + C.rtol))
        if len(again):
            T = compute_bounds(model, sub_f[again], B.k_max_re, certified=True,
                               moments=True, **how).certificate
            # both are valid: the smaller bound, the larger witness
            up[again] = np.fmin(up[again], T.upper)
            wit[again] = np.fmax(wit[again], T.upper_witness)
    return up, wit


def grid_too_coarse(model, freq_hz):
    """Whether a grid is too coarse to find the bound's peak, as for the members' peaks
    (:mod:`mcfric.core.peaks`): a step of more than ``N_FLANK_MAX`` half-power widths
    (``2 zeta f``) of the model's narrowest mode may hide a resonance between grid
    points.

    Parameters
    ----------
    model : Model
    freq_hz : ndarray, shape (n_f,)
        The grid, Hz.

    Returns
    -------
    float or None
        The grid's largest step (Hz) where it is too coarse, else None (also for a grid
        of one frequency, which has no step).
    """
    f_n, zeta, u = model.modal_arrays()
    real = np.any(u != 0, axis=2)                 # not a padding mode
    width = float(np.min((2.0 * zeta * f_n)[real])) if real.any() else np.inf
    if len(freq_hz) < 2:
        return None
    step = float(np.max(np.diff(freq_hz)))
    return step if not step <= N_FLANK_MAX * width else None


def peak_attrs(model, B, rtol=1e-4):
    """The ``bounds/`` group attributes of the upper bound's refined peak (``model``,
    ``B`` and ``rtol`` as for :func:`refine_upper_peak`).

    Returns
    -------
    dict
        ``peak_upper`` (the metric's unit), ``peak_upper_frequency`` (Hz) and
        ``peak_upper_refined`` (1 if the refinement converged), as
        :func:`refine_upper_peak` gives them, ``peak_upper_at_end`` (-1 or 1 where the
        peak lies at the lower or upper end of the band, else 0:
        :func:`mcfric.peaks.at_band_end`) and
        ``peak_upper_coarse_step`` (Hz: the grid's largest step where it is too coarse to
        find the bound's peak, :func:`grid_too_coarse`, else 0); where ``B`` is certified,
        the largest certified upper bound on the refinement's sub-grid and at the refined
        peak's frequency ``peak_upper_certified`` (the metric's unit; inf where one of
        these frequencies was not certified) at ``peak_upper_certified_frequency`` (Hz),
        the largest witness there ``peak_upper_witness`` at
        ``peak_upper_witness_frequency`` (both NaN where none of them has a witness), and
        the sub-grid's spacing ``peak_sub_grid_step`` (Hz).
    """
    f_pk, up_pk, ok, sub_f = _refine(model, B, rtol)
    coarse = grid_too_coarse(model, B.freq_hz)
    out = {"peak_upper": np.float64(up_pk), "peak_upper_frequency": np.float64(f_pk),
           "peak_upper_refined": np.int8(ok),
           "peak_upper_at_end": np.int8(at_band_end(B.freq_hz, f_pk)),
           "peak_upper_coarse_step": np.float64(coarse or 0.0)}
    if sub_f is not None and B.certificate is not None:
        # the refined peak's frequency joins the sub-grid: between sub-grid points the
        # certified values alone could fall below the searched peak they should bracket
        cert_f = np.union1d(sub_f, [f_pk]) if np.isfinite(f_pk) else sub_f
        for name, v in zip(("certified", "witness"), certified_near_peak(model, B, cert_f)):
            i = int(np.argmax(np.nan_to_num(v, nan=-np.inf)))
            out[f"peak_upper_{name}"] = np.float64(v[i])
            # no witness at all: no frequency either
            out[f"peak_upper_{name}_frequency"] = np.float64(cert_f[i] if not np.isnan(v[i])
                                                             else np.nan)
        out["peak_sub_grid_step"] = np.float64(sub_f[1] - sub_f[0])
    return out
