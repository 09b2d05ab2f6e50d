"""Lower witnesses: admissible points of small ``M = max_b |y_b|``.

The certified lower bound's witness must be admissible: every damper inside its
rectangle *and* at or below the force limit. The box search's minimum often breaks the
force limit, and then the best admissible start may be far above the joint set's
minimum (three times, at some eight-beam frequencies). Where the relaxation of the
minimum is (nearly) tight, its rounded primal point lies near that minimum. Each start
is pulled inside the force limit and descends by the minimum's log-barrier method with
the force limits as barriers too (:func:`mcfric.core.minimax.minimax_barrier`). The
result is a witness, never a bound.
"""

import math

import numpy as np

from ._jit import jit
from .branch_bound import admissible_value
from .coordinate_search import workspace
from .joint_ascent import pulled_inside, strictly_inside
from .minimax import minimax_barrier

#: Accepted points lie this far inside the force limit (relative), so that rounding in a
#: later solve cannot put them outside.
_INSIDE = 1e-9


@jit(nogil=True)
def _kept(v, ok, K, K_best, M_out, k):
    """Whether an admissible point ``K`` (``ok``) of ``M = v`` (m) is below ``M_out[k]``;
    if so it becomes ``K_best`` and ``M_out[k]``."""
    if not (ok and math.isfinite(v) and v < M_out[k]):
        return False
    M_out[k] = v
    K_best[:] = K
    return True


@jit(nogil=True)
def lowest(G, q0, ylin, H, kr, ki, F_lim, K_given, freqs, K_out, M_out):
    """Descend from given points to admissible ones of small ``M``, keeping the least.

    At each frequency ``k`` of ``freqs`` every row of ``K_given[k]`` (n_g, nd; N/m; rows
    with a NaN are skipped) and ``K_out[k]`` itself are each tried pulled towards
    ``K = 0`` until inside the force limit ``F_lim (1 - 1e-9)`` (N), and moved ``1e-6``
    of a side into the box ``[0, kr] x [0, ki]``, pulled strictly inside the force limit
    and descended from (:func:`minimax_barrier`). Where a point so reached, checked
    within ``F_lim (1 - 1e-9)``, has ``M`` below ``M_out[k]`` (m, the
    witness so far) it replaces ``K_out[k]`` (N/m) and ``M_out[k]``. Returns how many
    frequencies changed.
    """
    nd = q0.shape[1]
    nb = ylin.shape[1]
    hr = np.zeros((nb, 2), np.int64)
    hr[:, 1] = nd
    gr = np.zeros((nd, 2), np.int64)
    gr[:, 1] = nd
    w = workspace(nd, nb, hr, gr)
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    K = np.empty(nd, np.complex128)
    K0 = np.empty(nd, np.complex128)
    changed = 0
    for k in freqs:
        better = False
        for r in range(K_given.shape[1] + 1):
            if r < K_given.shape[1]:
                K[:] = K_given[k, r]
            else:
                K[:] = K_out[k]
            if not (math.isfinite(K[0].real) and math.isfinite(K[0].imag)):
                continue
            # the start itself, pulled just inside (the descent's start lies further in)
            K0[:] = K
            v, ok = pulled_inside(G[k], q0[k], ylin[k], H[k], K0, F_lim, 1.0 - _INSIDE, T,
                                  piv, q)
            better |= _kept(v, ok, K0, K_out[k], M_out, k)
            if not strictly_inside(G[k], q0[k], ylin[k], H[k], K, kr, ki, F_lim, 1e-6, T,
                                   piv, q):
                continue
            minimax_barrier(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, K, w)
            v, ok = admissible_value(G[k], q0[k], ylin[k], H[k], K, F_lim * (1.0 - _INSIDE),
                                     T, piv, q)
            better |= _kept(v, ok, K, K_out[k], M_out, k)
        changed += better
    return changed
