"""Search of the describing-function box for the extreme responses (physics.md section 7).

At one frequency the damper describing functions ``K_j`` are free complex numbers in the
box ``0 <= Re K_j <= kr``, ``0 <= Im K_j <= ki``, and the output is linear in the beam
forces: ``y = y_lin - H diag(K) q`` with ``(I + G diag(K)) q = q0``. We seek the max and
the min over the box of ``M = max_b |y_b|``.

Structure used (why a coordinate search is exact per coordinate):

* With all dampers but ``j`` fixed, every ``y_b`` is a Moebius function of ``z = K_j``
  with a common denominator: ``y_b(z) = (alpha_b + beta_b z) / (d0 + d1 z)``
  (Sherman-Morrison on ``I + G diag(K)``). The system is passive for every ``K`` in the
  box (``Re K, Im K >= 0``, positive modal damping), so the denominator has no zero there.
* Maximum modulus: ``|y_b|`` over the rectangle of ``z`` is largest on its perimeter, so
  the maximum of ``M`` over the rectangle is on the perimeter, and along an edge
  ``|y_b|^2`` is a ratio of quadratics whose critical points solve a quadratic: the
  coordinate maximisation is exact (edge end points and critical points).
* For the minimum, ``M`` is a maximum of moduli and may dip inside the rectangle. In
  ``w = 1 / (d0 + d1 z)`` every ``|y_b|`` is a weighted distance ``|p_b + r_b w|``, so
  ``M`` is convex in ``w``: inside the rectangle there is no local minimum but the
  global one of that convex function. Edges are solved exactly (end points, critical
  points, pairwise crossings ``|y_b| = |y_c|``, all quadratics); the interior exactly
  too: the minimiser of a maximum of weighted distances (the weighted 1-centre, at most
  three beams active) is found by an Elzinga-Hearn iteration and kept if it maps back
  inside the rectangle.
* On a chain of beams G is tridiagonal and each row of H has two dampers: the searches
  skip the exact zeros (:func:`_sparsity`), and the coordinate search and the smoothed
  gradient solve by O(nd) eliminations; reported values are recomputed with pivoted LU.

Across dampers the problem is not convex: each search is run from many starts (uniform
corners, the centre, random corners and interior points) and the extreme value over all
starts is kept. The minimum's last step is the Gauss-Newton minimax search of
:mod:`.valley`, which moves every damper at once along the ridges where many beams are
equal (there a coordinate search stalls). That is a search, not a proof; tests compare it
with dense grids (one damper), with ensembles and random searches (seven dampers), and
with scipy's SLSQP started from the minimum found.
"""

import math
from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from ._jit import inline_jit, jit
from .linalg import contact_solve, lu_factor, lu_solve
from .valley import _lsq_valley, _minimax_barrier

_TINY = 1e-300


@jit
def _factor_inverse(G, K, Tinv, T, piv, nd):
    """``Tinv = (I + G diag(K))^-1``. Returns False if singular."""
    for i in range(nd):
        for j in range(nd):
            T[i, j] = G[i, j] * K[j]
        T[i, i] += 1.0
    if lu_factor(T, piv, nd) != 0:
        return False
    col = np.zeros(nd, dtype=np.complex128)
    for j in range(nd):
        for i in range(nd):
            col[i] = 0.0j
        col[j] = 1.0
        lu_solve(T, piv, col, nd)
        for i in range(nd):
            Tinv[i, j] = col[i]
    return True


@inline_jit
def _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr, tri):
    """``q = (I + G diag(K))^-1 q0`` and ``y`` (:func:`_outputs`). With ``tri`` by the
    chain elimination (factors left in ``T``), else, or at a tiny pivot, by the inverse
    ``Tinv`` (kept for the search's updates). Returns 1 (chain), 0 (inverse) or -1
    (singular)."""
    mode = 1 if tri and _tri_factor(G, K, T, nd) else 0
    if mode == 1:
        for i in range(nd):
            q[i] = q0[i]
        _tri_solve(T, q, nd)
    else:
        if not _factor_inverse(G, K, Tinv, T, piv, nd):
            return -1
        for i in range(nd):
            acc = 0.0j
            for m in range(nd):
                acc += Tinv[i, m] * q0[m]
            q[i] = acc
    _outputs(ylin, H, K, q, y, b0, b1, hr)
    return mode


@inline_jit
def _contact_q(G, K, q0, T, piv, q, nd, tri):
    """``q = (I + G diag(K))^-1 q0``: by the chain elimination if ``tri`` (factors left
    in ``T``), else, or at a tiny pivot, by LU with pivoting. Returns 1 (chain), 0 (LU)
    or -1 (singular)."""
    if tri and _tri_factor(G, K, T, nd):
        for i in range(nd):
            q[i] = q0[i]
        _tri_solve(T, q, nd)
        return 1
    return 0 if contact_solve(G, K, q0, T, piv, q, nd) == 0 else -1


@inline_jit
def _outputs(ylin, H, K, q, y, b0, b1, hr):
    """``y_b = y_lin_b - (H diag(K) q)_b`` for the beams b0..b1-1 (``hr``: the dampers
    each beam's row of H can be nonzero for, see :func:`_sparsity`)."""
    for b in range(b0, b1):
        acc = ylin[b]
        for m in range(hr[b, 0], hr[b, 1]):
            acc -= H[b, m] * K[m] * q[m]
        y[b] = acc


@inline_jit
def _column(G, Tinv, T, u, j, nd, gr, tri):
    """``u = (I + G diag(K))^-1 G[:, j]``: from the inverse, or (``tri``) by the chain
    elimination whose factors are in ``T``."""
    if tri:
        for i in range(nd):
            u[i] = 0.0j
        for m in range(gr[j, 0], gr[j, 1]):
            u[m] = G[m, j]
        _tri_solve(T, u, nd)
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
    (:func:`_sparsity`)."""
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
def _metric(alpha, beta, d0, d1, z, b0, b1):
    """``max_b |alpha_b + beta_b z| / |d0 + d1 z|`` over the objective's beams b0..b1-1."""
    den = d0 + d1 * z
    m = 0.0
    for b in range(b0, b1):
        v = alpha[b] + beta[b] * z
        m = max(m, v.real * v.real + v.imag * v.imag)
    return math.sqrt(m / (den.real * den.real + den.imag * den.imag))


