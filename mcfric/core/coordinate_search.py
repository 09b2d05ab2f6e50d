"""Coordinate search of the box for the extreme of ``M``: one damper at a time, each exact.

Each step replaces one describing function ``K_j`` by the best point of its rectangle
(:mod:`.rectangle`), with Sherman-Morrison updates of the contact displacements; for the
maximum each sweep ends with a Hooke-Jeeves pattern move along the sweep's
displacement. On a chain of beams ``G`` is tridiagonal and each row of ``H`` has two
dampers: the search skips the exact zeros (the ``hr``, ``gr`` ranges of the workspace)
and solves by O(nd) eliminations; on a ring (cyclic ``G``) by the bordered O(nd)
elimination of :func:`.linalg.cyclic_factor`. :func:`workspace` is the scratch that this
search, the projected gradient (:mod:`.projected_gradient`) and the minimax search
(:mod:`.minimax`) share.
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .linalg import (
    banded,
    contact_solve,
    cyclic_factor_stable,
    cyclic_solve,
    factor_inverse,
    tri_factor,
    tri_solve,
)
from .rectangle import best_on_rectangle


@inline_jit
def _factor(G, K, T, nd, band):
    """Factors of ``I + G diag(K)`` in ``T`` for ``band`` 1 (chain) or 2 (ring, rows
    0-3). Returns ``band``, or 0 at a tiny pivot or for ``band`` 0."""
    if band == 1:
        return 1 if tri_factor(G, K, T, nd) else 0
    if band == 2:
        return 2 if cyclic_factor_stable(G, K, T, nd) else 0
    return 0


@inline_jit
def _banded_solve(G, K, T, x, nd, mode):
    """``x = (I + G diag(K))^-1 x`` with the factors of :func:`_factor` (mode 1 or 2)."""
    if mode == 1:
        tri_solve(T, x, nd)
    else:
        cyclic_solve(G, K, T, x, nd)


@inline_jit
def _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr, band):
    """``q = (I + G diag(K))^-1 q0`` and ``y`` (:func:`outputs`). For ``band`` 1 or 2
    (:func:`.linalg.banded`) by the O(nd) elimination (factors left in ``T``), else, or
    at a tiny pivot, by the inverse ``Tinv`` (kept for the search's updates). Returns 1
    (chain), 2 (ring), 0 (inverse) or -1 (singular)."""
    mode = _factor(G, K, T, nd, band)
    if mode > 0:
        for i in range(nd):
            q[i] = q0[i]
        _banded_solve(G, K, T, q, nd, mode)
    else:
        if not factor_inverse(G, K, Tinv, T, piv, nd):
            return -1
        for i in range(nd):
            acc = 0.0j
            for m in range(nd):
                acc += Tinv[i, m] * q0[m]
            q[i] = acc
    outputs(ylin, H, K, q, y, b0, b1, hr)
    return mode


@inline_jit
def contact_q(G, K, q0, T, piv, q, nd, band):
    """``q = (I + G diag(K))^-1 q0``: by the O(nd) elimination for ``band`` 1 or 2
    (:func:`.linalg.banded`; factors left in ``T``), else, or at a tiny pivot, by LU with
    pivoting. Returns 1 (chain), 2 (ring), 0 (LU) or -1 (singular)."""
    mode = _factor(G, K, T, nd, band)
    if mode > 0:
        for i in range(nd):
            q[i] = q0[i]
        _banded_solve(G, K, T, q, nd, mode)
        return mode
    return 0 if contact_solve(G, K, q0, T, piv, q, nd) == 0 else -1


@inline_jit
def outputs(ylin, H, K, q, y, b0, b1, hr):
    """``y_b = y_lin_b - (H diag(K) q)_b`` for the beams b0..b1-1 (``hr``: the dampers
    each beam's row of H can be nonzero for, see :func:`mcfric.bounds.search.sparsity`)."""
    for b in range(b0, b1):
        acc = ylin[b]
        for m in range(hr[b, 0], hr[b, 1]):
            acc -= H[b, m] * K[m] * q[m]
        y[b] = acc


@inline_jit
def _column(G, K, Tinv, T, u, j, nd, gr, mode):
    """``u = (I + G diag(K))^-1 G[:, j]``: from the inverse (``mode`` 0), or by the
    elimination whose factors are in ``T`` (1 chain, 2 ring)."""
    if mode > 0:
        for i in range(nd):
            u[i] = 0.0j
        for m in range(gr[j, 0], gr[j, 1]):
            u[m] = G[m, j]
        _banded_solve(G, K, T, u, nd, mode)
        return
    for i in range(nd):
        acc = 0.0j
        for m in range(gr[j, 0], gr[j, 1]):
            acc += Tinv[i, m] * G[m, j]
        u[i] = acc


@inline_jit
def _coefficients(ylin, H, K, q, y, j, u, alpha, beta, b0, b1, hr):
    """Moebius coefficients of ``y_b`` (b0 <= b < b1) in ``z = K_j``, given ``u`` from
    :func:`_column`. Returns (d0, d1).

    Only the objective's beams are needed: a search of one beam's maximum costs O(nd)
    per coordinate here instead of O(nb nd). ``hr``: nonzero ranges of the rows of H
    (:func:`mcfric.bounds.search.sparsity`)."""
    d1 = u[j]
    d0 = 1.0 - K[j] * d1
    qj = q[j]
    for b in range(b0, b1):
        P = 0.0j
        for m in range(hr[b, 0], hr[b, 1]):
            if m != j:
                P += H[b, m] * K[m] * u[m]
        base = y[b] + H[b, j] * K[j] * qj        # y_lin_b - S_b
        alpha[b] = base * d0 - K[j] * qj * P
        beta[b] = base * d1 + qj * (P - H[b, j])
    return d0, d1


@inline_jit
def max_abs(y, b0, b1):
    """``max |y_b|`` over beams b0..b1-1; NaN if any is NaN (never a silent 0)."""
    m = 0.0
    for b in range(b0, b1):
        v = abs(y[b])
        if not (v <= m):
            m = v
    return m


@jit
def coordinate_search(G, q0, ylin, H, kr, ki, K, want_max, b0, b1, max_sweeps, tol, w):
    """Coordinate search from the describing functions in ``K`` (N/m) for the extreme of
    ``max |y_b|`` over the beams ``b0 .. b1 - 1``. Returns that value.

    Each step replaces one ``K_j`` by the best point of its rectangle (exact, see the
    module docstring), so M never gets worse; sweeps stop when a whole sweep changes M by
    less than ``tol`` (relative). ``K`` holds the final point; NaN if the linear system
    was singular.
    """
    Tinv, T, piv, q, y, u, alpha, beta, rowj = w[:9]
    hr, gr = w[12], w[13]
    nd = K.shape[0]
    # a chain or a ring: O(nd) eliminations instead of keeping the inverse (O(nd^2) per
    # step, O(nd^3) per refresh); any other graph, or a tiny pivot, takes the inverse
    band = banded(G, gr, nd)
    w[14][0] = band
    mode = _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr, band)
    if mode < 0:
        return math.nan
    best = max_abs(y, b0, b1)
    stale = False                   # the factors in T are those of an earlier K
    K0, Kt = w[15], w[16]
    for sweep in range(max_sweeps):
        old = best
        changed = False
        for j in range(nd):
            K0[j] = K[j]
        for j in range(nd):
            if mode > 0 and stale:
                if _factor(G, K, T, nd, mode) > 0:
                    stale = False
                else:
                    mode = 0
                    if not factor_inverse(G, K, Tinv, T, piv, nd):
                        return math.nan
            _column(G, K, Tinv, T, u, j, nd, gr, mode)
            d0, d1 = _coefficients(ylin, H, K, q, y, j, u, alpha, beta, b0, b1, hr)
            # the interior only in tight searches (exploring relies on the edges and on
            # the smoothed-gradient polish)
            val, z = best_on_rectangle(alpha, beta, d0, d1, kr, ki, want_max, K[j], b0, b1,
                                        tol < 1e-9, w[11])
            delta = z - K[j]
            if delta == 0.0:
                continue
            changed = True
            # Sherman-Morrison update of q (and Tinv) and y for K_j -> z
            fac = delta / (1.0 + delta * u[j])
            qj = q[j]
            for i in range(nd):
                q[i] -= fac * u[i] * qj
            if mode > 0:
                stale = True
            else:
                for m in range(nd):
                    rowj[m] = Tinv[j, m]
                for i in range(nd):
                    ui = fac * u[i]
                    for m in range(nd):
                        Tinv[i, m] -= ui * rowj[m]
            K[j] = z
            for b in range(b0, b1):
                y[b] = (alpha[b] + beta[b] * z) / (d0 + d1 * z)
            best = val
        if not changed:
            break                   # converged: a refresh would reproduce the same state
        if want_max:
            # (not for the minimum: there it ends higher, see the performance page)
            _pattern_move(G, q0, ylin, H, kr, ki, K, K0, Kt, best, b0, b1, w)
        # refresh: Sherman-Morrison updates accumulate rounding
        mode = _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr,
                        band if mode > 0 else 0)
        if mode < 0:
            return math.nan
        stale = False
        best = max_abs(y, b0, b1)
        if abs(best - old) <= tol * max(best, old):
            break
    return best


