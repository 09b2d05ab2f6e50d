"""Multi-harmonic balance of the contact-space equations: Newton on the AFT, ``prange``
over samples.

Unknowns are the odd harmonics ``Q_jh`` of the relative contact displacement of every
damper ``j``. The contact-space reduction holds per harmonic, at ``n_h omega``::

    R_jh = Q_jh + sum_l G_jl(n_h omega) F_lh(Q_l) - q0_j(omega) [h = fundamental] = 0,

with ``F_lh`` the harmonics of damper ``l``'s force from :func:`mcfric.core.aft.jenkins` and
``q0`` nonzero only at the fundamental (the drive is a pure harmonic). Newton works on
the real and imaginary parts (the force is not complex-analytic in ``Q``) with the exact
AFT Jacobian (solved by block Thomas on a chain, bordered on a ring: O(nd) blocks of
size ``2 n_h``; by a dense LU of size ``2 nd n_h`` on any other damper graph), and a
halving line search. The residual is only piecewise smooth (a Jenkins loop gains or loses
a slip phase as ``Q`` moves), and across such a kink the line search can crawl at steps
of 1/64; after two short steps in a row a rejected full step is followed by a few
undamped Newton steps (a watchdog), kept if they reach a smaller sum of squares than the
iteration's start.

Each sample sweeps the frequencies in order. A point starts from a prediction out of the
previous frequencies: the higher harmonics extrapolated linearly from the last two
solutions, the fundamental moved from the last solution by the change of the
single-harmonic solution between the two frequencies (which follows the resonances far
better than an extrapolation). If that fails, it starts from the previous frequency's
solution itself; then (or at the first frequency) from the single-harmonic solution of
the same point (passed in as its slip ratios), with zero higher harmonics.

A point none of these reach is tried once more after the sweep, going back down the
grid: from the converged solution at the next frequency of the sweep (the one above, on
an upward grid), predicted as in the sweep, then from that solution itself, then by
continuation in frequency from it (the receptances and the drive moved from that
frequency's to the point's on a straight line, :func:`_continuation`). Such a point lies
on the branch continued from the other side, and its status says so (3). Then by
continuation in frequency from the converged solution below (status 0: continued from
below, as the sweep's points are). A point that pass leaves is tried in a second pass
down the grid, from rest: by continuation in the drive at its own frequency (``Q = 0`` at
zero drive, up to the point's drive; status 4), after retries from any neighbour that
converged since its first visit; on a band across a resonance, where no neighbour
converged, the only way in. The points below one reached so follow from it in that pass;
those above it get a third pass, up the grid, by continuation in frequency from a point
below that converged in the second or third (status 0). No attempt is repeated with the
same data, and the first pass alone decides what it converges, as without the others.

Arguments
---------
rech : ndarray of complex128, shape (n_r * n_h, n_f, 4, n_beams)
    Receptances at ``n_h omega`` (row ``r * n_h + h``), m/N.
force, a, b, omega, mu0, N0, kc, tol, max_iter
    As for :mod:`mcfric.core.sweep` (``tol`` relative to the largest fundamental
    contact displacement).
orders : ndarray of int64, shape (n_h,)
    Odd harmonic orders, 1 first.
n_time : int
    AFT samples per period (event brackets).
s1 : ndarray of float64, shape (n_s, n_f, nd)
    Slip ratios of the single-harmonic solution (NaN where it failed).
y : ndarray of complex128, shape (n_s, n_f, n_ho, n_beams)
    Out: the first ``n_ho`` harmonics of the output displacement (``n_ho`` = 1: the
    fundamental only), m.
y_peak : ndarray of float64, shape (n_s, n_f, n_beams)
    Out: largest ``|y(t)|`` over a period (sampled at ``4 n_time`` points), m.
s : ndarray of float64, shape (n_s, n_f, nd)
    Out: ``mu0 N0 / (kc |Q_j1|)``, the slip ratio of the fundamental.
status, iterations, residual
    Out: 0 from the previous frequencies (prediction or last solution; after the sweep,
    by continuation in frequency from the point below), 1 from the single-harmonic
    start, 2 by continuation in the higher harmonics' coupling from the single-harmonic
    start, 3 only from the converged solution at the next frequency (continued back down
    the grid), 4 after the sweep by continuation in the drive from rest, -1 not
    converged (``y``, ``y_peak`` and ``s`` NaN);
    iterations of all attempts; the final ``max |R| / max_j |Q_j1|`` (of the sweep's
    attempts where the point did not converge).
"""

import math

import numpy as np
from numba import prange

from . import aft
from ._jit import inline_jit, jit
from .friction import kappa
from .linalg import lu_factor, lu_solve
from .receptance import D11, D21, D23
from .sweep import _dense_G, _q0, g_entry

#: Status of a point that converged only from the solution at the next frequency,
#: sweeping back down the grid (on the branch reached from above).
FROM_ABOVE = 3
#: Status of a point that converged only from rest, by raising the drive at its own
#: frequency after the sweep (no neighbour converged).
FROM_REST = 4
#: Layouts of the damper graph, each with its own Newton step: dense LU (any graph), block
#: Thomas (a chain), bordered block Thomas (a ring).
DENSE = 0
CHAIN = 1
RING = 2
_MAX_HALVINGS = 10
#: Watchdog: after ``_CRAWL_ITERS`` iterations in a row whose accepted step was at most
#: ``_CRAWL_STEP``, a rejected full step is followed by up to ``_WATCHDOG_STEPS`` undamped
#: Newton steps, kept at the first whose sum of squares is below the start's; at most
#: ``_WATCHDOG_TRIES`` times per call.
_CRAWL_STEP = 0.125
_CRAWL_ITERS = 2
_WATCHDOG_STEPS = 5
_WATCHDOG_TRIES = 2


@inline_jit
def _neighbour(j, t, nd, layout):
    """The ``t``-th damper (ascending) that ``G`` couples to damper ``j`` in the layout, or
    -1 past the last: all on any graph, ``j - 1 .. j + 1`` on a chain, and modulo ``nd``
    on a ring (only the zero entries of ``G`` are left out, in the dense loop's order, so
    the sums are the same)."""
    if layout == DENSE or (layout == RING and nd <= 3):
        return t if t < nd else -1
    if layout == RING and j == 0:
        return (0, 1, nd - 1)[t] if t < 3 else -1
    if layout == RING and j == nd - 1:
        return (0, nd - 2, nd - 1)[t] if t < 3 else -1
    m = max(j - 1, 0) + t
    return m if m <= min(j + 1, nd - 1) else -1