@inline_jit
def _dominated(alpha_b, beta_b, d0, d1, z, best_val):
    """``|y_b(z)| > best_val`` with a 1e-12 margin, hence ``M(z) > best_val``: a candidate
    that cannot improve the minimum. The margin covers the rounding of :func:`_metric`,
    so skipping changes no result; no square root or division (most candidates end
    here)."""
    den = d0 + d1 * z
    v = alpha_b + beta_b * z
    return (v.real * v.real + v.imag * v.imag) >= best_val * best_val * (1.0 + 1e-12) * (
        den.real * den.real + den.imag * den.imag)


@inline_jit
def _quad_roots(a, b, c):
    """Real roots of ``a t^2 + b t + c`` (up to two; NaN where absent)."""
    if a == 0.0:
        if b == 0.0:
            return math.nan, math.nan
        return -c / b, math.nan
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return math.nan, math.nan
    sq = math.sqrt(disc)
    qq = -0.5 * (b + math.copysign(sq, b))
    r1 = qq / a
    r2 = c / qq if qq != 0.0 else math.nan
    return r1, r2


@inline_jit
def _edge_candidates(alpha, beta, d0, d1, z0, z1, want_max, b0, b1, best_val, best_z, pair,
                     E, first):
    """Best ``M`` on the segment ``z0 -> z1``, exactly (see module docstring).

    Updates and returns (best_val, best_z, b): ``b`` the beam that ruled the edge out
    (else ``first``), tried ``first`` on the next edge. ``pair``: the minimum (also
    pairwise crossings). ``E``: scratch, shape (>= 5, nb).
    """
    dz = z1 - z0
    den0 = d0 + d1 * z0
    den1 = d1 * dz
    c0 = den0.real * den0.real + den0.imag * den0.imag
    c1 = 2.0 * (den0.real * den1.real + den0.imag * den1.imag)
    c2 = den1.real * den1.real + den1.imag * den1.imag
    # |y_b|^2 |den|^2 along the edge is a2 t^2 + a1 t + a0 (rows 0-2), its stationary
    # points are rows 3-4. For the minimum (``pair``) a beam that stays above the best
    # value along the whole edge rules the edge out (M >= |y_b|): the edge ends there
    # (the 1e-6 margin covers the rounding of the quadratic forms), and so every beam
    # left comes below it: each pair's crossings are candidates
    lim = best_val * best_val * (1.0 + 1e-6)
    n = b1 - b0
    for i in range(n):
        b = b0 + (first - b0 + i) % n
        A = alpha[b] + beta[b] * z0
        B = beta[b] * dz
        a0 = A.real * A.real + A.imag * A.imag
        a1 = 2.0 * (A.real * B.real + A.imag * B.imag)
        a2 = B.real * B.real + B.imag * B.imag
        r1, r2 = _quad_roots(a2 * c1 - a1 * c2, 2.0 * (a2 * c0 - a0 * c2), a1 * c0 - a0 * c1)
        E[0, b] = a0
        E[1, b] = a1
        E[2, b] = a2
        E[3, b] = r1
        E[4, b] = r2
        if pair:
            emin = min(a0 / c0, (a0 + a1 + a2) / (c0 + c1 + c2))
            for t in (r1, r2):
                if t > 0.0 and t < 1.0:
                    emin = min(emin, (a0 + t * (a1 + t * a2)) / (c0 + t * (c1 + t * c2)))
            if emin >= lim:
                # M >= |y_b| >= best on the whole edge: nothing here can lower it
                return best_val, best_z, b
    for b in range(b0, b1):
        a0 = E[0, b]
        a1 = E[1, b]
        a2 = E[2, b]
        for t in (E[3, b], E[4, b]):
            if t > 0.0 and t < 1.0:
                if want_max:
                    # the edge maximum of M is the largest of each beam's own maximum:
                    # beam b's candidates need only |y_b|
                    v = math.sqrt((a0 + t * (a1 + t * a2)) / (c0 + t * (c1 + t * c2)))
                    if v > best_val:
                        best_val = v
                        best_z = z0 + t * dz
                    continue
                z = z0 + t * dz
                if _dominated(alpha[b], beta[b], d0, d1, z, best_val):
                    continue            # skips most full evaluations
                v = _metric(alpha, beta, d0, d1, z, b0, b1)
                if v < best_val:
                    best_val = v
                    best_z = z
        if pair:
            for c in range(b + 1, b1):
                s1, s2 = _quad_roots(E[2, c] - a2, E[1, c] - a1, E[0, c] - a0)
                for t in (s1, s2):
                    if t > 0.0 and t < 1.0:
                        z = z0 + t * dz
                        if _dominated(alpha[b], beta[b], d0, d1, z, best_val):
                            continue
                        v = _metric(alpha, beta, d0, d1, z, b0, b1)
                        if v < best_val:
                            best_val = v
                            best_z = z
    return best_val, best_z, first


@inline_jit
def _pair_centre(E, a, b):
    """Minimax point and value of two weighted distances ``rho |w - c|`` (E rows 0-2:
    Re c, Im c, rho): on the segment between the centres, where both are equal."""
    ra = E[2, a]
    rb = E[2, b]
    s = ra + rb
    wx = (ra * E[0, a] + rb * E[0, b]) / s
    wy = (ra * E[1, a] + rb * E[1, b]) / s
    return wx, wy, ra * rb * math.hypot(E[0, a] - E[0, b], E[1, a] - E[1, b]) / s


@inline_jit
def _wdist(E, b, wx, wy):
    return E[2, b] * math.hypot(wx - E[0, b], wy - E[1, b])