@jit
def _pattern_move(G, q0, ylin, H, kr, ki, K, K0, Kt, best, b0, b1, w):
    """Hooke-Jeeves pattern move of the maximum after a sweep: along the sweep's
    displacement ``K - K0``, steps 1, 2, 4, ... (projected on the box) while M grows;
    ``K`` takes the best. On a resonance ridge (many dampers tuned together) a coordinate sweep
    advances little and in the same direction each time: this takes the long step.
    Clobbers the search state (the caller refreshes it)."""
    T, piv, q, y = w[1], w[2], w[3], w[4]
    hr = w[12]
    nd = K.shape[0]
    t = 1.0
    v_best = best
    t_best = 0.0
    for _ in range(8):
        for j in range(nd):
            z = K[j] + t * (K[j] - K0[j])
            Kt[j] = complex(min(max(z.real, 0.0), kr), min(max(z.imag, 0.0), ki))
        if contact_q(G, Kt, q0, T, piv, q, nd, w[14][0]) < 0:
            break
        outputs(ylin, H, Kt, q, y, b0, b1, hr)
        v = max_abs(y, b0, b1)
        if not (v > v_best):
            break
        v_best = v
        t_best = t
        t *= 2.0
    if t_best > 0.0:
        for j in range(nd):
            z = K[j] + t_best * (K[j] - K0[j])
            K[j] = complex(min(max(z.real, 0.0), kr), min(max(z.imag, 0.0), ki))


@jit
def workspace(nd, nb, hr, gr):
    """Scratch of one thread's searches; ends with its own copies of the sparsity ranges
    (an array shared by the threads would have its reference count contended) and the
    structure of ``G`` (:func:`.linalg.banded`), set by each search for its ``G``."""
    c16 = np.complex128
    return (np.zeros((nd, nd), c16), np.zeros((nd, nd), c16), np.zeros(nd, np.int64),
            np.zeros(nd, c16), np.zeros(nb, c16), np.zeros(nd, c16), np.zeros(nb, c16),
            np.zeros(nb, c16), np.zeros(nd, c16), np.zeros(nd, c16), np.zeros(nb),
            np.zeros((6, nb)), hr.copy(), gr.copy(), np.zeros(1, np.int64),
            np.zeros(nd, c16), np.zeros(nd, c16))
