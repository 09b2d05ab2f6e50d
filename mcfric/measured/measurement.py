"""A measurement: points taken one way at one force level, per beam, in SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..metric import QUANTITIES
from ..validators import is_int, is_num

KINDS = ("stepped", "sweep")
#: Label of the response metric ``M = max_b |y_b|`` where a beam number is expected.
METRIC = 0


@dataclass(frozen=True, eq=False)
class Measurement:
    """Measured (or exported) responses of the beams at one force level.

    Parameters
    ----------
    frequency_hz : array_like, shape (n_f,)
        Excitation frequencies, Hz (> 0), in the order measured (an up-and-down sweep
        keeps its order).
    response : array_like, shape (n_f, n_beams)
        Per beam either the amplitude (real, >= 0) or the complex response
        (``x(t) = Re{X e^{i omega t}}``), in SI units of ``quantity``. NaN where a beam
        was not measured.
    beams : tuple of int
        Beam number (1-based) of each column; :data:`METRIC` (0) stands for the metric
        ``M``, the maximum over the beams.
    kind : {"stepped", "sweep"}
        Stepped-sine points (plotted as crosses) or a continuous sweep (a line).
    quantity : {"displacement", "velocity", "acceleration"}
    force_n : float, optional
        Force level ``F_meas`` of the run, N, if known.
    percentile : float, optional
        Set for ensemble percentiles exported by :func:`export_uff58`.
    source : str
        Where the data came from (used in messages).
    """

    frequency_hz: np.ndarray
    response: np.ndarray
    beams: tuple
    kind: str = "stepped"
    quantity: str = "displacement"
    force_n: float | None = None
    percentile: float | None = None
    source: str = field(default="", compare=False)

    def __post_init__(self):
        who = f"{self.source}: " if self.source else ""
        f = np.array(self.frequency_hz, dtype=float)
        if f.ndim != 1 or f.size == 0:
            raise ValueError(f"{who}frequency_hz: expected a non-empty 1-d array, got shape "
                             f"{f.shape}")
        if not np.all(np.isfinite(f) & (f > 0)):
            raise ValueError(f"{who}frequency_hz: frequencies must be finite and > 0 Hz")
        r = np.array(self.response)
        if not (np.issubdtype(r.dtype, np.number) and not np.issubdtype(r.dtype, np.bool_)):
            raise ValueError(f"{who}response: expected numbers")
        r = r.astype(complex if np.iscomplexobj(r) else float)
        if r.ndim == 1:
            r = r[:, None]
        if r.ndim != 2 or r.shape[0] != f.size:
            raise ValueError(f"{who}response: expected shape ({f.size}, n_beams), got "
                             f"{r.shape}")
        # NaN is "not measured"; inf in either part of a value is refused (a complex
        # inf + NaN j read as NaN and then counted as a point above the bounds)
        finite = ~(np.isinf(r.real) | np.isinf(r.imag))
        if not np.all(finite):
            raise ValueError(f"{who}response: values must be finite (NaN = not measured)")
        if not np.iscomplexobj(r) and np.any(r < 0):
            raise ValueError(f"{who}response: amplitudes must be >= 0")
        raw = np.atleast_1d(np.asarray(self.beams, dtype=object)).tolist()
        if not all(is_int(b) for b in raw):       # 1.7 or "1" is no beam number
            raise ValueError(f"{who}beams: expected integer beam numbers, got "
                             f"{self.beams!r}")
        beams = tuple(int(b) for b in raw)
        if len(beams) != r.shape[1]:
            raise ValueError(f"{who}beams: expected {r.shape[1]} beam numbers (one per "
                             f"column), got {len(beams)}")
        if len(set(beams)) != len(beams) or any(b < 0 for b in beams):
            raise ValueError(f"{who}beams: expected distinct beam numbers >= 1 (0 = metric), "
                             f"got {beams}")
        if self.kind not in KINDS:
            raise ValueError(f"{who}kind: expected one of {KINDS}, got {self.kind!r}")
        if self.percentile is not None and not (is_num(self.percentile)
                                                and 0 <= self.percentile <= 100):
            raise ValueError(f"{who}percentile: expected a number in 0..100, got "
                             f"{self.percentile!r}")
        if self.quantity not in QUANTITIES:
            raise ValueError(f"{who}quantity: expected one of {QUANTITIES}, got "
                             f"{self.quantity!r}")
        F = self.force_n
        if F is not None:
            F = float(F)
            if not (math.isfinite(F) and F > 0):
                raise ValueError(f"{who}force_n: expected a force > 0 N, got {self.force_n!r}")
        f.setflags(write=False)
        r.setflags(write=False)
        object.__setattr__(self, "frequency_hz", f)
        object.__setattr__(self, "response", r)
        object.__setattr__(self, "beams", beams)
        object.__setattr__(self, "force_n", F)

    @property
    def is_complex(self):
        """True when the response is complex (a phase is known), not amplitudes."""
        return np.iscomplexobj(self.response)

    @property
    def amplitude(self):
        """Amplitudes ``|response|``, shape (n_f, n_beams), SI units of ``quantity``."""
        return np.abs(self.response)

    @property
    def n_points(self):
        """Measured (non-NaN) values over all beams."""
        return int(np.count_nonzero(~np.isnan(self.response)))

    def column(self, beam):
        """Response of one beam (n_f,)."""
        try:
            return self.response[:, self.beams.index(int(beam))]
        except ValueError:
            raise ValueError(f"beam {beam} is not in the measurement (beams: "
                             f"{list(self.beams)})") from None

    def to_quantity(self, quantity):
        """The same data as ``quantity``: ``X = V / (i omega) = -A / omega^2``.

        Amplitudes convert by the powers of ``omega = 2 pi f``.
        """
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity: expected one of {QUANTITIES}, got {quantity!r}")
        k = QUANTITIES.index(quantity) - QUANTITIES.index(self.quantity)
        if k == 0:
            return self
        w = 2 * np.pi * self.frequency_hz[:, None]
        factor = (1j * w) ** k if self.is_complex else w ** k
        return replace(self, response=self.response * factor, quantity=quantity)

    def displacement(self):
        """The data as displacement (amplitude in m)."""
        return self.to_quantity("displacement")

    def metric(self):
        """``M = max_b |y_b|`` over this measurement's beams (docs: theory, "Response
        metric"), column 0.

        NaN at frequencies where a beam is missing: M needs every beam. Compare M, not
        single beams, with bounds on M: the lower bound of the maximum over beams is not
        a lower bound of each beam.
        """
        a = self.amplitude
        m = np.where(np.isnan(a).any(axis=1), np.nan,
                     np.max(np.where(np.isnan(a), -np.inf, a), axis=1))
        return replace(self, response=m[:, None], beams=(METRIC,))

    def scaled(self, c):
        """Response multiplied by ``c`` (> 0), force level too."""
        F = None if self.force_n is None else self.force_n * c
        return replace(self, response=self.response * c, force_n=F)

    def describe(self):
        """One line: kind, frequencies, beams, quantity and force level."""
        F = "unknown force" if self.force_n is None else f"F = {self.force_n:g} N"
        p = "" if self.percentile is None else f", percentile {self.percentile:g}"
        cols = ", ".join("M" if b == METRIC else str(b) for b in self.beams)
        return (f"{self.kind}: {self.frequency_hz.size} frequencies "
                f"({self.frequency_hz.min():g}-{self.frequency_hz.max():g} Hz), beams {cols}, "
                f"{self.quantity}{' (complex)' if self.is_complex else ''}, {F}{p}")
