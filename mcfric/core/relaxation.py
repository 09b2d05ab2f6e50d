"""A semidefinite relaxation of the admissible set: certificates from quadratic forms.

With ``z = (p, 1)``, ``p`` the damper forces, every constraint of the admissible set is a
quadratic form ``u^H S u <= 0`` in two linear functionals ``u = (v_a^H z, v_b^H z)``:
``q_j = w_j^T z`` and ``p_j``: ``a |q_j|^2 <= Re(conj(q_j) p_j) <= b |q_j|^2`` and the same
for ``Im`` (the rectangle), a disc holding it, and ``|p_j|^2 <= F_lim^2``. Writing
``A_i = V_i S_i V_i^H``, any ``theta >= 0`` and ``t`` with

    Z = t E - Y_b + sum_i theta_i A_i  >= 0     (E = e e^H, e the last unit vector)

prove ``|y_b|^2 <= t`` on the set: ``0 <= z^H Z z = t - |y_b|^2 + sum theta_i z^H A_i z``
and every ``z^H A_i z <= 0``. For the minimum, ``Z = sum lambda_b Y_b - s E + sum theta_i
A_i >= 0`` with ``lambda`` on the simplex proves ``max_b |y_b|^2 >= s``. The best such
multipliers solve a small semidefinite program; :func:`solve` finds them with a
log-det barrier (Newton steps with a backtracking line search, the barrier weight
shrunk tenfold per round). Whatever the solver reaches, only a *verified* point is
returned: ``Z`` is assembled in floating point beside a bound on its rounding, and a
Cholesky factorisation of ``Z - delta I`` must succeed, ``delta`` covering both the
assembly's and the factorisation's rounding (:func:`verified`).

The forms are exact: scalings are powers of two and the disc's radius is rounded up,
so rounding only enters through ``Z``.
"""

import math

import numpy as np

from ._jit import jit
from .linalg import ridge_solve

#: Relative accuracy at which :func:`solve` stops (in ``t``, a squared response).
TOL = 1e-3
#: Newton steps per barrier weight and in all at most.
STEPS_PER_ROUND = 40
MAX_STEPS = 160
#: Newton decrement below which a barrier weight counts as centred.
CENTRED = 1.0
#: Barrier weight factor per round.
MU_FACTOR = 0.1
#: A part's relaxation starts from its parent's last iterate whose barrier weight was at
#: least this fraction of the shift variable (``mu nu / |x_shift|``; a cold start is at
#: 1): later iterates lie too near the parent's boundary to start from.
WARM_RATIO = 0.05
#: Safety factors over the rounding bounds of the assembly (gamma_k |V| |C| |V|^T, k <=
#: ~100 operations: ~1e-14) and of the Cholesky test (Rump: (n + 1) u tr Z).
ASSEMBLY_MARGIN = 1e-12
CHOLESKY_MARGIN = 1e-11
#: Leading eigenvectors of the primal point combined, and random combinations tried, by
#: :func:`rounded` (a mixture of maximisers is not rank one).
PURIFY_RANK = 3
PURIFY_SAMPLES = 256


@jit
def _pow2(x):
    """The power of two nearest above ``x > 0`` (exact scalings)."""
    m, e = math.frexp(x)
    return math.ldexp(1.0, e)


@jit
def _sparse_product(V, C, T):
    """``T = V C`` over the nonzeros of ``C`` (a few per damper): complex, or the same
    sums in absolute values for the rounding bound."""
    nn, nv = V.shape
    T[:, :] = 0.0
    for b in range(nv):
        for a in range(nv):
            cab = C[a, b]
            if cab == 0:
                continue
            for j in range(nn):
                T[j, b] += V[j, a] * cab


@jit
def scatter(x, coef_const, V, idx, S, C, T, m):
    """``C = sum_i x_i S_i`` (+ the constant form, weight ``coef_const``) scattered on
    the basis, and ``T = V C``."""
    C[:, :] = 0.0
    for i in range(m + 1):
        w = x[i] if i < m else coef_const
        for a in range(2):
            for b in range(2):
                C[idx[i, a], idx[i, b]] += w * S[i, a, b]
    _sparse_product(V, C, T)


@jit
def _assemble(x, coef_const, V, idx, S, C, T, Z, m):
    """``Z = V C V^H`` with ``C`` and ``T = V C`` from :func:`scatter`."""
    nn, nv = V.shape
    scatter(x, coef_const, V, idx, S, C, T, m)
    for j in range(nn):
        for k in range(j, nn):
            Z[j, k] = 0j
    # the same sums in the same order, without the zero terms of V (most: a damper's p
    # is a unit vector, and on a ring a q or y touches two or three dampers)
    for b in range(nv):
        for k in range(nn):
            vkb = V[k, b].conjugate()
            if vkb == 0:
                continue
            for j in range(k + 1):
                Z[j, k] += T[j, b] * vkb
    for j in range(nn):
        Z[j, j] = Z[j, j].real
        for k in range(j + 1, nn):
            Z[k, j] = Z[j, k].conjugate()


