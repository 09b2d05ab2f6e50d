"""Measured points against response bounds: the fraction inside, per beam and overall."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..validators import flag, real, real_array
from .measurement import METRIC, Measurement


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
    off_grid : dict {beam: int}
        Of the points below or above, those between the bounds' grid frequencies, where
        the bounds are interpolated: the interpolation is not itself a bound (a resonance
        narrower than the grid step may rise above it).
    """

    beams: tuple
    inside: dict
    below: dict
    above: dict
    outside_range: dict
    missing: dict
    off_grid: dict = field(default_factory=dict)

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
        """The fraction of all compared points inside, 0..1."""
        return self.fraction()

    def text(self):
        """The fractions inside, overall and per beam, as one line."""
        parts = [f"{'M' if b == METRIC else f'beam {b}'} {_percent(self.fraction(b))} % "
                 f"({self.inside[b]}/{self.compared(b)})" for b in self.beams]
        excl = sum(self.outside_range.values())
        miss = sum(self.missing.values())
        s = (f"measured points inside the bounds: {_percent(self.overall)} % "
             f"({sum(self.inside.values())}/{self.compared()}); " + ", ".join(parts))
        off = sum(self.off_grid.values())
        if off:
            s += (f"; {off} of the points outside {'lies' if off == 1 else 'lie'} between "
                  f"grid frequencies, where the bounds are interpolated (not a bound there)")
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
    freq_hz = np.asarray(freq_hz, dtype=float)
    if freq_hz.ndim != 1 or freq_hz.size < 2 or not np.all(np.diff(freq_hz) > 0):
        raise ValueError("freq_hz: expected at least 2 strictly increasing frequencies")
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


def _on_grid(g, f):
    """Whether each frequency ``f`` is one of the grid's ``g``: within 1e-4 of the grid
    step (a file's frequencies are often printed to 6 digits)."""
    if not f.size:
        return np.zeros(0, bool)
    i = np.clip(np.searchsorted(g, f), 1, len(g) - 1)
    near = np.minimum(abs(f - g[i - 1]), abs(f - g[i]))
    return near <= 1e-4 * (g[i] - g[i - 1])


def _percent(x):
    """One decimal, rounded down: 9999 of 10000 must not read 100.0 %."""
    return "nan" if math.isnan(x) else f"{math.floor(1000 * x) / 10:.1f}"


