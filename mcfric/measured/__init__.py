"""Measured responses: import (UFF 58, CSV), normalisation to a simulated force, the
fraction of measured points inside response bounds, and export of computed responses to
UFF 58 (paper Eq. 11-12).

A :class:`Measurement` is one set of points taken in one way (``kind``: stepped-sine points
or a continuous sweep) at one force level: frequencies, and per beam an amplitude (real,
>= 0) or a complex response, in SI units of its quantity (displacement m, velocity m/s,
acceleration m/s^2). Readers return a list, one Measurement per (kind, force level,
percentile) found in the file, so stepped points and sweeps are never mixed.

Normalisation (paper Eq. 11-12): scaling the whole input by ``c`` scales the response and
the friction forces by ``c``, so a run at force ``F_meas`` with preload ``N0`` stands for
force ``c F_meas = F0`` with preload ``c N0``, ``c = F0 / F_meas``.

Tags in UFF ID lines: ``kind=stepped|sweep``, ``force_n=<N>``, ``percentile=<p>`` anywhere
in ID lines 1-5 are read (and written by :func:`export_uff58`); arguments fill in what a
file does not say and must agree with what it does.
"""

from .comparison import Inside, MetricParts, fraction_inside, interpolate_log, metric_parts
from .export import export_uff58
from .measurement import KINDS, METRIC, Measurement
from .normalisation import Normalisation, normalise
from .reading import read_measured

__all__ = ["Inside", "MetricParts", "fraction_inside", "interpolate_log", "metric_parts",
           "export_uff58", "KINDS", "METRIC", "Measurement", "Normalisation", "normalise",
           "read_measured"]