@jit
def cholesky(Z, L, nn):
    """Lower Cholesky factor of Hermitian ``Z`` into ``L``; ``log det Z``, or ``nan``
    where a pivot is not positive (not positive definite)."""
    logdet = 0.0
    for j in range(nn):
        d = Z[j, j].real
        for k in range(j):
            d -= L[j, k].real ** 2 + L[j, k].imag ** 2
        if not d > 0.0:
            return np.nan
        d = math.sqrt(d)
        L[j, j] = d
        logdet += 2.0 * math.log(d)
        for i in range(j + 1, nn):
            acc = Z[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k].conjugate()
            L[i, j] = acc / d
    return logdet


@jit
def _inverse(L, Zi, W, nn):
    """``Zi = (L L^H)^-1`` (``W``: scratch, ``L^-1``)."""
    for c in range(nn):
        for i in range(nn):
            acc = 1.0 + 0j if i == c else 0j
            for k in range(c, i):
                acc -= L[i, k] * W[k, c]
            W[i, c] = acc / L[i, i].real if i >= c else 0j
    for i in range(nn):
        for j in range(i, nn):
            acc = 0j
            for k in range(j, nn):
                acc += W[k, i].conjugate() * W[k, j]
            Zi[i, j] = acc
            Zi[j, i] = acc.conjugate()


@jit
def _barrier(x, mu, cvec, pos, simplex, m):
    """The linear part of the barrier: ``c.x / mu - sum log x_pos - log(1 - sum
    x_simplex)``; ``inf`` outside."""
    f = 0.0
    ssum = 0.0
    for i in range(m):
        f += cvec[i] * x[i] / mu
        if pos[i]:
            if not x[i] > 0.0:
                return np.inf
            f -= math.log(x[i])
        if simplex[i]:
            ssum += x[i]
    if simplex.any():
        if not ssum < 1.0:
            return np.inf
        f -= math.log(1.0 - ssum)
    return f


@jit
def verified(x, V, idx, S, m, pos, simplex, ws):
    """Whether ``Z(x)`` is proved positive semidefinite (and ``x`` in its cone): the
    rounding of the assembly is bounded by ``|V| |C| |V|^T`` entrywise and that of the
    Cholesky test by ``tr Z``; the test factorises ``Z - delta I`` with ``delta`` above
    both, by the margins."""
    C, T, Z, L, Zi, W, Q, Hm, g, dx, xn, Cabs, Vabs, Zabs, Lh, yv, P, R, Tabs, xb = ws
    nn = V.shape[0]
    ssum = 0.0
    for i in range(m):
        if pos[i] and not x[i] >= 0.0:
            return False
        if simplex[i]:
            ssum += x[i]
    if simplex.any() and not ssum <= 1.0 - 1e-12:
        return False
    _assemble(x, 1.0, V, idx, S, C, T, Z, m)
    # the same sums in absolute values: a bound on every entry's rounding
    for j in range(nn):
        for a in range(V.shape[1]):
            Vabs[j, a] = abs(V[j, a])
    for i in range(m + 1):
        w = abs(x[i]) if i < m else 1.0
        for a in range(2):
            for b in range(2):
                Cabs[idx[i, a], idx[i, b]] += w * abs(S[i, a, b])
    nv = V.shape[1]
    _sparse_product(Vabs, Cabs, Tabs)
    Zabs[:, :] = 0.0
    for b in range(nv):
        for k in range(nn):
            vkb = Vabs[k, b]
            if vkb == 0.0:
                continue
            for j in range(nn):
                Zabs[j, k] += Tabs[j, b] * vkb
    frob = math.sqrt((Zabs ** 2).sum())
    trace = 0.0
    for j in range(nn):
        trace += abs(Z[j, j].real)
    delta = ASSEMBLY_MARGIN * frob + CHOLESKY_MARGIN * trace + 1e-300
    Cabs[:, :] = 0.0
    for j in range(nn):
        Z[j, j] = Z[j, j].real - delta
    return not np.isnan(cholesky(Z, L, nn))


@jit
def workspace(nn, nv, m):
    """Scratch arrays of :func:`solve` for ``Z`` of order ``nn``, ``nv`` basis vectors and
    ``m`` multipliers."""
    c = np.complex128
    return (np.zeros((nv, nv), c), np.empty((nn, nv), c), np.empty((nn, nn), c),
            np.zeros((nn, nn), c), np.empty((nn, nn), c), np.empty((nn, nn), c),
            np.empty((nv, nv), c), np.empty((m, m)), np.empty(m), np.empty(m),
            np.empty(m), np.zeros((nv, nv)), np.empty((nn, nv)), np.empty((nn, nn)),
            np.zeros((m, m)), np.empty(m), np.empty((m, 2, 2), c), np.empty((m, 2, 2), c),
            np.empty((nn, nv)), np.empty(m))


