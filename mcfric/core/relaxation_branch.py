"""A branch and bound whose bounds are semidefinite relaxations of sub-boxes.

The relaxation of the whole box (:mod:`.relaxation`) is exact for one damper but can be
loose on a chain: its rectangle forms hold each damper separately, not their coupling.
Over a smaller box the forms are tighter, and the extreme over the box is the extreme of
the extremes over its parts. So the box is split, one side of one damper's rectangle in
half at a time, and each part is relaxed (its forms built from the part's rectangles,
:func:`.relaxation.forms`). Every bound is a verified relaxation (or its parent's, where
the part's relaxation verifies nothing: a part lies inside its parent), so the extreme
over the open parts is as valid as the whole box's.

Which side to split decides how fast this closes. It is chosen by *pseudo-costs*: the
mean gain per unit width each split of that side brought so far, times the side's
width in the part; the gains are started by splitting every side of the whole box once
(four relaxations per damper). For an upper bound the damper is chosen by how much the
part's relaxation mixes its describing function (:func:`.relaxation.spread`, per squared
diagonal of its rectangle) times its better side's pseudo-cost score, and its
relatively wider side is split.

A part's relaxation starts from its parent's multipliers (:func:`.relaxation.inherit`:
they keep ``Z`` positive definite on the part), taken from an iterate of the parent's
barrier still well inside its cone; the whole box is relaxed once more to start its
parts. This halves the Newton steps; every bound is still a verified one.

On a chain that is its own mirror image (the same dampers in reverse order, a drive
that is symmetric or antisymmetric), beam ``nb - 1 - b``'s largest response is beam
``b``'s: the parts that proved beam ``b``'s bound, reversed with their multipliers, are
checked as beam ``nb - 1 - b``'s certificate (:func:`mirrored`) instead of splitting the
box again. The check is a verification on the beam's own forms, so it is as sound on
any chain; where the chain is not symmetric it just fails and the beam is split.
"""

import math

import numpy as np

from ._jit import jit
from .relaxation import buffers, forms, per_damper, relaxed_bound, rounded, shifted, spread, weights

#: The branch and bound gives up where no single split of the whole box closes this
#: fraction of the gap between its bound and the goal.
STALL = 0.02

#: The beams after the first (the one of largest bound) share what it leaves of the
#: budget plus this fraction of it: where the first spends it all, the others would
#: otherwise keep their bounds of the whole box, often the frequency's largest.
TAIL = 0.25


@jit
def _split(lo, hi, j, side, lo2, hi2):
    """The two halves of the part ``[lo, hi]``: ``lo``/``hi`` become the lower half and
    ``lo2``/``hi2`` the upper one, split at the middle of damper ``j``'s real
    (``side == 0``) or imaginary side."""
    lo2[:] = lo
    hi2[:] = hi
    if side == 0:
        mid = 0.5 * (lo[j].real + hi[j].real)
        hi[j] = complex(mid, hi[j].imag)
        lo2[j] = complex(mid, lo2[j].imag)
    else:
        mid = 0.5 * (lo[j].imag + hi[j].imag)
        hi[j] = complex(hi[j].real, mid)
        lo2[j] = complex(lo2[j].real, mid)


@jit
def _bounded(b, parent, upper):
    """A part's bound: its relaxation's ``b``, or its parent's where that is better or
    ``b`` is ``nan`` (the part lies inside its parent)."""
    if np.isnan(b):
        return parent
    return min(b, parent) if upper else max(b, parent)


@jit
def _extreme(val, n, sgn):
    """The index of the part with the extreme bound among the first ``n`` (the largest
    for ``sgn = 1``, the smallest for ``-1``)."""
    best = 0
    for i in range(1, n):
        if sgn * val[i] > sgn * val[best]:
            best = i
    return best


