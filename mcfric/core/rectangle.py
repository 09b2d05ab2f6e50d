"""Exact extremes of ``M = max_b |y_b|`` over one damper's rectangle of describing functions.

With all dampers but ``j`` fixed, every beam's output is a Moebius function of
``z = K_j`` with a common denominator, ``y_b(z) = (alpha_b + beta_b z) / (d0 + d1 z)``
(Sherman-Morrison on ``I + G diag(K)``); the system is passive for every ``K`` in the
box, so the denominator has no zero there. The extreme of ``M`` over the rectangle
``0 <= Re z <= kr``, ``0 <= Im z <= ki`` is then found exactly:

* maximum modulus: ``|y_b|`` is largest on the perimeter, and along an edge ``|y_b|^2``
  is a ratio of quadratics whose critical points solve a quadratic (end points and
  critical points are the candidates);
* for the minimum, ``M`` may dip inside: edges also take the pairwise crossings
  ``|y_b| = |y_c|``, and in ``w = 1 / (d0 + d1 z)`` every ``|y_b|`` is a weighted
  distance, so the interior minimum is the weighted 1-centre (:mod:`.one_centre`), kept
  if it maps back inside the rectangle. Above ``PRUNE_BEAMS`` beams an edge makes
  candidates only inside the hull where every beam is below the best value, and only
  of beams that can be on top there (the same minimum, without all O(nb^2) pairs).

The docs' bounds page explains where this sits in the search.
"""

import math

from ._jit import inline_jit, jit
from .one_centre import one_centre, quad_roots


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


#: The minimum's edges are pruned (:func:`_edge_candidates`) above this many beams: below
#: it the pairwise crossings cost little, and on chains pruning changes the search's path
#: through ties (the same edge minima, other local minima found: docs/performance.md).
PRUNE_BEAMS = 16
#: Widening of each beam's below-the-best interval, in the edge parameter: far more than
#: the rounding of a quadratic's roots, so no candidate that could improve is dropped.
HULL_SLACK = 1e-6


@inline_jit
def _below_hull(c2, c1, c0):
    """Hull ``(lo, hi)`` within [0, 1] of the ``t`` where ``c2 t^2 + c1 t + c0 < 0``,
    widened by ``HULL_SLACK``; ``lo > hi`` where there is none."""
    r1, r2 = quad_roots(c2, c1, c0)
    if c2 == 0.0:
        if math.isnan(r1):                      # constant
            return (0.0, 1.0) if c0 < 0.0 else (1.0, 0.0)
        lo, hi = (r1, 1.0) if c1 < 0.0 else (0.0, r1)
    elif math.isnan(r1) or math.isnan(r2):      # no real root: one sign throughout
        return (0.0, 1.0) if c2 < 0.0 else (1.0, 0.0)
    else:
        if r1 > r2:
            r1, r2 = r2, r1
        if c2 > 0.0:                            # between the roots
            lo, hi = r1, r2
        else:                                   # outside them: the hull of both pieces
            lo = 0.0 if r1 > 0.0 else r2
            hi = 1.0 if r2 < 1.0 else r1
    return max(0.0, lo - HULL_SLACK), min(1.0, hi + HULL_SLACK)


@inline_jit
def _ratio(a0, a1, a2, c0, c1, c2, t):
    """``|y_b|^2`` at ``t`` on an edge: ``(a2 t^2 + a1 t + a0) / (c2 t^2 + c1 t + c0)``."""
    return (a0 + t * (a1 + t * a2)) / (c0 + t * (c1 + t * c2))


@inline_jit
def _range_on(E, b, c0, c1, c2, lo, hi):
    """Smallest and largest ``|y_b|^2`` for ``t`` in [lo, hi] (rows 0-4 of ``E`` as
    :func:`_edge_candidates` leaves them)."""
    fmin = math.inf
    fmax = 0.0
    for t in (lo, hi, E[3, b], E[4, b]):
        if t >= lo and t <= hi:
            v = _ratio(E[0, b], E[1, b], E[2, b], c0, c1, c2, t)
            fmin = min(fmin, v)
            fmax = max(fmax, v)
    return fmin, fmax


