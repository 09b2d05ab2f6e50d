"""A joint ascent of one beam's response with its own dampers' forces as variables.

Near a resonance ``|y_b|`` is a sharp ridge in the describing functions of the beam's own
dampers (the set ``A``: ``H[b, j] != 0``), but a linear function of their forces,
``y_b = ylin_b - H_b p``. Here the variables are those forces ``p_A`` and the other
dampers' ``K_O``; the rest follows from them:

    (I + G_OO diag K_O) q_O = q0_O - G_OA p_A,   p_O = K_O q_O,
    q_A = q0_A - G_A: p,                         K_A = p_A / q_A.

Projected quasi-Newton ascent (L-BFGS directions, backtracking; ``K_O`` held on a side
of the box it would leave) of

    log |y_b| + tau [ sum_j log(F_lim^2 - |p_j|^2) + sum_A log of the four box slacks of K_A ]

with ``tau`` cut tenfold per round; ``K_O`` is projected onto the box, ``p_A`` (hence
``K_A``) is kept strictly inside by the barrier. The gradient is exact, by the adjoint
of the steps above. (A first-order, Barzilai-Borwein ascent needed about ten times the
iterations to reach the same maxima.)
"""

import math

import numpy as np

from ._jit import jit
from .branch_bound import force_bounds
from .joint_ascent import boxed_value, strictly_inside
from .linalg import contact_solve, lu_factor, lu_solve, lu_solve_transposed

#: Barrier weights, one round each; iterations per round at most, and the rise of the
#: objective below which a round ends.
TAUS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
ITERATIONS = 200
GAIN = 1e-10
#: Step pairs the quasi-Newton (L-BFGS) direction remembers.
MEMORY = 8
#: How far inside the box a start's own-damper ``K`` is moved (fraction of the box side).
INSIDE = 1e-4
#: Beams ascended per start, in decreasing order of their force-only bound.
MAX_BEAMS = 2


@jit
def workspace(nd):
    """Scratch arrays of :func:`ascend` for ``nd`` dampers."""
    c = np.complex128
    return (np.empty((nd, nd), c), np.empty(nd, np.int64), np.empty(nd, c),
            np.empty(nd, c), np.empty(nd, c), np.empty(nd, c), np.empty(nd, c),
            np.empty(nd, c), np.empty(nd, c), np.empty(nd), np.empty(2 * nd),
            np.empty(2 * nd), np.empty(2 * nd), np.empty(2 * nd), np.empty(nd, c))


@jit
def _phi(G, q0, ylin, H, order, nA, u, F_lim, kr, ki, tau, beam, grad, ws):
    """The barrier objective at ``u`` (``p`` of ``order[:nA]``, N; ``K`` of the rest,
    N/m) and, if ``grad`` is not empty, its gradient in the scaled real coordinates
    ``(Re u, Im u) / (F_lim | kr, ki)``; ``-inf`` outside or where singular. Leaves the
    dampers' ``p``, ``q`` and ``K`` in ``ws``."""
    LU, piv, p, q, K, cp, cK, cq, r, room = ws[:10]
    nd = len(u)
    nO = nd - nA
    for a in range(nO):
        i = order[nA + a]
        for c in range(nO):
            LU[a, c] = G[i, order[nA + c]] * u[nA + c]
        LU[a, a] += 1.0
    if lu_factor(LU, piv, nO) != 0:
        return -math.inf
    for a in range(nO):
        i = order[nA + a]
        acc = q0[i]
        for m in range(nA):
            acc -= G[i, order[m]] * u[m]
        r[a] = acc
    lu_solve(LU, piv, r, nO)
    for a in range(nO):
        i = order[nA + a]
        q[i] = r[a]
        K[i] = u[nA + a]
        p[i] = K[i] * q[i]
    for m in range(nA):
        p[order[m]] = u[m]
    for m in range(nA):
        i = order[m]
        acc = q0[i]
        for j in range(nd):
            acc -= G[i, j] * p[j]
        if acc == 0:
            return -math.inf
        q[i] = acc
        K[i] = p[i] / acc
    bar = 0.0
    for j in range(nd):
        room[j] = F_lim * F_lim - (p[j].real ** 2 + p[j].imag ** 2)
        if not room[j] > 0.0:
            return -math.inf
        bar += math.log(room[j])
    for m in range(nA):
        i = order[m]
        sx = K[i].real / kr
        sy = K[i].imag / ki
        if not (0.0 < sx < 1.0 and 0.0 < sy < 1.0):
            return -math.inf
        bar += math.log(sx) + math.log(1.0 - sx) + math.log(sy) + math.log(1.0 - sy)
    y = ylin[beam]
    for j in range(nd):
        y -= H[beam, j] * p[j]
    if y == 0:
        return -math.inf
    value = math.log(abs(y)) + tau * bar
    if len(grad) == 0:
        return value
    # d value = Re(sum cp dp + sum cK dK): collect the coefficients, then eliminate the
    # dependent quantities in reverse order (K_A, q_A, p_O, q_O)
    cy = 1.0 / y
    for j in range(nd):
        cp[j] = -2.0 * tau * p[j].conjugate() / room[j] - cy * H[beam, j]
        cq[j] = 0.0
    for m in range(nA):
        i = order[m]
        sx = K[i].real / kr
        sy = K[i].imag / ki
        cK[i] = complex(tau * (1.0 / sx - 1.0 / (1.0 - sx)) / kr,
                        -tau * (1.0 / sy - 1.0 / (1.0 - sy)) / ki)
        cp[i] += cK[i] / q[i]
        cq[i] = -cK[i] * K[i] / q[i]
    for j in range(nd):
        acc = 0j
        for m in range(nA):
            acc += cq[order[m]] * G[order[m], j]
        cp[j] -= acc
    for a in range(nO):
        i = order[nA + a]
        r[a] = cp[i] * K[i]
        cK[i] = cp[i] * q[i]
    lu_solve_transposed(LU, piv, r, nO)
    for s in range(nd):
        j = order[s]
        acc = 0j
        for a in range(nO):
            acc += r[a] * G[order[nA + a], j]
        if s < nA:
            c = cp[j] - acc
            grad[s] = c.real * F_lim
            grad[nd + s] = -c.imag * F_lim
        else:
            c = cK[j] - acc * q[j]
            grad[s] = c.real * kr
            grad[nd + s] = -c.imag * ki
    return value


