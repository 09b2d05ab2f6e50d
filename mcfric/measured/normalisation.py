"""Normalisation of measured data to a simulated force (paper Eq. 11-12).

Scaling the whole input by ``c`` scales the response and the friction forces by ``c``,
so a run at force ``F_meas`` with preload ``N0`` stands for force ``c F_meas = F0`` with
preload ``c N0``, ``c = F0 / F_meas``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..validators import real
from .measurement import Measurement


@dataclass(frozen=True)
class Normalisation:
    """What :func:`normalise` did (paper Eq. 11-12).

    Attributes
    ----------
    F_meas, F0 : float
        Force level of the measurement and the simulated force, N.
    c : float
        ``F0 / F_meas``: factor applied to the response, and to the preload that the
        measurement stands for.
    N0_meas, N0_equivalent : float or None
        The run's preload (if given) and ``c N0_meas``, N.
    """

    F_meas: float
    F0: float
    c: float
    N0_meas: float | None = None
    N0_equivalent: float | None = None

    def text(self):
        """The normalisation applied and what it means for the preload, as text."""
        s = (f"normalised to F0 = {self.F0:g} N: c = F0/F_meas = {self.F0:g}/{self.F_meas:g} "
             f"= {self.c:.6g}; responses x c. A run at force {self.F_meas:g} N with preload "
             f"N0 stands for force {self.F0:g} N with preload {self.c:.6g} N0")
        if self.N0_meas is not None:
            s += (f" (N0 = {self.N0_meas:g} N -> {self.N0_equivalent:.6g} N: compare with "
                  f"bounds for that preload)")
        return s

    __str__ = text


def normalise(measurement, F0, *, N0_meas=None):
    """Rescale a measurement taken at ``F_meas`` to the simulated force ``F0``.

    The friction law is homogeneous: force ``cF`` with preload ``cN0`` gives ``c`` times
    the response of force ``F`` with preload ``N0``. So the rescaled data, ``c`` times the
    measured response with ``c = F0 / F_meas``, is what the rig would do at ``F0`` with
    preload ``c N0``: compare it with results for that preload.

    Parameters
    ----------
    measurement : Measurement
        With a known ``force_n`` (F_meas, N).
    F0 : float
        Simulated force amplitude, N (> 0).
    N0_meas : float, optional
        Preload of the measured run, N; the report then gives ``c N0_meas``.

    Returns
    -------
    Measurement
        Response times ``c``, ``force_n = F0``.
    Normalisation
        ``c`` and the implied preload scaling (``.text()`` for a printable line).
    """
    if not isinstance(measurement, Measurement):
        raise ValueError(f"measurement: expected a Measurement, got "
                         f"{type(measurement).__name__}")
    F0 = real("F0", F0, lo=0, lo_open=True)           # "1" and True are no force
    who = f"{measurement.source}: " if measurement.source else ""
    if measurement.force_n is None:
        raise ValueError(f"{who}force level unknown: normalising needs the measurement's "
                         f"force_n (pass force_n= when reading)")
    with np.errstate(over="ignore", invalid="ignore"):
        c = F0 / measurement.force_n
        finite = np.isfinite(measurement.response * c) | np.isnan(measurement.response)
    if not (math.isfinite(c) and c > 0 and finite.all()):
        # a force level of 1e-310 N makes c overflow (or a tiny F0 underflow): say so,
        # not a response of inf or 0
        raise ValueError(f"{who}normalising from F_meas = {measurement.force_n:g} N to F0 = "
                         f"{F0:g} N: the factor F0/F_meas = {c:g} puts the response out "
                         f"of range (is the force level in N?)")
    N0_eq = None
    if N0_meas is not None:
        N0_meas = real("N0_meas", N0_meas, lo=0)
        N0_eq = c * N0_meas
    out = replace(measurement.scaled(c), force_n=F0)
    return out, Normalisation(measurement.force_n, F0, c, N0_meas, N0_eq)
