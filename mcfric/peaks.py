"""Resolved peaks of every member, and folds: settings, the call into the kernel, results.

After a sweep, each member's largest local maxima of the metric are refined in frequency
(to a relative tolerance in amplitude) and the sweep is repeated downward around each
of them to find where the member has more than one steady state. The algorithm is in
:mod:`mcfric.core.peaks`; the docs' page on resolution and branches
(``docs/peaks.md``) explains it and shows what it changes.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from .core import peaks as _kernel
from .metric import QUANTITIES, check_beams, check_quantity
from .model import CONTACT_LAWS
from .quantiles import quantile_interval
from .validators import integer, real

#: Default relative tolerance of a refined peak's amplitude.
RTOL = 1e-4
#: Default number of grid points swept downward on each side of a peak.
WINDOW = 3
#: Coverage of the confidence intervals of the peak statistics in the summaries.
CONFIDENCE = 0.95
#: Status and fold codes (see :mod:`mcfric.core.peaks`).
REFINED, AT_EDGE, GRID, NONE = (_kernel.PEAK_REFINED, _kernel.PEAK_AT_EDGE,
                                _kernel.PEAK_GRID, _kernel.PEAK_NONE)
FOLD_NONE, FOLD_FOUND, FOLD_UNCHECKED, FOLD_OPEN = (
    _kernel.FOLD_NONE, _kernel.FOLD_FOUND, _kernel.FOLD_UNCHECKED, _kernel.FOLD_OPEN)


@dataclass(frozen=True)
class PeakSettings:
    """What to refine.

    Attributes
    ----------
    count : int
        Peaks reported per member, the largest refined local maxima of the metric,
        1..100 (grid maxima that may hide a higher peak are refined too).
    rtol : float
        Relative tolerance of the refined amplitude, 0 < rtol <= 0.1.
    window : int
        Grid points on each side of a peak swept downward to look for folds, 1..1000.
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
        # the limits of the configuration's [peaks] (mcfric.config.schema)
        integer(1, 100)(self.count, "peaks.count")
        r = real("peaks.rtol", self.rtol, lo=0, lo_open=True)
        if r > 0.1:
            raise ValueError(f"peaks.rtol: expected a number in (0, 0.1], got {self.rtol!r}")
        integer(1, 1000)(self.window, "peaks.window")
        check_quantity(self.quantity, "peaks.quantity")
        if self.beams is not None:     # their range: once the model is known
            check_beams(self.beams, None, "peaks.beams")