@jit
def buffers(nd, nb, force, lower):
    """The arrays :func:`forms` fills and :func:`solve` works in, for ``nd`` dampers and
    ``nb`` beams: ``(V, idx, S, x, cvec, pos, simplex, grow, ws)``."""
    nn = nd + 1
    nv = 2 * nd + 1 + nb
    m = n_forms(nd, nb, force, lower)
    return (np.empty((nn, nv), np.complex128), np.empty((m + 1, 2), np.int64),
            np.empty((m + 1, 2, 2), np.complex128), np.empty(m), np.empty(m),
            np.empty(m, np.bool_), np.empty(m, np.bool_), np.empty(m, np.bool_),
            workspace(nn, nv, m))


@jit
def _newton(x, mu, V, idx, S, gstart, cvec, pos, simplex, m, ws):
    """The barrier's Newton direction at ``x`` (into ``dx``, from ``ws``); returns the
    decrement squared (``-1`` if the system could not be solved) and the barrier's
    value."""
    C, T, Z, L, Zi, W, Q, Hm, g, dx, xn, Cabs, Vabs, Zabs, Lh, yv, P, R, Tabs, xb = ws
    nn, nv = V.shape
    _assemble(x, 1.0, V, idx, S, C, T, Z, m)
    logdet = cholesky(Z, L, nn)
    if np.isnan(logdet):
        return -1.0, np.inf
    f = _barrier(x, mu, cvec, pos, simplex, m) - logdet
    _inverse(L, Zi, W, nn)
    # Q = V^H Zi V: every trace below is a product of its 2 x 2 blocks
    for j in range(nn):
        for b in range(nv):
            acc = 0j
            for k in range(nn):
                acc += Zi[j, k] * V[k, b]
            T[j, b] = acc
    for a in range(nv):
        for b in range(a, nv):
            acc = 0j
            for j in range(nn):
                acc += V[j, a].conjugate() * T[j, b]
            Q[a, b] = acc
            Q[b, a] = acc.conjugate()
    ssum = 0.0
    for i in range(m):
        if simplex[i]:
            ssum += x[i]
    sgap = 1.0 - ssum
    for i in range(m):
        ia, ib = idx[i, 0], idx[i, 1]
        # d(-log det Z)/dx_i = -tr(Zi A_i) = -sum_ab S_ab Q_ba
        tr = (S[i, 0, 0] * Q[ia, ia] + S[i, 0, 1] * Q[ib, ia]
              + S[i, 1, 0] * Q[ia, ib] + S[i, 1, 1] * Q[ib, ib])
        gi = cvec[i] / mu - tr.real
        if pos[i]:
            gi -= 1.0 / x[i]
        if simplex[i]:
            gi += 1.0 / sgap
        g[i] = gi
    # tr(Zi A_i Zi A_l) = tr(S_i Q[I_i, I_l] S_l Q[I_l, I_i]); forms in a group share
    # their basis pair, so the 2 x 2 products are formed once per group pair
    ng = len(gstart) - 1
    for gg in range(ng):
        i0, i1 = gstart[gg], gstart[gg + 1]
        ga, gb = idx[i0, 0], idx[i0, 1]
        for hh in range(gg, ng):
            l0, l1 = gstart[hh], gstart[hh + 1]
            ha, hb = idx[l0, 0], idx[l0, 1]
            q00, q01, q10, q11 = Q[ga, ha], Q[ga, hb], Q[gb, ha], Q[gb, hb]
            for i in range(i0, i1):
                P[i, 0, 0] = S[i, 0, 0] * q00 + S[i, 0, 1] * q10
                P[i, 0, 1] = S[i, 0, 0] * q01 + S[i, 0, 1] * q11
                P[i, 1, 0] = S[i, 1, 0] * q00 + S[i, 1, 1] * q10
                P[i, 1, 1] = S[i, 1, 0] * q01 + S[i, 1, 1] * q11
            # Q[I_l, I_i] is the conjugate transpose of Q[I_i, I_l]
            r00, r01, r10, r11 = q00.conjugate(), q10.conjugate(), q01.conjugate(), \
                q11.conjugate()
            for l in range(l0, l1):
                R[l, 0, 0] = S[l, 0, 0] * r00 + S[l, 0, 1] * r10
                R[l, 0, 1] = S[l, 0, 0] * r01 + S[l, 0, 1] * r11
                R[l, 1, 0] = S[l, 1, 0] * r00 + S[l, 1, 1] * r10
                R[l, 1, 1] = S[l, 1, 0] * r01 + S[l, 1, 1] * r11
            for i in range(i0, i1):
                for l in range(max(l0, i), l1):
                    h = (P[i, 0, 0] * R[l, 0, 0] + P[i, 0, 1] * R[l, 1, 0]
                         + P[i, 1, 0] * R[l, 0, 1] + P[i, 1, 1] * R[l, 1, 1]).real
                    if i == l and pos[i]:
                        h += 1.0 / x[i] ** 2
                    if simplex[i] and simplex[l]:
                        h += 1.0 / sgap ** 2
                    Hm[i, l] = h
                    Hm[l, i] = h
    # dx = -Hm^-1 g (a growing ridge where rounding makes Hm indefinite)
    for i in range(m):
        yv[i] = -g[i]
    if not ridge_solve(Hm, Lh, yv, dx, m, 1e-12, 100.0, np.int64(8)):
        return -1.0, f
    lam2 = 0.0
    for i in range(m):
        lam2 -= g[i] * dx[i]
    return lam2, f


