"""Coordinate ascent of one beam's response over the admissible set: upper witnesses.

The certified upper bound's witness must be admissible: every damper inside its
rectangle *and* at or below the force limit, ``|K_j q_j| <= F_lim``. The box searches
ignore the force limit, so their optimum is often not admissible, and the corners are
poor witnesses. :func:`ascend` climbs ``|y_b|`` inside the admissible set one damper at a
time.

Changing damper j alone, ``K_j -> K_j + D``, is a rank-one update of ``I + G diag(K)``.
With ``u = (I + G diag(K))^{-1} G e_j`` and ``s = D q_j / (1 + D u_j)``:

* the outputs are ``y - s w``, with ``w = H e_j - H diag(K) u``;
* damper i's force (``i != j``) is ``p_i - K_i u_i s``, damper j's
  ``K_j (q_j - s u_j) + s``;
* ``K_j + D = K_j + s / (q_j - s u_j)``.

Every force is affine in ``s``, so each force limit is a disc in the ``s``-plane, and the
rectangle of ``K_j`` maps to a region bounded by four circular arcs. ``|y_b - s w_b|`` is
convex in ``s``: its largest value over that region lies on the boundary, on a force
circle or on an edge of the rectangle. A step samples those curves (and takes each
circle's farthest point from the pole ``y_b / w_b`` exactly), keeps the admissible
candidates and moves to the best. Sweeps over the dampers repeat until a sweep gains less
than a given relative amount. The result is a local maximum of the sampled problem: a
witness, never a bound.
"""

import math

import numpy as np

from ._jit import jit
from .branch_bound import admissible_value, force_bounds
from .linalg import contact_solve, lu_solve

#: Candidates are kept this far inside the force limit (relative), so that rounding in
#: the final solve cannot push an accepted point over it.
_INSIDE = 1e-9
#: Halvings of the sample spacing around a step's best sample.
_ZOOMS = 12


@jit(nogil=True)
def workspace(nd):
    """Scratch arrays of :func:`ascend` for ``nd`` dampers."""
    c = np.complex128
    return (np.empty((nd, nd), c), np.empty(nd, np.int64), np.empty(nd, c),
            np.empty(nd, c), np.empty(nd, c), np.empty(nd, c))


@jit(nogil=True)
def _abs2(z):
    return z.real * z.real + z.imag * z.imag


@jit(nogil=True)
def _consider(s, Kc, kr, ki, a, bco, F, yb, wb, best2):
    """``|yb - s wb|^2`` if ``s`` is admissible (``Kc``: damper j's new value) and beats
    ``best2``, else -1 (squares: no square roots in the inner loop)."""
    if not (-1e-12 * kr <= Kc.real <= kr * (1.0 + 1e-12)
            and -1e-12 * ki <= Kc.imag <= ki * (1.0 + 1e-12)):
        return -1.0
    v2 = _abs2(yb - s * wb)
    if not v2 > best2:
        return -1.0
    lim2 = (F * (1.0 - _INSIDE)) ** 2
    for i in range(a.shape[0]):
        if _abs2(a[i] + bco[i] * s) > lim2:
            return -1.0
    return v2


@jit(nogil=True)
def _point(c, t, a, bco, qj, uj, Kj, kr, ki, F):
    """Point ``t`` in [0, 1] of boundary curve ``c`` in the s-plane: force circle ``c``
    (``c < nd``, just inside the limit) or edge ``c - nd`` of the rectangle (bottom,
    right, top, left). Returns ``s``, damper j's new ``K`` and whether it exists."""
    nd = a.shape[0]
    if c < nd:
        if bco[c] == 0.0:
            return 0.0j, 0.0j, False
        th = 2.0 * math.pi * t
        s = (F * (1.0 - 2.0 * _INSIDE) * complex(math.cos(th), math.sin(th)) - a[c]) / bco[c]
        den = qj - s * uj
        if den == 0.0:
            return 0.0j, 0.0j, False
        return s, Kj + s / den, True
    e = c - nd
    if e == 0:
        Kn = complex(t * kr, 0.0)
    elif e == 1:
        Kn = complex(kr, t * ki)
    elif e == 2:
        Kn = complex(t * kr, ki)
    else:
        Kn = complex(0.0, t * ki)
    D = Kn - Kj
    den = 1.0 + D * uj
    if den == 0.0:
        return 0.0j, 0.0j, False
    return D * qj / den, Kn, True


