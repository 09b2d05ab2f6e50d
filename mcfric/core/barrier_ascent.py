"""A joint ascent of one beam's response over the admissible set, by a log barrier.

The coordinate ascent (:mod:`.joint_ascent`) moves one damper at a time; where the force
limits of several dampers are active together, every single move leaves the set and it
stops short of the maximum. Here all dampers move at once: projected gradient ascent
(Barzilai-Borwein steps with backtracking) of

    log |y_b(K)| + tau sum_j log(F_lim^2 - |K_j q_j|^2)

over the box, with ``tau`` cut tenfold per round: the iterates stay strictly inside the
force limit and approach the constrained maximum as ``tau -> 0``. Gradients are exact:
with ``A = I + G diag(K)`` and ``W = A^-1 G``, ``dq/dK_j = -W[:, j] q_j``.
"""

import math

import numpy as np

from ._jit import jit
from .branch_bound import admissible_value
from .joint_ascent import pulled_inside
from .linalg import lu_factor, lu_solve

#: Barrier weights, one round each, and iterations per round at most.
TAUS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
ITERATIONS = 60


@jit
def workspace(nd):
    """Scratch arrays of :func:`ascend` for ``nd`` dampers."""
    c = np.complex128
    return (np.empty((nd, nd), c), np.empty(nd, np.int64), np.empty(nd, c),
            np.empty((nd, nd), c), np.empty(nd, c), np.empty(2 * nd), np.empty(2 * nd),
            np.empty(2 * nd), np.empty(2 * nd), np.empty(nd, c), np.empty((nd, nd), c),
            np.empty(nd))


@jit
def _phi(G, q0, ylin, H, K, F_lim, tau, beam, grad, ws, kr, ki):
    """The barrier objective at ``K`` and, if ``grad`` is not empty, its gradient in
    ``(Re K / kr, Im K / ki)`` (``-inf`` outside the force limit or where singular)."""
    A, piv, q, W, p, _, _, _, _, col, LU, room = ws
    nd = len(K)
    for i in range(nd):
        for j in range(nd):
            A[i, j] = G[i, j] * K[j]
        A[i, i] += 1.0
    LU[:, :] = A
    if lu_factor(LU, piv, nd) != 0:
        return -math.inf
    q[:] = q0
    lu_solve(LU, piv, q, nd)
    bar = 0.0
    for i in range(nd):
        p[i] = K[i] * q[i]
        room[i] = F_lim * F_lim - (p[i].real ** 2 + p[i].imag ** 2)
        if not room[i] > 0.0:
            return -math.inf
        bar += math.log(room[i])
    y = ylin[beam]
    for i in range(nd):
        y -= H[beam, i] * p[i]
    if y == 0:
        return -math.inf
    value = math.log(abs(y)) + tau * bar
    if len(grad) == 0:
        return value
    for j in range(nd):
        for i in range(nd):
            col[i] = G[i, j]
        lu_solve(LU, piv, col, nd)
        W[:, j] = col
    for j in range(nd):
        # dp_i/dK_j = delta_ij q_j - K_i W_ij q_j; dy/dK_j = -sum_i H_bi dp_i/dK_j
        dyj = 0j
        dr = 0.0
        di = 0.0
        for i in range(nd):
            dp = -K[i] * W[i, j] * q[j]
            if i == j:
                dp += q[j]
            dyj -= H[beam, i] * dp
            cp = p[i].conjugate() * dp
            dr -= 2.0 * cp.real / room[i]
            di += 2.0 * cp.imag / room[i]
        f = dyj / y
        grad[j] = (f.real + tau * dr) * kr
        grad[nd + j] = (-f.imag + tau * di) * ki
    return value


@jit(nogil=True)
def ascend(G, q0, ylin, H, kr, ki, F_lim, beam, K, ws):
    """Climb ``K`` (N/m, strictly inside the force limit, in place) towards the largest
    ``|y_beam|`` over the admissible set; returns False if ``K`` did not start inside."""
    nd = len(K)
    g, gold, x, xold = ws[5], ws[6], ws[7], ws[8]
    Kt = np.empty(nd, np.complex128)
    empty = np.empty(0)
    for j in range(nd):
        x[j] = K[j].real / kr
        x[nd + j] = K[j].imag / ki
    if _phi(G, q0, ylin, H, K, F_lim, TAUS[0], beam, empty, ws, kr, ki) == -math.inf:
        return False
    for tau in TAUS:
        f = _phi(G, q0, ylin, H, K, F_lim, tau, beam, g, ws, kr, ki)
        step = 1e-3
        for it in range(ITERATIONS):
            # projected step, halved until inside and the objective rises enough
            moved = False
            for back in range(30):
                gain = 0.0
                for j in range(nd):
                    xr = min(max(x[j] + step * g[j], 0.0), 1.0)
                    xi = min(max(x[nd + j] + step * g[nd + j], 0.0), 1.0)
                    gain += g[j] * (xr - x[j]) + g[nd + j] * (xi - x[nd + j])
                    Kt[j] = complex(xr * kr, xi * ki)
                fn = _phi(G, q0, ylin, H, Kt, F_lim, tau, beam, empty, ws, kr, ki)
                if fn >= f + 1e-4 * gain and fn > -math.inf:
                    moved = True
                    break
                step *= 0.5
            if not moved or gain <= 1e-14:
                break
            xold[:] = x
            gold[:] = g
            K[:] = Kt
            for j in range(nd):
                x[j] = K[j].real / kr
                x[nd + j] = K[j].imag / ki
            f = _phi(G, q0, ylin, H, K, F_lim, tau, beam, g, ws, kr, ki)
            # Barzilai-Borwein step for an ascent: s.s / -(s.dg)
            ss = 0.0
            sy = 0.0
            for i in range(2 * nd):
                s = x[i] - xold[i]
                ss += s * s
                sy -= s * (g[i] - gold[i])
            step = ss / sy if sy > 0.0 else 10.0 * step
            step = min(max(step, 1e-12), 1e6)
    return True


@jit(nogil=True)
def ascend_frequencies(G, q0, ylin, H, kr, ki, F_lim, K_start, freqs, K_out, M_out):
    """:func:`ascend` from each row of ``K_start[k]`` (n_s, nd; rows with a NaN are
    skipped, others scaled towards 0 until strictly inside the force limit) for the beam
    of largest ``|y_b|`` there; the best admissible result by ``M`` to ``K_out[k]`` and
    ``M_out[k]`` (``-inf`` if none)."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    ws = workspace(nd)
    K = np.empty(nd, np.complex128)
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    for k in freqs:
        M_out[k] = -math.inf
        for s in range(K_start.shape[1]):
            K[:] = K_start[k, s]
            if np.isnan(K[0].real):
                continue
            # strictly inside the force limit: the barrier is finite there
            v, ok = pulled_inside(G[k], q0[k], ylin[k], H[k], K, F_lim, 0.999, T, piv, q)
            if not ok:
                continue
            # the beam of largest response at the start
            beam = 0
            best = -1.0
            for b in range(nb):
                y = ylin[k, b]
                for j in range(nd):
                    y -= H[k, b, j] * K[j] * q[j]
                if abs(y) > best:
                    best = abs(y)
                    beam = b
            if not ascend(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, beam, K, ws):
                continue
            v, ok = admissible_value(G[k], q0[k], ylin[k], H[k], K, F_lim, T, piv, q)
            if ok and math.isfinite(v) and v > M_out[k]:
                M_out[k] = v
                K_out[k, :] = K