@jit
def _value(x, mu, V, idx, S, cvec, pos, simplex, m, ws):
    """The barrier ``c.x / mu - log det Z - sum log(cone)`` at ``x`` (``inf`` outside)."""
    C, T, Z, L = ws[0], ws[1], ws[2], ws[3]
    f = _barrier(x, mu, cvec, pos, simplex, m)
    if not np.isfinite(f):
        return np.inf
    _assemble(x, 1.0, V, idx, S, C, T, Z, m)
    logdet = cholesky(Z, L, V.shape[0])
    if np.isnan(logdet):
        return np.inf
    return f - logdet


@jit
def solve(x, shift, V, idx, S, cvec, pos, simplex, grow, target, ws, stats, warm, save):
    """Improve the multipliers ``x`` (in place) and return the best *verified* value of
    the shift variable ``x[shift]`` (``nan`` if none verified; where no round's iterate
    verifies, the first iterate that reached ``target`` and then the last one shifted
    are tried, see :func:`_rescued`).

    Parameters
    ----------
    x : ndarray, shape (m,)
        Start; unless ``warm``, the ``grow`` entries are doubled until the leading block
        of ``Z`` is positive definite, then ``x[shift]`` is set to make ``Z`` so.
    shift : int
        The variable on ``E`` (``t`` with ``S = +1``, ``s`` with ``S = -1``).
    V, idx, S
        Basis vectors (columns), each form's two basis indices and 2 x 2 matrix; form
        ``m`` (the last) is the constant one.
    cvec : ndarray, shape (m,)
        Minimised objective (``+1`` or ``-1`` on ``shift``).
    pos, simplex, grow : ndarray of bool
        Multipliers kept positive, kept with a sum below 1, grown at the start.
    target : float
        Stop once the verified objective ``cvec[shift] x[shift]`` is at or below this.
    stats : ndarray of int64, shape (2,)
        Newton steps and barrier rounds are added to it.
    warm : float
        ``0``: a cold start as above. Otherwise ``x`` is strictly feasible (``Z``
        positive definite, the cone's interior) and the barrier starts at the weight
        ``warm |x_shift| / nu``.
    save : ndarray, shape (m + 1,)
        Receives the last iterate whose weight ratio ``mu nu / |x_shift|`` was at least
        :data:`WARM_RATIO` (the first one if none was), and that ratio last: a start
        for a neighbour.
    """
    C, T, Z, L, Zi, W, Q, Hm, g, dx, xn, Cabs, Vabs, Zabs, Lh, yv, P, R, Tabs, xb = ws
    nn, nv = V.shape
    m = len(x)
    sgn = S[shift, 0, 0].real
    # groups: runs of forms on the same basis pair
    gstart = np.empty(m + 1, np.int64)
    ng = 0
    for i in range(m):
        if i == 0 or idx[i, 0] != idx[i - 1, 0] or idx[i, 1] != idx[i - 1, 1]:
            gstart[ng] = i
            ng += 1
    gstart[ng] = m
    gstart = gstart[:ng + 1]
    nu = float(nn)
    for i in range(m):
        if pos[i]:
            nu += 1.0
    if simplex.any():
        nu += 1.0
    if warm > 0.0:
        val = _rounds(x, shift, warm * max(abs(x[shift]), 1e-300) / nu, nu, V, idx, S,
                      gstart, cvec, pos, simplex, target, ws, stats, save)
        return _rescued(val, x, shift, V, idx, S, cvec, pos, simplex, ws)
    # start: the leading block positive definite, then the shift from its Schur complement
    x[shift] = 0.0
    found = False
    for attempt in range(200):
        _assemble(x, 1.0, V, idx, S, C, T, Z, m)
        if not np.isnan(cholesky(Z, L, nn - 1)):
            found = True
            break
        for i in range(m):
            if grow[i]:
                x[i] *= 2.0
    if not found:
        return np.nan
    r = _schur(Z, L, W, nn)
    # sgn x_shift + r > 0, with a margin
    x[shift] = (1.0 + abs(r) - r) / sgn
    val = _rounds(x, shift, max(abs(x[shift]), 1e-300) / nu, nu, V, idx, S, gstart, cvec,
                  pos, simplex, target, ws, stats, save)
    return _rescued(val, x, shift, V, idx, S, cvec, pos, simplex, ws)


@jit
def _rescued(val, x, shift, V, idx, S, cvec, pos, simplex, ws):
    """``val``, or where no iterate verified (``nan``) the last one's multipliers with the
    shift set just past the least value that makes ``Z`` definite (:func:`shifted`, with
    its wider margins; ``nan`` if that fails too). Where a part holds no admissible
    point, the barrier runs its multipliers off towards ``t -> -inf`` (the minimum's
    ``s -> +inf``) until its Newton system fails, and no round verifies at those scales;
    the shifted point often does: a valid bound, and for the maximum with ``t < 0`` a
    proof that the part is empty.
    """
    if not np.isnan(val):
        return val
    last = x[shift]
    v = shifted(x, shift, V, idx, S, pos, simplex, ws)
    if np.isnan(v):
        x[shift] = last             # the last iterate as it was, for rounded()
        return np.nan
    return cvec[shift] * x[shift]