@jit(nogil=True)
def _farthest(c, a, bco, yb, wb):
    """Parameter ``t`` of force circle ``c``'s point farthest from the pole ``yb / wb``
    (where ``|yb - s wb|`` is largest on it); -1 for an edge or a degenerate circle."""
    if c >= a.shape[0] or bco[c] == 0.0 or wb == 0.0:
        return -1.0
    d = -a[c] / bco[c] - yb / wb
    if not abs(d) > 0.0:
        return -1.0
    # s - centre = F e^{i th} / bco points along d
    e = d * bco[c]
    return math.atan2(e.imag, e.real) / (2.0 * math.pi) % 1.0


@jit(nogil=True)
def _try(c, t, a, bco, qj, uj, Kj, kr, ki, F, yb, wb, best2):
    """:func:`_consider` at point ``t`` of curve ``c``: ``(|y_b|^2 or -1, damper j's K)``."""
    s, Kn, exists = _point(c, t, a, bco, qj, uj, Kj, kr, ki, F)
    if not exists:
        return -1.0, Kn
    return _consider(s, Kn, kr, ki, a, bco, F, yb, wb, best2), Kn


@jit(nogil=True)
def _step(G, q0, ylin, H, kr, ki, F, b, K, j, n_samples, ws):
    """Move damper ``j`` to the best admissible boundary point for beam ``b``: every curve
    sampled at ``n_samples`` points, then the best one's neighbourhood zoomed into
    (``_ZOOMS`` times, the spacing halved each time: sharp resonance peaks and corners
    where a force circle meets an edge). Returns ``|y_b|`` after the step (-1 if the
    system is singular)."""
    A, piv, q, u, a, bco = ws
    nd = q0.shape[0]
    if contact_solve(G, K, q0, A, piv, q, nd) != 0:
        return -1.0
    for r in range(nd):
        u[r] = G[r, j]
    lu_solve(A, piv, u, nd)
    yb = ylin[b]
    wb = H[b, j]
    for i in range(nd):
        p = K[i] * q[i]
        yb -= H[b, i] * p
        wb -= H[b, i] * K[i] * u[i]
        a[i] = p
        bco[i] = -K[i] * u[i]
    bco[j] = 1.0 - K[j] * u[j]
    qj = q[j]
    uj = u[j]
    Kj = K[j]
    best = _abs2(yb)
    k_best = Kj
    c_best = np.int64(-1)
    t_best = 0.0
    for c in range(nd + 4):
        # the samples, then (circles) the farthest point from the pole y_b / w_b
        for n in range(n_samples + 2):
            t = n / n_samples if n <= n_samples else _farthest(c, a, bco, yb, wb)
            if t < 0.0:
                continue
            v, Kn = _try(c, t, a, bco, qj, uj, Kj, kr, ki, F, yb, wb, best)
            if v > best:
                best = v
                k_best = Kn
                c_best = c
                t_best = t
    if c_best >= 0:
        h = 1.0 / n_samples
        for _ in range(_ZOOMS):
            h *= 0.5
            t0 = t_best
            for m in (-1.0, 1.0):
                t = t0 + m * h
                if c_best < nd:
                    t = t % 1.0
                elif not 0.0 <= t <= 1.0:
                    continue
                v, Kn = _try(c_best, t, a, bco, qj, uj, Kj, kr, ki, F, yb, wb, best)
                if v > best:
                    best = v
                    k_best = Kn
                    t_best = t
        K[j] = complex(min(max(k_best.real, 0.0), kr), min(max(k_best.imag, 0.0), ki))
    return math.sqrt(best)