@jit
def _contact_G(rec, r, k, a, b, G, nd, layout):
    """``G = B diag(d11) B^T`` at receptance row ``r``, frequency ``k``: every entry on
    any graph; on a chain or a ring only the couplings (the others stay 0 from the
    allocation: O(nd) instead of O(nd^2) a frequency)."""
    if layout == DENSE:
        _dense_G(rec, r, k, a, b, G, nd)
        return
    d11 = rec[r, k, D11]
    for j in range(nd):
        t = 0
        m = _neighbour(j, t, nd, layout)
        while m >= 0:
            G[j, m] = g_entry(d11, a, b, j, m)
            t += 1
            m = _neighbour(j, t, nd, layout)


@jit
def _evaluate(Q, orders, G, q0, kc, fs, n_time, F, dF, R, work, nd, n_h, layout):
    """Force harmonics, their Jacobians and the residual; returns
    ``(max |R|, sum |R|^2, ok)``. ``G F`` over the layout's couplings only: O(nd) on a
    chain or a ring."""
    ok = True
    for j in range(nd):
        if aft.jenkins(Q[j], orders, kc[j], fs[j], n_time, F[j], dF[j], work) < 0:
            ok = False
    err = 0.0
    ss = 0.0
    for j in range(nd):
        for h in range(n_h):
            r = Q[j, h]
            t = 0
            m = _neighbour(j, t, nd, layout)
            while m >= 0:
                r += G[h, j, m] * F[m, h]
                t += 1
                m = _neighbour(j, t, nd, layout)
            if h == 0:
                r -= q0[j]
            R[j, h] = r
            err = max(err, abs(r))
            ss += r.real * r.real + r.imag * r.imag
    # max() drops a NaN component; the sum of squares keeps it
    if not (math.isfinite(err) and math.isfinite(ss)):
        ok = False
    return err, ss, ok


@jit
def _scale(Q, q0, nd):
    s = 0.0
    for j in range(nd):
        s = max(s, abs(Q[j, 0]), abs(q0[j]))
    return s if s > 0.0 else 1e-300


@inline_jit
def _block(G, dF, h, j, l, m, n_h, out, r0, c0):
    """Add the 2x2 real block ``G_h[j, l] dF_l[h, m]`` at ``out[r0, c0]``."""
    g = G[h, j, l]
    gr = g.real
    gi = g.imag
    a11 = dF[l, 2 * h, 2 * m]
    a12 = dF[l, 2 * h, 2 * m + 1]
    a21 = dF[l, 2 * h + 1, 2 * m]
    a22 = dF[l, 2 * h + 1, 2 * m + 1]
    out[r0, c0] += gr * a11 - gi * a21
    out[r0, c0 + 1] += gr * a12 - gi * a22
    out[r0 + 1, c0] += gi * a11 + gr * a21
    out[r0 + 1, c0 + 1] += gi * a12 + gr * a22


@jit
def _assemble(G, dF, J, nd, n_h):
    """Dense Jacobian ``I + G dF`` (any damper graph)."""
    n = 2 * nd * n_h
    for i in range(n):
        for k in range(n):
            J[i, k] = 0.0
        J[i, i] = 1.0
    for j in range(nd):
        for h in range(n_h):
            for l in range(nd):
                if G[h, j, l] == 0.0:
                    continue
                for m in range(n_h):
                    _block(G, dF, h, j, l, m, n_h, J, 2 * (j * n_h + h), 2 * (l * n_h + m))


@inline_jit
def _linear_gain(dF, j, n_h):
    """``c`` if damper ``j``'s Jacobian is ``c I`` (a stuck or force-free element: the
    AFT then writes exactly that), else NaN."""
    c = dF[j, 0, 0]
    for r in range(2 * n_h):
        for k in range(2 * n_h):
            if dF[j, r, k] != (c if r == k else 0.0):
                return math.nan
    return c


@inline_jit
def _couple(G, dF, h, j, l, n_h, c, out, r0):
    """Add the block row ``h`` of ``G_h[j, l] dF_l`` at rows ``r0``, ``r0 + 1`` of
    ``out`` (columns from 0): only its diagonal 2x2 block if ``dF_l = c I``."""
    if math.isnan(c):
        for m in range(n_h):
            _block(G, dF, h, j, l, m, n_h, out, r0, 2 * m)
    else:
        g = G[h, j, l] * c
        out[r0, 2 * h] += g.real
        out[r0, 2 * h + 1] -= g.imag
        out[r0 + 1, 2 * h] += g.imag
        out[r0 + 1, 2 * h + 1] += g.real


@jit
def _stuck_eliminate(G, dF, W, x, j0, j1, step, n_h):
    """Eliminate the stuck dampers ``j0, j0 + step, ...`` (up to ``j1`` excluded) of a
    chain, each towards the next: their blocks are ``c I``, so every harmonic is a complex
    scalar recurrence. The pivot of damper ``j``, harmonic ``h`` goes to
    ``W[2 j m2, 2 h : 2 h + 2]`` (``m2 = 2 n_h``), the reduced right side into ``x``.
    Returns False on a zero pivot."""
    m2 = 2 * n_h
    for h in range(n_h):
        for j in range(j0, j1, step):
            c = dF[j, 0, 0]
            d = 1.0 + G[h, j, j] * c
            xj = complex(x[j * m2 + 2 * h], x[j * m2 + 2 * h + 1])
            if j != j0:
                p = j - step
                t = G[h, j, p] * dF[p, 0, 0] / complex(W[2 * p * m2, 2 * h],
                                                        W[2 * p * m2, 2 * h + 1])
                d -= t * G[h, p, j] * c
                xj -= t * complex(x[p * m2 + 2 * h], x[p * m2 + 2 * h + 1])
            if d == 0.0 or not math.isfinite(abs(d)):
                return False
            W[2 * j * m2, 2 * h] = d.real
            W[2 * j * m2, 2 * h + 1] = d.imag
            x[j * m2 + 2 * h] = xj.real
            x[j * m2 + 2 * h + 1] = xj.imag
    return True


@inline_jit
def _force_step(dF, x, p, h, m2):
    """``(dF_p x_p)`` at harmonic ``h``, complex."""
    re = 0.0
    im = 0.0
    for k in range(m2):
        re += dF[p, 2 * h, k] * x[p * m2 + k]
        im += dF[p, 2 * h + 1, k] * x[p * m2 + k]
    return complex(re, im)