@jit
def _rounds(x, shift, mu, nu, V, idx, S, gstart, cvec, pos, simplex, target, ws, stats,
            save):
    """The barrier rounds of :func:`solve` from the strictly feasible ``x``, the weight
    ``mu`` cut by :data:`MU_FACTOR` per round (``nu``: the barrier's parameter)."""
    dx, xn, xb = ws[9], ws[10], ws[19]
    m = len(x)
    best = np.nan
    steps = 0
    # the first iterate at the target: where no round verifies, it is tried last
    xc = np.empty(m)
    kept = False
    save[m] = np.nan
    while steps < MAX_STEPS:
        for inner in range(STEPS_PER_ROUND):
            lam2, f0 = _newton(x, mu, V, idx, S, gstart, cvec, pos, simplex, m, ws)
            steps += 1
            stats[0] += 1
            if lam2 < 0.0:
                steps = MAX_STEPS
                break
            step = 1.0
            moved = False
            for back in range(40):
                for i in range(m):
                    xn[i] = x[i] + step * dx[i]
                if _value(xn, mu, V, idx, S, cvec, pos, simplex, m, ws) <= f0 - 0.25 * step * lam2:
                    moved = True
                    break
                step *= 0.5
            if moved:
                x[:] = xn
                if not kept and cvec[shift] * x[shift] <= target:
                    xc[:] = x
                    kept = True
            if not moved or lam2 < CENTRED ** 2 or steps >= MAX_STEPS:
                break
        stats[1] += 1
        ratio = mu * nu / max(abs(x[shift]), 1e-300)
        if ratio >= WARM_RATIO or np.isnan(save[m]):
            save[:m] = x
            save[m] = ratio
        if verified(x, V, idx, S, m, pos, simplex, ws):
            val = cvec[shift] * x[shift]
            if np.isnan(best) or val < best:
                best = val
                xb[:] = x
            if best <= target:
                break
        if mu * nu <= TOL * abs(x[shift]):
            break
        mu *= MU_FACTOR
    if np.isnan(best) and kept and verified(xc, V, idx, S, m, pos, simplex, ws):
        # an empty part's multipliers run off (t -> -inf) until the Newton system fails,
        # where they no longer verify; early on they do, and prove it empty (t < 0)
        best = cvec[shift] * xc[shift]
        xb[:] = xc
    if not np.isnan(best):
        x[:] = xb
    return best


@jit
def shifted(x, shift, V, idx, S, pos, simplex, ws):
    """Set ``x[shift]`` to (just past) the least value that makes ``Z`` positive definite
    for the other multipliers as they are, and return the verified objective
    ``S_shift x[shift]`` (``nan`` if the leading block is not definite or the
    verification fails): a certificate from multipliers found for a neighbour."""
    C, T, Z, L, W = ws[0], ws[1], ws[2], ws[3], ws[5]
    nn = V.shape[0]
    m = len(x)
    sgn = S[shift, 0, 0].real
    x[shift] = 0.0
    _assemble(x, 1.0, V, idx, S, C, T, Z, m)
    if np.isnan(cholesky(Z, L, nn - 1)):
        return np.nan
    r = _schur(Z, L, W, nn)
    trace = 0.0
    for j in range(nn):
        trace += abs(Z[j, j].real)
    for margin in (1e-9, 1e-6, 1e-3):
        x[shift] = (-r + margin * (abs(r) + trace)) / sgn
        if verified(x, V, idx, S, m, pos, simplex, ws):
            return sgn * x[shift]
    return np.nan


@jit
def rounded(x, V, idx, S, kr, ki, F_lim, ws, K):
    """Candidate optimisers from the relaxation at ``x`` (of the maximum or of the
    minimum): ``X = Z^-1`` is (a multiple of) the barrier's primal point, and where the
    relaxation is tight it is ``z z^H`` for ``z = (p, 1)`` at the optimum, or a mixture
    of such. ``K[0]``: ``K_j = p_j / q_j``
    from its leading eigenvector; ``K[1]``: from the combination of its ``PURIFY_RANK``
    leading eigenvectors (scaled by the square roots of their eigenvalues) that leaves
    the box and the force limit least, of that eigenvector and ``PURIFY_SAMPLES`` random
    ones (the same at every call); both clipped to the box ``[0, kr] x [0, ki]`` (N/m).
    False if ``Z`` is not definite."""
    C, T, Z, L, Zi, W = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
    nn = V.shape[0]
    nd = nn - 1
    _assemble(x, 1.0, V, idx, S, C, T, Z, len(x))
    if np.isnan(cholesky(Z, L, nn)):
        return False
    _inverse(L, Zi, W, nn)
    lam, U = np.linalg.eigh(Zi)
    z = U[:, nn - 1].copy()
    best = _candidate(z, V, kr, ki, F_lim, K[0])
    if not best < math.inf:
        return False
    K[1, :] = K[0]
    r = min(PURIFY_RANK, nn)
    np.random.seed(0)
    Kc = np.empty(nd, np.complex128)
    for s in range(PURIFY_SAMPLES):
        z[:] = 0.0
        for i in range(r):
            c = complex(np.random.standard_normal(), np.random.standard_normal())
            c *= math.sqrt(max(lam[nn - 1 - i], 0.0))
            for a in range(nn):
                z[a] += c * U[a, nn - 1 - i]
        v = _candidate(z, V, kr, ki, F_lim, Kc)
        if v < best:
            best = v
            K[1, :] = Kc
    return True