@inline_jit
def _equal_point(E, a, b, c):
    """The point where three weighted distances are equal and smallest (two points solve
    ``rho_a |w - c_a| = rho_b |w - c_b| = rho_c |w - c_c|``: two circles of Apollonius).
    Returns (wx, wy, value); value NaN if degenerate."""
    Aa = E[2, a] * E[2, a]
    xa, ya = E[0, a], E[1, a]
    # rho_a^2 |w - c_a|^2 - rho_m^2 |w - c_m|^2 = al |w|^2 - 2 be . w + ga = 0
    Ab = E[2, b] * E[2, b]
    al1 = Aa - Ab
    b1x = Aa * xa - Ab * E[0, b]
    b1y = Aa * ya - Ab * E[1, b]
    g1 = Aa * (xa * xa + ya * ya) - Ab * (E[0, b] * E[0, b] + E[1, b] * E[1, b])
    Ac = E[2, c] * E[2, c]
    al2 = Aa - Ac
    b2x = Aa * xa - Ac * E[0, c]
    b2y = Aa * ya - Ac * E[1, c]
    g2 = Aa * (xa * xa + ya * ya) - Ac * (E[0, c] * E[0, c] + E[1, c] * E[1, c])
    scale = max(Aa, Ab, Ac)
    if abs(al1) <= 1e-12 * scale and abs(al2) <= 1e-12 * scale:
        # equal weights: two lines (perpendicular bisectors)
        det = b1x * b2y - b1y * b2x
        if det == 0.0:
            return 0.0, 0.0, math.nan
        wx = 0.5 * (g1 * b2y - g2 * b1y) / det
        wy = 0.5 * (b1x * g2 - b2x * g1) / det
        return wx, wy, _wdist(E, a, wx, wy)
    # eliminate |w|^2: a line L . w = h; then the circle with the larger |al| on it
    lx = al2 * b1x - al1 * b2x
    ly = al2 * b1y - al1 * b2y
    h = 0.5 * (al2 * g1 - al1 * g2)
    ll = lx * lx + ly * ly
    if ll == 0.0:
        return 0.0, 0.0, math.nan
    if abs(al1) < abs(al2):
        al1, b1x, b1y, g1 = al2, b2x, b2y, g2
    x0 = h * lx / ll
    y0 = h * ly / ll
    nl = math.sqrt(ll)
    ex = -ly / nl
    ey = lx / nl
    # al t^2 - 2 (be . e) t + (al |w0|^2 - 2 be . w0 + ga) = 0 (w0 . e = 0)
    t1, t2 = _quad_roots(al1, -2.0 * (b1x * ex + b1y * ey),
                         al1 * (x0 * x0 + y0 * y0) - 2.0 * (b1x * x0 + b1y * y0) + g1)
    best = math.nan
    bx = by = 0.0
    for t in (t1, t2):
        if not math.isnan(t):
            wx = x0 + t * ex
            wy = y0 + t * ey
            v = _wdist(E, a, wx, wy)
            if not (v >= best):
                best, bx, by = v, wx, wy
    return bx, by, best


@inline_jit
def _set_max(E, cands, m, wx, wy):
    """Largest weighted distance at w over the beams in ``cands`` (-1: none) and m."""
    v = _wdist(E, m, wx, wy)
    for o in cands:
        if o >= 0:
            v = max(v, _wdist(E, o, wx, wy))
    return v


@inline_jit
def _one_centre(E, b0, b1):
    """Minimax point of the weighted distances ``rho_b |w - c_b|`` (beams b0..b1-1 with
    rho > 0; E rows 0-2). Elzinga-Hearn: the optimum of a set of at most three active
    beams, extended by the farthest beam until every beam is covered (the value grows
    at every step, so it ends; at most 3 beams are ever active in the plane).
    Returns (wx, wy); NaN if it did not settle."""
    s0 = -1
    for b in range(b0, b1):
        if E[2, b] > 0.0:
            s0 = b
            break
    if s0 < 0:
        return math.nan, math.nan
    sa, sb, sc = s0, -1, -1           # the active set (-1: empty slot)
    wx, wy, v = E[0, s0], E[1, s0], 0.0
    for _ in range(3 * (b1 - b0) + 3):
        m = -1
        fm = v * (1.0 + 1e-12)
        for b in range(b0, b1):
            if E[2, b] > 0.0:
                d = _wdist(E, b, wx, wy)
                if d > fm:
                    fm, m = d, b
        if m < 0:
            return wx, wy           # every beam covered: optimal
        if sb < 0:
            sb = m
            wx, wy, v = _pair_centre(E, sa, sb)
            continue
        # optimum of the set with m: m is active there (the old optimum does not
        # cover it), so it is the pair point of m with one member or the equal point of
        # m with two; the candidate of smallest max over the set is it
        cands = (sa, sb, sc)
        best_v = math.inf
        nx, ny, na, nb_, nc = wx, wy, -1, -1, -1
        for i in range(3):
            p = cands[i]
            if p < 0:
                continue
            px, py, _ = _pair_centre(E, p, m)
            fv = _set_max(E, cands, m, px, py)
            if fv < best_v:
                best_v, nx, ny, na, nb_, nc = fv, px, py, p, m, -1
            for i2 in range(i + 1, 3):
                r = cands[i2]
                if r < 0:
                    continue
                px, py, pv = _equal_point(E, p, r, m)
                if math.isnan(pv):
                    continue
                fv = _set_max(E, cands, m, px, py)
                if fv < best_v:
                    best_v, nx, ny, na, nb_, nc = fv, px, py, p, r, m
        if not (best_v > v):
            return wx, wy           # no progress (rounding): the point reached
        sa, sb, sc = na, nb_, nc
        wx, wy, v = nx, ny, best_v
    return math.nan, math.nan


@jit
def _interior_min(alpha, beta, d0, d1, kr, ki, b0, b1, E):
    """The minimum of ``M`` over the rectangle's interior, exactly, if it lies inside.

    In ``w = 1 / (d0 + d1 z)``, ``|y_b| = rho_b |w - c_b|``: M is a maximum of weighted
    distances, convex, with one minimiser (the weighted 1-centre, :func:`_one_centre`).
    If that maps back inside the rectangle it is the interior minimum; otherwise the
    minimum over the rectangle is on its perimeter (solved by the edges). With
    ``d1 = 0`` M is convex in z itself. Returns (value, z); (inf, 0) if outside.
    """
    lin = d1 == 0.0
    for b in range(b0, b1):
        if lin:
            # |alpha + beta z| / |d0|: centre -alpha / beta, weight |beta / d0|
            r = beta[b] / d0
            p = alpha[b] / d0
        else:
            r = alpha[b] - beta[b] * d0 / d1
            p = beta[b] / d1
        rho = abs(r)
        if rho > 0.0:
            cc = -p / r
            E[0, b] = cc.real
            E[1, b] = cc.imag
        E[2, b] = rho
    wx, wy = _one_centre(E, b0, b1)
    if math.isnan(wx):
        return math.inf, 0.0j
    w = complex(wx, wy)
    if lin:
        z = w
    else:
        if w == 0.0:
            return math.inf, 0.0j
        z = (1.0 / w - d0) / d1
    if not (0.0 <= z.real <= kr and 0.0 <= z.imag <= ki):
        return math.inf, 0.0j
    return _metric(alpha, beta, d0, d1, z, b0, b1), z