@jit
def _stuck_back(G, dF, W, x, j0, j1, step, full, n_h):
    """Back-substitution after :func:`_stuck_eliminate` (same ``j0``, ``j1``, ``step``),
    from ``j1 - step`` back to ``j0``. Damper ``j1`` is solved already (``dF_j1``
    full if ``full``) unless ``j1`` is off the chain."""
    m2 = 2 * n_h
    nd = dF.shape[0]
    for h in range(n_h):
        for j in range(j1 - step, j0 - step, -step):
            p = j + step
            xj = complex(x[j * m2 + 2 * h], x[j * m2 + 2 * h + 1])
            if 0 <= p < nd:
                if p == j1 and full:
                    v = _force_step(dF, x, p, h, m2)
                else:
                    v = dF[p, 0, 0] * complex(x[p * m2 + 2 * h], x[p * m2 + 2 * h + 1])
                xj -= G[h, j, p] * v
            xj /= complex(W[2 * j * m2, 2 * h], W[2 * j * m2, 2 * h + 1])
            x[j * m2 + 2 * h] = xj.real
            x[j * m2 + 2 * h + 1] = xj.imag


@inline_jit
def _stuck_correction(G, dF, W, x, j, p, n_h, rd):
    """Fold the eliminated stuck neighbour ``p`` of the nonlinear damper ``j`` into
    ``j``'s diagonal block (rows from ``rd`` of ``W``) and right side: per harmonic,
    ``D_j -= t G_h[p, j] dF_j`` and ``x_j -= t y_p`` with ``t = G_h[j, p] c_p / d_p``."""
    m2 = 2 * n_h
    for h in range(n_h):
        t = G[h, j, p] * dF[p, 0, 0] / complex(W[2 * p * m2, 2 * h], W[2 * p * m2, 2 * h + 1])
        g = t * G[h, p, j]
        gr = g.real
        gi = g.imag
        r0 = rd + 2 * h
        for c in range(m2):
            a0 = dF[j, 2 * h, c]
            a1 = dF[j, 2 * h + 1, c]
            W[r0, c] -= gr * a0 - gi * a1
            W[r0 + 1, c] -= gi * a0 + gr * a1
        y = t * complex(x[p * m2 + 2 * h], x[p * m2 + 2 * h + 1])
        x[j * m2 + 2 * h] -= y.real
        x[j * m2 + 2 * h + 1] -= y.imag


@inline_jit
def _solve_rows(D, p, W, r0, m2):
    """``W[r0:r0 + m2] = D^-1 W[r0:r0 + m2]`` with the LU factors ``D``, ``p`` of
    :func:`~mcfric.core.linalg.lu_factor`: all ``m2`` columns at once, row by row."""
    for k in range(m2):
        pk = p[k]
        if pk != k:
            for c in range(m2):
                t = W[r0 + k, c]
                W[r0 + k, c] = W[r0 + pk, c]
                W[r0 + pk, c] = t
    for r in range(1, m2):
        for k in range(r):
            lk = D[r, k]
            if lk != 0.0:
                for c in range(m2):
                    W[r0 + r, c] -= lk * W[r0 + k, c]
    for r in range(m2 - 1, -1, -1):
        for k in range(r + 1, m2):
            uk = D[r, k]
            if uk != 0.0:
                for c in range(m2):
                    W[r0 + r, c] -= uk * W[r0 + k, c]
        inv = 1.0 / D[r, r]
        for c in range(m2):
            W[r0 + r, c] *= inv


@jit
def _chain_step(G, dF, W, piv, x, nd, n_h):
    """Solve ``(I + G dF) dx = x`` in place for a chain (``G_h`` tridiagonal): block
    Thomas elimination on blocks of size ``2 n_h``, O(nd) blocks. ``W`` is scratch of at
    least ``(2 nd + 1) * 2 n_h`` rows and ``2 n_h`` columns. Returns False on a singular
    block.

    A damper whose Jacobian is ``c I`` (stuck) makes its coupling blocks 2x2-block
    diagonal; the elimination then updates with those blocks alone. The stuck dampers
    before the first nonlinear one ``f`` and after the last one ``l`` are eliminated
    towards them harmonic by harmonic, as complex scalars; the blocks run over ``f..l``
    only."""
    m2 = 2 * n_h
    rl = 2 * nd * m2                 # rows of the scratch block Lo
    f = 0
    while f < nd and not math.isnan(_linear_gain(dF, f, n_h)):
        f += 1
    if f == nd:
        if not _stuck_eliminate(G, dF, W, x, np.int64(0), nd, np.int64(1), n_h):
            return False
        _stuck_back(G, dF, W, x, np.int64(0), nd, np.int64(1), np.bool_(False), n_h)
        return True
    l = nd - 1
    while not math.isnan(_linear_gain(dF, l, n_h)):
        l -= 1
    if not _stuck_eliminate(G, dF, W, x, np.int64(0), f, np.int64(1), n_h):
        return False
    if not _stuck_eliminate(G, dF, W, x, nd - 1, l, np.int64(-1), n_h):
        return False
    c_prev = math.nan
    c_cur = math.nan
    for j in range(f, l + 1):
        c_next = _linear_gain(dF, j + 1, n_h) if j < l else math.nan
        rd = 2 * j * m2              # D_j, then its LU factors
        rx = rd + m2                 # Up_j, then X_j = D_j^-1 Up_j
        for r in range(m2):
            for c in range(m2):
                W[rd + r, c] = 0.0
            W[rd + r, r] = 1.0
        for h in range(n_h):
            _couple(G, dF, h, j, j, n_h, c_cur, W, rd + 2 * h)
        if j == f and f > 0:
            _stuck_correction(G, dF, W, x, j, j - 1, n_h, rd)
        if j == l and l < nd - 1:
            _stuck_correction(G, dF, W, x, j, j + 1, n_h, rd)
        if j > f:
            rxp = rx - 2 * m2        # X_{j-1}
            o = (j - 1) * m2
            if not math.isnan(c_prev):
                # Lo_j is 2x2-block diagonal: D -= Lo X_{j-1}, x_j -= Lo y_{j-1} by blocks
                for h in range(n_h):
                    g = G[h, j, j - 1] * c_prev
                    gr = g.real
                    gi = g.imag
                    r0 = 2 * h
                    for c in range(m2):
                        a0 = W[rxp + r0, c]
                        a1 = W[rxp + r0 + 1, c]
                        W[rd + r0, c] -= gr * a0 - gi * a1
                        W[rd + r0 + 1, c] -= gi * a0 + gr * a1
                    a0 = x[o + r0]
                    a1 = x[o + r0 + 1]
                    x[j * m2 + r0] -= gr * a0 - gi * a1
                    x[j * m2 + r0 + 1] -= gi * a0 + gr * a1
            else:
                for r in range(m2):
                    for c in range(m2):
                        W[rl + r, c] = 0.0
                for h in range(n_h):
                    _couple(G, dF, h, j, j - 1, n_h, c_prev, W, rl + 2 * h)
                for r in range(m2):
                    acc = 0.0
                    for k in range(m2):
                        lk = W[rl + r, k]
                        if lk != 0.0:
                            acc += lk * x[o + k]
                            for c in range(m2):
                                W[rd + r, c] -= lk * W[rxp + k, c]
                    x[j * m2 + r] -= acc
        D = W[rd:rd + m2]               # W has m2 columns: a C-contiguous block
        p = piv[j * m2:(j + 1) * m2]
        if lu_factor(D, p, m2) != 0:
            return False
        xj = x[j * m2:(j + 1) * m2]
        lu_solve(D, p, xj, m2)
        if j < l:
            for r in range(m2):
                for c in range(m2):
                    W[rx + r, c] = 0.0
            for h in range(n_h):
                _couple(G, dF, h, j, j + 1, n_h, c_next, W, rx + 2 * h)
            _solve_rows(D, p, W, rx, m2)    # X_j = D_j^-1 Up_j
        c_prev = c_cur
        c_cur = c_next
    for j in range(l - 1, f - 1, -1):
        rx = (2 * j + 1) * m2
        for r in range(m2):
            acc = 0.0
            for c in range(m2):
                acc += W[rx + r, c] * x[(j + 1) * m2 + c]
            x[j * m2 + r] -= acc
    _stuck_back(G, dF, W, x, nd - 1, l, np.int64(-1), np.bool_(True), n_h)
    _stuck_back(G, dF, W, x, np.int64(0), f, np.int64(1), np.bool_(True), n_h)
    return True