@jit
def spread(x, V, idx, S, ws, out):
    """How much the relaxation at ``x`` mixes each damper's describing function: with
    ``X = Z^-1`` (a multiple of the barrier's primal point, ``E[z z^H]`` of a mixture of
    points ``z = (p, 1)``), ``out[j] = E|p_j|^2 / E|q_j|^2 - |E[conj(q_j) p_j] /
    E|q_j|^2|^2`` ((N/m)^2): 0 where every point of the mixture has the same ``K_j =
    p_j / q_j``. False (``out`` 0) if ``Z`` is not definite."""
    C, T, Z, L, Zi, W = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
    nn = V.shape[0]
    nd = nn - 1
    out[:] = 0.0
    _assemble(x, 1.0, V, idx, S, C, T, Z, len(x))
    if np.isnan(cholesky(Z, L, nn)):
        return False
    _inverse(L, Zi, W, nn)
    for j in range(nd):
        # q_j = V[:, j]^H z, p_j = V[:, nd + j]^H z
        a = 0j
        c = 0j
        e = 0j
        for r in range(nn):
            for t in range(nn):
                a += V[r, j].conjugate() * Zi[r, t] * V[t, j]
                c += V[r, nd + j].conjugate() * Zi[r, t] * V[t, j]
                e += V[r, nd + j].conjugate() * Zi[r, t] * V[t, nd + j]
        if a.real > 0.0:
            out[j] = max(e.real / a.real - abs(c / a.real) ** 2, 0.0)
    return True


@jit
def _candidate(z, V, kr, ki, F_lim, K):
    """``K_j = p_j / q_j`` (N/m, clipped to the box) at ``z`` scaled to ``z[nd] = 1``
    (``p_j = V[j, nd + j] z_j``, ``q_j = V[:, j]^H z``), and how far it lies outside the
    box (relative to its sides) and the force limit (relative to ``F_lim``), summed over
    the dampers; ``inf`` if not finite."""
    nn = V.shape[0]
    nd = nn - 1
    if z[nd] == 0:
        return math.inf
    scale = 1.0 / z[nd]
    for i in range(nn):
        z[i] *= scale
    out = 0.0
    for j in range(nd):
        q = 0j
        for i in range(nn):
            q += V[i, j].conjugate() * z[i]
        p = z[j] * V[j, nd + j]
        Kj = p / q
        if not np.isfinite(Kj.real) or not np.isfinite(Kj.imag):
            return math.inf
        out += (max(-Kj.real, 0.0) + max(Kj.real - kr, 0.0)) / kr
        out += (max(-Kj.imag, 0.0) + max(Kj.imag - ki, 0.0)) / ki
        if np.isfinite(F_lim):
            out += max(abs(p) / F_lim - 1.0, 0.0)
        K[j] = complex(min(max(Kj.real, 0.0), kr), min(max(Kj.imag, 0.0), ki))
    return out


@jit
def _schur(Z, L, W, nn):
    """``Z_ee - b^H P^-1 b`` for the last row and column ``b`` of ``Z`` and its leading
    block ``P = L L^H``."""
    for i in range(nn - 1):
        acc = Z[i, nn - 1]
        for k in range(i):
            acc -= L[i, k] * W[k, 0]
        W[i, 0] = acc / L[i, i].real
    r = Z[nn - 1, nn - 1].real
    for i in range(nn - 1):
        r -= W[i, 0].real ** 2 + W[i, 0].imag ** 2
    return r


