"""Figures (matplotlib, Agg canvas: no display and no pyplot state needed).

* :func:`results_figure` (``mcfric plot``, and the figure ``mcfric run`` writes): the
  response bounds as a band over the ensemble as a grey cloud, one highlighted member,
  log amplitude against frequency; measured data on top (stepped-sine crosses, sweep
  lines).
* :func:`hbm_figure` (``mcfric hbm``): one parameter set, each beam a line.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
from matplotlib import patheffects

from .hbm import INDICATOR_THRESHOLD
from .measured.comparison import metric_rows
from .measured.measurement import METRIC
from .metric import METRIC_UNITS, omega_power
from .peaks import (
    FOLD_FOUND,
    FOLD_OPEN,
    at_band_end,
    cut_by_band,
    member_above_bound_peak,
    nominal_bounds,
    unchecked_fold,
)
from .peaks import GRID as PEAK_GRID
from .store import dataset_names, iter_records, read, read_attrs, read_group, replacing
from .validators import InputError, flag

#: Characters per line of a legend entry below the results figure (two columns, 7 pt,
#: 8 in wide).
LEGEND_WRAP = 60

#: Colours of measured files, in the order given.
MEASURED_COLORS = ("tab:green", "tab:olive", "tab:cyan", "tab:brown", "tab:pink")

#: Colour of the harmonic indicator's marks (a member's flagged points, the share flagged):
#: orange ran too close in hue to the red lower bound.
INDICATOR_COLOR = "darkgoldenrod"

#: A dot of refined member peaks holding at least this many peaks (and this share of them)
#: is labelled with its count: identical peaks (members whose dampers stick) draw one dot.
STACK_MIN, STACK_SHARE = 20, 0.05

#: A dot's size in axes fractions, x and y (about 1.5 pixels of the 8 x 6 in figure).
STACK_CELL = np.array([0.0015, 0.003])


def _figure(size=(8, 4.5)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path, dpi):
    """Write ``fig`` to ``path`` in one step (the old file stays until it is complete)."""
    with replacing(path, "figure") as tmp:
        fig.savefig(tmp, dpi=dpi)


def _mathtext(text):
    """``m/s^2`` with the exponent drawn as a superscript."""
    return text.replace("^2", "$^2$")


def _stored_quantity(attrs):
    return _config(attrs).get("metric", {}).get("quantity", "displacement")


def results_figure(path, out, *, quantity=None, f_window=None, member=0, max_lines=400,
                   measured=(), title=None, indicator=True):
    """Bounds band over the ensemble cloud, log amplitude vs frequency.

    Reads the file in blocks (memory does not grow with the ensemble). The cloud is one
    ``LineCollection`` of at most ``max_lines`` members spread evenly over the ensemble
    (low alpha, rasterised, so vector output stays small); non-converged points are gaps.
    A file without bounds gives the cloud alone, a bounds file (``mcfric bounds``) the
    band alone.

    Parameters
    ----------
    path : str or Path
        Results file of ``mcfric run`` or bounds file of ``mcfric bounds``.
    out : str or Path
        Figure file; the format follows the suffix (``.png``, ``.pdf``, ``.svg``).
    quantity : {"displacement", "velocity", "acceleration"}, optional
        Plot ``omega^k`` times the stored amplitudes; default the stored quantity.
    f_window : (float, float), optional
        Frequency window, Hz, ``0 <= f_min < f_max``; the axis spans its part inside the
        frequencies drawn (the file's and the measured ones).
    member : int or None
        Ensemble member (sample index) drawn in black; None for none.
    max_lines : int
        Members drawn in the cloud.
    measured : sequence of Measurement
        Drawn in the plotted quantity: stepped-sine points as crosses, sweeps as lines,
        each as its metric (max over the beams measured).
    title : str, optional
    indicator : bool
        If the file has a ``harmonic_indicator`` (single-harmonic runs): mark the points
        where one harmonic may not be enough. The share of converged members flagged at
        each frequency is drawn on a right-hand axis (0-100 %), and the highlighted
        member's flagged points are circled (underlined above 300 frequencies).

    Returns
    -------
    dict
        ``n_members`` (the ensemble's, 0 in a bounds file), ``n_drawn``, ``has_bounds``,
        ``n_flagged`` (flagged points over the whole ensemble, 0 if not marked),
        ``n_not_converged`` (points of the whole ensemble in the window that did not
        converge: gaps in the lines) and
        ``n_peaks_unrefined`` (drawn member peaks left at their grid values),
        ``n_fold_lower`` (drawn lower estimates beside a fold: an open fold's branch
        from above, an unchecked fold's peak) and
        ``bound_peaks`` (the bound's peaks marked: ``"searched"``, the refined peak of
        the searched upper bound, and ``"certified"``, the largest certified upper bound
        on the sub-grid around it), ``legend`` (its entries) and ``ylabel``: what was
        drawn.
    """
    from matplotlib.collections import LineCollection

    from .bounds import read_bounds

    flag("indicator", indicator)
    attrs = read_attrs(path)
    f = read(path, "frequency")
    stored = _stored_quantity(attrs)
    quantity = quantity or stored
    scale = omega_power(f, quantity, stored)
    # peaks refined in another quantity, converted at their own frequency: the
    # converted quantity peaks a little higher up (omega^k |y|), so a lower estimate
    conv = "" if quantity == stored else f"; refined as {stored}, converted: may lie slightly low"
    measured = tuple(measured)        # read twice (drawn, then the axis' extent)
    lo_f, hi_f = (f.min(), f.max()) if f_window is None else map(float, f_window)
    if not (math.isfinite(lo_f) and math.isfinite(hi_f) and 0 <= lo_f < hi_f):
        raise InputError("f_window", f"expected 0 <= f_min < f_max (finite, Hz), got "
                         f"{lo_f:g}, {hi_f:g}")
    win = (f >= lo_f) & (f <= hi_f)
    if not win.any():
        raise InputError("f_window", f"no frequencies of {path} in {lo_f:g}..{hi_f:g} Hz")
    fw = f[win]

    fig = _figure((8, 6.0))      # the extra height holds the legend below the axes
    ax = fig.add_subplot()
    n = int(attrs.get("samples", 0))
    harmonics = int(attrs.get("harmonics", 1))
    drawn = 0
    names = dataset_names(path)
    mark = indicator and "harmonic_indicator" in names
    flagged_at = np.zeros(len(f))          # flagged members per frequency
    counted_at = np.zeros(len(f))          # converged members per frequency
    member_flags = None
    n_failed = 0
    if not (isinstance(max_lines, (int, np.integer)) and max_lines >= 1):
        raise InputError("max_lines", f"expected an integer >= 1, got {max_lines!r}")
    # the envelope of every member (the cloud may draw only some)
    env_hi = np.full(len(fw), -np.inf)
    env_lo = np.full(len(fw), np.inf)
    if "sample" in names:
        if member is not None and not 0 <= member < n:
            raise InputError("member", f"expected None or a member in 0..{n - 1}, got {member}")
        segs, dots, highlight = [], [], None
        fields = ["metric", "sample", "converged"] + (["harmonic_indicator"] if mark else [])
        for _, arr in iter_records(path, fields):
            # a point not converged is a gap, whatever value the file holds there
            m = np.where(arr["converged"][:, win], arr["metric"][:, win] * scale[win], np.nan)
            n_failed += int(np.count_nonzero(~arr["converged"][:, win]))
            pos = np.where(m > 0, m, np.nan)
            with np.errstate(invalid="ignore"):
                env_hi = np.fmax(env_hi, np.nanmax(pos, axis=0, initial=-np.inf))
                env_lo = np.fmin(env_lo, np.nanmin(pos, axis=0, initial=np.inf))
            for idx in np.flatnonzero(_drawn(arr["sample"], n, max_lines)):
                y = pos[idx]
                segs.append(np.column_stack([fw, y]))
                dots.append(np.column_stack([fw[_alone(y)], y[_alone(y)]]))
            if mark:
                hit = arr["converged"] & (arr["harmonic_indicator"] > INDICATOR_THRESHOLD)
                flagged_at += hit.sum(axis=0)
                counted_at += arr["converged"].sum(axis=0)
            if member is not None and member in arr["sample"]:
                row = np.flatnonzero(arr["sample"] == member)[0]
                highlight = m[row]
                if mark:
                    member_flags = hit[row, win]
        drawn = len(segs)
        if segs:
            gaps = (f"; {n_failed:,} points not converged: gaps" if n_failed else "")
            # with H > 1 or --no-peaks no peak is refined: a resonance narrower than the
            # grid step reaches higher than its grid values
            grid_only = ("; grid values (peaks not refined with H > 1)" if harmonics > 1 else
                         "; grid values (peaks not refined: --no-peaks)"
                         if "peak_metric" not in names else "")
            what = (f"{_count(n, 'member')}, all drawn" if drawn == n
                    else f"{_count(n, 'member')}, {drawn} drawn")
            if not np.isfinite(env_hi).any():
                what = f"{_count(n, 'member')}: no point in the window converged"
                gaps = ""
            lc = LineCollection(segs, colors="0.45", linewidths=0.5, alpha=0.25,
                                rasterized=True,
                                label=f"ensemble ({what}{gaps}{grid_only})")
            ax.add_collection(lc)
            dots = np.concatenate(dots)
            if len(dots):
                ax.plot(dots[:, 0], dots[:, 1], ".", color="0.45", ms=1.5, alpha=0.5,
                        rasterized=True)
            if drawn < n and np.isfinite(env_hi).any():
                ax.plot(fw, np.where(np.isfinite(env_hi), env_hi, np.nan), color="0.3",
                        lw=0.7, ls=(0, (4, 2)), label=f"envelope of all {n:,} members")
                ax.plot(fw, np.where(np.isfinite(env_lo), env_lo, np.nan), color="0.3",
                        lw=0.7, ls=(0, (4, 2)))
        if highlight is not None:
            y = np.where(highlight > 0, highlight, np.nan)
            ax.plot(fw, y, color="k", lw=1.1, zorder=2.2, label=f"member {member}")
            ax.plot(fw[_alone(y)], y[_alone(y)], ".", color="k", ms=3)
            if member_flags is not None and member_flags.any():
                label = (f"member {member}: higher harmonics > {INDICATOR_THRESHOLD:g} "
                         f"(indicator)")
                if len(fw) <= 300:
                    ax.plot(fw[member_flags], highlight[member_flags], "o", mfc="none",
                            color=INDICATOR_COLOR, ms=3.5, mew=0.8, label=label)
                else:
                    # on a fine grid the circles merge into a band that hides the member:
                    # its flagged stretches underlined instead
                    ax.plot(fw, np.where(member_flags, y, np.nan), color=INDICATOR_COLOR,
                            lw=4.0, alpha=0.6, zorder=2.1, label=label)
    n_unrefined = n_fold_lower = 0
    peak_dots = None
    largest_peak = np.nan          # the members' largest refined peak, stored quantity
    if "peak_metric" in names:
        # the members' refined peaks (the grid underestimates lightly damped peaks), and
        # where a fold was checked, the peaks of the branches reached from above
        folds = all(k in names for k in ("fold", "peak_metric_down", "peak_frequency_down"))
        keys = ["peak_metric", "peak_frequency", "peak_status"] + \
            (["fold", "peak_metric_down", "peak_frequency_down"] if folds else [])
        cols = {k: [] for k in keys}
        for _, arr in iter_records(path, keys):
            # every member's: the cloud may draw only some, the peaks are the extremes
            for k in keys:
                cols[k].append(arr[k].ravel())
        # no member done (a partial file): nothing to draw
        cols = {k: np.concatenate(v) if v else np.empty(0) for k, v in cols.items()}
        px, ps = cols["peak_frequency"], cols["peak_status"]
        if np.isfinite(cols["peak_metric"]).any():
            largest_peak = np.nanmax(cols["peak_metric"])
        py = cols["peak_metric"] * omega_power(px, quantity, stored)
        fold = cols["fold"] if folds else np.zeros(len(px), np.int8)
        dx = cols["peak_frequency_down"] if folds else np.full(len(px), np.nan)
        dy = (cols["peak_metric_down"] if folds else np.full(len(px), np.nan)) * \
            omega_power(dx, quantity, stored)
        ok = np.isfinite(py) & (px >= lo_f) & (px <= hi_f) & (py > 0)
        dok = np.isfinite(dy) & (dx >= lo_f) & (dx <= hi_f) & (dy > 0)
        grid = ok & (ps == PEAK_GRID)
        end = ok & cut_by_band(ps, px, f)
        # a fold's branch from above refined up to an end of the band: cut by it too
        found = dok & (fold == FOLD_FOUND)
        found_end = found & (at_band_end(f, dx) != 0)
        found &= ~found_end
        # a fold not checked: a branch from above, if any, is unknown, so this peak may
        # not be the largest near it (at an end of the band it is no peak anyway)
        unchecked = ok & ~grid & ~end & unchecked_fold(fold, ps)
        # an open fold's branch was not followed to its peak: its largest point so far
        opened = dok & (fold == FOLD_OPEN)
        n_unrefined = int(np.count_nonzero(grid))
        plain = ok & ~grid & ~end & ~unchecked
        if plain.any():
            line, = ax.plot(px[plain], py[plain], ".", color="0.15", ms=2.5, alpha=0.6,
                            rasterized=True, label=f"refined member peaks (every member{conv})")
            # counted once the axes' limits are known (a dot is a few pixels)
            peak_dots = px[plain], py[plain], line
        if end.any() or found_end.any():
            # the band cuts a resonance: the largest value at its end is no peak
            ax.plot(np.r_[px[end], dx[found_end]], np.r_[py[end], dy[found_end]], "|",
                    color="0.4", ms=5,
                    label="member maxima at an end of the band (not resonance peaks)")
        if grid.any():
            # a solver failed near them: the true peak may lie higher
            ax.plot(px[grid], py[grid], "o", mfc="none", color="tab:purple", ms=3.5,
                    mew=0.8, label="member peaks not refined (grid values, may lie higher)")
        if found.any():
            # dark, as the refined dots: the measurements' crosses are coloured
            ax.plot(dx[found], dy[found], "x", color="0.15", ms=4, mew=0.9,
                    label=f"member peaks on a branch reached from above (a fold{conv})")
        n_fold_lower = int(np.count_nonzero(opened) + np.count_nonzero(unchecked))
        if n_fold_lower:
            ax.plot(np.r_[dx[opened], px[unchecked]], np.r_[dy[opened], py[unchecked]], "^",
                    mfc="none", color="tab:red", ms=4, mew=0.9,
                    label="member peaks beside a fold not followed or not checked (may lie "
                          f"higher{conv})")
    B = read_bounds(path)
    band = None
    marked = []
    if B is not None:
        C = B.certificate
        if C is None:
            # searched bounds only (--no-certify): the paper's construction, a search
            up = B.upper[win] * scale[win]
            lo = B.lower[win] * scale[win]
            label = " (searched"
        else:
            up = C.upper[win] * scale[win]
            lo = C.lower[win] * scale[win]
            label = " (certified"
        # they hold at the grid frequencies; the lines between them are no bound (a
        # narrow resonance between grid points can rise above them)
        label += " at the grid points"
        # the bounds rest on the describing function: with H > 1 they are the
        # single-harmonic model's, the members' curves the fundamentals; a mistuned
        # run's members are not the nominal rig the bounds are for
        if nominal_bounds(attrs):
            label += "; nominal rig"
        label += "; single-harmonic model)" if harmonics > 1 else ")"
        up = np.where(np.isfinite(up), up, np.nan)
        band = lo, up
        # on a coarse grid the straight lines between grid points read as a bound: the
        # points where it holds are marked
        dot = "." if len(fw) <= 60 else None
        ax.plot(fw, up, color="tab:blue", lw=2.0, marker=dot, ms=5, label="upper bound" + label)
        ax.plot(fw, np.where(lo > 0, lo, np.nan), color="tab:red", lw=2.0, marker=dot, ms=5,
                label="lower bound" + label)
        if C is not None:
            # the witnesses (attained by admissible describing functions: the true extreme
            # lies between them and the certified bound) where the gap shows, > 1 %
            wu = C.upper_witness[win] * scale[win]
            wl = C.lower_witness[win] * scale[win]
            # darker and above the bound's line: a gap of a few % lies inside its width
            for w, gap, color, name in ((wu, ~(up <= wu * 1.01), "navy", "upper"),
                                        (wl, ~(lo >= wl * 0.99), "darkred", "lower")):
                valid = (w > 0) & np.isfinite(w)
                show = gap & valid
                # one neighbour on each side: an isolated frequency shows as a segment
                show = (show | np.r_[show[1:], False] | np.r_[False, show[:-1]]) & valid
                if show.any():
                    ax.plot(fw, np.where(show, w, np.nan), color=color, lw=0.9, ls="--",
                            zorder=2.5,
                            label=f"{name} witness, where the gap is > 1 %")
        g = read_group(path, "bounds")[1]
        if "peak_upper" in g and lo_f <= g["peak_upper_frequency"] <= hi_f:
            fb = g["peak_upper_frequency"]
            # a member above it: the bound, which holds everywhere, peaks higher elsewhere
            below_member = member_above_bound_peak(largest_peak, g["peak_upper"],
                                                   nominal_bounds(attrs))
            what = ("largest value of the upper bound, at an end of the band"
                    if g.get("peak_upper_at_end", 0) else
                    "peak of the upper bound, a lower estimate: grid too coarse"
                    if g.get("peak_upper_coarse_step", 0) > 0 else
                    "peak of the upper bound, a lower estimate: members lie above it"
                    if below_member else
                    "refined peak of the upper bound" if g.get("peak_upper_refined", 1)
                    else "largest (not refined) peak of the upper bound")
            ax.plot([fb], [g["peak_upper"] * omega_power(fb, quantity, stored)], "*",
                    color="tab:blue", ms=9, label=f"{what} (searched{conv})")
            marked.append("searched")
        fc = g.get("peak_upper_certified_frequency", np.nan)
        if (np.isfinite(g.get("peak_upper_certified", np.nan)) and lo_f <= fc <= hi_f):
            # the grid can miss the certified bound's peak: its largest near the peak
            ax.plot([fc], [g["peak_upper_certified"] * omega_power(fc, quantity, stored)],
                    "v", color="tab:blue", mfc="none", ms=8, mew=1.2,
                    # the star is the paper's construction, box and force limit apart;
                    # the certificate bounds the joint set, often lower
                    label="largest certified upper bound near the peak (sub-grid, "
                          "peak's frequency; of the joint admissible set, it can lie below "
                          "the searched star)")
            marked.append("certified")
    metric_beams = _metric_beams(attrs)
    for i, mm in enumerate(measured):
        q = mm.to_quantity(quantity)
        color = MEASURED_COLORS[i % len(MEASURED_COLORS)]
        lab = (f"measured {mm.kind}" + (f" {Path(mm.source).name}" if mm.source else "")
               + (f" ({mm.force_n:g} N)" if mm.force_n else "")
               + (f", {mm.percentile:g}th percentile" if mm.percentile is not None else ""))
        mine = [b for b in mm.beams if b in metric_beams]
        if q.beams == (METRIC,):            # a record of M itself (an export)
            values = q.amplitude[:, 0]
            complete, some = ~np.isnan(values), np.zeros(len(values), bool)
        else:
            complete, some, values = metric_rows(q, metric_beams)
        # M (solid) where every beam of the metric is measured; the largest measured beam
        # of the metric where some are not (dashed: M at least that); with no beam of the
        # metric measured the largest measured beam (dashed: drawn, compared to nothing)
        entries = [(complete, True, lab)] if complete.any() else []
        if some.any():
            entries.append((some, False, lab + (
                ": points where not every beam is measured, M at least this"
                if set(metric_beams) <= set(mine) else
                f": beam{'s' if len(mine) > 1 else ''} {', '.join(map(str, mine))} only, "
                f"M at least this")))
        if not entries:
            values = q.metric().response[:, 0].real
            entries = [(~np.isnan(values), False,
                        lab + f": beam{'s' if len(mm.beams) > 1 else ''} "
                        f"{', '.join(map(str, mm.beams))}, not in the metric")]
        mf = q.frequency_hz
        for rows, is_m, text in entries:
            # on the measurement's own points, NaN elsewhere: a line breaks where this
            # part has no point instead of joining its points across the others
            y = np.where(rows, values, np.nan)
            keep = (mf >= lo_f) & (mf <= hi_f)
            if mm.kind == "stepped" or np.count_nonzero(keep & rows) == 1:   # no line
                keep &= rows
                ax.plot(mf[keep], y[keep], "x" if is_m else "+", color=color, ms=4,
                        mew=1.0, label=text)
            else:
                ax.plot(mf[keep], y[keep], color=color, lw=1.0, ls="-" if is_m else "--",
                        label=text)
    with np.errstate(over="ignore"):     # matplotlib's margin past 1e308: _log_ylim's job
        ax.set_yscale("log")
    # a margin: markers at the ends of the band stay visible
    # the axis spans the window's part inside the frequencies drawn (the file's and the
    # measured ones): --f-max 1e308 is no axis to draw
    shown = [f] + [np.asarray(m.frequency_hz, float) for m in measured]
    x_lo = max(lo_f, min(float(x.min()) for x in shown if x.size))
    x_hi = min(hi_f, max(float(x.max()) for x in shown if x.size))
    pad = 0.005 * (x_hi - x_lo) or 0.005 * max(x_hi, 1.0)    # a window of one frequency
    ax.set_xlim(x_lo - pad, x_hi + pad)
    _log_ylim(ax)
    if band is not None:
        # the band between the bounds; where only 0 is proved below, down to the axis,
        # and where nothing is proved above (no force limit), up to it
        bottom, top = ax.get_ylim()
        lo, up = band
        ax.fill_between(fw, np.where(lo > 0, lo, bottom), np.where(up > 0, up, top),
                        color="tab:blue", alpha=0.12, lw=0)
        # a lower bound of 0 has no place on a log axis: the red line breaks there, and
        # the band's floor is the axis', not a bound; marked on the axis instead
        zero = lo == 0
        if zero.any():
            ax.plot(fw[zero], np.full(np.count_nonzero(zero), bottom), "^", color="tab:red",
                    ms=4, clip_on=False, zorder=5,
                    label="lower bound 0 (nothing above 0 proved), on the axis")
        ax.set_ylim(bottom, top)
    if peak_dots is not None:
        x, y, line = peak_dots
        stacks = _stacks((ax.transScale + ax.transLimits).transform(np.c_[x, y]))
        if stacks:
            line.set_label(line.get_label()[:-1] + "; a number: peaks in one dot)")
        for i, k in stacks:
            ax.annotate(f"{k:,}", (x[i], y[i]), xytext=(4, -2), textcoords="offset points",
                        fontsize=6, color="0.15", va="top", zorder=5,
                        path_effects=[patheffects.withStroke(linewidth=2, foreground="w")])
    ax.set_xlabel("frequency [Hz]")
    unit = _mathtext(METRIC_UNITS[quantity])
    ax.set_ylabel(f"{quantity} amplitude M [{unit}]" if harmonics == 1 else
                  f"{quantity} amplitude M of the fundamental, H = {harmonics} [{unit}]")
    if title is None:
        title = _title(attrs, B if "sample" not in names else None)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    if mark and counted_at.any():
        # where one harmonic may not be enough: share of members flagged per frequency
        share = 100.0 * flagged_at / np.maximum(counted_at, 1)
        ax2 = ax.twinx()
        ax2.plot(fw, share[win], color=INDICATOR_COLOR, lw=0.9, alpha=0.8)
        # behind the response axes: the share crossed the bounds' peak markers
        ax.set_zorder(ax2.get_zorder() + 1)
        ax.patch.set_visible(False)
        # a little past 0 and 100 %: a share at either end would hide under the frame
        ax2.set_ylim(-3, 103)
        ax2.set_ylabel("members flagged by harmonic_indicator [%]", color=INDICATOR_COLOR,
                       fontsize=8)
        ax2.tick_params(axis="y", colors=INDICATOR_COLOR, labelsize=8)
        handles += ax2.get_lines()
        labels.append("share flagged (right axis; rerun with --harmonics)")
    # below the axes: with ten entries or more no corner of the axes is free of data
    # entries wrapped: two columns of long ones would run past the figure's edges
    fig.legend(handles, [textwrap.fill(t, LEGEND_WRAP) for t in labels],
               loc="outside lower center", ncol=2, fontsize=7)
    _save(fig, out, 150)
    return {"n_members": n, "n_drawn": drawn, "has_bounds": B is not None,
            "n_flagged": int(flagged_at.sum()), "n_not_converged": n_failed,
            "n_peaks_unrefined": n_unrefined, "n_fold_lower": n_fold_lower,
            "bound_peaks": marked,
            "legend": list(labels), "ylabel": ax.get_ylabel(), "xlim": ax.get_xlim()}


def _config(attrs):
    import json
    try:
        return json.loads(attrs["config_json"])
    except (KeyError, ValueError, TypeError):
        return {}


def _count(n, noun):
    """``"1 member"``, ``"2 members"``."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


def _drawn(sample, n, max_lines):
    """Mask of the members ``sample`` that the cloud draws: at most ``max_lines`` of the
    ``n``, spread evenly (member ``s`` where ``floor(s k / n)`` steps up, ``k =
    min(max_lines, n)``)."""
    k = min(max_lines, n)
    s = np.asarray(sample, np.int64)
    return (s + 1) * k // n != s * k // n


def _stacks(xy):
    """Dots of many peaks: ``(index, count)``, at most three, the fullest first.

    ``xy`` (n, 2) are the peaks in axes fractions. A dot is a peak and every peak within
    ``STACK_CELL`` of it on both axes (about a pixel and a half of the figure: a dot is
    five across); one is labelled where it holds at least ``STACK_MIN`` peaks and
    ``STACK_SHARE`` of them. Candidates are the largest peaks of the fullest cells of
    that size; one within four cells of a labelled dot is skipped (its label would
    cover the other's).
    """
    inside = np.flatnonzero(np.all((xy >= 0) & (xy <= 1), axis=1))
    need = max(STACK_MIN, STACK_SHARE * len(xy))
    if len(inside) < need:
        return []
    u = xy[inside] / STACK_CELL
    _, inverse, counts = np.unique(np.floor(u), axis=0, return_inverse=True,
                                   return_counts=True)
    inverse = inverse.ravel()
    out = []
    for c in np.argsort(-counts, kind="stable")[:10]:
        i = np.flatnonzero(inverse == c)
        j = i[np.argmax(u[i, 1])]
        if any(np.all(np.abs(u[j] - u[m]) < 4) for m, _ in out):
            continue
        k = int(np.count_nonzero(np.all(np.abs(u - u[j]) <= 1, axis=1)))
        if k >= need:
            out.append((j, k))
    return [(int(inside[j]), k) for j, k in sorted(out, key=lambda t: -t[1])[:3]]


def _alone(y):
    """Points between two gaps (no line joins them: they need a marker)."""
    ok = np.isfinite(y)
    return ok & ~np.r_[False, ok[:-1]] & ~np.r_[ok[1:], False]


def _log_ylim(ax):
    """Fit a log y-axis to its data, as ``autoscale`` does, also near the float range's ends.

    matplotlib adds its margin in linear space after ``10 **``, which overflows for data
    near 1e308 (a measured amplitude of 1e308 m left an empty axis from 1 to 10 and a
    numpy warning); the margin is added here to the exponents, clipped to the range, and
    the ticks are decades chosen here (the log locator's ticks reach past 1e308, where
    its formatter fails on inf).
    """
    from matplotlib.ticker import FixedLocator, NullLocator

    lo, hi = ax.dataLim.minposy, ax.dataLim.y1
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 < lo < hi):
        ax.autoscale(axis="y")
        return
    a, b = math.log10(lo), math.log10(hi)
    margin = ax.margins()[1] * (b - a)
    if -300 < a - margin and b + margin < 300:        # every ordinary figure
        ax.autoscale(axis="y")
        return
    a, b = max(a - margin, -323.0), min(b + margin, 308.0)
    ax.set_ylim(10.0 ** a, 10.0 ** b)
    step = max(1, math.ceil((b - a) / 8))
    ax.yaxis.set_major_locator(FixedLocator(10.0 ** np.arange(math.ceil(a), b, step)))
    ax.yaxis.set_minor_locator(NullLocator())


def _metric_beams(attrs):
    """The metric's beams, 1-based, from a file's configuration."""
    cfg = _config(attrs)
    beams = cfg.get("metric", {}).get("beams", "all")
    if beams == "all" or beams is None:
        return tuple(range(1, int(cfg.get("model", {}).get("n_beams", 0)) + 1))
    return tuple(int(b) for b in beams)


def _title(attrs, B=None):
    """The model, the force and what sets this run apart: its engine order on a ring,
    the mistuning, the harmonics; and the constraints of bounds ``B`` (given for a bounds
    file)."""
    cfg = _config(attrs)
    parts = [attrs.get("model_name", "")]
    ex = cfg.get("excitation", {})
    if ex.get("F0"):
        parts.append(f"F0 = {ex['F0']:g} N")
    if cfg.get("model", {}).get("topology") == "circular" and ex.get("pattern") == "travelling":
        parts.append(f"engine order {ex.get('engine_order')}")
    mis = cfg.get("sampling", {}).get("mistuning", 0)
    if mis:
        parts.append(f"mistuned {100 * mis:g} %")
    if int(attrs.get("harmonics", 1)) > 1:
        parts.append(f"H = {int(attrs['harmonics'])}")
    if B is not None:
        F = "no force limit" if not np.isfinite(B.F_lim) else f"F_lim = {B.F_lim:.3g} N"
        parts.append(f"k_max = {B.k_max_re:g} N/m, {F}")
    return ", ".join(p for p in parts if p)


def hbm_figure(freq_hz, amplitude, metric, converged, png_path, title="",
               metric_label="M [m]", ylabel="displacement amplitude at the output [m]"):
    """Log amplitude vs frequency of one parameter set: each beam a line, the metric bold.

    Parameters
    ----------
    freq_hz : ndarray, shape (n_f,)
        Drive frequencies, Hz.
    amplitude : ndarray, shape (n_f, n_beams)
        ``|y|`` per beam, in the unit of ``ylabel`` (the metric's: one axis, one unit).
    metric : ndarray, shape (n_f,)
        The metric M, in the same unit.
    converged : ndarray of bool, shape (n_f,)
        Non-converged points are not drawn.
    png_path : str or Path
        Where the figure is written.
    title : str
        Figure title.
    metric_label, ylabel : str
        Legend entry of the metric and the axis label, with the unit.

    Returns
    -------
    str or Path
        ``png_path``.
    """
    freq_hz = np.asarray(freq_hz, float)
    n_f = freq_hz.shape[0] if freq_hz.ndim == 1 else -1
    ok = np.asarray(converged, bool)
    amplitude = np.asarray(amplitude, float)
    metric = np.asarray(metric, float)
    if n_f < 1 or amplitude.ndim != 2 or amplitude.shape[0] != n_f \
            or metric.shape != (n_f,) or ok.shape != (n_f,):
        raise ValueError(f"expected freq_hz (n_f,), amplitude (n_f, n_beams), metric and "
                         f"converged (n_f,), got shapes {freq_hz.shape}, {amplitude.shape}, "
                         f"{metric.shape}, {ok.shape}")
    amp = np.where(ok[:, None], amplitude, np.nan)
    met = np.where(ok, metric, np.nan)
    fig = _figure()
    ax = fig.add_subplot()
    # M first and wide, beneath the beams: it equals the largest beam, which stays visible
    m = np.where(met > 0, met, np.nan)
    line, = ax.plot(freq_hz, m, color="k", lw=3.0, alpha=0.3, label=_mathtext(metric_label))
    ax.plot(freq_hz[_alone(m)], m[_alone(m)], "o", color="k", alpha=0.3, ms=5)
    for b in range(amp.shape[1]):
        y = np.where(amp[:, b] > 0, amp[:, b], np.nan)
        line, = ax.plot(freq_hz, y, lw=0.9, label=f"beam {b + 1}")
        # a point between two failed ones draws no line: a marker instead
        ax.plot(freq_hz[_alone(y)], y[_alone(y)], ".", color=line.get_color(), ms=4)
    ax.set_yscale("log")
    if n_f > 1:
        # the sweep, not only what converged; a margin keeps markers at its ends whole
        lo, hi = freq_hz.min(), freq_hz.max()
        ax.set_xlim(lo - 0.005 * (hi - lo), hi + 0.005 * (hi - lo))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_mathtext(ylabel))
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2 if amp.shape[1] > 4 else 1)
    _save(fig, png_path, 120)
    return png_path