@jit
def _scale(s, nA, F_lim, kr, ki):
    """The scales of slot ``s``'s real and imaginary parts."""
    return (F_lim, F_lim) if s < nA else (kr, ki)


@jit
def _direction(g, x, nA, nd, Sm, Ym, rho, al, count, head, gamma, d):
    """The L-BFGS ascent direction ``d = H g`` from the ``count`` newest pairs of the
    memory (ring ending before ``head``; ``gamma``: the initial scaling), with the
    ``K_O`` coordinates held that sit on a bound of the box and would leave it; returns
    ``g . d``."""
    n = len(g)
    d[:] = g
    m = len(rho)
    for c in range(count):
        i = (head - 1 - c) % m
        acc = 0.0
        for k in range(n):
            acc += Sm[i, k] * d[k]
        al[i] = rho[i] * acc
        for k in range(n):
            d[k] -= al[i] * Ym[i, k]
    for k in range(n):
        d[k] *= gamma
    for c in range(count - 1, -1, -1):
        i = (head - 1 - c) % m
        acc = 0.0
        for k in range(n):
            acc += Ym[i, k] * d[k]
        beta = rho[i] * acc
        for k in range(n):
            d[k] += Sm[i, k] * (al[i] - beta)
    slope = 0.0
    for s in range(nA, nd):
        for c in (s, nd + s):
            if (x[c] <= 0.0 and d[c] < 0.0) or (x[c] >= 1.0 and d[c] > 0.0):
                d[c] = 0.0
    for k in range(n):
        slope += g[k] * d[k]
    return slope