@inline_jit
def _sub_product(W, rl, rm, rd, m2):
    """``W[rd:rd + m2] -= W[rl:rl + m2] W[rm:rm + m2]`` (blocks of ``m2`` columns)."""
    for r in range(m2):
        for k in range(m2):
            lk = W[rl + r, k]
            if lk != 0.0:
                for c in range(m2):
                    W[rd + r, c] -= lk * W[rm + k, c]


@inline_jit
def _sub_vector(W, rl, x, o, j, m2):
    """``x_j -= W[rl:rl + m2] x_o`` (blocks of ``m2`` entries of ``x``)."""
    for r in range(m2):
        acc = 0.0
        for k in range(m2):
            acc += W[rl + r, k] * x[o * m2 + k]
        x[j * m2 + r] -= acc


@inline_jit
def _coupling(G, dF, j, l, n_h, W, r0):
    """``W[r0:r0 + 2 n_h] = G[j, l] dF_l``, the block of dampers ``j``, ``l``."""
    m2 = 2 * n_h
    for r in range(m2):
        for c in range(m2):
            W[r0 + r, c] = 1.0 if (j == l and r == c) else 0.0
    c = _linear_gain(dF, l, n_h)
    for h in range(n_h):
        _couple(G, dF, h, j, l, n_h, c, W, r0 + 2 * h)


@jit
def _ring_step(G, dF, W, piv, x, nd, n_h):
    """Solve ``(I + G dF) dx = x`` in place for a ring (``G_h`` cyclic tridiagonal:
    damper ``j`` meets ``j - 1`` and ``j + 1`` modulo ``nd``; ``nd >= 2``). Bordering, as
    the single-harmonic ring kernel does: dampers ``0 .. nd - 2`` form a block chain whose
    extra right-hand side is the last damper's block column (nonzero in its first and last
    block rows); block Thomas solves it for both, ``y`` and ``Z``; the last damper then
    solves its Schur complement ``S x_l = x_l - C_0 y_0 - C_p y_p`` (``S = D_l - C_0 Z_0 -
    C_p Z_p``, ``C`` its blocks in row ``l``, ``p = nd - 2``) and the others follow as ``y -
    Z x_l``. O(nd) blocks of size ``2 n_h``. ``W`` is scratch of at least ``(3 nd + 1) 2
    n_h`` rows and ``2 n_h`` columns: per damper ``D_j`` (then its LU factors), ``X_j =
    D_j^-1 Up_j`` and ``Z_j``. Returns False on a singular block."""
    m2 = 2 * n_h
    last = nd - 1
    rl = 3 * nd * m2                 # scratch: a coupling block
    for j in range(last):
        rd = 3 * j * m2
        rx = rd + m2
        rz = rd + 2 * m2
        _coupling(G, dF, j, j, n_h, W, rd)
        if j == 0 or j == last - 1:
            _coupling(G, dF, j, last, n_h, W, rz)
        else:
            for r in range(m2):
                for c in range(m2):
                    W[rz + r, c] = 0.0
        if j > 0:
            # D_j -= Lo_j X_{j-1}, Z_j -= Lo_j Z_{j-1}, x_j -= Lo_j y_{j-1}
            _coupling(G, dF, j, j - 1, n_h, W, rl)
            _sub_product(W, rl, rx - 3 * m2, rd, m2)
            _sub_product(W, rl, rz - 3 * m2, rz, m2)
            _sub_vector(W, rl, x, j - 1, j, m2)
        D = W[rd:rd + m2]
        p = piv[j * m2:(j + 1) * m2]
        if lu_factor(D, p, m2) != 0:
            return False
        lu_solve(D, p, x[j * m2:(j + 1) * m2], m2)
        _solve_rows(D, p, W, rz, m2)
        if j < last - 1:
            _coupling(G, dF, j, j + 1, n_h, W, rx)
            _solve_rows(D, p, W, rx, m2)
    for j in range(last - 2, -1, -1):
        # y_j -= X_j y_{j+1}, Z_j -= X_j Z_{j+1}
        rx = (3 * j + 1) * m2
        _sub_vector(W, rx, x, j + 1, j, m2)
        _sub_product(W, rx, rx + 4 * m2, rx + m2, m2)
    rd = 3 * last * m2
    _coupling(G, dF, last, last, n_h, W, rd)
    for t in range(2):
        o = 0 if t == 0 else last - 1
        if t == 1 and o == 0:
            break                    # two dampers: one block to the other, not two
        _coupling(G, dF, last, o, n_h, W, rl)
        _sub_product(W, rl, (3 * o + 2) * m2, rd, m2)
        _sub_vector(W, rl, x, o, last, m2)
    D = W[rd:rd + m2]
    p = piv[last * m2:nd * m2]
    if lu_factor(D, p, m2) != 0:
        return False
    lu_solve(D, p, x[last * m2:nd * m2], m2)
    for j in range(last):
        # x_j = y_j - Z_j x_l
        _sub_vector(W, (3 * j + 2) * m2, x, last, j, m2)
    return True