@dataclass
class Peaks:
    """Refined peaks of ``n_s`` members, ``count`` per member, largest first (which ones:
    the member's largest, the unrefined ones, status 2, and the open folds, fold 2, then
    the largest of the rest; with ``count`` 1 one of those takes the place of the
    largest, unless the largest is one, so that the member is not called resolved).

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
        2 not refined (a solver failed in the refinement or in the search between grid
        points, or at a grid neighbour, where the peak may lie; or the grid is too coarse
        to search): the grid value; -1 no such peak (NaN).
    fold : ndarray of int8, shape (n_s, count)
        1 where the downward sweep around the peak reached another steady state, 0 where
        it reproduced the upward one (or the peak is the band's last point), -1 where it
        could not be checked (a branch from above, if any, is unknown: the member's
        largest is a lower estimate); 2 a fold whose
        branch from above was not followed to its peak (largest at the lowest point the
        downward sweep reached and still apart from the upward branch there, or its
        refinement failed):
        ``metric_down`` is then a lower estimate.
    freq_hz_down, metric_down : ndarray, shape (n_s, count)
        The peak of the branch reached from above (equal to the above without a fold;
        with ``fold`` 2, the largest converged point of the downward sweep; NaN where a
        grid neighbour did not converge or the point is isolated).
    """

    freq_hz: np.ndarray
    metric: np.ndarray
    response: np.ndarray
    status: np.ndarray
    fold: np.ndarray
    freq_hz_down: np.ndarray
    metric_down: np.ndarray

    def largest(self):
        """Each member's largest peak of the metric over both branches, shape (n_s,).

        Only a lower estimate where :meth:`resolved` is False: a peak left at its grid
        value may lie far above it (a narrow resonance between grid points), and so may
        an open fold's branch from above (``fold`` 2).
        """
        both = np.concatenate([self.metric, self.metric_down], axis=1)
        with np.errstate(invalid="ignore"):
            return np.nanmax(np.where(np.isnan(both), -np.inf, both), axis=1)

    def resolved(self):
        """True for a member none of whose peaks is a grid value (status 2) and none of
        whose folds is open or unchecked (``fold`` 2 or -1, :func:`fold_unsettled`), shape
        (n_s,): its :meth:`largest` is then its largest peak, refined."""
        return ((unresolved(self.status, self.metric) == 0)
                & ~fold_unsettled(self.fold, self.status))


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
    beams = np.arange(n_beams) if settings.beams is None else np.asarray(
        check_beams(settings.beams, n_beams, "peaks.beams"))
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
        out_w, out_m, out_y, out_st, out_fold, out_wd, out_md,
        np.int64(CONTACT_LAWS.index(model.contact_law)))
    # largest first by the upward value (the kernel chose which: an unrefined one or an
    # open fold is kept)
    order = np.argsort(np.where(np.isnan(out_m), np.inf, -out_m), axis=1, kind="stable")
    take = np.take_along_axis
    to_hz = 1.0 / (2.0 * np.pi)
    return Peaks(take(out_w, order, 1) * to_hz, take(out_m, order, 1),
                 take(out_y, order[:, :, None], 1), take(out_st, order, 1),
                 take(out_fold, order, 1), take(out_wd, order, 1) * to_hz,
                 take(out_md, order, 1))


def statistics(largest, confidence=CONFIDENCE, raised=0):
    """Median, 95th percentile and maximum of the members' largest peaks, with
    distribution-free confidence intervals of the first two.

    Parameters
    ----------
    largest : array_like, shape (n_s,)
        Each member's largest peak of the metric; NaN for a member without one (no
        converged point): left out of the values, allowed anywhere by the intervals.
    confidence : float
        Least coverage of the intervals (:func:`mcfric.quantiles.quantile_interval`).
    raised : int
        How many of the values are lower estimates (a peak not refined, an open or
        unchecked fold): the intervals' upper ends move up by that many members.

    Returns
    -------
    dict
        ``members`` (with a peak), ``unknown`` (members without one), ``median``,
        ``p95``, ``max`` (the metric's unit),
        ``median_ci`` and ``p95_ci`` (two members' values holding the population's
        median, or 95th percentile, with at least ``confidence``; ``inf`` on a side too
        few members close) and ``confidence``.
    """
    v = np.asarray(largest, dtype=float)
    unknown = int(np.count_nonzero(~np.isfinite(v)))
    v = v[np.isfinite(v)]
    if v.size == 0:
        nan2 = (np.nan, np.nan)
        return {"members": 0, "unknown": unknown, "median": np.nan, "p95": np.nan,
                "max": np.nan, "median_ci": nan2, "p95_ci": nan2, "confidence": confidence}
    return {"members": int(v.size), "unknown": unknown, "median": float(np.median(v)),
            "p95": float(np.percentile(v, 95)), "max": float(v.max()),
            "median_ci": quantile_interval(v, 0.5, confidence, raised, unknown),
            "p95_ci": quantile_interval(v, 0.95, confidence, raised, unknown),
            "confidence": confidence}