@inline_jit
def _edge_candidates(alpha, beta, d0, d1, z0, z1, want_max, b0, b1, best_val, best_z, pair,
                     E, first):
    """Best ``M`` on the segment ``z0 -> z1``, exactly (see module docstring).

    Updates and returns (best_val, best_z, b): ``b`` the beam that ruled the edge out
    (else ``first``), tried ``first`` on the next edge. ``pair``: the minimum (also
    pairwise crossings). ``E``: scratch, shape (>= 6, nb).
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
    # for the minimum, the part of the edge where every beam is below ``lim`` (its hull
    # [lo, hi]): a candidate outside it has some |y_b| above the best value, so it
    # cannot improve; when the hull is empty the O(nb^2) pairwise crossings are skipped
    prune = pair and n > PRUNE_BEAMS
    lo = 0.0
    hi = 1.0
    for i in range(n):
        b = b0 + (first - b0 + i) % n
        A = alpha[b] + beta[b] * z0
        B = beta[b] * dz
        a0 = A.real * A.real + A.imag * A.imag
        a1 = 2.0 * (A.real * B.real + A.imag * B.imag)
        a2 = B.real * B.real + B.imag * B.imag
        r1, r2 = quad_roots(a2 * c1 - a1 * c2, 2.0 * (a2 * c0 - a0 * c2), a1 * c0 - a0 * c1)
        E[0, b] = a0
        E[1, b] = a1
        E[2, b] = a2
        E[3, b] = r1
        E[4, b] = r2
        if pair:
            emin = min(a0 / c0, (a0 + a1 + a2) / (c0 + c1 + c2))
            for t in (r1, r2):
                if t > 0.0 and t < 1.0:
                    emin = min(emin, _ratio(a0, a1, a2, c0, c1, c2, t))
            if emin >= lim:
                # M >= |y_b| >= best on the whole edge: nothing here can lower it
                return best_val, best_z, b
            if prune:
                blo, bhi = _below_hull(a2 - lim * c2, a1 - lim * c1, a0 - lim * c0)
                lo = max(lo, blo)
                hi = min(hi, bhi)
    top = 0.0
    if prune:
        if lo > hi:
            return best_val, best_z, first
        # the minimum of M inside [lo, hi] is a stationary point of the beam on top there
        # or a crossing of two beams on top: a beam whose largest value in [lo, hi] is
        # below another's smallest is never on top, and makes no candidates (row 5)
        for b in range(b0, b1):
            fmin, fmax = _range_on(E, b, c0, c1, c2, lo, hi)
            E[5, b] = fmax
            top = max(top, fmin)
        top *= 1.0 - 1e-6
    for b in range(b0, b1):
        if prune and E[5, b] < top:
            continue
        a0 = E[0, b]
        a1 = E[1, b]
        a2 = E[2, b]
        for t in (E[3, b], E[4, b]):
            if t > lo and t < hi:       # (lo, hi) = (0, 1) unless pruned
                if want_max:
                    # the edge maximum of M is the largest of each beam's own maximum:
                    # beam b's candidates need only |y_b|
                    v = math.sqrt(_ratio(a0, a1, a2, c0, c1, c2, t))
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
                if prune and E[5, c] < top:
                    continue
                s1, s2 = quad_roots(E[2, c] - a2, E[1, c] - a1, E[0, c] - a0)
                for t in (s1, s2):
                    if t > lo and t < hi:
                        z = z0 + t * dz
                        if _dominated(alpha[b], beta[b], d0, d1, z, best_val):
                            continue
                        v = _metric(alpha, beta, d0, d1, z, b0, b1)
                        if v < best_val:
                            best_val = v
                            best_z = z
    return best_val, best_z, first


@jit
def _interior_min(alpha, beta, d0, d1, kr, ki, b0, b1, E):
    """The minimum of ``M`` over the rectangle's interior, exactly, if it lies inside.

    In ``w = 1 / (d0 + d1 z)``, ``|y_b| = rho_b |w - c_b|``: M is a maximum of weighted
    distances, convex, with one minimiser (the weighted 1-centre, :func:`one_centre`).
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
    wx, wy = one_centre(E, b0, b1)
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
def best_on_rectangle(alpha, beta, d0, d1, kr, ki, want_max, z_now, b0, b1, interior, E):
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