@jit(nogil=True)
def ascend(G, q0, ylin, H, kr, ki, F_lim, beam, K, ws):
    """Climb ``K`` (N/m, strictly inside the box and the force limit, in place) towards
    the largest ``|y_beam|`` over the admissible set; returns False if it did not start
    inside."""
    nd = len(K)
    g, gold, x, xold, u = ws[10], ws[11], ws[12], ws[13], ws[14]
    # the beam's own dampers first, then the others
    order = np.empty(nd, np.int64)
    nA = np.int64(0)
    for j in range(nd):
        if H[beam, j] != 0:
            order[nA] = j
            nA += 1
    slot = nA
    for j in range(nd):
        if H[beam, j] == 0:
            order[slot] = j
            slot += 1
    # the start's forces, from the full solve
    q = ws[3]
    if contact_solve(G, K, q0, ws[0], ws[1], q, nd) != 0:
        return False
    for s in range(nd):
        j = order[s]
        u[s] = K[j] * q[j] if s < nA else K[j]
    empty = np.empty(0)
    if _phi(G, q0, ylin, H, order, nA, u, F_lim, kr, ki, TAUS[0], beam, empty,
            ws) == -math.inf:
        return False
    for s in range(nd):
        sr, si = _scale(s, nA, F_lim, kr, ki)
        x[s] = u[s].real / sr
        x[nd + s] = u[s].imag / si
    ut = np.empty(nd, np.complex128)
    n = 2 * nd
    Sm = np.empty((MEMORY, n))
    Ym = np.empty((MEMORY, n))
    rho = np.empty(MEMORY)
    al = np.empty(MEMORY)
    d = np.empty(n)
    for tau in TAUS:
        f = _phi(G, q0, ylin, H, order, nA, u, F_lim, kr, ki, tau, beam, g, ws)
        count = np.int64(0)
        head = np.int64(0)
        gamma = 1e-3
        for it in range(ITERATIONS):
            slope = _direction(g, x, nA, nd, Sm, Ym, rho, al, count, head, gamma, d)
            if not slope > 0.0:
                # the quasi-Newton direction does not rise: start the memory again
                count = np.int64(0)
                slope = _direction(g, x, nA, nd, Sm, Ym, rho, al, count, head, gamma, d)
                if not slope > 0.0:
                    break
            # projected step (K_O onto the box), halved until inside and rising enough
            moved = False
            step = 1.0
            for back in range(30):
                gain = 0.0
                for s in range(nd):
                    xr = x[s] + step * d[s]
                    xi = x[nd + s] + step * d[nd + s]
                    if s >= nA:
                        xr = min(max(xr, 0.0), 1.0)
                        xi = min(max(xi, 0.0), 1.0)
                    gain += g[s] * (xr - x[s]) + g[nd + s] * (xi - x[nd + s])
                    sr, si = _scale(s, nA, F_lim, kr, ki)
                    ut[s] = complex(xr * sr, xi * si)
                fn = _phi(G, q0, ylin, H, order, nA, ut, F_lim, kr, ki, tau, beam, empty,
                          ws)
                if fn >= f + 1e-4 * gain and fn > -math.inf:
                    moved = True
                    break
                step *= 0.5
            if not moved or gain <= GAIN:
                break
            xold[:] = x
            gold[:] = g
            u[:] = ut
            for s in range(nd):
                sr, si = _scale(s, nA, F_lim, kr, ki)
                x[s] = u[s].real / sr
                x[nd + s] = u[s].imag / si
            f = _phi(G, q0, ylin, H, order, nA, u, F_lim, kr, ki, tau, beam, g, ws)
            # the pair of the step for the memory (of -f: its gradient change is -dg)
            sy = 0.0
            yy = 0.0
            for i in range(n):
                Sm[head, i] = x[i] - xold[i]
                Ym[head, i] = gold[i] - g[i]
                sy += Sm[head, i] * Ym[head, i]
                yy += Ym[head, i] * Ym[head, i]
            if sy > 0.0 and yy > 0.0:
                rho[head] = 1.0 / sy
                head = (head + 1) % MEMORY
                count = min(count + 1, MEMORY)
                gamma = sy / yy
    _phi(G, q0, ylin, H, order, nA, u, F_lim, kr, ki, TAUS[-1], beam, empty, ws)
    K[:] = ws[4]
    return True


@jit(nogil=True)
def ascend_frequencies(G, q0, ylin, H, kr, ki, F_lim, K_start, floor, stop, freqs, K_out,
                       M_out):
    """:func:`ascend` from each row of ``K_start[k]`` (n_s, nd; rows with a NaN are
    skipped, others moved ``INSIDE`` into the box and scaled towards 0 until strictly
    inside the force limit), for the first ``MAX_BEAMS`` beams in decreasing order of
    their force-only bound (Eq. 10) while that is above the best ``M`` so far (at least
    ``floor[k]``, m), until one reaches ``stop[k]`` (m). The best admissible result by
    ``M`` to ``K_out[k]`` and ``M_out[k]`` (``-inf`` if none above ``floor[k]``)."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    ws = workspace(nd)
    K = np.empty(nd, np.complex128)
    Kb = np.empty(nd, np.complex128)
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    eq10 = np.empty(nb)
    for k in freqs:
        M_out[k] = -math.inf
        best = floor[k]
        force_bounds(ylin[k], H[k], F_lim, eq10)
        by_bound = np.argsort(-eq10)
        for s in range(K_start.shape[1]):
            K[:] = K_start[k, s]
            if np.isnan(K[0].real):
                continue
            if not strictly_inside(G[k], q0[k], ylin[k], H[k], K, kr, ki, F_lim, INSIDE, T,
                                   piv, q):
                continue
            for r in range(min(nb, MAX_BEAMS)):
                beam = by_bound[r]
                if eq10[beam] <= best or best >= stop[k]:
                    break
                Kb[:] = K
                if not ascend(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, beam, Kb, ws):
                    continue
                v = boxed_value(G[k], q0[k], ylin[k], H[k], Kb, kr, ki, F_lim, T, piv, q)
                if v > best:
                    best = v
                    M_out[k] = v
                    K_out[k, :] = Kb
