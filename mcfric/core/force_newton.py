"""A barrier Newton ascent of one beam's response over all the damper forces.

With every damper force ``p`` as a variable, the problem is a quadratically constrained
quadratic one: ``y_b = ylin_b - H_b p`` and ``q = q0 - G p`` are affine in ``p``, and
``K_j = p_j / q_j`` lies in the box if and only if

    Re(p_j conj q_j) >= 0,   k_max_re |q_j|^2 - Re(p_j conj q_j) >= 0,
    Im(p_j conj q_j) >= 0,   k_max_im |q_j|^2 - Im(p_j conj q_j) >= 0

(with ``q_j != 0``), besides the force limit ``F_lim^2 - |p_j|^2 >= 0``. In the real
coordinates ``x = (Re p, Im p) / F_lim`` each of these, and ``|y_b|^2``, is ``z^T M z``
with ``z = (x, 1)``, so the gradient and the Hessian of

    log |y_b|^2 + tau sum_c log g_c(x)

are exact and cheap (``2 nd`` variables). Newton directions (the Hessian shifted until
negative definite), backtracking inside the constraints, ``tau`` cut tenfold per round.
Unlike :mod:`mcfric.core.force_ascent` no damper is held by its ``K``: all forces move
at once, which reaches maxima where the other dampers' forces matter as much as the
beam's own (the two-sided constraints of a damper between two resonating beams).
"""

import math

import numpy as np

from ._jit import jit
from .branch_bound import force_bounds
from .joint_ascent import boxed_value, strictly_inside
from .linalg import ridge_solve
from .quadratic_forms import PER_DAMPER, admissible_forms, response_form

#: Barrier weights, one round each; Newton steps per round at most; the Newton
#: decrement below which a round ends.
TAUS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
STEPS = 30
DECREMENT = 1e-12
#: How far inside the box a start's ``K`` is moved (fraction of the box side).
INSIDE = 1e-4
#: Beams ascended per start, in decreasing order of their force-only bound.
MAX_BEAMS = 2


@jit
def supports(Mc, sup, ns):
    """The coordinates each form involves: ``sup[c, :ns[c]]`` (rows of ``Mc[c]`` not all
    zero); on a chain six of the ``2 nd`` and the constant."""
    m, n, _ = Mc.shape
    for c in range(m):
        k = 0
        for a in range(n):
            for b in range(n):
                if Mc[c, a, b] != 0.0:
                    sup[c, k] = a
                    k += 1
                    break
        ns[c] = k


@jit
def _phi(z, Mc, sup, ns, My, tau, g, Hs, need, w):
    """The barrier objective at ``z`` (``-inf`` outside the constraints); with ``need``
    its gradient ``g`` and Hessian ``Hs`` in ``x``. ``My`` is over all coordinates, each
    ``Mc[c]`` over ``sup[c, :ns[c]]`` only."""
    m, n, _ = Mc.shape
    nx = n - 1
    f = 0.0
    for a in range(n):
        s = 0.0
        for b in range(n):
            s += My[a, b] * z[b]
        w[a] = s
        f += z[a] * s
    if not f > 0.0:
        return -math.inf
    val = math.log(f)
    if need:
        for a in range(nx):
            g[a] = 2.0 * w[a] / f
            for b in range(nx):
                Hs[a, b] = 2.0 * My[a, b] / f - 4.0 * w[a] * w[b] / (f * f)
    for c in range(m):
        gc = 0.0
        k = ns[c]
        for i in range(k):
            a = sup[c, i]
            s = 0.0
            for j in range(k):
                s += Mc[c, a, sup[c, j]] * z[sup[c, j]]
            w[a] = s
            gc += z[a] * s
        if not gc > 0.0:
            return -math.inf
        val += tau * math.log(gc)
        if need:
            for i in range(k):
                a = sup[c, i]
                if a == nx:
                    continue
                g[a] += tau * 2.0 * w[a] / gc
                for j in range(k):
                    b = sup[c, j]
                    if b != nx:
                        Hs[a, b] += tau * (2.0 * Mc[c, a, b] / gc
                                           - 4.0 * w[a] * w[b] / (gc * gc))
    return val


@jit
def _direction(g, Hs, A, L, y, d, nx):
    """``d = (lambda I - Hs)^-1 g`` with the smallest tried ``lambda >= 0`` that makes
    the matrix positive definite; returns the Newton decrement ``g . d`` (-1 if none)."""
    for a in range(nx):
        for b in range(nx):
            A[a, b] = -Hs[a, b]
        y[a] = g[a]
    if not ridge_solve(A, L, y, d, nx, 1e-10, 10.0, np.int64(60)):
        return -1.0
    dec = 0.0
    for a in range(nx):
        dec += g[a] * d[a]
    return dec