@jit
def forms(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos, simplex, grow):
    """The relaxation of one frequency's admissible set (dampers in ``[lo_j, hi_j]``,
    N/m, and ``|p_j| <= F_lim``, N) into the given arrays; returns ``(shift, 2**e)``:
    the shift variable's index and the factor from its value to ``|y|^2`` (m^2).

    ``beam >= 0``: the upper bound of that beam's ``|y_b|``; ``beam < 0``: the lower
    bound of ``max_b |y_b|``. Sizes: ``nd`` dampers, ``nb`` beams, ``V``: (nd + 1,
    2 nd + 1 + nb); forms: 6 per damper (5 without a force limit), the shift, ``nb - 1``
    simplex weights for the minimum, and the constant form last.
    """
    nd = len(q0)
    nb = len(ylin)
    nn = nd + 1
    e_last = 2 * nd
    force = np.isfinite(F_lim)
    # p in units of a power of two near the force scale: Z better conditioned, exactly
    sp = _pow2(F_lim) if force else 1.0
    V[:, :] = 0.0
    for j in range(nd):
        for k in range(nd):
            V[k, j] = -G[j, k].conjugate() * sp
        V[nd, j] = q0[j].conjugate()
        V[j, nd + j] = sp
    V[nd, e_last] = 1.0
    ymax = 0.0
    for b in range(nb):
        col = e_last + 1 + b
        for k in range(nd):
            V[k, col] = -H[b, k].conjugate() * sp
        V[nd, col] = ylin[b].conjugate()
        for k in range(nn):
            ymax = max(ymax, abs(V[k, col]))
    ys = _pow2(ymax * ymax * nn)
    vmax = np.zeros(V.shape[1])
    for a in range(V.shape[1]):
        for k in range(nn):
            vmax[a] = max(vmax[a], abs(V[k, a]))
    S[:, :, :] = 0.0
    i = 0
    per = per_damper(force)
    for j in range(nd):
        a, b, c, d = lo[j].real, hi[j].real, lo[j].imag, hi[j].imag
        mid, rho2 = _disc(lo[j], hi[j])
        for f in range(5):
            idx[i + f, 0] = j
            idx[i + f, 1] = nd + j
        S[i, 0, 0] = a
        S[i, 0, 1] = -0.5
        S[i, 1, 0] = -0.5
        S[i + 1, 0, 0] = -b
        S[i + 1, 0, 1] = 0.5
        S[i + 1, 1, 0] = 0.5
        S[i + 2, 0, 0] = c
        S[i + 2, 0, 1] = 0.5j
        S[i + 2, 1, 0] = -0.5j
        S[i + 3, 0, 0] = -d
        S[i + 3, 0, 1] = -0.5j
        S[i + 3, 1, 0] = 0.5j
        S[i + 4, 0, 0] = abs(mid) ** 2 - rho2
        S[i + 4, 0, 1] = -mid.conjugate()
        S[i + 4, 1, 0] = -mid
        S[i + 4, 1, 1] = 1.0
        if force:
            idx[i + 5, 0] = nd + j
            idx[i + 5, 1] = e_last
            S[i + 5, 0, 0] = 1.0
            S[i + 5, 1, 1] = -(F_lim * F_lim) * (1.0 + 1e-12)
        for f in range(per):
            # each form scaled by a power of two to entries of order one (exact)
            big = 0.0
            for r in range(2):
                for s_ in range(2):
                    big = max(big, abs(S[i + f, r, s_]) * vmax[idx[i + f, r]]
                              * vmax[idx[i + f, s_]])
            sc = _pow2(big)
            for r in range(2):
                for s_ in range(2):
                    S[i + f, r, s_] /= sc
            x[i + f] = 1.0 if f >= 4 else 1e-2
            pos[i + f] = True
            simplex[i + f] = False
            grow[i + f] = f == 5
            cvec[i + f] = 0.0
        i += per
    shift = i
    idx[i, 0] = e_last
    idx[i, 1] = e_last
    S[i, 0, 0] = 1.0 if beam >= 0 else -1.0
    x[i] = 0.0
    cvec[i] = S[i, 0, 0].real
    pos[i] = False
    simplex[i] = False
    grow[i] = False
    i += 1
    last = e_last + nb
    if beam < 0:
        for b in range(nb - 1):
            idx[i, 0] = e_last + 1 + b
            idx[i, 1] = last
            S[i, 0, 0] = 1.0 / ys
            S[i, 1, 1] = -1.0 / ys
            x[i] = 1.0 / nb
            cvec[i] = 0.0
            pos[i] = True
            simplex[i] = True
            grow[i] = False
            i += 1
        idx[i, 0] = last
        idx[i, 1] = last
        S[i, 0, 0] = 1.0 / ys
    else:
        idx[i, 0] = e_last + 1 + beam
        idx[i, 1] = e_last + 1 + beam
        S[i, 0, 0] = -1.0 / ys
    return shift, ys


@jit
def _disc(lo, hi):
    """Centre (N/m) and squared radius ((N/m)^2) of the disc :func:`forms` puts around
    the rectangle ``[lo, hi]``."""
    mid = 0.5 * (lo + hi)
    rho2 = 0.0
    for corner in (lo, hi, complex(lo.real, hi.imag), complex(hi.real, lo.imag)):
        rho2 = max(rho2, abs(corner - mid) ** 2)
    # rounded up past the rounding of |mid|^2: the disc still holds the rectangle
    return mid, rho2 * (1.0 + 1e-10) + 1e-10 * abs(mid) ** 2