@jit
def _newton_step(G, dF, R, J, piv, dx, nd, n_h, layout):
    """``dx`` = the Newton step ``-(I + G dF)^-1 R``; False on a singular system."""
    n = 2 * nd * n_h
    for j in range(nd):
        for h in range(n_h):
            dx[2 * (j * n_h + h)] = -R[j, h].real
            dx[2 * (j * n_h + h) + 1] = -R[j, h].imag
    if layout == CHAIN:
        return _chain_step(G, dF, J, piv, dx, nd, n_h)
    if layout == RING:
        return _ring_step(G, dF, J, piv, dx, nd, n_h)
    _assemble(G, dF, J, nd, n_h)
    if lu_factor(J, piv, n) != 0:
        return False
    lu_solve(J, piv, dx, n)
    return True


@jit
def _newton(Q, orders, G, q0, kc, fs, n_time, tol, max_iter, F, dF, R, J, piv, dx, dw, Qt,
            work, nd, n_h, layout):
    """Newton from ``Q`` (updated in place); returns ``(converged, iterations, err)``.

    A halving line search on the sum of squares. Where it crawls (the residual is only
    piecewise smooth: a Jenkins loop gains or loses a slip phase between ``Q`` and the
    solution, and the Jacobian jumps there), a watchdog: undamped steps from the full
    step (``dw`` is their scratch, like ``dx``). They come on top of the ``max_iter``
    iterations (at most ``_WATCHDOG_TRIES * _WATCHDOG_STEPS``: counting them against it
    left 16 of 8,000 bench points unconverged instead of 10) and are counted in the
    iterations returned."""
    err, ss, ok = _evaluate(Q, orders, G, q0, kc, fs, n_time, F, dF, R, work, nd, n_h, layout)
    if not ok:
        return False, 0, math.inf
    rel = err / _scale(Q, q0, nd)
    extra = 0                        # undamped steps of the watchdog
    tries = 0
    crawl = 0                        # iterations in a row with a short accepted step
    for it in range(1, max_iter + 1):
        if rel <= 0.1 * tol:
            return True, it - 1 + extra, rel
        if not _newton_step(G, dF, R, J, piv, dx, nd, n_h, layout):
            return False, it + extra, rel
        step = 1.0
        accepted = False
        for _ in range(_MAX_HALVINGS):
            for j in range(nd):
                for h in range(n_h):
                    i0 = 2 * (j * n_h + h)
                    Qt[j, h] = Q[j, h] + step * complex(dx[i0], dx[i0 + 1])
            err_t, ss_t, ok = _evaluate(Qt, orders, G, q0, kc, fs, n_time, F, dF, R, work, nd,
                                        n_h, layout)
            # sufficient decrease of the sum of squares (smoother than the max norm)
            if ok and ss_t < (1.0 - 1e-4 * step) * ss:
                accepted = True
                break
            if ok and step == 1.0 and crawl >= _CRAWL_ITERS and tries < _WATCHDOG_TRIES:
                # undamped steps from the full step (F, dF, R are Qt's), kept at the
                # first whose sum of squares is below the start's
                tries += 1
                for _w in range(_WATCHDOG_STEPS):
                    if not _newton_step(G, dF, R, J, piv, dw, nd, n_h, layout):
                        break
                    extra += 1
                    for j in range(nd):
                        for h in range(n_h):
                            i0 = 2 * (j * n_h + h)
                            Qt[j, h] += complex(dw[i0], dw[i0 + 1])
                    err_t, ss_t, ok = _evaluate(Qt, orders, G, q0, kc, fs, n_time, F, dF, R,
                                                work, nd, n_h, layout)
                    if not ok:
                        break
                    if ss_t < (1.0 - 1e-4) * ss:
                        accepted = True
                        break
                if accepted:
                    break
            step *= 0.5
        if not accepted:
            # no decrease: at the rounding floor if already within tol, else stuck
            _evaluate(Q, orders, G, q0, kc, fs, n_time, F, dF, R, work, nd, n_h, layout)
            return rel <= tol, it + extra, rel
        crawl = crawl + 1 if step <= _CRAWL_STEP else 0
        for j in range(nd):
            for h in range(n_h):
                Q[j, h] = Qt[j, h]
        err = err_t
        ss = ss_t
        rel = err / _scale(Q, q0, nd)
    return rel <= tol, max_iter + extra, rel


@jit
def _single_harmonic_start(s1, G, q0, kc, Q, T, dF1, J, piv, x, nd, n_h, layout):
    """``Q`` from single-harmonic slip ratios: ``(I + G_1 K) q = q0``; False if unusable.

    On a chain or a ring by the layout's Newton step with one harmonic (``K_m`` as the
    2x2 real block ``dF1[m]``; ``J``, ``x``: the step's scratch, ``x`` at least ``2 nd``
    long), O(nd); on any other graph by a complex dense LU of ``T``."""
    for j in range(nd):
        if math.isnan(s1[j]):
            return False
    if layout == DENSE:
        for j in range(nd):
            for m in range(nd):
                T[j, m] = G[0, j, m] * kc[m] * kappa(s1[m])
            T[j, j] += 1.0
        if lu_factor(T, piv, nd) != 0:
            return False
        q = np.empty(nd, dtype=np.complex128)
        for j in range(nd):
            q[j] = q0[j]
        lu_solve(T, piv, q, nd)
        for j in range(nd):
            Q[j, 0] = q[j]
    else:
        for m in range(nd):
            k = kc[m] * kappa(s1[m])
            dF1[m, 0, 0] = k.real
            dF1[m, 0, 1] = -k.imag
            dF1[m, 1, 0] = k.imag
            dF1[m, 1, 1] = k.real
            x[2 * m] = q0[m].real
            x[2 * m + 1] = q0[m].imag
        if layout == CHAIN:
            ok = _chain_step(G, dF1, J, piv, x, nd, np.int64(1))
        else:
            ok = _ring_step(G, dF1, J, piv, x, nd, np.int64(1))
        if not ok:
            return False
        for j in range(nd):
            Q[j, 0] = complex(x[2 * j], x[2 * j + 1])
    for j in range(nd):
        for h in range(1, n_h):
            Q[j, h] = 0.0j
    return True