def at_band_end(freq_hz, f_pk):
    """Where the peak frequencies ``f_pk`` (Hz, any shape) lie at an end of the band
    ``freq_hz`` (an increasing grid of two or more frequencies, Hz).

    Parameters
    ----------
    freq_hz : ndarray, shape (n_f,)
        The grid, Hz.
    f_pk : float or ndarray
        Peak frequencies, Hz (NaN: none).

    Returns
    -------
    ndarray of int8, the shape of ``f_pk``
        -1 at the lower end, 1 at the upper end (within 1e-9 of the band's width: the
        largest value is there, not at a resonance peak), else 0.
    """
    f_pk = np.asarray(f_pk, dtype=float)
    if len(freq_hz) < 2:
        return np.zeros(f_pk.shape, np.int8)
    tol = 1e-9 * (freq_hz[-1] - freq_hz[0])
    with np.errstate(invalid="ignore"):
        return np.where(f_pk <= freq_hz[0] + tol, -1,
                        np.where(f_pk >= freq_hz[-1] - tol, 1, 0)).astype(np.int8)


def cut_by_band(status, f_pk, freq_hz):
    """Where a peak is the largest value at an end of the band, not a resonance peak:
    status 1 (the grid's maximum was at an end) and the refined frequency ``f_pk`` (Hz)
    still there (the refinement may climb to a resonance inside the first or last grid
    interval); ``freq_hz`` the grid (Hz). Boolean, the shape of ``status``."""
    return (np.asarray(status) == AT_EDGE) & (at_band_end(freq_hz, f_pk) != 0)


def nominal_bounds(attrs):
    """True where a file's bounds are the nominal rig's while its members are mistuned
    (``attrs``: the root attributes; a bounds file has no members to say it of)."""
    cfg = json.loads(attrs.get("config_json", "{}"))
    return cfg.get("sampling", {}).get("mistuning", 0) > 0 and int(attrs.get("samples", 0)) > 0


def unresolved(status, metric):
    """Per member, how many of its peaks are grid values, not refined (status 2 with a
    value), shape (n_s,). Any one of them may be the member's true largest peak."""
    return np.count_nonzero((status == GRID) & np.isfinite(metric), axis=1)


def has_open_fold(fold):
    """Per member, whether it has an open fold (``fold`` 2: the branch from above was
    not followed to its peak, which may lie above every peak reported), shape (n_s,)."""
    return (fold == FOLD_OPEN).any(axis=1)


def unchecked_fold(fold, status):
    """Per peak slot, whether its fold check failed (``fold`` -1 where ``status`` is not
    -1: the downward sweep did not converge, so a branch from above, which may lie above
    every peak reported, is unknown), the shape of ``fold``."""
    return (fold == FOLD_UNCHECKED) & (status != NONE)


def has_unchecked_fold(fold, status):
    """Per member, whether the fold check failed at one of its peaks
    (:func:`unchecked_fold`), shape (n_s,)."""
    return unchecked_fold(fold, status).any(axis=1)


def fold_unsettled(fold, status):
    """Per member, whether a fold leaves its largest a lower estimate: an open or an
    unchecked one (:func:`has_open_fold`, :func:`has_unchecked_fold`), shape (n_s,)."""
    return has_open_fold(fold) | has_unchecked_fold(fold, status)