@inline_jit
def _best_on_rectangle(alpha, beta, d0, d1, kr, ki, want_max, z_now, b0, b1, interior, E):
    """Exact extreme of ``M`` over the perimeter of ``[0, kr] x [0, ki]`` (and, for the
    minimum with ``interior``, over the inside). Never worse than ``z_now``."""
    best_z = z_now
    best_val = _metric(alpha, beta, d0, d1, z_now, b0, b1)
    corners = (0.0j, complex(kr, 0.0), complex(kr, ki), complex(0.0, ki))
    for c in range(4):
        z = corners[c]
        v = _metric(alpha, beta, d0, d1, z, b0, b1)
        if (v > best_val) if want_max else (v < best_val):
            best_val = v
            best_z = z
    first = b0
    for c in range(4):
        best_val, best_z, first = _edge_candidates(alpha, beta, d0, d1, corners[c],
                                                   corners[(c + 1) % 4], want_max, b0, b1,
                                                   best_val, best_z, not want_max, E, first)
    if want_max or not interior:
        return best_val, best_z
    # interior: the weighted 1-centre in w (exact; none inside: the perimeter has it)
    v, z = _interior_min(alpha, beta, d0, d1, kr, ki, b0, b1, E)
    if v < best_val:
        best_val = v
        best_z = z
    return best_val, best_z


@inline_jit
def _objective(y, b0, b1):
    """``max |y_b|`` over beams b0..b1-1; NaN if any is NaN (never a silent 0)."""
    m = 0.0
    for b in range(b0, b1):
        v = abs(y[b])
        if not (v <= m):
            m = v
    return m


