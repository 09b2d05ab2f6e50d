"""The ensemble's members checked against the bounds stored beside them in a results file."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..results_check import check_file
from ..store import iter_records
from .results import read_bounds


class MembersCheck(NamedTuple):
    """Counts of :func:`check_members` (points are converged member points)."""

    #: points outside the searched bounds ``[lower, upper]``
    outside: int
    #: points checked against the searched bounds
    total: int
    #: points outside the certified bounds, None where the file has no certificate
    outside_certified: int | None
    #: members whose friction the bounds' constraints do not admit: not checked
    left_out: int
    #: points at frequencies where the search failed (no searched bounds): not checked
    unbounded: int
    #: points at frequencies without certified bounds: not checked against them
    uncertified: int
    #: converged points whose stored metric is not finite (a damaged file): not checked
    non_finite: int = 0


def check_members(path):
    """Count the converged member points of the results file ``path`` outside its bounds.

    A validity check: only members whose friction the bounds' constraints admit
    (:meth:`~mcfric.bounds.Bounds.admits`) are checked, and at frequencies where a search
    failed (bounds NaN) a point is not counted as outside them, nor is a converged point
    whose stored metric is not finite (``non_finite``: a damaged file). ``mcfric run``
    prints these counts as its "bounds check" lines. The file's structure is checked
    first (:func:`mcfric.results_check.check_file`: a ``StoreError`` in one line).

    Parameters
    ----------
    path : str or Path
        A complete results file.

    Returns
    -------
    MembersCheck or None
        None where the file holds no bounds.
    """
    check_file(path)        # a damaged file in one line, not a KeyError or TypeError
    B = read_bounds(path)
    if B is None:
        return None
    C = B.certificate
    searched = np.isfinite(B.upper) & np.isfinite(B.lower)
    # a certified upper bound may be inf (nothing proved): a bound, unlike NaN
    certified = C is not None and ~np.isnan(C.upper) & ~np.isnan(C.lower)
    outside = total = outside_cert = left_out = unbounded = uncertified = non_finite = 0
    for _, arr in iter_records(path, ["metric", "converged", "mu0", "kc", "N0"]):
        admitted = B.admits(arr["mu0"], arr["kc"], arr["N0"])
        left_out += int(np.count_nonzero(~admitted))
        ok = arr["converged"] & admitted[:, None]
        # a number that is no number is no point outside the bounds: counted apart
        bad = ok & ~np.isfinite(arr["metric"])
        non_finite += int(np.count_nonzero(bad))
        ok &= ~bad
        outside += int(np.count_nonzero(~B.contains(arr["metric"]) & ok & searched))
        if C is not None:
            outside_cert += int(np.count_nonzero(~C.contains(arr["metric"]) & ok
                                                 & certified))
            uncertified += int(np.count_nonzero(ok & ~certified))
        total += int(np.count_nonzero(ok & searched))
        unbounded += int(np.count_nonzero(ok & ~searched))
    return MembersCheck(outside, total, None if C is None else outside_cert, left_out,
                        unbounded, uncertified, non_finite)