@jit
def ascend(Mc, sup, ns, My, z, stop2, ws):
    """Barrier Newton ascent of ``z^T My z`` from the strictly feasible ``z`` (in place)
    over ``TAUS``; stops early once ``z^T My z >= stop2``. Returns False if the start is
    not strictly feasible."""
    g, Hs, A, L, y, d, zn, w = ws
    nx = len(z) - 1
    if not math.isfinite(_phi(z, Mc, sup, ns, My, TAUS[0], g, Hs, np.bool_(False), w)):
        return False
    for tau in TAUS:
        for step in range(STEPS):
            f0 = _phi(z, Mc, sup, ns, My, tau, g, Hs, np.bool_(True), w)
            dec = _direction(g, Hs, A, L, y, d, nx)
            if not dec > DECREMENT:
                break
            t = 1.0
            moved = False
            for back in range(40):
                for a in range(nx):
                    zn[a] = z[a] + t * d[a]
                zn[nx] = 1.0
                if _phi(zn, Mc, sup, ns, My, tau, g, Hs, np.bool_(False), w) >= f0 + 1e-4 * t * dec:
                    moved = True
                    break
                t *= 0.5
            if not moved:
                break
            z[:] = zn
        f = 0.0
        for a in range(nx + 1):
            for b in range(nx + 1):
                f += z[a] * My[a, b] * z[b]
        if f >= stop2:
            break
    return True


@jit
def workspace(nd):
    """Scratch arrays of :func:`ascend` for ``nd`` dampers."""
    nx = 2 * nd
    return (np.empty(nx), np.empty((nx, nx)), np.empty((nx, nx)), np.empty((nx, nx)),
            np.empty(nx), np.empty(nx), np.empty(nx + 1), np.empty(nx + 1))


@jit(nogil=True)
def climb_frequencies(G, q0, ylin, H, kr, ki, F_lim, K_start, floor, stop, freqs, K_out,
                      M_out):
    """:func:`ascend` (all forces) with the contract of
    :func:`mcfric.core.force_ascent.ascend_frequencies`: the same starts (rows of
    ``K_start[k]``, NaN rows skipped), beams (the first ``MAX_BEAMS`` by Eq. 10 while
    above the best ``M`` so far, at least ``floor[k]``), stop (``stop[k]``, m) and
    outputs (the best admissible ``K_out[k]``, ``M_out[k]``; ``-inf`` if none above
    ``floor[k]``)."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    n = 2 * nd + 1
    ws = workspace(nd)
    Mc = np.empty((PER_DAMPER * nd, n, n))
    sup = np.empty((PER_DAMPER * nd, n), np.int64)
    ns = np.empty(PER_DAMPER * nd, np.int64)
    My = np.empty((n, n))
    z = np.empty(n)
    K = np.empty(nd, np.complex128)
    Kb = np.empty(nd, np.complex128)
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    eq10 = np.empty(nb)
    scale = np.full(nd, F_lim)
    lo = np.zeros(nd, np.complex128)
    hi = np.full(nd, complex(kr, ki))
    for k in freqs:
        M_out[k] = -math.inf
        best = floor[k]
        force_bounds(ylin[k], H[k], F_lim, eq10)
        by_bound = np.argsort(-eq10)
        admissible_forms(G[k], q0[k], lo, hi, scale, Mc)
        supports(Mc, sup, ns)
        for r in range(min(nb, MAX_BEAMS)):
            beam = by_bound[r]
            if eq10[beam] <= best or best >= stop[k]:
                break
            response_form(ylin[k], H[k], scale, beam, My)
            for s in range(K_start.shape[1]):
                if best >= stop[k]:
                    break
                K[:] = K_start[k, s]
                if np.isnan(K[0].real):
                    continue
                if not strictly_inside(G[k], q0[k], ylin[k], H[k], K, kr, ki, F_lim, INSIDE,
                                       T, piv, q):
                    continue
                for j in range(nd):
                    p = K[j] * q[j] / F_lim
                    z[j] = p.real
                    z[nd + j] = p.imag
                z[n - 1] = 1.0
                if not ascend(Mc, sup, ns, My, z, stop[k] * stop[k], ws):
                    continue
                # back to describing functions, checked
                for j in range(nd):
                    pj = F_lim * complex(z[j], z[nd + j])
                    qj = q0[k, j]
                    for i in range(nd):
                        qj -= G[k, j, i] * F_lim * complex(z[i], z[nd + i])
                    Kb[j] = pj / qj if qj != 0 else 0.0j
                v = boxed_value(G[k], q0[k], ylin[k], H[k], Kb, kr, ki, F_lim, T, piv, q)
                if v > best:
                    best = v
                    M_out[k] = v
                    K_out[k, :] = Kb
