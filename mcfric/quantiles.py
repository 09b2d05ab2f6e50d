"""Distribution-free confidence intervals of a quantile from a sample.

The number of members at or below the population's ``p``-quantile ``xi_p`` is
binomial with a probability of at least ``p``, the number below it with at most ``p``
(both ``Bin(n, p)`` for a continuous distribution). For order statistics
``x_(l) <= x_(u)`` (1-based) of the sorted sample, with ``B ~ Bin(n, p)``,

    P(x_(l) > xi_p) <= P(B <= l - 1),    P(x_(u) < xi_p) <= P(B >= u),

so choosing ``l`` and ``u`` with at most ``(1 - confidence) / 2`` of the binomial's mass
on each side gives an interval that holds ``xi_p`` with at least that confidence, ties
or not. No
shape is assumed; the members must be independent draws (each member of an ensemble has
its own random stream). Where the sample is too small for a side (``l < 1`` or
``u > n``), that side is open (``-inf`` or ``inf``).

Where ``k`` of the values are lower estimates (each true value at or above the one
given), the true ``u``-th order statistic is at most ``x_(u + k)``: of the ``u + k``
smallest values at least ``u`` are exact. The interval ``x_(l)`` to ``x_(u + k)`` holds
the quantile with the same confidence (``x_(l)`` lies below the true ``l``-th anyway).

Where ``m`` members have no value at all (unknown: anywhere), ``n`` counts them, and of
the known values sorted, ``y_(1) <= ... <= y_(n - m)``, the true ``j``-th order
statistic lies between ``y_(j - m)`` (all unknown below it) and ``y_(j)`` (all above):
the interval ``y_(l - m)`` to ``y_(u + k)`` holds the quantile with the same confidence.
"""

from __future__ import annotations

import numpy as np


def quantile_interval(values, p, confidence=0.95, raised=0, unknown=0):
    """Confidence interval of the ``p``-quantile of the population behind ``values``.

    Parameters
    ----------
    values : array_like, shape (n,)
        Independent draws, any unit. Non-finite values are left out and not counted:
        members without a value go in ``unknown`` (as :func:`mcfric.peaks.statistics`
        does with NaN).
    p : float
        Probability of the quantile, ``0 < p < 1`` (0.95: the 95th percentile).
    confidence : float
        Least coverage of the interval, ``0 < confidence < 1``.
    raised : int
        How many of the values are lower estimates (their true values lie at or above):
        the upper end moves up by that many order statistics.
    unknown : int
        How many members have no value (not in ``values``; each may lie anywhere): they
        count in the sample size, and the lower end moves down by that many.

    Returns
    -------
    (float, float)
        Two order statistics of ``values`` (their unit) that hold the quantile with at
        least ``confidence``; ``-inf`` or ``inf`` on a side the sample cannot close, both
        NaN for an empty sample.
    """
    if not 0.0 < p < 1.0 or not 0.0 < confidence < 1.0:
        raise ValueError(f"quantile_interval: expected 0 < p, confidence < 1, got {p!r}, "
                         f"{confidence!r}")
    for name, v in (("raised", raised), ("unknown", unknown)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 0:
            raise ValueError(f"quantile_interval: {name}: expected an integer >= 0, got {v!r}")
    try:
        x = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ValueError("quantile_interval: values: expected numbers") from None
    if x.ndim != 1:
        raise ValueError(f"quantile_interval: values: expected shape (n,), got {x.shape}")
    x = np.sort(x)
    x = x[np.isfinite(x)]
    known = x.size
    if known == 0:
        return float("nan"), float("nan")
    n = known + int(unknown)
    # imported here, not at the top: slow to import, and every command would wait for it
    from scipy import stats

    tail = 0.5 * (1.0 - confidence)
    k = np.arange(n + 2)
    # the largest l with P(B <= l - 1) <= tail, the smallest u with P(B >= u) <= tail
    below = stats.binom.cdf(k - 1, n, p)
    above = stats.binom.sf(k - 1, n, p)
    l_ok = np.flatnonzero(below <= tail)
    u_ok = np.flatnonzero(above <= tail)
    lo = (int(l_ok[-1]) if l_ok.size else 0) - int(unknown)
    hi = (int(u_ok[0]) if u_ok.size else n + 1) + int(raised)
    return (float(x[lo - 1]) if lo >= 1 else -np.inf,
            float(x[hi - 1]) if hi <= known else np.inf)