@jit
def _search(G, q0, ylin, H, kr, ki, K, want_max, b0, b1, max_sweeps, tol, w):
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
    # a chain: O(nd) eliminations instead of keeping the inverse (O(nd^2) per step,
    # O(nd^3) per refresh); any other graph, or a tiny pivot, takes the inverse
    tri = _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr, w[14])
    if tri < 0:
        return math.nan
    best = _objective(y, b0, b1)
    stale = False                   # the chain factors are those of an earlier K
    K0, Kt = w[15], w[16]
    for sweep in range(max_sweeps):
        old = best
        changed = False
        for j in range(nd):
            K0[j] = K[j]
        for j in range(nd):
            if tri and stale:
                if _tri_factor(G, K, T, nd):
                    stale = False
                else:
                    tri = 0
                    if not _factor_inverse(G, K, Tinv, T, piv, nd):
                        return math.nan
            _column(G, Tinv, T, u, j, nd, gr, tri == 1)
            d0, d1 = _coefficients(ylin, H, K, q, y, j, u, alpha, beta, b0, b1, hr)
            # the interior only in tight searches (exploring relies on the edges and on
            # the smoothed-gradient polish)
            val, z = _best_on_rectangle(alpha, beta, d0, d1, kr, ki, want_max, K[j], b0, b1,
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
            if tri:
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
            # (for the minimum measured worse: lower bound 0.06 % higher on average)
            _pattern_move(G, q0, ylin, H, kr, ki, K, K0, Kt, best, b0, b1, w)
        # refresh: Sherman-Morrison updates accumulate rounding
        tri = _refresh(G, q0, ylin, H, K, Tinv, T, piv, q, y, nd, b0, b1, hr, tri == 1)
        if tri < 0:
            return math.nan
        stale = False
        best = _objective(y, b0, b1)
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
        if _contact_q(G, Kt, q0, T, piv, q, nd, w[14]) < 0:
            break
        _outputs(ylin, H, Kt, q, y, b0, b1, hr)
        v = _objective(y, b0, b1)
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
def _smooth_max(G, q0, ylin, H, K, mu, b0, b1, grad, w):
    """``mu log sum_b exp(log|y_b| / mu)`` (a smooth max of log|y_b|) and its gradient
    with respect to (Re K_j, Im K_j), stored as ``grad[j] = d/dRe + i d/dIm``.
    Returns (value, log M); value = inf if the system is singular."""
    T, piv, q, y, u, r, lb = w[1], w[2], w[3], w[4], w[5], w[9], w[10]
    hr, gr = w[12], w[13]
    nd = K.shape[0]
    # a chain: O(nd) elimination; else (or at a tiny pivot) LU with pivoting. Only the
    # search path depends on this: values are taken from the coordinate search's own
    mode = _contact_q(G, K, q0, T, piv, q, nd, w[14])
    if mode < 0:
        return math.inf, math.inf
    lmax = -math.inf
    for b in range(b0, b1):
        acc = ylin[b]
        for m in range(hr[b, 0], hr[b, 1]):
            acc -= H[b, m] * K[m] * q[m]
        y[b] = acc
        lb[b] = 0.5 * math.log(max(acc.real * acc.real + acc.imag * acc.imag, _TINY))
        lmax = max(lmax, lb[b])
    if not math.isfinite(lmax):
        return math.inf, math.inf
    tot = 0.0
    for b in range(b0, b1):
        lb[b] = math.exp((lb[b] - lmax) / mu)      # from here on: unnormalised weights
        tot += lb[b]
    val = lmax + mu * math.log(tot)
    # v_b = w_b / y_b with softmax weights w_b; r = v^T H; g_j = -q_j (r_j - (s^T G)_j)
    # where T^T s = r o K (adjoint solve; G symmetric, T^T = I + diag(K) G)
    for m in range(nd):
        r[m] = 0.0j
    for b in range(b0, b1):
        yb = y[b]
        a2 = max(yb.real * yb.real + yb.imag * yb.imag, _TINY)   # an exact zero (undriven beam)
        wb = lb[b] / tot
        vb = wb * yb.conjugate() / a2
        for m in range(hr[b, 0], hr[b, 1]):
            r[m] += vb * H[b, m]
    # solve (I + diag(K) G) s = r o K by the transpose of the LU of I + G diag(K)
    for m in range(nd):
        u[m] = r[m] * K[m]
    if mode == 1:
        _tri_solve_transposed(T, u, nd)
    else:
        _lu_solve_transposed(T, piv, u, nd)
    for j in range(nd):
        sg = 0.0j
        for m in range(gr[j, 0], gr[j, 1]):
            sg += u[m] * G[m, j]
        gj = -q[j] * (r[j] - sg)      # d(sum w_b log|y_b|)/dK_j as a complex derivative
        grad[j] = complex(gj.real, -gj.imag)
    return val, lmax


@inline_jit
def _tri_factor(G, K, T, nd):
    """LU factors of ``I + G diag(K)`` for a tridiagonal G, without pivoting, in rows
    0-2 of ``T`` (1 / pivots, the eliminated super-diagonal, the sub-diagonal). Returns
    False (use pivoting instead) at a pivot small against its row."""
    cp = 0.0j
    for i in range(nd):
        a = 1.0 + G[i, i] * K[i]
        if i > 0:
            lo = G[i, i - 1] * K[i - 1]
            a -= lo * cp
            T[2, i - 1] = lo
        if not (abs(a) > 1e-10 * (1.0 + abs(G[i, i] * K[i]))):
            return False
        inv = 1.0 / a
        cp = G[i, i + 1] * K[i + 1] * inv if i < nd - 1 else 0.0j
        T[0, i] = inv
        T[1, i] = cp
    return True


@inline_jit
def _tri_solve(T, x, nd):
    """Solve ``(I + G diag(K)) x = b`` in place (``x`` holds b) with the factors of
    :func:`_tri_factor`."""
    x[0] *= T[0, 0]
    for i in range(1, nd):
        x[i] = (x[i] - T[2, i - 1] * x[i - 1]) * T[0, i]
    for i in range(nd - 2, -1, -1):
        x[i] -= T[1, i] * x[i + 1]


@inline_jit
def _tri_solve_transposed(T, b, nd):
    """Solve ``(I + G diag(K))^T x = b`` in place with the factors of
    :func:`_tri_factor` (``A = L U``, U unit upper: ``U^T`` forward, ``L^T`` back)."""
    for i in range(1, nd):
        b[i] -= T[1, i - 1] * b[i - 1]
    b[nd - 1] *= T[0, nd - 1]
    for i in range(nd - 2, -1, -1):
        b[i] = (b[i] - T[2, i] * b[i + 1]) * T[0, i]


@jit
def _lu_solve_transposed(A, piv, b, n):
    """Solve ``A^T x = b`` in place with the factors of :func:`lu_factor` (P A = L U)."""
    # A^T = U^T L^T P: solve U^T z = b, L^T v = z, then x = P^T v
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= A[j, i] * b[j]
        b[i] = acc / A[i, i]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[j, i] * b[j]
        b[i] = acc
    for k in range(n - 1, -1, -1):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t


#: Iterations per smoothing stage of :func:`_spg` in the minimum's searches, chosen in
#: :func:`box_extreme` (a constant passed inside the jitted code would compile another
#: specialisation, see :func:`_improve`). The continuation takes shorter ones than the
#: polish: measured, 12 % less time for a lower bound higher by 0.005 % (geometric mean
#: over 1000 frequencies). The maximum's searches take none (0): measured on eight grids
#: (137-2000 frequencies, 0.25-1.1 N) with three seeds each, the upper bound without the
#: gradient stage (it had 20 iterations) was lower by more than 1e-9 at one frequency of
#: a run at most (2.9e-8; once 7.3e-6, at 15.15 Hz), higher by 1.1e-5 at two, the same
#: elsewhere; the bounds took 10 % less time at 0.25 and at 1.1 N. The coordinate
#: search's pattern move already takes the long steps along resonance ridges.
_SPG_ITER = 40
_SPG_ITER_CONTINUATION = 12
#: Memory of the nonmonotone line search of :func:`_spg` (Grippo-Lampariello-Lucidi):
#: a step is accepted against the worst of the last ``_GLL`` values, so the spectral
#: (Barzilai-Borwein) step is rarely cut back.
_GLL = 8


@jit
def _spg(G, q0, ylin, H, kr, ki, K, sign, b0, b1, w, max_iter):
    """Spectral projected gradient on ``sign`` times a smoothed max of ``log|y_b|``
    (sign = 1: the minimum of M; sign = -1: the maximum).

    Coordinate searches move one damper at a time: they stall where beams are equal (a
    ridge of the minimum); a joint gradient step does not. (The bounds use it for the
    minimum only; for the maximum the pattern move of :func:`_search` does as well, see
    ``_SPG_ITER``.) The
    smoothing ``mu`` is reduced in two stages of at most ``max_iter`` iterations; the line
    search is nonmonotone (``_GLL``), so the best point evaluated (by M itself) is the
    one returned. Returns M at ``K``. (The smoothed max exceeds the max by up to
    ``mu log(n_beams)``: where many beams are equal at the minimum it stops short of it;
    :func:`.valley._minimax_barrier` finishes the minimum.)
    """
    nd = K.shape[0]
    g = np.zeros(nd, dtype=np.complex128)
    x = np.zeros(nd, dtype=np.complex128)      # K scaled to the unit box
    xt = np.zeros(nd, dtype=np.complex128)
    Kt = np.zeros(nd, dtype=np.complex128)
    d = np.zeros(nd, dtype=np.complex128)
    gt = np.zeros(nd, dtype=np.complex128)
    x_best = np.zeros(nd, dtype=np.complex128)
    hist = np.empty(_GLL)
    for j in range(nd):
        x[j] = complex(K[j].real / kr, K[j].imag / ki)
        x_best[j] = x[j]
    l_best = math.nan                           # sign * log M at x_best
    for mu in (0.01, 0.002):
        for j in range(nd):
            K[j] = complex(kr * x[j].real, ki * x[j].imag)
        f, lm = _smooth_max(G, q0, ylin, H, K, mu, b0, b1, g, w)
        if not math.isfinite(f):
            break
        f *= sign
        if math.isnan(l_best) or sign * lm < l_best:
            l_best = sign * lm
            for j in range(nd):
                x_best[j] = x[j]
        for m in range(_GLL):
            hist[m] = f
        for j in range(nd):
            g[j] = complex(sign * g[j].real * kr, sign * g[j].imag * ki)
        alpha = 0.1
        for it in range(max_iter):
            gd = 0.0
            for j in range(nd):
                v = x[j] - alpha * g[j]
                v = complex(min(max(v.real, 0.0), 1.0), min(max(v.imag, 0.0), 1.0))
                d[j] = v - x[j]
                gd += g[j].real * d[j].real + g[j].imag * d[j].imag
            if gd >= -1e-14:
                break
            f_ref = hist[0]
            for m in range(1, _GLL):
                f_ref = max(f_ref, hist[m])
            lam = 1.0
            ok = False
            for _ in range(20):
                for j in range(nd):
                    xt[j] = x[j] + lam * d[j]
                    Kt[j] = complex(kr * xt[j].real, ki * xt[j].imag)
                ft, lt = _smooth_max(G, q0, ylin, H, Kt, mu, b0, b1, gt, w)
                ft *= sign
                if ft <= f_ref + 1e-4 * lam * gd:
                    ok = True
                    break
                lam *= 0.5
            if not ok:
                break
            if sign * lt < l_best:
                l_best = sign * lt
                for j in range(nd):
                    x_best[j] = xt[j]
            ss = 0.0
            sy = 0.0
            for j in range(nd):
                gt[j] = complex(sign * gt[j].real * kr, sign * gt[j].imag * ki)
                sj = xt[j] - x[j]
                yj = gt[j] - g[j]
                ss += sj.real * sj.real + sj.imag * sj.imag
                sy += sj.real * yj.real + sj.imag * yj.imag
                x[j] = xt[j]
                g[j] = gt[j]
            f = ft
            hist[(it + 1) % _GLL] = f
            alpha = min(max(ss / sy, 1e-6), 10.0) if sy > 0.0 else 1.0
        # the next stage starts from the best point so far
        for j in range(nd):
            x[j] = x_best[j]
    for j in range(nd):
        K[j] = complex(kr * x_best[j].real, ki * x_best[j].imag)
    _, lm = _smooth_max(G, q0, ylin, H, K, 1.0, b0, b1, g, w)
    return math.exp(lm)


@jit
def _workspace(nd, nb, hr, gr):
    """Scratch of one thread's searches; ends with its own copies of the sparsity ranges
    (an array shared by the threads would have its reference count contended)."""
    c16 = np.complex128
    return (np.zeros((nd, nd), c16), np.zeros((nd, nd), c16), np.zeros(nd, np.int64),
            np.zeros(nd, c16), np.zeros(nb, c16), np.zeros(nd, c16), np.zeros(nb, c16),
            np.zeros(nb, c16), np.zeros(nd, c16), np.zeros(nd, c16), np.zeros(nb),
            np.zeros((5, nb)), hr.copy(), gr.copy(), _is_tridiagonal(gr, nd),
            np.zeros(nd, c16), np.zeros(nd, c16))


@jit
def _is_tridiagonal(gr, nd):
    """G is tridiagonal (a chain of dampers) and large enough for the row storage of
    :func:`_tri_factor`."""
    if nd < 3:
        return False
    for j in range(nd):
        if gr[j, 0] < j - 1 or gr[j, 1] > j + 2:
            return False
    return True


@inline_jit
def _beam_range(objective, nb):
    """Objective -1: M = max over all beams; objective b >= 0: |y_b| alone."""
    if objective < 0:
        return 0, nb
    return objective, objective + 1


@jit
def _improve(G, q0, ylin, H, kr, ki, K, want_max, objective, max_sweeps, tol, w, spg_iter):
    """One local search: coordinate search, the smoothed-gradient search (``spg_iter``
    iterations per stage) from where it ends, and a second coordinate search from there;
    keeps the better end point. With ``spg_iter = 0`` the coordinate search alone.

    Every caller passes run-time values: numba compiles a separate specialisation for a
    literal argument (``False``, ``0``), and the search takes ~10 s to compile."""
    b0, b1 = _beam_range(objective, ylin.shape[0])
    v = _search(G, q0, ylin, H, kr, ki, K, want_max, b0, b1, max_sweeps, tol, w)
    if not math.isfinite(v) or spg_iter <= 0:
        return v
    nd = K.shape[0]
    K2 = K.copy()
    v2 = _spg(G, q0, ylin, H, kr, ki, K2, -1.0 if want_max else 1.0, b0, b1, w, spg_iter)
    if math.isfinite(v2):
        v2 = _search(G, q0, ylin, H, kr, ki, K2, want_max, b0, b1, max_sweeps, tol, w)
        if (v2 > v) if want_max else (v2 < v):
            for j in range(nd):
                K[j] = K2[j]
            v = v2
    return v


@inline_jit
def _better(v, ref, want_max):
    """``v`` is finite and improves on ``ref`` (NaN ``ref``: nothing yet)."""
    if not math.isfinite(v):
        return False
    if math.isnan(ref):
        return True
    return v > ref if want_max else v < ref


@inline_jit
def _keep_if_better(v, K, best, K_best, o, k, want_max):
    """Store ``v`` and its describing functions ``K`` as the best of objective ``o`` at
    frequency ``k`` if it improves on what is there."""
    if _better(v, best[o, k], want_max):
        best[o, k] = v
        for j in range(K.shape[0]):
            K_best[o, k, j] = K[j]


@inline_jit
def _irrelevant(best, cap, o, k, n_o):
    """For the maximum: beam ``o`` cannot set the bound at frequency ``k`` when its force
    bound is already reached by another beam's ``min(box value found, force bound)``."""
    top = -math.inf
    for p in range(n_o):
        if p != o and not math.isnan(best[p, k]):
            top = max(top, min(best[p, k], cap[k, p]))
    return cap[k, o] <= top


@jit(nogil=True)
def _multistart(G, q0, ylin, H, hr, gr, kr, ki, starts, want_max, objectives, cap, max_sweeps, tol,
                best, K_best, freqs):
    """Phase 1: coordinate search from every start, for every objective, at the
    frequencies ``freqs`` (one task of :func:`_in_threads`)."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    n_o = objectives.shape[0]
    w = _workspace(nd, nb, hr, gr)
    K = np.zeros(nd, dtype=np.complex128)
    for k in freqs:
        for o in range(n_o):
            best[o, k] = math.nan
        # beams with the largest force bound first: the others may then be skipped
        by_cap = np.argsort(-cap[k]) if want_max else np.arange(n_o)
        for o in by_cap:
            if want_max and _irrelevant(best, cap, o, k, n_o):
                continue
            b0, b1 = _beam_range(objectives[o], nb)
            for s in range(starts.shape[1]):
                for j in range(nd):
                    K[j] = complex(kr * starts[k, s, j].real, ki * starts[k, s, j].imag)
                v = _search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                            max_sweeps, tol, w)
                _keep_if_better(v, K, best, K_best, o, k, want_max)
                if want_max and best[o, k] >= cap[k, o]:
                    break               # at the force limit: the box no longer matters
            if not want_max and objectives[o] < 0 and nd > 1:
                # the valley where all beams rest at once: least squares from the centre
                for j in range(nd):
                    K[j] = complex(0.5 * kr, 0.5 * ki)
                v = _lsq_valley(G[k], q0[k], ylin[k], H[k], kr, ki, K, w)
                if math.isfinite(v):
                    v = _search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                                max_sweeps, tol, w)
                _keep_if_better(v, K, best, K_best, o, k, want_max)


@jit(nogil=True)
def _chain(d, o, G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap, max_sweeps, tol,
           spg_iter, best, K_best, cand, K_cand, first, ran):
    """Phase 2: continuation along frequency, upward (``d = 0``) or downward (``d = 1``),
    for objective ``o`` (one chain per direction and objective, each a task of
    :func:`_in_threads`); each frequency starts from the neighbour's best and keeps what
    improves, in ``cand[d, o]``.

    Later rounds (``first`` False) search only where the start changed: where the
    decision to search (``ran``) and the neighbour's result (value and describing
    functions, exactly) are those of the previous round, the search would repeat the
    previous round's, whose value is no better than the previous candidate, itself no
    better than ``best`` (the best of the candidates): the candidate is ``best``, without
    searching.
    """
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    w = _workspace(nd, nb, hr, gr)
    K = np.zeros(nd, dtype=np.complex128)
    K_old = np.zeros(nd, dtype=np.complex128)
    same_up = False         # the neighbour's result equals the previous round's
    for i in range(n_f):
        k = i if d == 0 else n_f - 1 - i
        kp = k - 1 if d == 0 else k + 1
        run = i > 0 and not math.isnan(cand[d, o, kp])
        if run and want_max and (best[o, k] >= cap[k, o] or
                                 _irrelevant(best, cap, o, k, objectives.shape[0])):
            run = False         # at the force limit, or cannot set the bound
        # the same start and decision as the previous round: the same search, no better
        # than ``best``
        repeat = not first and same_up and run and ran[d, o, k]
        v_old = cand[d, o, k]
        for j in range(nd):
            K_old[j] = K_cand[d, o, k, j]
        cand[d, o, k] = best[o, k]
        for j in range(nd):
            K_cand[d, o, k, j] = K_best[o, k, j]
        ran[d, o, k] = run
        if run and not repeat:
            for j in range(nd):
                K[j] = K_cand[d, o, kp, j]
            v = _improve(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max,
                         objectives[o], max_sweeps, tol, w, spg_iter)
            if _better(v, cand[d, o, k], want_max):
                cand[d, o, k] = v
                for j in range(nd):
                    K_cand[d, o, k, j] = K[j]
        same_up = not first and cand[d, o, k] == v_old
        if same_up:
            for j in range(nd):
                if K_cand[d, o, k, j] != K_old[j]:
                    same_up = False
                    break


@jit(nogil=True)
def _polish(G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap, max_sweeps, tol, spg_iter,
            best, K_best, freqs, polish_sweeps, polish_tol):
    """Phase 3: a local search from the best point of every objective at the frequencies
    ``freqs`` (one task of :func:`_in_threads`), ended by a tight one (``polish_sweeps``,
    ``polish_tol``); for the minimum then the minimax search of
    :func:`.valley._minimax_barrier`."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    w = _workspace(nd, nb, hr, gr)
    K = np.empty(nd, dtype=np.complex128)
    for k in freqs:
        for o in range(objectives.shape[0]):
            if math.isnan(best[o, k]) or (want_max and (
                    best[o, k] >= cap[k, o] or
                    _irrelevant(best, cap, o, k, objectives.shape[0]))):
                continue
            for j in range(nd):
                K[j] = K_best[o, k, j]
            v = _improve(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, objectives[o],
                         max_sweeps, tol, w, spg_iter)
            if polish_sweeps > 0 and math.isfinite(v):
                b0, b1 = _beam_range(objectives[o], nb)
                v = _search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                            polish_sweeps, polish_tol, w)
            if not want_max and math.isfinite(v):
                # the minimum's ridges: every beam and damper at once (see .valley)
                K2 = K.copy()
                v2 = _minimax_barrier(G[k], q0[k], ylin[k], H[k], kr, ki, K2, w)
                if v2 < v:
                    v = v2
                    for j in range(nd):
                        K[j] = K2[j]
            if math.isfinite(v) and ((v >= best[o, k]) if want_max else (v <= best[o, k])):
                best[o, k] = v
                for j in range(nd):
                    K_best[o, k, j] = K[j]