def verify_figure(verifications, png_path, title=""):
    """Time histories over one period, per frequency: the integration, the multi-harmonic
    and the single-harmonic solutions at the beam with the largest response.

    Parameters
    ----------
    verifications : list of mcfric.verify.Verification
    png_path : str or Path
    title : str
        Figure title.

    Returns
    -------
    dict
        ``path`` and ``titles``: each panel's, with what it cannot show (an integration
        that did not settle, a harmonic balance that did not converge).
    """
    n = len(verifications)
    fig = _figure()
    fig.set_size_inches(7.5, 2.2 * n + 0.8)
    titles = []
    for k, v in enumerate(verifications):
        ax = fig.add_subplot(n, 1, k + 1)
        b = int(np.argmax(v.peak))
        t = v.time
        theta = 2 * np.pi * v.freq_hz * t
        n_h = v.multi.shape[0]
        orders = np.arange(1, 2 * n_h, 2)
        multi = np.real(np.exp(1j * np.outer(theta, orders)) @ v.multi[:, b])
        single = np.real(v.single[b] * np.exp(1j * theta))
        ax.plot(t * 1e3, v.history[:, b] * 1e6, color="k", lw=2.0,
                label="time integration" + ("" if v.periodic else " (NOT periodic)"))
        ax.plot(t * 1e3, multi * 1e6, color="C1", lw=1.2, ls="--",
                label=f"harmonic balance, H = {orders[-1]}")
        ax.plot(t * 1e3, single * 1e6, color="C0", lw=1.0, ls=":",
                label="single harmonic")
        ax.set_ylabel(f"beam {b + 1} [\u00b5m]")
        # what the panel cannot show: a run that did not settle, a solve that failed
        # (NaN: no curve)
        issues = ([] if v.periodic else ["time integration NOT periodic (not settled)"]) + \
            ([f"H = {orders[-1]} not converged"] if not np.all(np.isfinite(multi)) else []) + \
            (["single harmonic not converged"] if not np.all(np.isfinite(single)) else [])
        titles.append(f"{v.freq_hz:g} Hz" + (": " + "; ".join(issues) if issues else ""))
        ax.set_title(titles[-1], fontsize=8, color="tab:red" if issues else "k")
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    fig.axes[-1].set_xlabel("time over one period [ms]; displacement at the output of the "
                            "beam with the largest response")
    fig.suptitle(title, fontsize=9)
    _save(fig, png_path, 110)
    return {"path": png_path, "titles": titles}