@jit
def _extremum(yh, orders, bb, t, n_peak, v0):
    """The extremum of ``y(theta) = Re sum_h Y_h e^{i n_h theta}`` next to sample ``t``
    (value ``v0``): a few Newton steps on ``y'``, kept within one sample spacing. The
    orders are ``1, 3, 5, ...``."""
    th0 = 2.0 * math.pi * t / n_peak
    th = th0
    best = v0
    for _ in range(4):
        d1 = 0.0
        d2 = 0.0
        # exp(i n th) for the odd orders by powers of exp(2 i th): one sin/cos per step
        e = complex(math.cos(th), math.sin(th))
        e2 = e * e
        p = e
        for h in range(orders.shape[0]):
            n = orders[h]
            z = yh[h, bb] * p
            d1 -= n * z.imag
            d2 -= n * n * z.real
            p *= e2
        if d2 == 0.0:
            break
        th = th - d1 / d2
        if abs(th - th0) > 2.0 * math.pi / n_peak:
            break
    v = 0.0
    e = complex(math.cos(th), math.sin(th))
    e2 = e * e
    p = e
    for h in range(orders.shape[0]):
        v += (yh[h, bb] * p).real
        p *= e2
    # keep the sampled value unless the refined point is further out on the same side
    if (v0 >= 0.0 and v > best) or (v0 < 0.0 and v < best):
        best = v
    return best


#: Continuation: first step in lambda, smallest step before giving up.
_LAMBDA_STEP = 0.25
_LAMBDA_MIN_STEP = 1.0 / 64.0


@jit
def _continuation(Q, Qc, orders, G, Gs, G0, q0, q0s, q00, kc, fs, n_time, tol, max_iter, F,
                  dF, R, J, piv, dx, dw, Qt, work, nd, n_h, layout):
    """Follow the solution from ``Q``, which solves the equations with receptances ``G0``
    and drive ``q00``, while they move in a straight line to ``G`` and ``q0``: natural
    continuation in the line's parameter with step halving (``Gs``, ``q0s`` hold the
    point on the line). From the single-harmonic start, ``G0`` is ``G`` with the higher
    harmonics' receptances zero; from a grid neighbour's solution, its ``G`` and ``q0``
    (continuation in frequency, the straight line standing for the frequencies between).
    Returns like :func:`_newton`; ``Q`` holds the solution on success."""
    lam = 0.0
    step = _LAMBDA_STEP
    total = 0
    ok = False
    rel = math.inf
    for j in range(nd):
        for h in range(n_h):
            Qc[j, h] = Q[j, h]
    while lam < 1.0 and step >= _LAMBDA_MIN_STEP:
        target = min(1.0, lam + step)
        end = target == 1.0             # the point's own equations, not rounded ones
        for h in range(n_h):
            for j in range(nd):
                # the couplings of the layout (the other entries are 0 in all three)
                t = 0
                m = _neighbour(j, t, nd, layout)
                while m >= 0:
                    Gs[h, j, m] = (G[h, j, m] if end else
                                   G0[h, j, m] + target * (G[h, j, m] - G0[h, j, m]))
                    t += 1
                    m = _neighbour(j, t, nd, layout)
        for j in range(nd):
            q0s[j] = q0[j] if end else q00[j] + target * (q0[j] - q00[j])
            for h in range(n_h):
                Q[j, h] = Qc[j, h]
        ok, it, rel = _newton(Q, orders, Gs, q0s, kc, fs, n_time, tol, max_iter, F, dF, R, J,
                              piv, dx, dw, Qt, work, nd, n_h, layout)
        total += it
        if ok:
            lam = target
            for j in range(nd):
                for h in range(n_h):
                    Qc[j, h] = Q[j, h]
            step *= 1.5
        else:
            step *= 0.5
    return ok and lam >= 1.0, total, rel


@jit(parallel=True, nogil=True)
def sweep_multi_harmonic(rech, force, a, b, orders, omega, mu0, N0, kc, n_time, s1, tol,
                         max_iter, y, y_peak, s, status, iterations, residual):
    """Multi-harmonic sweep of every sample (module docstring for the arguments)."""
    n_s = mu0.shape[0]
    for i in prange(n_s):
        _sample(np.int64(i), rech, force, a, b, orders, omega, mu0, N0, kc, n_time, s1, tol,
                max_iter, y, y_peak, s, status, iterations, residual)