@jit(nogil=True)
def ascend(G, q0, ylin, H, kr, ki, F_lim, b, K, max_sweeps, gain, n_samples, ws):
    """Coordinate ascent of ``|y_b|`` over the admissible set, from the admissible ``K``.

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        Contact-space arrays at one frequency (:mod:`.enclosure`), m/N and m.
    kr, ki : float
        Box limits of Re K and Im K, N/m.
    F_lim : float
        Force limit, N (finite).
    b : int
        The beam whose response is climbed.
    K : ndarray of complex, shape (nd,)
        In: an admissible start; out: the point reached, N/m.
    max_sweeps : int
        Sweeps over the dampers at most.
    gain : float
        Stop when a sweep raises ``|y_b|`` by less than this (relative).
    n_samples : int
        Samples per force circle and per edge of the rectangle.
    ws : tuple
        From :func:`workspace`.

    Returns
    -------
    float
        ``|y_b|`` at the point reached as the last step saw it, m (-1 if singular).
    """
    nd = q0.shape[0]
    last = -1.0
    for _ in range(max_sweeps):
        v = -1.0
        for j in range(nd):
            v = _step(G, q0, ylin, H, kr, ki, F_lim, b, K, j, n_samples, ws)
            if v < 0.0:
                return -1.0
        if last > 0.0 and v <= last * (1.0 + gain):
            return v
        last = v
    return last


@jit(nogil=True)
def values(G, q0, ylin, H, K, out):
    """``M`` at ``K[k]`` (N/m) per frequency into ``out`` (m; ``inf`` where singular):
    the box optimum's, where the first climb stops."""
    nd = q0.shape[1]
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    for k in range(len(out)):
        v, ok = admissible_value(G[k], q0[k], ylin[k], H[k], K[k], math.inf, T, piv, q)
        out[k] = v if math.isfinite(v) else math.inf


@jit(nogil=True)
def pulled_inside(G, q0, ylin, H, K, F_lim, limit, T, piv, q):
    """Scale ``K`` (in place) towards 0 until every damper force is at most ``limit``
    times ``F_lim``: first by ``0.999 limit`` over the largest ratio, then by 0.7 at a
    time (forces are not linear in ``K``), at most 12 times. Returns ``M`` there and
    whether it got inside (``nan`` if singular)."""
    nd = len(K)
    v, ok = admissible_value(G, q0, ylin, H, K, F_lim, T, piv, q)
    for shrink in range(12):
        if not math.isfinite(v):
            return v, False
        worst = 0.0
        for j in range(nd):
            worst = max(worst, abs(K[j] * q[j]) / F_lim)
        if worst <= limit:
            return v, True
        f = 0.999 * limit / worst if shrink == 0 else 0.7
        for j in range(nd):
            K[j] *= f
        v, ok = admissible_value(G, q0, ylin, H, K, F_lim, T, piv, q)
    return v, False


@jit(nogil=True)
def strictly_inside(G, q0, ylin, H, K, kr, ki, F_lim, inside, T, piv, q):
    """Move ``K`` (in place) at least ``inside`` (a fraction of the side) into the box
    ``[0, kr] x [0, ki]``, then pull it strictly inside the force limit
    (:func:`pulled_inside` to 0.999): a start for a barrier ascent. Returns whether it
    got there (``q`` then holds its contact solve)."""
    for j in range(len(K)):
        K[j] = complex(min(max(K[j].real / kr, inside), 1.0 - inside) * kr,
                       min(max(K[j].imag / ki, inside), 1.0 - inside) * ki)
    v, ok = pulled_inside(G, q0, ylin, H, K, F_lim, 0.999, T, piv, q)
    return ok