@jit
def weights(S, nd, per, w):
    """``w`` such that ``x_i w_i`` is form ``i``'s multiplier before :func:`forms`
    scaled it by a power of two (from the entries the scaling leaves known: the
    rectangle's ``1/2``, the disc's and the force limit's ``1``); 1 for the others."""
    w[:] = 1.0
    for i in range(nd * per):
        f = i % per
        if f < 4:
            w[i] = 2.0 * abs(S[i, 0, 1])
        elif f == 4:
            w[i] = S[i, 1, 1].real
        else:
            w[i] = S[i, 0, 0].real


@jit
def inherit(theta, lo, hi, plo, phi, per):
    """A parent part's multipliers ``theta`` (of the unscaled forms, see :func:`weights`)
    moved, in place, to its part ``[lo, hi]`` inside ``[plo, phi]`` (N/m) so that ``Z``
    only grows: positive definite for the parent, it stays so for the part.

    The rectangle's forms only tighten. The parent's disc form is the part's plus
    ``d(K) |q|^2`` with ``d`` affine in ``K``; ``d <= 0`` at the part's corners (they lie
    on the part's disc and inside the parent's), so on its rectangle ``d`` is a
    nonnegative combination of the sides' ``a - Re K``, ... plus a constant ``<= 0``:
    the parent's disc multiplier moves onto those sides, and the constant's term is
    ``-c |q|^2 >= 0`` in ``Z``.
    """
    for j in range(len(lo)):
        if lo[j] == plo[j] and hi[j] == phi[j]:
            continue
        mc, _ = _disc(lo[j], hi[j])
        mp, _ = _disc(plo[j], phi[j])
        td = theta[j * per + 4]
        # d(K) = 2 Re(K conj(mc - mp)) + const
        a = 2.0 * (mc.real - mp.real)
        b = 2.0 * (mc.imag - mp.imag)
        if a >= 0.0:
            theta[j * per + 1] += td * a
        else:
            theta[j * per] -= td * a
        if b >= 0.0:
            theta[j * per + 3] += td * b
        else:
            theta[j * per + 2] -= td * b


@jit
def turned(a, nd, per, s, out):
    """``out``: the multipliers ``a`` (of the unscaled forms, :func:`weights`) with the
    dampers' forms turned by ``s`` places (damper ``j``'s to ``j + s`` mod ``nd``), the
    rest as they are: a certificate of beam ``b`` made one of beam ``b + s`` on a ring."""
    out[:] = a
    for j in range(nd):
        for f in range(per):
            out[((j + s) % nd) * per + f] = a[j * per + f]


@jit
def per_damper(force):
    """Forms per damper in :func:`forms`: the rectangle's four sides, its disc, and the
    force limit where one is given (``force``)."""
    return 6 if force else 5


@jit
def n_forms(nd, nb, force, lower):
    """Multipliers of :func:`forms` (the constant form not counted)."""
    return nd * per_damper(force) + 1 + (nb - 1 if lower else 0)


@jit
def relaxed_bound(G, q0, ylin, H, lo, hi, F_lim, beam, goal, V, idx, S, x, cvec, pos,
                  simplex, grow, ws, stats, theta, plo, phi):
    """The verified bound over the dampers in ``[lo_j, hi_j]`` (N/m) and the force limit
    (m): of ``|y_beam|`` from above (``beam >= 0``), of ``max_b |y_b|`` from below
    (``beam < 0``); ``nan`` where nothing verified (rounded outwards). The solver stops
    once it proves ``goal`` (m); ``stats[2]`` counts the relaxation, and ``stats[3]`` it
    again where nothing verified.

    ``theta`` (shape (m + 1,)): the multipliers (unscaled, :func:`weights`) and weight
    ratio a relaxation of the part ``[plo, phi]`` holding this one saved (``theta[0]``
    NaN: none); where they, :func:`inherit`-ed, make ``Z`` positive definite the solver
    starts there instead of cold (about half the Newton steps, the same bounds: a
    start, never a proof). On return ``theta`` holds this relaxation's, for its parts.
    """
    shift, ys = forms(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos,
                      simplex, grow)
    stats[2] += 1
    m = len(x)
    per = per_damper(np.isfinite(F_lim))
    w = np.empty(m)
    weights(S, len(q0), per, w)
    warm = 0.0
    if not np.isnan(theta[0]):
        inherit(theta, lo, hi, plo, phi, per)
        xw = theta[:m] / w
        C, T, Z, L = ws[0], ws[1], ws[2], ws[3]
        _assemble(xw, 1.0, V, idx, S, C, T, Z, m)
        if not np.isnan(cholesky(Z, L, V.shape[0])):
            x[:] = xw
            warm = theta[m]
    goal2 = goal * goal / ys
    save = np.empty(m + 1)
    val = solve(x, shift, V, idx, S, cvec, pos, simplex, grow,
                goal2 if beam >= 0 else -goal2, ws, stats, warm, save)
    theta[0] = np.nan
    if np.isnan(val):
        stats[3] += 1
        return np.nan
    theta[:m] = save[:m] * w
    theta[m] = save[m]
    if beam >= 0:
        return math.sqrt(max(val, 0.0) * ys) * (1.0 + 1e-14)
    return math.sqrt(max(-val * ys, 0.0)) * (1.0 - 1e-14)