def fraction_inside(measurement, freq_hz, lower, upper, beams=None, *,
                    quantity="displacement", check_lower=True, rtol=1e-9):
    """Fraction of measured points between lower and upper bounds, per beam and overall.

    The bounds are interpolated log-linearly (log amplitude linear in frequency) to the
    measured frequencies; points outside the bounds' frequency range are excluded and
    counted in ``outside_range``; NaN values (no data, failed bound) in ``missing``. The
    bounds hold at their grid frequencies; points found outside between them are also
    counted in ``off_grid`` (an interpolated value is not a bound near a narrow
    resonance: compute the bounds at the measured frequencies to decide).

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
    g = real_array("freq_hz", freq_hz)
    lo = real_array("lower", lower)
    up = real_array("upper", upper)
    real("rtol", rtol, lo=0)
    flag("check_lower", check_lower)
    if not rtol < 0.5:          # a tolerance, not a second band
        raise ValueError(f"rtol: expected a number in [0, 0.5), got {rtol!r}")
    if g.ndim != 1 or g.size < 2 or not np.all(np.isfinite(g)) or not np.all(np.diff(g) > 0):
        raise ValueError("freq_hz: expected at least 2 finite, strictly increasing "
                         "frequencies")
    if lo.shape != up.shape or lo.shape[:1] != g.shape or lo.ndim not in (1, 2):
        raise ValueError(f"lower, upper: expected shape ({g.size},) or ({g.size}, n_beams), "
                         f"got {lo.shape} and {up.shape}")
    if np.any(lo < 0) or np.any(up < 0):
        raise ValueError("lower, upper: bounds must be >= 0 (NaN allowed)")
    if np.any(lo > up):
        k = np.argwhere(lo > up)[0]
        raise ValueError(f"lower, upper: lower above upper at index {tuple(int(i) for i in k)}")
    wanted = None if beams is None else tuple(int(b) for b in beams)
    counts = {k: {} for k in ("inside", "below", "above", "outside_range", "missing",
                              "off_grid")}
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
            counts["off_grid"][b] += int(np.count_nonzero((below | above)
                                                          & ~_on_grid(g, f[in_range][ok])))
            counts["below"][b] += int(np.count_nonzero(below))
            counts["above"][b] += int(np.count_nonzero(above))
            counts["inside"][b] += int(np.count_nonzero(~below & ~above))
    if wanted is not None:
        absent = [b for b in wanted if b not in order]
        if absent:
            raise ValueError(f"beams: beam {absent[0]} is not in the measurement")
    return Inside(beams=tuple(order), **counts)


@dataclass(frozen=True)
class MetricParts:
    """Measurements sorted for bounds of the metric ``M`` over some beams.

    Attributes
    ----------
    single : list of Measurement
        The measurements of single beams (to hold to the upper bound of M only).
    full : list of Measurement
        The measured M (column :data:`METRIC`): of measurements of every beam of the
        metric, and records of M itself (an export). Held to both bounds.
    part : list of Measurement
        The largest of the measured beams where some beam of the metric is not measured:
        the true M could be larger, so only the upper bound applies.
    skipped : tuple of int
        Measured beams outside the metric (no bound of M applies to them).
    """

    single: list
    full: list
    part: list
    skipped: tuple


def metric_parts(measured, beams):
    """Sort ``measured`` for a comparison with bounds of the metric over ``beams``.

    Parameters
    ----------
    measured : sequence of Measurement
    beams : sequence of int
        The metric's beams, 1-based (every beam of the model by default).

    Returns
    -------
    MetricParts
        ``m.metric()`` of a measurement missing a beam of the metric is no measured M: it
        may lie below the lower bound of M legitimately, so it goes to ``part``. The rule
        holds per point: where a measurement of every beam of the metric lacks some of
        them at some frequencies (records merged from beams measured at different
        frequencies), its points with every beam go to ``full`` and the others, the
        largest of the beams there, to ``part``.
    """
    beams = tuple(int(b) for b in beams)
    single, full, part, skipped = [], [], [], set()
    for m in measured:
        if m.beams == (METRIC,):
            full.append(m)
            continue
        j = [i for i, b in enumerate(m.beams) if b in beams]
        skipped.update(b for b in m.beams if b not in beams)
        if not j:
            continue
        sub = replace(m, response=m.response[:, j], beams=tuple(m.beams[i] for i in j))
        single.append(sub)
        complete, some, largest = metric_rows(sub, beams)
        if not some.any():
            (full if set(beams) <= set(sub.beams) else part).append(sub.metric())
            continue
        for group, rows in ((full, complete), (part, some)):
            if rows.any():
                group.append(replace(sub, frequency_hz=sub.frequency_hz[rows],
                                     response=largest[rows, None], beams=(METRIC,)))
    return MetricParts(single, full, part, tuple(sorted(skipped)))


def metric_rows(m, beams):
    """Per point of ``m``: where M is measured, and where only some of its beams are.

    Parameters
    ----------
    m : Measurement
    beams : sequence of int
        The metric's beams, 1-based.

    Returns
    -------
    complete, some : ndarray of bool, shape (n_f,)
        Every beam of the metric measured there (M measured); some of them measured,
        not all (M at least their largest). Records merged from beams measured at
        different frequencies have each beam at some points only.
    largest : ndarray, shape (n_f,)
        The largest measured amplitude of the metric's beams, -inf where none is.
    """
    mine = [i for i, b in enumerate(m.beams) if b in beams]
    a = m.amplitude[:, mine]
    present = ~np.isnan(a)
    largest = np.max(np.where(present, a, -np.inf), axis=1, initial=-np.inf)
    complete = present.all(axis=1) & (set(beams) <= {m.beams[i] for i in mine})
    return complete, present.any(axis=1) & ~complete, largest