@jit(nogil=True)
def _evaluate(G, q0, ylin, H, objectives, best, K_best):
    """``best[o, k]``: the objective at ``K_best[o, k]`` by LU with partial pivoting.

    The searches may have used the unpivoted chain elimination; the values reported are
    computed afresh by the pivoted solve."""
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    T = np.empty((nd, nd), dtype=np.complex128)
    piv = np.empty(nd, dtype=np.int64)
    q = np.empty(nd, dtype=np.complex128)
    y = np.empty(nb, dtype=np.complex128)
    for k in range(n_f):
        for o in range(objectives.shape[0]):
            if math.isnan(best[o, k]):
                continue
            b0, b1 = _beam_range(objectives[o], nb)
            if contact_solve(G[k], K_best[o, k], q0[k], T, piv, q, nd) != 0:
                best[o, k] = math.nan
                continue
            for b in range(b0, b1):
                acc = ylin[k, b]
                for m in range(nd):
                    acc -= H[k, b, m] * K_best[o, k, m] * q[m]
                y[b] = acc
            best[o, k] = _objective(y, b0, b1)


def _sparsity(G, H):
    """Nonzero ranges: ``hr[b] = (first, last + 1)`` of the dampers with a nonzero
    ``H[:, b, m]`` at some frequency, ``gr[j]`` the same for the rows of column j of G.

    A damper acts on two beams, so on a chain of beams both are short (G tridiagonal, H
    two dampers per beam) and the searches skip the exact zeros: the same results at a
    fraction of the O(nd^2) work per coordinate. Any other damper graph gets the ranges
    it has (at worst all dampers).
    """
    def ranges(nz):
        out = np.zeros((nz.shape[0], 2), np.int64)
        for i, row in enumerate(nz):
            idx = np.flatnonzero(row)
            out[i] = (idx[0], idx[-1] + 1) if idx.size else (0, 0)
        return out

    return ranges((H != 0).any(axis=0)), ranges((G != 0).any(axis=0).T)


