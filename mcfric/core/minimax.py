"""Gauss-Newton searches of the box minimum of ``M = max_b |y_b|``: a valley fit and minimax.

Where the lower bound is small the minimum is a deep, narrow valley in which every beam
is nearly at rest at once and several beams are equal at its bottom. The coordinate and
smoothed-gradient searches (:mod:`.coordinate_search`, :mod:`.projected_gradient`)
stall on such ridges (a dozen beams equal, one damper moved at a time). Here the outputs
``y_b(K)`` are used with their Jacobian:

* :func:`lsq_valley` fits every ``y_b`` to zero (projected Levenberg-Marquardt on
  ``sum_b |y_b|^2``): it falls into the valley from far away, and starts a coordinate
  search at every frequency;
* :func:`minimax_barrier` minimises ``max_b |y_b|^2`` itself, as ``min t`` subject to
  ``|y_b|^2 <= t`` and the box, by a log-barrier Newton method with the Gauss-Newton
  curvature ``2 Re(J_b^H J_b)`` of each ``|y_b|^2``: every beam and box face enters the
  step together, so it walks along the ridge where the others stall. It ends the
  minimum's search, from the best point found; with a force limit (each damper force
  ``p_j = K_j q_j`` another barrier) it is the lower witnesses' descent
  (:mod:`.joint_descent`).

Variables are the describing functions scaled to the unit box, ``x = (Re K_j / kr,
Im K_j / ki)`` interleaved; the Jacobian of ``y`` is ``dy_b / dK_j = -q_j (H_bj -
(H diag(K) (I + G diag(K))^-1 G)_bj)`` (``y`` is analytic in each ``K_j``).
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .linalg import (
    contact_solve,
    cyclic_factor,
    cyclic_solve,
    is_cyclic,
    lm_solve,
    lu_factor,
    lu_solve,
)


@inline_jit
def _sumsq(G, q0, ylin, H, K, T, piv, q, y, nd, nb, hr, F, cyc):
    """``sum_b |y_b|^2`` at ``K`` (fills q, y; the factors of I + G K in T, or in F for a
    ring, ``cyc``); inf if singular."""
    if cyc:
        if cyclic_factor(G, K, F, nd) != 0:
            return math.inf
        for i in range(nd):
            q[i] = q0[i]
        cyclic_solve(G, K, F, q, nd)
    elif contact_solve(G, K, q0, T, piv, q, nd) != 0:
        return math.inf
    tot = 0.0
    for b in range(nb):
        acc = ylin[b]
        for m in range(hr[b, 0], hr[b, 1]):
            acc -= H[b, m] * K[m] * q[m]
        y[b] = acc
        tot += acc.real * acc.real + acc.imag * acc.imag
    return tot if math.isfinite(tot) else math.inf


@inline_jit
def _jacobian(G, H, K, T, piv, q, kr, ki, X, col, D, nd, nb, hr, F, cyc):
    """``D[b, 2j] = dy_b / d(Re K_j / kr)``, ``D[b, 2j + 1] = dy_b / d(Im K_j / ki)``
    (complex, m), from the factors of ``I + G diag(K)`` (``T``, or ``F`` for a ring) and
    ``q`` at ``K``."""
    for j in range(nd):
        for i in range(nd):
            col[i] = G[i, j]
        if cyc:
            cyclic_solve(G, K, F, col, nd)
        else:
            lu_solve(T, piv, col, nd)
        for i in range(nd):
            X[i, j] = col[i]
    for b in range(nb):
        for j in range(nd):
            acc = 0.0j
            for m in range(hr[b, 0], hr[b, 1]):
                acc += H[b, m] * K[m] * X[m, j]
            c = -q[j] * (H[b, j] - acc)
            D[b, 2 * j] = c * kr
            D[b, 2 * j + 1] = complex(-c.imag * ki, c.real * ki)


@jit
def lsq_valley(G, q0, ylin, H, kr, ki, K, w, n_iter=40):
    """Projected Levenberg-Marquardt on ``sum_b |y_b|^2`` from ``K`` (in place).

    The box minimum of M can be a deep, narrow valley where all beams are nearly at rest
    at once; coordinate and max-smoothed searches rarely fall into it, a least-squares
    fit of every ``y_b`` to zero does (its minimiser starts the minimax search). Returns
    the sum of squares at the final ``K``, m^2 (inf if singular).
    """
    T, piv, q, y = w[1], w[2], w[3], w[4]
    nd = K.shape[0]
    # a ring: O(nd) eliminations instead of dense LU (the values reported are
    # recomputed by pivoted LU, as for the chain's)
    cyc = is_cyclic(G, nd)
    F = np.empty((4, nd), dtype=np.complex128)
    nb = ylin.shape[0]
    n = 2 * nd
    X = np.empty((nd, nd), dtype=np.complex128)
    D = np.empty((nb, n), dtype=np.complex128)
    N = np.empty((n, n))
    N0 = np.empty((n, n))
    col = np.empty(nd, dtype=np.complex128)
    g = np.empty(n)
    d = np.empty(n)
    rpiv = np.empty(n, dtype=np.int64)
    Kt = np.empty(nd, dtype=np.complex128)
    hr = w[12]
    phi = _sumsq(G, q0, ylin, H, K, T, piv, q, y, nd, nb, hr, F, cyc)
    if not math.isfinite(phi):
        return math.inf
    # the damping in the units of A^T A (m^2, like phi): an absolute lam (responses
    # ~1e-6 m) made the first ~15 steps plain gradient steps of negligible length
    lam_unit = phi
    lam = 1e-3 * lam_unit
    for it in range(n_iter):
        _jacobian(G, H, K, T, piv, q, kr, ki, X, col, D, nd, nb, hr, F, cyc)
        # the real normal equations: A^T A = Re(D^H D), A^T r = Re(D^H y)
        for i in range(n):
            acc = 0.0
            for b in range(nb):
                acc += D[b, i].real * y[b].real + D[b, i].imag * y[b].imag
            g[i] = acc
        # A^T A once per iteration (symmetric): only the damping changes between tries
        for i in range(n):
            for j in range(i + 1):
                acc = 0.0
                for b in range(nb):
                    acc += D[b, i].real * D[b, j].real + D[b, i].imag * D[b, j].imag
                N0[i, j] = acc
                N0[j, i] = acc
        improved = False
        for _ in range(12):
            N[:, :] = N0
            if lm_solve(N, g, lam, rpiv, d, n) != 0:
                lam *= 10.0
                continue
            for j in range(nd):
                re = min(max(K[j].real + d[2 * j] * kr, 0.0), kr)
                im = min(max(K[j].imag + d[2 * j + 1] * ki, 0.0), ki)
                Kt[j] = complex(re, im)
            phit = _sumsq(G, q0, ylin, H, Kt, T, piv, q, y, nd, nb, hr, F, cyc)
            if phit < phi:
                improved = True
                break
            lam *= 4.0
        if not improved:
            break
        for j in range(nd):
            K[j] = Kt[j]
        conv = phi - phit <= 1e-12 * phi
        phi = phit
        lam = max(lam / 3.0, 1e-12 * lam_unit)
        if conv:
            break
    return phi


#: Barrier weights of :func:`minimax_barrier` (in units of the starting ``M^2``): the
#: first, the last, and the factor between stages; a stage ends when the Newton decrement
#: falls below ``_BARRIER_DECREMENT`` times the weight. Chosen by measurement against
#: reference searches (the docs' performance page, "Measured design choices").
_BARRIER_MU = 1e-2
_BARRIER_MU_END = 1e-9
_BARRIER_SHRINK = 0.02
_BARRIER_DECREMENT = 0.1
_BARRIER_STEPS = 200
#: Distance from the box faces of the barrier's start (normalised box units).
_BARRIER_INSET = 1e-6


@inline_jit
def _barrier_value(t, ph, x, mu, nb, n):
    """``t - mu (sum log(t - phi_b) + sum log x_i + sum log(1 - x_i))``; inf outside."""
    acc = 0.0
    for b in range(nb):
        c = t - ph[b]
        if not (c > 0.0):
            return math.inf
        acc += math.log(c)
    for i in range(n):
        if not (0.0 < x[i] < 1.0):
            return math.inf
        acc += math.log(x[i]) + math.log(1.0 - x[i])
    return t - mu * acc


@inline_jit
def _scaled_phi(G, q0, ylin, H, x, Kt, T, piv, q, y, ph, s, kr, ki, nd, nb, hr, F, cyc):
    """``ph_b = |y_b|^2 / s`` at the scaled point ``x`` (``Kt`` its describing functions);
    returns ``max_b ph_b`` (inf if singular)."""
    for j in range(nd):
        Kt[j] = complex(x[2 * j] * kr, x[2 * j + 1] * ki)
    if not math.isfinite(_sumsq(G, q0, ylin, H, Kt, T, piv, q, y, nd, nb, hr, F, cyc)):
        return math.inf
    m = 0.0
    for b in range(nb):
        ph[b] = (y[b].real * y[b].real + y[b].imag * y[b].imag) / s
        m = max(m, ph[b])
    return m


@inline_jit
def _force_barrier(Kt, q, F2, pf, mu, nd):
    """``pf_j = |K_j q_j|^2 / F_lim^2`` into ``pf`` and the force limit's barrier term
    ``-mu sum_j log(1 - pf_j)`` (inf outside the limit)."""
    acc = 0.0
    for j in range(nd):
        p = Kt[j] * q[j]
        pf[j] = (p.real * p.real + p.imag * p.imag) / F2
        if not (pf[j] < 1.0):
            return math.inf
        acc += math.log(1.0 - pf[j])
    return -mu * acc


@jit
def minimax_barrier(G, q0, ylin, H, kr, ki, F_lim, K, w):
    """Minimise ``M = max_b |y_b|`` over the box, and the force limit if ``F_lim`` is
    finite, from ``K`` by a log-barrier method.

    ``min t`` subject to ``t >= |y_b|^2 / s`` (``s``: the starting ``M^2``), ``0 < x <
    1`` and ``|K_j q_j| < F_lim``: Newton steps on ``t - mu (sum_b log(t - |y_b|^2 / s)
    + sum_i log x_i (1 - x_i) + sum_j log(1 - |K_j q_j|^2 / F_lim^2))`` with the
    Gauss-Newton curvature of each ``|y_b|^2`` and ``|K_j q_j|^2``, a backtracking line
    search on the true outputs, and ``mu`` reduced in stages (``_BARRIER_MU`` ...
    ``_BARRIER_MU_END``). The best point met (by M itself) is kept. With a force limit
    ``K`` must start strictly inside it (else nothing moves).

    Returns M at the point left in ``K`` (m): never above the starting M, which it
    returns with ``K`` unchanged if nothing better was met; NaN if singular.
    """
    T, piv, q, y = w[1], w[2], w[3], w[4]
    hr = w[12]
    nd = K.shape[0]
    # a ring: O(nd) eliminations instead of dense LU (the values reported are
    # recomputed by pivoted LU, as for the chain's)
    cyc = is_cyclic(G, nd)
    F = np.empty((4, nd), dtype=np.complex128)
    nb = ylin.shape[0]
    n = 2 * nd
    x = np.empty(n)
    xt = np.empty(n)
    x_best = np.empty(n)
    Kt = np.empty(nd, dtype=np.complex128)
    ph = np.empty(nb)
    pht = np.empty(nb)
    c = np.empty(nb)
    gphi = np.empty((nb, n))
    X = np.empty((nd, nd), dtype=np.complex128)
    col = np.empty(nd, dtype=np.complex128)
    D = np.empty((nb, n), dtype=np.complex128)
    # D's parts as contiguous real rows: the curvature's inner loop vectorises on them
    Dre = np.empty(n)
    Dim = np.empty(n)
    Hm = np.empty((n + 1, n + 1))
    step = np.empty(n + 1)
    grad = np.empty(n + 1)
    spiv = np.empty(n + 1, dtype=np.int64)
    force = math.isfinite(F_lim)
    F2 = F_lim * F_lim
    pf = np.empty(nd)
    pft = np.empty(nd)
    gpf = np.empty((nd, n))
    P = np.empty((nd, n), dtype=np.complex128)
    phi0 = _sumsq(G, q0, ylin, H, K, T, piv, q, y, nd, nb, hr, F, cyc)
    if not math.isfinite(phi0):
        return math.nan
    s = 0.0
    for b in range(nb):
        s = max(s, y[b].real * y[b].real + y[b].imag * y[b].imag)
    if not (s > 0.0):
        return 0.0                  # every beam at rest: nothing lower
    m_start = math.sqrt(s)
    for j in range(nd):
        x[2 * j] = min(max(K[j].real / kr, _BARRIER_INSET), 1.0 - _BARRIER_INSET)
        x[2 * j + 1] = min(max(K[j].imag / ki, _BARRIER_INSET), 1.0 - _BARRIER_INSET)
    m = _scaled_phi(G, q0, ylin, H, x, Kt, T, piv, q, y, ph, s, kr, ki, nd, nb, hr, F,
                        cyc)
    if not math.isfinite(m):
        return m_start
    if force and not math.isfinite(_force_barrier(Kt, q, F2, pf, _BARRIER_MU, nd)):
        return m_start
    t = 1.01 * m + 1e-3
    best = 1.0                      # the start, in units of s
    found = False
    mu = _BARRIER_MU
    steps = 0
    while mu >= _BARRIER_MU_END * (1.0 - 1e-9) and steps < _BARRIER_STEPS:
        while steps < _BARRIER_STEPS:
            steps += 1
            # T, q, y, ph are at x (the last evaluation was the accepted one)
            _jacobian(G, H, Kt, T, piv, q, kr, ki, X, col, D, nd, nb, hr, F, cyc)
            for i in range(n + 1):
                grad[i] = 0.0
                for k in range(n + 1):
                    Hm[i, k] = 0.0
            for b in range(nb):
                c[b] = t - ph[b]
                ib = 1.0 / c[b]
                for i in range(n):
                    # d|y_b|^2 / dx_i = 2 Re(conj(y_b) D_bi)
                    gphi[b, i] = 2.0 * (y[b].real * D[b, i].real +
                                        y[b].imag * D[b, i].imag) / s
                    grad[i] += mu * gphi[b, i] * ib
                grad[n] -= mu * ib
                # mu (dc dc^T / c^2 + GN curvature / c), dc = (-grad phi_b, 1)
                ib2 = mu * ib * ib
                gn = 2.0 * mu * ib / s
                gb = gphi[b]
                for i in range(n):
                    Dre[i] = D[b, i].real
                    Dim[i] = D[b, i].imag
                for i in range(n):
                    a = ib2 * gb[i]
                    dr = Dre[i]
                    di = Dim[i]
                    row = Hm[i]
                    for k in range(i + 1):
                        row[k] += a * gb[k] + gn * (dr * Dre[k] + di * Dim[k])
                    Hm[n, i] -= a
                Hm[n, n] += ib2
            if force:
                # the force limits: like the beams' rows, without t
                for j in range(nd):
                    for i in range(nd):
                        dp = -Kt[j] * X[j, i] * q[i]
                        if i == j:
                            dp += q[j]
                        P[j, 2 * i] = dp * kr
                        P[j, 2 * i + 1] = complex(-dp.imag * ki, dp.real * ki)
                    p = Kt[j] * q[j]
                    cj = 1.0 - pf[j]
                    ib = 1.0 / cj
                    for i in range(n):
                        gpf[j, i] = 2.0 * (p.real * P[j, i].real + p.imag * P[j, i].imag) / F2
                        grad[i] += mu * gpf[j, i] * ib
                    ib2 = mu * ib * ib
                    gn = 2.0 * mu * ib / F2
                    for i in range(n):
                        a = ib2 * gpf[j, i]
                        row = Hm[i]
                        for k in range(i + 1):
                            row[k] += a * gpf[j, k] + gn * (P[j, i].real * P[j, k].real +
                                                            P[j, i].imag * P[j, k].imag)
            grad[n] += 1.0
            for i in range(n):
                grad[i] -= mu * (1.0 / x[i] - 1.0 / (1.0 - x[i]))
                Hm[i, i] += mu * (1.0 / (x[i] * x[i]) + 1.0 / ((1.0 - x[i]) * (1.0 - x[i])))
            for i in range(n + 1):
                for k in range(i):
                    Hm[k, i] = Hm[i, k]
                step[i] = -grad[i]
            if lu_factor(Hm, spiv, n + 1) != 0:
                steps = _BARRIER_STEPS
                break
            lu_solve(Hm, spiv, step, n + 1)
            dec = 0.0
            for i in range(n + 1):
                dec -= grad[i] * step[i]
            if not (dec >= _BARRIER_DECREMENT * mu):
                break               # centred enough: next stage
            f0 = _barrier_value(t, ph, x, mu, nb, n)
            if force:
                f0 += _force_barrier(Kt, q, F2, pf, mu, nd)
            lam = 1.0
            ok = False
            for _ in range(40):
                for i in range(n):
                    xt[i] = x[i] + lam * step[i]
                tt = t + lam * step[n]
                inside = True
                for i in range(n):
                    if not (0.0 < xt[i] < 1.0):
                        inside = False
                        break
                if inside:
                    mt = _scaled_phi(G, q0, ylin, H, xt, Kt, T, piv, q, y, pht, s, kr, ki,
                                     nd, nb, hr, F, cyc)
                    ft = _barrier_value(tt, pht, xt, mu, nb, n)
                    if force and math.isfinite(mt):
                        ft += _force_barrier(Kt, q, F2, pft, mu, nd)
                    if math.isfinite(mt) and ft <= f0 - 1e-4 * lam * dec:
                        ok = True
                        break
                lam *= 0.5
            if not ok:
                # T, q, y belong to a rejected trial: restore them at x
                _scaled_phi(G, q0, ylin, H, x, Kt, T, piv, q, y, ph, s, kr, ki, nd, nb, hr, F,
                        cyc)
                break
            for i in range(n):
                x[i] = xt[i]
            for b in range(nb):
                ph[b] = pht[b]
            if force:
                for j in range(nd):
                    pf[j] = pft[j]
            t = tt
            if mt < best:
                best = mt
                found = True
                for i in range(n):
                    x_best[i] = x[i]
        mu *= _BARRIER_SHRINK
    if not found:
        return m_start
    for j in range(nd):
        K[j] = complex(x_best[2 * j] * kr, x_best[2 * j + 1] * ki)
    return math.sqrt(best * s)