def file_report(path):
    """Peak statistics of a results file (None if it has no refined peaks).

    Returns
    -------
    dict or None
        ``statistics`` of the members' largest peaks (:func:`statistics`), ``grid_ratio``
        (median over members of the grid's maximum over the refined peak), ``folds``
        (members with a fold), ``open_folds`` (members with a fold whose branch from
        above was not followed to its peak), ``unchecked`` (members whose fold check
        failed), ``members``, ``unresolved`` (members with a peak not refined, an open
        fold or an unchecked one: their largest is a lower estimate, and they are left out
        of ``grid_ratio``; ``unresolved_fold`` of them for a fold alone), ``at_end`` (members
        whose largest value lies at an end of the band, not at a resonance peak; left out
        of ``grid_ratio`` too), and the bound's peak (``bound_peak``, ``bound_peak_hz``,
        ``bound_peak_refined``, ``bound_peak_at_end``, ``bound_peak_coarse_step``,
        ``bound_peak_nominal`` and, where certified, ``certified_peak``) when the file has
        it (:func:`bound_peak`).
    """
    from .store import dataset_names, iter_records

    if "peak_metric" not in dataset_names(path):
        return None
    from .store import read

    largest, ratio, folds, open_folds, unchecked, n_unresolved, n_end = [], [], 0, 0, 0, 0, 0
    n_by_fold = 0
    # blocks of ~1 MB of metric: memory stays flat in the number of members (8 bytes per
    # member are kept for the percentiles)
    block = max(1, (1 << 17) // max(1, len(read(path, "frequency"))))
    names = ["metric", "peak_metric", "peak_metric_down", "fold", "peak_status",
             "peak_frequency", "peak_frequency_down"]
    f = read(path, "frequency")
    for _, arr in iter_records(path, names, block=block):
        both = np.concatenate([arr["peak_metric"], arr["peak_metric_down"]], axis=1)
        big = np.max(np.where(np.isnan(both), -np.inf, both), axis=1)
        big = np.where(np.isfinite(big), big, np.nan)
        # any peak left at its grid value may be the member's true largest (a narrow
        # resonance between grid points): that member's largest is a lower estimate
        grid_ = unresolved(arr["peak_status"], arr["peak_metric"]) > 0
        by_fold = fold_unsettled(arr["fold"], arr["peak_status"])
        open_ = (grid_ | by_fold) & np.isfinite(big)
        n_by_fold += int(np.count_nonzero(by_fold & ~grid_ & np.isfinite(big)))
        n_unresolved += int(np.count_nonzero(open_))
        # a largest value at an end of the band is no resonance peak (the band cuts it)
        st = np.concatenate([arr["peak_status"]] * 2, axis=1)
        fq = np.concatenate([arr["peak_frequency"], arr["peak_frequency_down"]], axis=1)
        top = np.argmax(np.where(np.isnan(both), -np.inf, both), axis=1)
        rows = np.arange(len(top))
        end = cut_by_band(st[rows, top], fq[rows, top], f) & np.isfinite(big) & ~open_
        n_end += int(np.count_nonzero(end))
        with np.errstate(invalid="ignore"):
            grid = np.nanmax(np.where(np.isnan(arr["metric"]), -np.inf, arr["metric"]), axis=1)
        largest.append(big)
        with np.errstate(invalid="ignore", divide="ignore"):    # a metric zero everywhere
            ratio.append(np.where(open_ | end, np.nan, grid / big))
        folds += int(np.count_nonzero(((arr["fold"] == FOLD_FOUND)
                                       | (arr["fold"] == FOLD_OPEN)).any(axis=1)))
        open_folds += int(np.count_nonzero(has_open_fold(arr["fold"])))
        unchecked += int(np.count_nonzero(has_unchecked_fold(arr["fold"],
                                                             arr["peak_status"])))
    largest = np.concatenate(largest) if largest else np.empty(0)
    ratio = np.concatenate(ratio) if ratio else np.empty(0)
    out = {"statistics": statistics(largest, raised=n_unresolved),
           "members": int(largest.size),
           "grid_ratio": float(np.nanmedian(ratio)) if np.isfinite(ratio).any() else np.nan,
           "folds": folds, "open_folds": open_folds, "unchecked": unchecked,
           "unresolved": n_unresolved, "unresolved_fold": n_by_fold,
           "at_end": n_end}
    out.update(bound_peak(path))
    return out


#: ``bounds/`` attributes of the certified bound near its peak (:func:`bound_peak`).
CERTIFIED_PEAK_ATTRS = ("peak_upper_certified", "peak_upper_certified_frequency",
                        "peak_upper_witness", "peak_upper_witness_frequency",
                        "peak_sub_grid_step")


def bound_peak(path):
    """The bound's refined peak stored in a file's ``bounds/`` group: ``bound_peak``,
    ``bound_peak_hz`` (Hz), ``bound_peak_refined``, ``bound_peak_at_end`` (-1, 0 or 1:
    at the band's lower end, inside, at its upper end) and ``bound_peak_coarse_step``
    (Hz, 0 unless the grid is too coarse to find it), ``bound_peak_failed`` (frequencies
    where the upper bound's search failed: the peak may lie there); where the bounds were
    certified,
    ``certified_peak``, a dict of the certified bound near the peak (``certified``,
    ``witness``, their ``*_frequency``, ``peak_sub_grid_step`` and the grid's largest
    certified upper bound ``grid`` at ``grid_frequency``); empty where none was
    stored. ``bound_peak_nominal`` is True in a mistuned run (the nominal rig's
    bounds)."""
    from .store import read_attrs, read_group

    g = read_group(path, "bounds")
    if g is None or "peak_upper" not in g[1]:
        return {}
    a = g[1]
    out = {"bound_peak": float(a["peak_upper"]),
           "bound_peak_hz": float(a["peak_upper_frequency"]),
           "bound_peak_refined": bool(a.get("peak_upper_refined", 0)),
           "bound_peak_at_end": int(a.get("peak_upper_at_end", 0)),
           "bound_peak_coarse_step": float(a.get("peak_upper_coarse_step", 0.0)),
           "bound_peak_failed": (int(np.count_nonzero(np.isnan(np.asarray(g[0]["upper"],
                                                                         float))))
                                 if "upper" in g[0] else 0)}
    if nominal_bounds(read_attrs(path)):
        out["bound_peak_nominal"] = True
    if "peak_upper_certified" in a:
        out["certified_peak"] = {k[len("peak_upper_"):] if k.startswith("peak_upper_") else k:
                                 float(a[k]) for k in CERTIFIED_PEAK_ATTRS}
        if "upper_certified" in g[0]:
            from .store import read

            c = np.asarray(g[0]["upper_certified"], float)
            c = np.where(np.isnan(c), np.inf, c)
            i = int(np.argmax(c))
            out["certified_peak"].update(grid=float(c[i]),
                                         grid_frequency=float(read(path, "frequency")[i]))
    return out


def unrefined_lines(harmonics):
    """The ``peaks:`` line of a run or file without refined peaks (``--no-peaks``, or
    ``harmonics`` > 1): its members' largest values are the grid's."""
    why = (f"refinement is single-harmonic; this run balances the odd harmonics "
           f"1..{harmonics}"
           if harmonics > 1 else "--no-peaks: [peaks] enabled = false")
    return [f"peaks:       not refined ({why}): a member's largest value is the grid's, "
            f"which can lie far below its resonance peak where a mode is narrower than the "
            f"grid's step"]


def report_text(report, unit):
    """The lines ``mcfric info`` and the run summary print about the peaks."""
    st = report["statistics"]
    k = report.get("unresolved", 0)
    kf = report.get("unresolved_fold", 0)
    e = report.get("at_end", 0)
    share = (f"the grid's maximum is {report['grid_ratio']:.3g} of the refined peak, median"
             + (f" of the {st['members'] - k - e} fully refined inside the band" if k or e
                else "")
             if st["members"] > k + e else "none fully refined inside the band")
    # lower estimates among the members: statistics() moved the intervals' upper ends
    lines = [f"peaks:       each member's largest, refined: median {st['median']:.4g}"
             f"{_interval(st, 'median_ci')}, 95th percentile {st['p95']:.4g}"
             f"{_interval(st, 'p95_ci')}, max {st['max']:.4g} {unit} "
             f"({st['members']} members"
             + (f", and {st['unknown']} with no converged point, whose largest is "
                f"unknown (the intervals allow any value)" if st.get("unknown") else "")
             + f"; {share})"
             + (f"; {k} of these {'is a lower estimate' if k == 1 else 'are lower estimates'}"
                + (": a peak of the member was not refined (a solver failed near it, or "
                   "the grid is too coarse to search) and may lie higher" if k > kf else "")
                + (f"{'; ' if k > kf else ': '}{kf} because a fold's branch from above was "
                   f"not followed to its peak, or could not be checked, and may lie higher"
                   if kf else "")
                if k else "")
             + (f"; {e} of these {'lies' if e == 1 else 'lie'} at an end of the band (the "
                f"largest value there, not a resonance peak: the band cuts it)" if e else ""),
             f"folds:       {report['folds']} of {report['members']} members have more than "
             f"one steady state near a peak"
             + (f" ({report['unchecked']} could not be checked: their largest is a lower "
                f"estimate)" if report["unchecked"] else "")
             + (f"; in {report['open_folds']} the branch from above was not followed to "
                f"its peak (peak_metric_down a lower estimate)" if report.get("open_folds")
                else "")]
    if not st["members"]:
        # a partial file with no sample done yet, or no member converged at its peaks:
        # statistics of nothing would print as NaN
        lines[0] = "peaks:       no member's peak to count (none done yet, or none converged)"
    return lines + bound_peak_lines(report, unit, st["max"] if st["members"] else None)


def _interval(st, key):
    """`` (lo to hi, 95 % conf.)``: the confidence interval of a statistic as the summary
    prints it (``above lo`` or ``below hi`` where the members cannot close one side, as
    too few members or members without a value leave it; empty where neither is closed)."""
    lo, hi = st.get(key, (np.nan, np.nan))
    pct = f"{100 * st.get('confidence', CONFIDENCE):g} % conf."
    if np.isfinite(lo) and np.isfinite(hi):
        return f" ({lo:.4g} to {hi:.4g}, {pct})"
    if np.isfinite(lo):
        return f" (above {lo:.4g}, {pct})"
    return f" (below {hi:.4g}, {pct})" if np.isfinite(hi) else ""


#: Relative excess of the members' largest peak over the bound's peak that the summary
#: calls a bound's peak not found (both are refined to about 1e-4).
PEAK_RTOL_EXCESS = 1e-3


def member_above_bound_peak(largest_member, bound_peak, nominal=False):
    """Whether the members' largest (refined) peak lies above the bound's refined peak:
    the bound holds at every frequency, so its own largest value is higher and its peak
    is a lower estimate. Not for ``nominal`` bounds (a mistuned ensemble's members are
    not the rig they bound)."""
    return largest_member > bound_peak * (1 + PEAK_RTOL_EXCESS) and not nominal


def bound_peak_lines(pk, unit, largest_member=None):
    """The ``bound peak:`` lines of a summary, ``pk`` as :func:`bound_peak` gives it
    (none where it is empty); ``largest_member`` (``unit``), when given, is compared with
    the searched peak."""
    if "bound_peak" not in pk:
        return []
    lines = [bound_peak_line(pk["bound_peak"], pk["bound_peak_hz"],
                             pk.get("bound_peak_refined", True), unit,
                             pk.get("bound_peak_at_end", 0),
                             pk.get("bound_peak_coarse_step", 0.0))
             + ("; the nominal rig's bounds (the members are mistuned)"
                if pk.get("bound_peak_nominal") else "")
             + (f"; the search failed at {pk['bound_peak_failed']} frequencies, where the "
                f"bound's peak may lie" if pk.get("bound_peak_failed") else "")
             + ("" if largest_member is None else
                f"; largest member / bound {largest_member / pk['bound_peak']:.4g}"
                + (", above 1: the bound holds at every frequency, so its largest value is "
                   "higher than this peak (between grid points, near the members' largest "
                   "peak, or missed by the search), and this peak is a lower estimate; use "
                   "more frequencies"
                   if member_above_bound_peak(largest_member, pk["bound_peak"],
                                              pk.get("bound_peak_nominal", False))
                   else ""))]
    if "certified_peak" in pk:
        lines.append(certified_peak_line(pk["certified_peak"], unit))
    return lines


def certified_peak_line(cp, unit):
    """The second ``bound peak:`` line of a summary (indented under the first): the worst
    case on the sub-grid around the bound's peak, between the largest witness and the
    largest certified upper bound; ``cp`` as :func:`bound_peak` gives it
    (``certified_peak``), values in ``unit``."""
    up = ("unbounded (a frequency not certified)" if np.isinf(cp["certified"])
          else f"{cp['certified']:.4g} {unit} (certified)")
    low = (f"{cp['witness']:.4g} {unit} (attained by a witness at "
           f"{cp['witness_frequency']:.6g} Hz)" if np.isfinite(cp["witness"])
           else "0 (no witness)")
    grid = ("" if "grid" not in cp else
            "; the grid's largest certified value anywhere: "
            + ("unbounded" if np.isinf(cp["grid"]) else
               f"{cp['grid']:.4g} {unit} at {cp['grid_frequency']:.6g} Hz"))
    return (f"             certified: at its frequency and a sub-grid "
            f"{cp['peak_sub_grid_step']:.2g} Hz apart around it (only there), the worst case "
            f"is at least {low} and at most {up}{grid}")


def bound_peak_line(value, hz, refined, unit, at_end=0, coarse_step=0.0):
    """The ``bound peak:`` line of a summary: the upper bound's refined peak, ``value`` in
    ``unit`` at ``hz`` (Hz); ``refined`` False says the refinement did not converge,
    ``at_end`` (-1, 1) that the largest value lies at the band's lower or upper end,
    ``coarse_step`` (Hz, > 0) that the grid is too coarse to find the peak."""
    if not np.isfinite(value):
        return "bound peak:  none (the upper bound's search failed at every frequency)"
    if at_end:
        how = (f"at the band's {'lower' if at_end < 0 else 'upper'} end: the largest value "
               f"there, not a resonance peak; the band cuts it")
    elif coarse_step > 0:
        how = (f"{'refined' if refined else 'not refined'} around the grid's largest "
               f"value, yet a lower estimate: the grid's step, {coarse_step:.3g} Hz, is "
               f"more than {_kernel.N_FLANK_MAX} half-power widths of the narrowest mode, "
               f"and the bound may peak far higher between grid points; use more "
               f"frequencies")
    else:
        how = "refined" if refined else "not refined"
    return f"bound peak:  searched upper bound {value:.4g} {unit} at {hz:.5g} Hz ({how})"


def maximize(fun, lo, hi, m_lo, m_hi, rtol, n_sub=_kernel.N_SUB, max_steps=_kernel.MAX_STEPS):
    """Largest value of a peaked function of one variable on ``[lo, hi]``, refined.

    A search like the kernel's (:mod:`mcfric.core.peaks`) for functions evaluated in
    Python (the response bounds): ``n_sub`` sub-intervals, then parabolic steps on
    ``1/m^2`` (golden-section steps where no parabola fits) until a prediction has come
    true within ``rtol / 4`` and the next one promises less. ``fun(x)`` returns ``(m,
    extra)``; NaN ``m`` counts as a failure: the search stops, unconverged.

    Returns
    -------
    (x, m, extra, complete)
        The best point evaluated and whether the search converged (False after any
        failed evaluation: the peak may lie where it failed).
    """
    pts = {lo: (m_lo, None), hi: (m_hi, None)}

    def add(x):
        m, extra = fun(x)
        pts[x] = (m, extra)
        return m

    failed = False
    for t in range(1, n_sub):
        if not np.isfinite(add(lo + (hi - lo) * t / n_sub)):
            failed = True
            break
    last_pred = np.nan
    last = None
    complete = False
    for _ in range(0 if failed else max_steps):
        xs = np.array(sorted(x for x, (m, _) in pts.items() if np.isfinite(m)))
        ms = np.array([pts[x][0] for x in xs])
        ib = int(np.argmax(ms))
        if 0 < ib < len(xs) - 1:
            x0, x1, x2 = xs[ib - 1:ib + 2]
            g0, g1, g2 = 1.0 / ms[ib - 1:ib + 2] ** 2
            d01, d12 = (g1 - g0) / (x1 - x0), (g2 - g1) / (x2 - x1)
            curv = (d12 - d01) / (x2 - x0)
        else:
            curv = 0.0
        new, pred = np.nan, np.nan
        if curv > 0:
            xv = 0.5 * (x0 + x1) - d01 / (2.0 * curv)
            gv = g1 + d01 * (xv - x1) + curv * (xv - x0) * (xv - x1)
            pred = 1.0 / np.sqrt(gv) if gv > 0 else np.nan
            tol_m = 0.25 * rtol * ms[ib]
            if last is not None and abs(pts[last][0] - last_pred) <= tol_m and \
                    pred <= ms[ib] + tol_m:
                complete = True
                break
            if x0 < xv < x2 and abs(xv - x1) > 1e-12 * x1:
                new = xv
        if not np.isfinite(new):
            left = xs[ib - 1] if ib > 0 else xs[ib]
            right = xs[ib + 1] if ib < len(xs) - 1 else xs[ib]
            lo_s, hi_s = xs[ib] - left, right - xs[ib]
            if max(lo_s, hi_s) <= 1e-12 * xs[ib]:
                complete = True
                break
            new = (xs[ib] - (1 - _INV_PHI) * lo_s if lo_s > hi_s
                   else xs[ib] + (1 - _INV_PHI) * hi_s)
            pred = np.nan
        last, last_pred = new, pred
        if not np.isfinite(add(new)):
            break
    best = max((x for x in pts if np.isfinite(pts[x][0])), key=lambda x: pts[x][0])
    return best, pts[best][0], pts[best][1], complete


_INV_PHI = _kernel._INV_PHI


def golden_maximize(fun, lo, hi, rtol, x_rtol=1e-8, max_steps=80):
    """Golden-section search for the largest ``fun(x)[0]`` on ``[lo, hi]``.

    ``fun(x)`` returns ``(m, extra)``; NaN ``m`` counts as a failure. Like any
    golden-section search it assumes one maximum in ``[lo, hi]``, kink or not, where
    :func:`maximize`'s parabolic steps assume a smooth peak (the upper bound's kink where
    the force limit takes over from the box: :mod:`mcfric.bounds.peak`).

    Returns
    -------
    (x, m, complete)
        The best point evaluated, its value, and whether the search ended with a bracket
        narrower than ``x_rtol`` times its centre whose two inner points' values are
        within ``rtol / 4`` of the best (a failed evaluation ends it unconverged).
    """

    def key(t):                     # a failed (NaN) value never counts as the best
        return t[0] if np.isfinite(t[0]) else -np.inf

    r = _INV_PHI
    a, b = lo, hi
    c, d = b - r * (b - a), a + r * (b - a)
    mc, md = fun(c)[0], fun(d)[0]
    best = max((mc, c), (md, d), key=key)
    for _ in range(max_steps):
        if not (np.isfinite(mc) and np.isfinite(md)):
            return best[1], best[0], False
        if mc >= md:
            b, d, md = d, c, mc
            c = b - r * (b - a)
            mc = fun(c)[0]
            best = max(best, (mc, c), key=key)
        else:
            a, c, mc = c, d, md
            d = a + r * (b - a)
            md = fun(d)[0]
            best = max(best, (md, d), key=key)
        if b - a <= x_rtol * 0.5 * (a + b):
            ok = min(mc, md) >= best[0] * (1.0 - 0.25 * rtol)
            return best[1], best[0], bool(ok)
    return best[1], best[0], False