def _chunks(n_f):
    """The frequency indices in tasks of :func:`_in_threads`: ``_CHUNKS`` blocks of a
    permutation that spreads each block over the band (the search costs vary ~2x across
    it, measured), so the tasks cost about the same."""
    order = np.argsort((np.arange(n_f) * 0.6180339887498949) % 1.0, kind="stable")
    return np.array_split(order, min(n_f, _CHUNKS))


#: Tasks per phase over the frequencies: several per thread, so that a thread that
#: finishes early takes another.
_CHUNKS = 32


def _in_threads(task, items):
    """``task(item)`` for every item, on ``numba.get_num_threads()`` threads, each taking
    the next item when it is free; the first exception is raised here.

    The tasks are ``nogil`` kernels that write disjoint parts of the output, so the result
    does not depend on the number of threads or the order. Python threads rather than
    ``prange``: each ``prange`` kernel compiled the whole search again (~15-25 s of
    compilation each, measured with numba's compile events).
    """
    items = list(items)
    n = min(numba.get_num_threads(), len(items))
    if n <= 1:
        for item in items:
            task(item)
        return
    pool = ThreadPoolExecutor(n)
    try:
        for future in [pool.submit(task, item) for item in items]:
            future.result()
    finally:
        # on an error or Ctrl-C the queued tasks are dropped, not run to the end
        pool.shutdown(wait=True, cancel_futures=True)