@jit
def parts(nd, m, budget):
    """Room for the parts of :func:`branch` with ``budget`` relaxations, ``nd`` dampers
    and ``m`` multipliers: ``(los, his, val, th, fin)``, each part's rectangles (N/m),
    bound (m), saved multipliers and ratio (a start for its halves) and verified
    multipliers (unscaled, :func:`.relaxation.weights`; NaN where none)."""
    n = max(budget + 2, 4)
    return (np.zeros((n, nd), np.complex128), np.empty((n, nd), np.complex128),
            np.empty(n), np.full((n, m + 1), np.nan), np.full((n, m), np.nan))


@jit
def _keep(b, x, V, idx, S, ws, per, w, upper, fin, spr):
    """After a part's relaxation (bound ``b``, ``nan`` if none verified; its forms in
    ``S``): ``fin`` its verified multipliers ``x``, unscaled (NaN if none), and for an
    upper bound ``spr`` its :func:`.relaxation.spread` (0 if none)."""
    spr[:] = 0.0
    if np.isnan(b):
        fin[0] = np.nan
        return
    weights(S, len(spr), per, w)
    for i in range(len(x)):
        fin[i] = x[i] * w[i]
    if upper:
        spread(x, V, idx, S, ws, spr)


@jit
def mirror_sign(G, q0, ylin, H):
    """``s = +1`` or ``-1`` where the chain is its own mirror image (dampers and beams
    in reverse order, ``G`` the same, ``q0`` and ``H`` times ``s``, ``ylin`` the same;
    to ``1e-9`` of each array's largest entry), else ``0``. Only a hint: the mirrored
    certificates of :func:`mirrored` are verified anyway."""
    nd, nb = len(q0), len(ylin)
    tol = 1e-9
    gm = np.abs(G).max()
    for i in range(nd):
        for j in range(nd):
            if abs(G[nd - 1 - i, nd - 1 - j] - G[i, j]) > tol * gm:
                return 0
    ym = np.abs(ylin).max()
    for b in range(nb):
        if abs(ylin[nb - 1 - b] - ylin[b]) > tol * ym:
            return 0
    qm = np.abs(q0).max()
    hm = np.abs(H).max()
    for s in (1.0, -1.0):
        ok = True
        for j in range(nd):
            if abs(q0[nd - 1 - j] - s * q0[j]) > tol * qm:
                ok = False
        for b in range(nb):
            for j in range(nd):
                if abs(H[nb - 1 - b, nd - 1 - j] - s * H[b, j]) > tol * hm:
                    ok = False
        if ok:
            return int(s)
    return 0


@jit
def mirrored(G, q0, ylin, H, F_lim, beam, goal, prt, n, V, idx, S, x, cvec, pos, simplex,
             grow, ws, stats):
    """A bound of ``|y_beam|`` (m) from the ``n`` parts ``prt`` (:func:`parts`) that
    proved the mirror beam's: on a chain that is its own mirror image the mirrored
    parts (dampers reversed) cover the box too, and each part's multipliers, reversed
    with it, are this beam's certificate there; each is verified
    (:func:`.relaxation.shifted`), and where it does not prove ``goal`` the part is
    relaxed once, started from them. Returns the largest (``nan`` where a part stays
    above ``goal``: then the beam is split itself) and the relaxations used."""
    los, his, val, th, fin = prt
    nd = len(q0)
    m = len(x)
    per = per_damper(np.isfinite(F_lim))
    lo = np.empty(nd, np.complex128)
    hi = np.empty(nd, np.complex128)
    w = np.empty(m)
    theta = np.empty(m + 1)
    worst = 0.0
    used = 0
    for i in range(n):
        for j in range(nd):
            lo[j] = los[i, nd - 1 - j]
            hi[j] = his[i, nd - 1 - j]
        b = np.nan
        if not np.isnan(fin[i, 0]):
            shift, ys = forms(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos,
                              simplex, grow)
            weights(S, nd, per, w)
            _reverse(fin[i], nd, per, x)
            for k in range(m):
                x[k] /= w[k]
            t = shifted(x, shift, V, idx, S, pos, simplex, ws)
            if not np.isnan(t):
                b = math.sqrt(max(t, 0.0) * ys) * (1.0 + 1e-14)
            stats[4] += 1
        if not b <= goal and not np.isnan(th[i, 0]):
            _reverse(th[i], nd, per, theta)
            b = relaxed_bound(G, q0, ylin, H, lo, hi, F_lim, beam, goal, V, idx, S, x,
                              cvec, pos, simplex, grow, ws, stats, theta, lo, hi)
            used += 1
        if not b <= goal:
            return np.nan, used
        worst = max(worst, b)
    return worst, used