@jit
def _sample(i, rech, force, a, b, orders, omega, mu0, N0, kc, n_time, s1, tol, max_iter,
            y, y_peak, s, status, iterations, residual):
    n_h = orders.shape[0]
    nd = a.shape[0]
    n_beams = force.shape[0]
    n_f = omega.shape[0]
    n = 2 * nd * n_h
    # damper j couples beams j and j + 1: G tridiagonal; on a ring the last couples the
    # last beam and the first: cyclic tridiagonal
    layout = CHAIN
    for j in range(nd):
        if a[j] != j or b[j] != j + 1:
            layout = DENSE
    if nd >= 2 and nd == n_beams:
        layout = RING
        for j in range(nd):
            if a[j] != j or b[j] != (j + 1) % n_beams:
                layout = DENSE
    r_base = 0
    if rech.shape[0] > n_h:          # per-sample receptances (mistuned rigs)
        r_base = np.int64(i) * n_h
    # zeros: on a chain or a ring only the couplings are written (_contact_G)
    G = np.zeros((n_h, nd, nd), dtype=np.complex128)
    Gs = np.zeros((n_h, nd, nd), dtype=np.complex128)
    G0 = np.zeros((n_h, nd, nd), dtype=np.complex128)
    Qc = np.zeros((nd, n_h), dtype=np.complex128)
    Qall = np.empty((n_f, nd, n_h), dtype=np.complex128)   # rows of converged points
    q0 = np.empty(nd, dtype=np.complex128)
    q0n = np.empty(nd, dtype=np.complex128)
    q0s = np.empty(nd, dtype=np.complex128)
    Q = np.zeros((nd, n_h), dtype=np.complex128)
    Qp = np.zeros((nd, n_h), dtype=np.complex128)
    Qpp = np.zeros((nd, n_h), dtype=np.complex128)
    Qsh = np.zeros((nd, n_h), dtype=np.complex128)
    Qsh_prev = np.zeros((nd, n_h), dtype=np.complex128)
    Qt = np.zeros((nd, n_h), dtype=np.complex128)
    F = np.zeros((nd, n_h), dtype=np.complex128)
    dF = np.zeros((nd, 2 * n_h, 2 * n_h))
    R = np.zeros((nd, n_h), dtype=np.complex128)
    # dense Jacobian, or the blocks of 2 n_h rows of a chain (2 per damper) or a ring (3)
    if layout == CHAIN:
        J = np.zeros((2 * n + 2 * n_h, 2 * n_h))
    elif layout == RING:
        J = np.zeros((3 * n + 2 * n_h, 2 * n_h))
    else:
        J = np.zeros((n, n))
    # the single-harmonic start's scratch: a dense complex matrix, or one harmonic's blocks
    T = np.zeros((nd, nd) if layout == DENSE else (1, 1), dtype=np.complex128)
    dF1 = np.zeros((nd, 2, 2))
    x1 = np.zeros(2 * nd)
    piv = np.zeros(n, dtype=np.int64)
    dx = np.zeros(n)
    dw = np.zeros(n)
    work = np.zeros(aft.work_size(n_h, n_time))
    yh = np.zeros((n_h, n_beams), dtype=np.complex128)
    kci = kc[i]
    fs = np.empty(nd)
    for j in range(nd):
        fs[j] = mu0[i, j] * N0[i, j]
    n_failed = 0
    have_prev = False
    have_prev2 = False               # Qpp holds the solution two frequencies back
    sh_prev = False                  # Qsh_prev holds the single-harmonic start of k - 1
    n_peak = 4 * n_time
    # cos and sin of n_h theta on the peak samples, once per sample; real arrays, the
    # sample index innermost, so that the sums over the samples run in SIMD lanes
    pc = np.empty((n_h, n_peak))
    ps = np.empty((n_h, n_peak))
    for t in range(n_peak):
        for h in range(n_h):
            th = 2.0 * math.pi * orders[h] * t / n_peak
            pc[h, t] = math.cos(th)
            ps[h, t] = math.sin(th)
    yt = np.empty(n_peak)
    for k in range(n_f):
        for h in range(n_h):
            _contact_G(rech, r_base + h, k, a, b, G[h], nd, layout)
        for j in range(nd):
            q0[j] = _q0(rech, r_base, k, force, a, b, j)
        its = 0
        ok = False
        st = 0
        rel = math.inf
        sh = _single_harmonic_start(s1[i, k], G, q0, kci, Qsh, T, dF1, J, piv, x1, nd,
                                    n_h, layout)
        if have_prev and (have_prev2 or (sh and sh_prev)):
            for j in range(nd):
                for h in range(n_h):
                    if h == 0 and sh and sh_prev:
                        Q[j, h] = Qp[j, h] + (Qsh[j, h] - Qsh_prev[j, h])
                    elif have_prev2:
                        Q[j, h] = 2.0 * Qp[j, h] - Qpp[j, h]
                    else:
                        Q[j, h] = Qp[j, h]
            ok, it, rel = _newton(Q, orders, G, q0, kci, fs, n_time, tol, max_iter, F, dF,
                                  R, J, piv, dx, dw, Qt, work, nd, n_h, layout)
            its += it
        if have_prev and not ok:
            for j in range(nd):
                for h in range(n_h):
                    Q[j, h] = Qp[j, h]
            ok, it, rel = _newton(Q, orders, G, q0, kci, fs, n_time, tol, max_iter, F, dF,
                                  R, J, piv, dx, dw, Qt, work, nd, n_h, layout)
            its += it
        sh_prev = sh
        for j in range(nd):
            Qsh_prev[j, 0] = Qsh[j, 0]
        if not ok:
            # from here on the start is the single-harmonic solution (also at a first
            # frequency, where there was no previous one to start from)
            st = 1
            if sh:
                for j in range(nd):
                    for h in range(n_h):
                        Q[j, h] = Qsh[j, h]
                ok, it, rel = _newton(Q, orders, G, q0, kci, fs, n_time, tol, max_iter, F,
                                      dF, R, J, piv, dx, dw, Qt, work, nd, n_h, layout)
                its += it
        if not ok and sh:
            st = 2
            for j in range(nd):
                for h in range(n_h):
                    Q[j, h] = Qsh[j, h]
                    for m in range(nd):
                        G0[h, j, m] = G[h, j, m] if h == 0 else 0.0j
            ok, it, rel = _continuation(Q, Qc, orders, G, Gs, G0, q0, q0s, q0, kci, fs,
                                        n_time, tol, max_iter, F, dF, R, J, piv, dx, dw, Qt,
                                        work, nd, n_h, layout)
            its += it
        iterations[i, k] = min(its, 32767)
        residual[i, k] = rel
        if not ok:
            status[i, k] = -1
            n_failed += 1
            have_prev = False
            have_prev2 = False
            for bb in range(n_beams):
                for h in range(y.shape[2]):
                    y[i, k, h, bb] = complex(math.nan, math.nan)
                y_peak[i, k, bb] = math.nan
            for j in range(nd):
                s[i, k, j] = math.nan
            continue
        status[i, k] = st
        have_prev2 = have_prev
        have_prev = True
        for j in range(nd):
            for h in range(n_h):
                Qpp[j, h] = Qp[j, h]
                Qp[j, h] = Q[j, h]
                Qall[k, j, h] = Q[j, h]
        _outputs(i, k, Q, F, rech, r_base, force, a, b, orders, kci, fs, y, y_peak, s, yh,
                 yt, pc, ps)
    if n_failed == 0:
        return
    # Three passes over the points the sweep missed. Pass 0, back down the grid: a failed
    # point next to a converged one starts from it: from the one above (predicted,
    # itself, by continuation in frequency), then by continuation in frequency from the
    # one below (the sweep tried it directly). Pass 1, down again: from rest by raising
    # the drive at the point's own frequency (where no neighbour converged, e.g. on a
    # band across a resonance, the only way in), after the retries from neighbours that
    # converged since the point's visit in pass 0. Pass 2, up the grid: from a neighbour
    # below that converged since the point's visit in pass 1 (a run of failures above a
    # point the drive reached). An attempt with the same data as before is not repeated;
    # pass 0 runs to its end first, so what it converges does not depend on the others.
    when = np.full(n_f, -1, dtype=np.int64)      # the pass that converged the point
    for p in range(3 * n_f):
        phase = p // n_f
        k = p % n_f if phase == 2 else n_f - 1 - p % n_f
        if status[i, k] >= 0:
            continue
        above = phase < 2 and k + 1 < n_f and status[i, k + 1] >= 0
        below = k > 0 and status[i, k - 1] >= 0
        if phase == 1:
            # pass 0 visited the point above before this one, the one below after it
            above = above and when[k + 1] == 1
            below = below and when[k - 1] == 0
        elif phase == 2:
            below = below and when[k - 1] >= 1
        drive = phase == 1
        if not (above or below or drive):
            continue
        for h in range(n_h):
            _contact_G(rech, r_base + h, k, a, b, G[h], nd, layout)
        for j in range(nd):
            q0[j] = _q0(rech, r_base, k, force, a, b, j)
        sh = False
        sh_next = False
        if above:
            for h in range(n_h):
                _contact_G(rech, r_base + h, k + 1, a, b, G0[h], nd, layout)
            for j in range(nd):
                q0n[j] = _q0(rech, r_base, k + 1, force, a, b, j)
            sh = _single_harmonic_start(s1[i, k], G, q0, kci, Qsh, T, dF1, J, piv, x1, nd,
                                        n_h, layout)
            sh_next = _single_harmonic_start(s1[i, k + 1], G0, q0n, kci, Qsh_prev, T, dF1,
                                             J, piv, x1, nd, n_h, layout)
        next2 = above and k + 2 < n_f and status[i, k + 2] >= 0
        its = 0
        ok = False
        st = FROM_ABOVE
        # one call site each of _newton and _continuation: every copy adds to the
        # compile time
        for attempt in range(5):
            if attempt < 3 and not above or attempt == 3 and not below:
                continue
            if attempt == 4 and not drive:
                continue
            if attempt == 0 and not ((sh and sh_next) or next2):
                continue                 # no prediction: the solution above alone
            if attempt < 2:
                for j in range(nd):
                    for h in range(n_h):
                        if attempt == 0 and h == 0 and sh and sh_next:
                            Q[j, h] = Qall[k + 1, j, h] + (Qsh[j, h] - Qsh_prev[j, h])
                        elif attempt == 0 and next2:
                            Q[j, h] = 2.0 * Qall[k + 1, j, h] - Qall[k + 2, j, h]
                        else:
                            Q[j, h] = Qall[k + 1, j, h]
                ok, it, rel = _newton(Q, orders, G, q0, kci, fs, n_time, tol, max_iter, F,
                                      dF, R, J, piv, dx, dw, Qt, work, nd, n_h, layout)
            else:
                kn = k + 1                   # G0 and q0n hold its receptances and drive
                if attempt == 3:
                    kn = k - 1
                    st = 0                   # on the branch continued from below
                    for h in range(n_h):
                        _contact_G(rech, r_base + h, kn, a, b, G0[h], nd, layout)
                    for j in range(nd):
                        q0n[j] = _q0(rech, r_base, kn, force, a, b, j)
                if attempt == 4:
                    # the point's own receptances, the drive from 0 (solved by Q = 0) up
                    st = FROM_REST
                    for h in range(n_h):
                        for j in range(nd):
                            for m in range(nd):
                                G0[h, j, m] = G[h, j, m]
                    for j in range(nd):
                        q0n[j] = 0.0j
                for j in range(nd):
                    for h in range(n_h):
                        Q[j, h] = Qall[kn, j, h] if attempt < 4 else 0.0j
                ok, it, rel = _continuation(Q, Qc, orders, G, Gs, G0, q0, q0s, q0n, kci, fs,
                                            n_time, tol, max_iter, F, dF, R, J, piv, dx, dw,
                                            Qt, work, nd, n_h, layout)
            its += it
            if ok:
                break
        iterations[i, k] = min(iterations[i, k] + its, 32767)
        if not ok:
            continue
        status[i, k] = st
        residual[i, k] = rel
        when[k] = phase
        for j in range(nd):
            for h in range(n_h):
                Qall[k, j, h] = Q[j, h]
        _outputs(i, k, Q, F, rech, r_base, force, a, b, orders, kci, fs, y, y_peak, s, yh,
                 yt, pc, ps)