@jit(nogil=True)
def boxed_value(G, q0, ylin, H, K, kr, ki, F_lim, T, piv, q):
    """Clip ``K`` (in place) to the box ``[0, kr] x [0, ki]``; ``M`` there (m) if it is
    within the force limit, else ``-inf``: the end of a barrier ascent, checked."""
    for j in range(len(K)):
        K[j] = complex(min(max(K[j].real, 0.0), kr), min(max(K[j].imag, 0.0), ki))
    v, ok = admissible_value(G, q0, ylin, H, K, F_lim, T, piv, q)
    return v if ok and math.isfinite(v) else -math.inf


@jit(nogil=True)
def witnesses(G, q0, ylin, H, kr, ki, F_lim, K_given, n_pool, n_climb, n_beams, max_sweeps,
              gain, n_samples, seed, stop, freqs, K_out, M_out):
    """The best admissible point :func:`ascend` reaches at each frequency of ``freqs``.

    At frequency ``k`` the starts are the rows of ``K_given[k]`` (n_g, nd; each one
    outside the force limit pulled towards ``K = 0`` until it is inside) and ``n_pool``
    random points of the box, each damper's ``K`` uniform in the box scaled by one factor
    ``10^U(-3, 0)`` per point (drawn from ``seed + k``: the same whatever the thread).
    The ``n_climb`` admissible starts of largest ``M = max_b |y_b|`` are climbed, each
    for the ``n_beams`` beams with the largest force bound ``|ylin_b| + F_lim sum_j
    |H_bj|`` (those that can set the maximum), until a witness comes within ``1e-4`` of
    the smaller of that force bound and ``stop[k]`` (m; the caller's bound on the
    maximum, or the box optimum's ``M``): climbing further is wasted. The best point by
    ``M``, solved afresh and admissible, goes to ``K_out[k]`` (N/m) and its ``M`` (m) to
    ``M_out[k]`` (``-inf`` if no start was admissible).
    """
    nd = q0.shape[1]
    nb = ylin.shape[1]
    n_g = K_given.shape[1]
    ws = workspace(nd)
    K = np.empty(nd, np.complex128)
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    bound = np.empty(nb)
    pool = np.empty((n_g + n_pool, nd), np.complex128)
    value = np.empty(n_g + n_pool)
    for k in freqs:
        force_bounds(ylin[k], H[k], F_lim, bound)
        order = np.argsort(-bound)
        enough = min(bound[order[0]], stop[k]) * (1.0 - 1e-4)
        np.random.seed(seed + k)
        for r in range(n_g + n_pool):
            if r < n_g:
                pool[r, :] = K_given[k, r]
            else:
                f = 10.0 ** (-3.0 * np.random.random())
                for j in range(nd):
                    pool[r, j] = complex(f * kr * np.random.random(),
                                         f * ki * np.random.random())
            if r < n_g:
                # a given start beyond the force limit: a fraction of it inside
                v, ok = pulled_inside(G[k], q0[k], ylin[k], H[k], pool[r], F_lim, 1.0, T,
                                      piv, q)
            else:
                v, ok = admissible_value(G[k], q0[k], ylin[k], H[k], pool[r], F_lim, T, piv,
                                         q)
            value[r] = v if ok and math.isfinite(v) else -math.inf
        rank = np.argsort(-value)
        M_out[k] = -math.inf
        for c in range(min(n_climb, n_g + n_pool)):
            r = rank[c]
            if value[r] == -math.inf:
                break
            if value[r] > M_out[k]:
                M_out[k] = value[r]
                K_out[k, :] = pool[r]
            if M_out[k] >= enough:
                break
            for bi in range(min(n_beams, nb)):
                K[:] = pool[r]
                ascend(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, order[bi], K, max_sweeps,
                       gain, n_samples, ws)
                v, ok = admissible_value(G[k], q0[k], ylin[k], H[k], K, F_lim, T, piv, q)
                if ok and math.isfinite(v) and v > M_out[k]:
                    M_out[k] = v
                    K_out[k, :] = K
                if M_out[k] >= enough:
                    break