#: Exploration (multistart, continuation) stops sweeps at this relative change; the final
#: polish at POLISH_TOL, so that members touching a bound are not cut off by rounding.
EXPLORE_TOL = 1e-6
POLISH_TOL = 1e-11


def box_extreme(G, q0, ylin, H, kr, ki, starts, want_max, cap=None, max_sweeps=20, rounds=2):
    """Max (``want_max``) or min of ``M = max_b |y_b|`` over the box at every frequency.

    The maximum is sought beam by beam (the maximum over the box of a maximum over beams
    is the largest of the beams' own maxima): a beam whose response hardly depends on the
    dampers would otherwise hold a search of M on a plateau while another beam could
    still grow. The minimum is sought for M itself.

    Parameters
    ----------
    G : ndarray of complex, shape (n_f, nd, nd)
        ``B D11 B^T``, m/N.
    q0 : ndarray of complex, shape (n_f, nd)
        Relative contact displacement of the uncoupled array, m.
    ylin : ndarray of complex, shape (n_f, nb)
        Uncoupled output displacement of the beams in the metric, m.
    H : ndarray of complex, shape (n_f, nb, nd)
        Output displacement per unit damper force, m/N.
    kr, ki : float
        Box limits of Re K and Im K, N/m.
    starts : ndarray of complex, shape (n_f, n_start, nd)
        Starting points per frequency in normalised box coordinates (``Re, Im in
        [0, 1]``). Different random starts at different frequencies, joined by the
        continuation along frequency, explore far more of the box than the same starts
        everywhere.
    want_max : bool
    cap : ndarray, shape (n_f, nb), optional
        For the maximum: stop searching beam b at frequency k once ``|y_b|`` reaches
        ``cap[k, b]`` (its force bound: beyond it the box no longer sets the bound).
    max_sweeps : int
        Coordinate sweeps per local search.
    rounds : int
        Upward-and-downward continuation passes (stops early when nothing improves).

    Returns
    -------
    best : ndarray, shape (n_o, n_f)
        The extreme found per objective (one per beam for the maximum, M for the
        minimum), m (NaN where every start failed). A capped maximum may stop anywhere
        at or above its cap.
    K_best : ndarray of complex, shape (n_o, n_f, nd)
        Describing functions reaching it, N/m.
    """
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    objectives = np.arange(nb) if want_max else np.array([-1])
    n_o = len(objectives)
    if cap is None or not want_max:
        cap = np.full((n_f, n_o), np.inf)
    cap = np.ascontiguousarray(cap, dtype=float)
    best = np.full((n_o, n_f), np.nan)
    K_best = np.zeros((n_o, n_f, nd), complex)
    chunks = _chunks(n_f)
    hr, gr = _sparsity(G, H)
    _in_threads(lambda freqs: _multistart(G, q0, ylin, H, hr, gr, kr, ki, starts, want_max,
                                          objectives, cap, max_sweeps, EXPLORE_TOL, best,
                                          K_best, freqs), chunks)
    cand = np.empty((2, n_o, n_f))
    K_cand = np.empty((2, n_o, n_f, nd), complex)
    pick = np.nanargmax if want_max else np.nanargmin
    idx = np.arange(n_f)
    ran = np.zeros((2, n_o, n_f), dtype=np.bool_)
    # the maximum's local searches are coordinate searches alone (see _SPG_ITER)
    spg_continuation = 0 if want_max else _SPG_ITER_CONTINUATION
    for r in range(rounds):
        # one chain per direction and objective, interleaved by direction
        _in_threads(lambda t: _chain(t % 2, t // 2, G, q0, ylin, H, hr, gr, kr, ki, want_max,
                                     objectives, cap, max_sweeps, EXPLORE_TOL, spg_continuation,
                                     best, K_best, cand, K_cand, r == 0, ran),
                    range(2 * n_o))
        any_better = False
        for o in range(n_o):
            c = cand[:, o]
            allnan = np.all(np.isnan(c), axis=0)
            d = pick(np.where(allnan[None, :], -np.inf if want_max else np.inf, c), axis=0)
            new = np.where(allnan, np.nan, c[d, idx])
            with np.errstate(invalid="ignore"):
                better = np.isfinite(new) & (np.isnan(best[o]) |
                                             ((new > best[o]) if want_max else (new < best[o])))
            best[o] = np.where(better, new, best[o])
            K_best[o][better] = K_cand[d[better], o, idx[better]]
            any_better |= bool(better.any())
        if not any_better:
            break
    if want_max:
        # tight searches of the maximum are cheap (no interior search), and the maximum
        # is sensitive to the path: tight from the start
        sweeps, tol, end_sweeps, end_tol = 5 * max_sweeps, POLISH_TOL, 0, 0.0
        spg_iter = 0
    else:
        # the minimum's tight sweeps are costly (interior searches) and stall on its ridge:
        # explore, then one tight sweep, then the minimax search. Measured (1000
        # frequencies, 0.25 and 1.1 N): the lower bound within 2e-5 of 100 tight sweeps
        # (without the tight sweep up to 1 % higher at 2-4 frequencies), 0.1 s less at
        # one thread
        sweeps, tol, end_sweeps, end_tol = max_sweeps, EXPLORE_TOL, 1, POLISH_TOL
        spg_iter = _SPG_ITER
    _in_threads(lambda freqs: _polish(G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap,
                                      sweeps, tol, spg_iter, best, K_best, freqs, end_sweeps,
                                      end_tol), chunks)
    _evaluate(G, q0, ylin, H, objectives, best, K_best)
    return best, K_best