@jit
def _outputs(i, k, Q, F, rech, r_base, force, a, b, orders, kci, fs, y, y_peak, s, yh, yt,
             pc, ps):
    """Slip ratios, output harmonics and the largest ``|y(t)|`` of the converged point
    ``(i, k)`` (``F`` holds the forces at ``Q``)."""
    nd = a.shape[0]
    n_h = orders.shape[0]
    n_beams = force.shape[0]
    n_peak = pc.shape[1]
    for j in range(nd):
        amp = abs(Q[j, 0])
        if fs[j] == 0.0:
            s[i, k, j] = 0.0
        elif kci[j] == 0.0 or amp == 0.0:
            s[i, k, j] = math.inf
        else:
            s[i, k, j] = fs[j] / (kci[j] * amp)
    # output harmonics: y_h = D23 F [h = 1] - D21(n_h omega) B^T F_h
    for h in range(n_h):
        for bb in range(n_beams):
            yh[h, bb] = 0.0j
        for j in range(nd):
            yh[h, a[j]] -= rech[r_base + h, k, D21, a[j]] * F[j, h]
            yh[h, b[j]] += rech[r_base + h, k, D21, b[j]] * F[j, h]
    for bb in range(n_beams):
        yh[0, bb] += rech[r_base, k, D23, bb] * force[bb]
        for h in range(y.shape[2]):
            y[i, k, h, bb] = yh[h, bb]
        hi = -math.inf
        lo = math.inf
        t_hi = np.int64(0)
        t_lo = np.int64(0)
        for t in range(n_peak):
            yt[t] = 0.0
        for h in range(n_h):
            yr = yh[h, bb].real
            yi = yh[h, bb].imag
            for t in range(n_peak):
                yt[t] += yr * pc[h, t] - yi * ps[h, t]
        for t in range(n_peak):
            v = yt[t]
            if v > hi:
                hi = v
                t_hi = t
            if v < lo:
                lo = v
                t_lo = t
        y_peak[i, k, bb] = max(_extremum(yh, orders, bb, t_hi, n_peak, hi),
                               -_extremum(yh, orders, bb, t_lo, n_peak, lo))

