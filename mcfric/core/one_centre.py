"""The weighted 1-centre: the point of the plane nearest, in the worst case, to weighted points.

The minimiser of ``max_b rho_b |w - c_b|`` over ``w`` in the plane (convex, one
minimiser, at most three points active), found by an Elzinga-Hearn iteration. The box
search of the bounds needs it for the interior minimum of ``M`` over one damper's
rectangle (:mod:`.rectangle`). Also the real roots of a quadratic, which the geometry
here and the rectangle's edges both need.
"""

import math

from ._jit import inline_jit


@inline_jit
def quad_roots(a, b, c):
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
    t1, t2 = quad_roots(al1, -2.0 * (b1x * ex + b1y * ey),
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
def one_centre(E, b0, b1):
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