@jit
def _reverse(a, nd, per, out):
    """``out``: the multipliers ``a`` with the dampers' forms in reverse order (the
    rest as they are)."""
    out[:] = a
    for j in range(nd):
        for f in range(per):
            out[j * per + f] = a[(nd - 1 - j) * per + f]


@jit
def branch(G, q0, ylin, H, kr, ki, F_lim, beam, root, goal, budget, V, idx, S, x, cvec,
           pos, simplex, grow, ws, stats, K_round, prt):
    """A bound over the box ``[0, kr] x [0, ki]`` proved by relaxing its parts: of
    ``|y_beam|`` from above (``beam >= 0``) or of ``max_b |y_b|`` from below (``beam <
    0``), m. ``root`` is a bound of the whole box already proved (m); the branch and
    bound stops once the extreme over the open parts reaches ``goal`` or after
    ``budget`` relaxations. Returns the bound, the relaxations used and the number of
    parts, which ``prt`` (:func:`parts`, room for ``budget``) holds on return.

    Where it stops short of ``goal``, the ``len(K_round) // 2`` open parts of extreme
    bound are relaxed once more (in ``stats``, not in ``used``) and their
    :func:`.relaxation.rounded` points written to ``K_round`` (N/m; rows left as they
    are where none): starts for a witness. Over a part the relaxation is tighter than
    over the box, and a part holds one of a mirror pair of optima where the whole box's
    primal point mixes them.
    """
    nd = len(q0)
    upper = beam >= 0
    sgn = 1.0 if upper else -1.0
    los, his, val, th, fin = prt
    n_max = min(max(budget + 2, 4), len(val))
    los[0, :] = 0.0
    for j in range(nd):
        his[0, j] = complex(kr, ki)
    val[0] = root
    n = 1
    gain = np.zeros((nd, 2))
    count = np.zeros((nd, 2))
    lo2 = np.empty(nd, np.complex128)
    hi2 = np.empty(nd, np.complex128)
    plo = np.empty(nd, np.complex128)
    phi = np.empty(nd, np.complex128)
    # each part's multipliers, the start of its parts' relaxations (relaxed_bound)
    m = len(x)
    per = per_damper(np.isfinite(F_lim))
    w = np.empty(m)
    th[0, 0] = np.nan
    th2 = np.empty(m + 1)
    th3 = np.empty(m + 1)
    fin2 = np.empty(m)
    fin3 = np.empty(m)
    # each part's spread of K_j (upper bounds: which damper to split)
    spr = np.zeros((n_max, nd))
    spr2 = np.zeros(nd)
    spr3 = np.zeros(nd)
    b0 = relaxed_bound(G, q0, ylin, H, los[0], his[0], F_lim, beam, goal, V, idx, S, x,
                       cvec, pos, simplex, grow, ws, stats, th[0], los[0], his[0])
    _keep(b0, x, V, idx, S, ws, per, w, upper, fin[0], spr[0])
    val[0] = _bounded(b0, root, upper)
    root = val[0]
    used = 1
    # the pseudo-costs' start: every side of the whole box split once (widths 1); the
    # best split's halves are the first open parts
    if budget >= 4 * nd + 2:
        pick = -1.0
        for j in range(nd):
            for side in range(2):
                los[2] = los[0]
                his[2] = his[0]
                _split(los[2], his[2], j, side, lo2, hi2)
                th2[:] = th[0]
                th3[:] = th[0]
                b1 = relaxed_bound(G, q0, ylin, H, los[2], his[2], F_lim, beam, goal, V,
                                   idx, S, x, cvec, pos, simplex, grow, ws, stats, th2,
                                   los[0], his[0])
                _keep(b1, x, V, idx, S, ws, per, w, upper, fin2, spr2)
                b2 = relaxed_bound(G, q0, ylin, H, lo2, hi2, F_lim, beam, goal, V, idx, S,
                                   x, cvec, pos, simplex, grow, ws, stats, th3, los[0],
                                   his[0])
                _keep(b2, x, V, idx, S, ws, per, w, upper, fin3, spr3)
                b1 = _bounded(b1, root, upper)
                b2 = _bounded(b2, root, upper)
                used += 2
                g = max(sgn * (root - sgn * max(sgn * b1, sgn * b2)), 0.0) / max(root, 1e-300)
                gain[j, side] = g + 1e-6
                count[j, side] = 1.0
                if g > pick:
                    pick = g
                    los[1] = los[2]
                    his[1] = his[2]
                    val[1] = b1
                    th[1] = th2
                    fin[1] = fin2
                    spr[1] = spr2
                    los[3] = lo2
                    his[3] = hi2
                    val[3] = b2
                    th[3] = th3
                    fin[3] = fin3
                    spr[3] = spr3
        if pick < STALL * sgn * (root - goal) / max(root, 1e-300):
            # no side's split gains: more of them will not either (measured)
            return root, used, 1
        for a, c in ((0, 1), (1, 3)):
            los[a] = los[c]
            his[a] = his[c]
            val[a] = val[c]
            th[a] = th[c]
            fin[a] = fin[c]
            spr[a] = spr[c]
        n = 2
    while used + 2 <= budget:
        best = _extreme(val, n, sgn)
        if sgn * val[best] <= sgn * goal:
            break
        if n + 1 >= n_max:
            break
        width = np.empty((nd, 2))
        pick_j = np.int64(0)
        pick_s = np.int64(0)
        score = -1.0
        for j in range(nd):
            width[j, 0] = (his[best, j].real - los[best, j].real) / kr
            width[j, 1] = (his[best, j].imag - los[best, j].imag) / ki
            for side in range(2):
                sc = gain[j, side] / max(count[j, side], 1.0) * width[j, side]
                if sc > score:
                    score = sc
                    pick_j = j
                    pick_s = side
        if upper and spr[best].max() > 0.0:
            score = -1.0
            for j in range(nd):
                d2 = (width[j, 0] * kr) ** 2 + (width[j, 1] * ki) ** 2
                sc = spr[best, j] / max(d2, 1e-300) * max(
                    gain[j, 0] / max(count[j, 0], 1.0) * width[j, 0],
                    gain[j, 1] / max(count[j, 1], 1.0) * width[j, 1])
                if sc > score:
                    score = sc
                    pick_j = j
                    pick_s = 0 if width[j, 0] >= width[j, 1] else 1
        parent = val[best]
        plo[:] = los[best]
        phi[:] = his[best]
        _split(los[best], his[best], pick_j, pick_s, los[n], his[n])
        th[n] = th[best]
        for i in (best, n):
            b = relaxed_bound(G, q0, ylin, H, los[i], his[i], F_lim, beam, goal, V, idx, S,
                              x, cvec, pos, simplex, grow, ws, stats, th[i], plo, phi)
            _keep(b, x, V, idx, S, ws, per, w, upper, fin[i], spr[i])
            val[i] = _bounded(b, parent, upper)
        used += 2
        worst = sgn * max(sgn * val[best], sgn * val[n])
        n += 1
        gain[pick_j, pick_s] += (max(sgn * (parent - worst), 0.0) / max(parent, 1e-300)
                                 / max(width[pick_j, pick_s], 1e-12))
        count[pick_j, pick_s] += 1.0
    extreme = val[_extreme(val, n, sgn)]
    if sgn * extreme > sgn * goal:
        Kc = np.empty((2, nd), np.complex128)
        for r in range(len(K_round) // 2):
            i = _extreme(val, n, sgn)
            if not np.isfinite(val[i]):
                break
            th2[:] = th[i]
            # for its primal point only: a failure here loses no bound, so is not counted
            failed = stats[3]
            relaxed_bound(G, q0, ylin, H, los[i], his[i], F_lim, beam, goal, V, idx, S, x,
                          cvec, pos, simplex, grow, ws, stats, th2, los[i], his[i])
            stats[3] = failed
            if rounded(x, V, idx, S, kr, ki, F_lim, ws, Kc):
                K_round[2 * r:2 * r + 2] = Kc
            val[i] = -sgn * np.inf
    return extreme, used, n


@jit(nogil=True)
def branch_frequencies(G, q0, ylin, H, kr, ki, F_lim, want_max, cert, target, budget,
                       freqs, beam_bounds, out, stats, K_round):
    """Certified bounds at ``freqs`` tightened by :func:`branch`: ``out[k]`` the upper
    bound of ``max_b |y_b|`` (``want_max``) or the lower one (m), never looser than
    ``cert[k]``, aiming at ``target[k]``, with at most ``budget`` relaxations per
    frequency (the upper bound's beams after the first: ``TAIL * budget`` more). For
    the lower bound, ``K_round[k]`` (shape (2 r, nd), N/m) receives the
    rounded points of the ``r`` open parts of least bound where the target is not met.

    The upper bound takes the beams in decreasing order of ``beam_bounds[k]`` (each
    beam's proven bound, m, updated in place) and stops at the first at or below the
    running maximum or ``target[k]``; each beam's branch and bound stops once it proves
    the beam below both. On a chain that is its own mirror image a beam whose mirror
    beam was just proved takes its mirrored parts (:func:`mirrored`) and is split only
    where they fail. ``stats`` (int64, shape (5,)): Newton steps, barrier rounds,
    relaxations, failed relaxations (nothing verified) and mirrored parts verified are
    added to it.
    """
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    V, idx, S, x, cvec, pos, simplex, grow, ws = buffers(nd, nb, np.isfinite(F_lim),
                                                         not want_max)
    # the first beam may spend the whole budget; the others get a share more (TAIL)
    share = np.int64(TAIL * budget)
    prt = parts(nd, len(x), budget + share)
    none = np.empty((0, nd), np.complex128)
    for k in freqs:
        if not want_max:
            b, _, _ = branch(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, np.int64(-1), cert[k],
                             target[k], budget, V, idx, S, x, cvec, pos, simplex, grow, ws,
                             stats, K_round[k], prt)
            out[k] = max(cert[k], b)
            continue
        sym = mirror_sign(G[k], q0[k], ylin[k], H[k]) != 0
        left = budget
        R = 0.0
        last = -1
        n_last = np.int64(0)
        for i, b in enumerate(np.argsort(-beam_bounds[k])):
            bound = beam_bounds[k, b]
            goal = max(R, target[k])
            if bound <= goal:
                # the rest are no higher
                R = max(R, bound)
                break
            if i == 1:
                left += share
            if left >= 6:
                got = np.nan
                if sym and last == nb - 1 - b:
                    got, used = mirrored(G[k], q0[k], ylin[k], H[k], F_lim, b, goal, prt,
                                         n_last, V, idx, S, x, cvec, pos, simplex, grow,
                                         ws, stats)
                    left -= used
                if np.isnan(got) and left >= 6:
                    got, used, n_last = branch(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, b,
                                               bound, goal, left, V, idx, S, x, cvec, pos,
                                               simplex, grow, ws, stats, none, prt)
                    last = b
                    left -= used
                if not np.isnan(got):
                    bound = min(bound, got)
                beam_bounds[k, b] = bound
            R = max(R, bound)
        out[k] = min(cert[k], R)
