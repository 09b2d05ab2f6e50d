"""Resolved resonance peaks of each member's sweep, and folds between sweep directions.

A lightly damped resonance is narrower than a practical frequency grid (the first mode of
the paper's beams, zeta = 0.0017, is about 0.055 Hz wide), so the largest value of a
sweep on a grid underestimates the member's peak. After the sweep, for every member:

1. the local maxima of the metric ``M = max_b omega^p |y_b|`` over the grid are ranked
   (the metric, not each beam: ``M`` is what the bounds and the statistics are about);
   the ``n_peaks`` largest are refined (2, 3 and 5 below), and then every other whose
   grid value could belong to a higher peak than the ``n_peaks``-th refined so far (a
   resonance as wide as the narrowest mode, peaking midway between grid points:
   ``_hidden_fraction``);
   reported, ``n_peaks`` in all: the largest result, the unrefined maxima and open or
   unchecked folds of 5 (lower estimates; with one place, one of them instead of the
   largest, unless the largest is one), then the largest of the rest;
2. each is refined in frequency: parabolic steps on ``1/M^2`` from its grid neighbours
   (golden-section steps where no parabola fits, or where two steps have not halved the
   bracket: a parabola fitted across a corner of ``M``, where a damper starts to slip,
   creeps towards the top) for a peak broader than the grid; for a
   sharper one, or where that does not converge in a few steps, eight sub-intervals of
   the bracket are solved first and the best one is climbed the same way. ``M`` is a
   maximum over beams, so its top can be a kink where two beams cross: every beam within
   2 % of ``M`` there is then climbed on its own amplitude. Every new point is
   solved by continuation from the nearest solved point below it (so the refined peak is
   on the branch the upward sweep follows). The search stops when the nearest solved
   points on both sides of the best are within a quarter of ``rtol`` of it; the peak
   reported is the best point actually
   solved, never an interpolation;
3. each kept maximum's bracket and flanks are searched again: the first mode of
   coupled beams is a cluster of narrow resonances, and one of them can lie between two
   grid points beside the maximum (neither of them a local maximum), or in the bracket
   beside the one refined. Each grid interval of the bracket and within ``FLANK`` steps
   of it is solved at inner points ``FLANK_DENSITY`` per half-power width of the
   narrowest mode (continued from below), and any inner point above both its neighbours
   is climbed as above, and so is a grid point between two such intervals above the
   inner points on both sides of it; around the refined peak's own sample (an inner point or a grid
   point), each side is solved ``N_FLANK`` times finer and searched the same way (two
   resonances closer than the spacing show as one bump). The best point found replaces
   the peak where it is higher. A flank
   that could not be solved or climbed, or a grid step of more than ``N_FLANK_MAX``
   widths, leaves the peak a lower estimate (``PEAK_GRID``);
4. the gap search: a resonance more than ``FLANK`` intervals from every kept bracket,
   hidden between grid points on a slope, can still peak above the member's largest
   value. Every other grid interval whose larger end could belong to a peak above that
   value (the width rule of 1) is searched as the flanks are, in stretches of
   consecutive intervals (with the interval beside a stretch again where a kept
   maximum's search covered it), climbing only samples that could belong to such a
   peak; a resonance found above the largest value becomes a refined peak of its own
   (with the fold check of 5), or raises the peak it belongs to, and a stretch that
   could not be searched makes a lower estimate. A member with a peak left at its
   grid value is not searched (past the largest value, a lower peak hidden so is not
   looked for);
5. the sweep is repeated downward over ``window`` grid points on each side of the peak,
   from the upward solution above it. Where the downward branch differs from the upward
   one (relative ``FOLD_RTOL`` in ``M``), the member has more than one steady state
   there: the fold is flagged and the downward branch's peak is refined the same way,
   continued from above (flagged open where it is a lower estimate: the branch from
   above is largest at the lowest point the downward sweep reached and still apart from
   the upward one there, or the refinement failed).

Points are solved from receptances formed here at each new frequency (per-member modal
frequencies allowed): on a chain or a ring of friction dampers by the O(nd) Newton of
:mod:`.chain_newton` in one lane, then, as for any other damper graph or contact law, by
the dense Newton of :mod:`.newton` with its fallbacks. A point that fails every solver is
skipped; a peak whose refinement failed keeps its grid value and says so in its status.
"""

import math

import numpy as np
from numba import prange

from . import chain_newton as cn
from ._jit import jit
from .friction import LAW_COULOMB
from .newton import levenberg_marquardt, newton, workspace
from .receptance import CONTACT, D11, D13, D21, D23, DRIVE, OUTPUT
from .sweep import g_entry

#: Status of a reported peak.
PEAK_REFINED = 0        # a local maximum, refined to rtol
PEAK_AT_EDGE = 1        # the largest values are at an end of the band: refined there
PEAK_GRID = 2           # not refined (a solver did not converge in the refinement or at a
                        # grid neighbour, where the peak may lie): the grid value
PEAK_NONE = -1          # fewer local maxima than asked (or no converged point): NaN
#: Fold flags.
FOLD_NONE = 0           # the downward sweep reproduces the upward one (or the peak is
                        # the band's last point: nothing above it to sweep down from)
FOLD_FOUND = 1          # the two directions reach different steady states
FOLD_OPEN = 2           # a fold whose branch from above was not followed to its peak (it
                        # is largest, and still apart, where the downward sweep ends, or
                        # its refinement failed): the downward peak is a lower estimate
FOLD_UNCHECKED = -1     # the downward sweep failed to converge somewhere, or the
                        # upward point it starts from did not: a branch from above unknown
#: Relative difference of M between the sweep directions that counts as another branch
#: (converged points agree to ~1e-9; the tolerance of the residual is 1e-10).
FOLD_RTOL = 1e-6
#: Sub-intervals of the bracket sampled before the golden-section search.
N_SUB = 8
#: Rank of an unrefined slot (or an open or unchecked fold) among the reported: above every value,
#: below the largest.
_GRID_KEY = 1e300
#: Parabolic (or golden-section) steps at most per peak.
MAX_STEPS = 40
#: Steps of the first climb from the grid neighbours alone, before sub-sampling.
QUICK_STEPS = 4
#: Grid intervals searched on each side of a kept grid maximum's bracket, and the
#: sub-intervals each is solved at: at least ``N_FLANK``, ``FLANK_DENSITY`` per half-power
#: width of the narrowest mode, ``2 zeta f``; a step of more than ``N_FLANK_MAX`` widths is
#: not searched
#: (a resonance hidden between grid points shows as an inner point above both its
#: neighbours).
FLANK = 2
N_FLANK = 4
#: Flank points per half-power width: at one, two resonances a width apart beside the
#: refined one can show as one bump
FLANK_DENSITY = 2
N_FLANK_MAX = 64
_INV_PHI = 0.6180339887498949


@jit
def _receptances_at(omega, r, modal_f, zeta, u, rec1):
    """``rec1[p, b]``: the four receptances of every beam at ``omega`` (rad/s), m/N."""
    n_beams, n_modes = zeta.shape
    for b in range(n_beams):
        d11 = d13 = d21 = d23 = 0.0j
        for k in range(n_modes):
            wk = 2.0 * math.pi * modal_f[r, b, k]
            den = complex(wk * wk - omega * omega, 2.0 * zeta[b, k] * wk * omega)
            inv = 1.0 / den
            uc, uo, ud = u[b, k, CONTACT], u[b, k, OUTPUT], u[b, k, DRIVE]
            d11 += uc * uc * inv
            d13 += uc * ud * inv
            d21 += uo * uc * inv
            d23 += uo * ud * inv
        rec1[D11, b] = d11
        rec1[D13, b] = d13
        rec1[D21, b] = d21
        rec1[D23, b] = d23


@jit
def _lane_newton(x, kc, c, act, G, q0, tol, max_iter, L, ring):
    """The chain or ring Newton of :mod:`.chain_newton` for one point in lane 0 of the
    scratch ``L``; on success ``x``, and ``K``, ``q`` in ``L``'s slots. Returns ok."""
    C, R, B, V, M = L
    nd = x.shape[0]
    for l in range(cn.LANES):
        M[cn.NEED_, l] = l == 0
    for j in range(nd):
        C[cn.GD_, j, 0] = G[j, j]
        C[cn.GU_, j, 0] = G[j, (j + 1) % nd] if ring or j < nd - 1 else 0.0j
        C[cn.Q0_, j, 0] = q0[j]
        R[cn.KC_, j, 0] = kc[j]
        R[cn.CC_, j, 0] = c[j]
        M[cn.ACT_ + j, 0] = act[j]
        R[cn.X_, j, 0] = x[j]
    cn.newton_lanes(tol, max_iter, C, R, B, V, M, nd, ring)
    if not M[cn.OK_, 0]:
        return False
    for j in range(nd):
        x[j] = R[cn.X_, j, 0]
    return True


@jit
def _solve_at(omega, r, modal_f, zeta, u, force, a, b, kc, c, act, x, tol, max_iter, w,
              rec1, G, q0, y, law, L, lanes):
    """Solve one frequency from the guess ``x`` (log s); fills ``y`` (output amplitudes
    of every beam, m) and ``x``. With ``lanes`` (a chain or a ring of friction dampers)
    the O(nd) Newton first, from the guess and from ``s = 1``; then Newton, Newton from
    ``s = 1`` and Levenberg-Marquardt, dense; returns False if all fail."""
    nd = a.shape[0]
    n_beams = force.shape[0]
    _receptances_at(omega, r, modal_f, zeta, u, rec1)
    d11 = rec1[D11]
    for j in range(nd):
        q0[j] = rec1[D13, a[j]] * force[a[j]] - rec1[D13, b[j]] * force[b[j]]
    for j in range(nd):
        if not math.isfinite(x[j]):
            x[j] = 0.0
    if lanes:
        # the O(nd) Newton reads G's diagonal and super-diagonal (and a ring's corner)
        # alone: the full G, nd^2 entries, only where the dense solvers must run
        for j in range(nd):
            G[j, j] = g_entry(d11, a, b, j, j)
            m = (j + 1) % nd
            G[j, m] = g_entry(d11, a, b, j, m)
        x0 = x.copy()
        ring = nd == n_beams
        # from the guess, then from s = 1 on the same Newton: the dense Newton from
        # s = 1 below costs O(nd^3) a step (minutes a member on 1500 beams)
        ok = _lane_newton(x, kc, c, act, G, q0, tol, max_iter, L, ring)
        if not ok:
            for j in range(nd):
                x[j] = 0.0
            ok = _lane_newton(x, kc, c, act, G, q0, tol, max_iter, L, ring)
        if ok:
            for bb in range(n_beams):
                y[bb] = rec1[D23, bb] * force[bb]
            for j in range(nd):
                fj = -L[0][cn.K_, j, 0] * L[0][cn.Q_, j, 0]
                y[a[j]] += rec1[D21, a[j]] * fj
                y[b[j]] -= rec1[D21, b[j]] * fj
            return True
        for j in range(nd):
            x[j] = x0[j]
    for j in range(nd):
        for m in range(nd):
            G[j, m] = g_entry(d11, a, b, j, m)
    ok, _ = newton(x, kc, c, act, G, q0, tol, max_iter, w, law)
    if not ok:
        for j in range(nd):
            x[j] = 0.0
        ok, _ = newton(x, kc, c, act, G, q0, tol, max_iter, w, law)
    if not ok:
        for j in range(nd):
            x[j] = 0.0
        ok, _ = levenberg_marquardt(x, kc, c, act, G, q0, tol, w, law)
    if not ok:
        return False
    K, q = w[0], w[1]
    for bb in range(n_beams):
        y[bb] = rec1[D23, bb] * force[bb]
    for j in range(nd):
        fj = -K[j] * q[j]
        y[a[j]] += rec1[D21, a[j]] * fj
        y[b[j]] -= rec1[D21, b[j]] * fj
    return True


@jit
def _metric_of(y, omega, beams, power):
    """``max over beams of omega^power |y_b|``."""
    m = 0.0
    for bb in beams:
        v = abs(y[bb])
        if not (v <= m):
            m = v
    return m * omega ** power


@jit
def _seed(om, x, y, m, S):
    """Store a solved point (omega, metric, state, responses) as the next point of
    ``S = (w, m, x, y, count)``; returns its index."""
    pw, pm, px, py, cnt = S
    n = cnt[0]
    pw[n] = om
    pm[n] = m
    for j in range(x.shape[0]):
        px[n, j] = x[j] if math.isfinite(x[j]) else 0.0
    for bb in range(y.shape[0]):
        py[n, bb] = y[bb]
    cnt[0] = n + 1
    return n


@jit
def _add_point(om, src, P, S):
    """Solve at ``om`` (rad/s) from the state ``src`` and store it as the next point of
    ``S = (w, m, x, y, count)``; returns its index, or -1 (not converged, or no room)."""
    (r, modal_f, zeta, u, force, a, b, kc, c, act, tol, max_iter, w, rec1, G, q0, beams,
     power, xs, ys, law, L, lanes) = P
    if S[4][0] >= S[0].shape[0]:
        return -1
    nd = a.shape[0]
    for j in range(nd):
        xs[j] = src[j]
    if not _solve_at(om, r, modal_f, zeta, u, force, a, b, kc, c, act, xs, tol, max_iter,
                     w, rec1, G, q0, ys, law, L, lanes):
        return -1
    return _seed(om, xs, ys, _metric_of(ys, om, beams, power), S)


@jit
def _guess(om, from_below, S, fallback, x):
    """The start at ``om``: extrapolated linearly in ``omega`` from the two solved points
    nearest to it on the side of continuation (below or above it); the nearest alone if
    there is one, ``fallback``'s state if none."""
    pw, px, cnt = S[0], S[2], S[4]
    p1, p2, d1, d2 = fallback, -1, math.inf, math.inf
    for p in range(cnt[0]):
        d = om - pw[p] if from_below else pw[p] - om
        if 0.0 <= d < d1:
            p2, d2 = p1 if d1 < math.inf else -1, d1
            p1, d1 = p, d
        elif d1 <= d < d2:
            p2, d2 = p, d
    t = 0.0
    if p2 >= 0 and pw[p1] != pw[p2]:
        t = (om - pw[p1]) / (pw[p1] - pw[p2])
    for j in range(x.shape[0]):
        x[j] = px[p1, j] + (t * (px[p1, j] - px[p2, j]) if p2 >= 0 else 0.0)


@jit
def _val(S, p, beam, power):
    """The metric at point ``p`` (``beam`` -1) or one beam's ``omega^power |y_b|``."""
    if beam < 0:
        return S[1][p]
    return abs(S[3][p, beam]) * S[0][p] ** power


@jit
def _climb(best, left, right, start, from_below, P, S, rtol, max_steps, beam):
    """Parabolic steps (on ``1/v^2``, nearly quadratic near a resonance; golden-section
    steps where no parabola fits, or where two steps have not halved the bracket, as
    across a corner of ``v``) from the best point ``best`` inside ``[left, right]``,
    on ``v`` = the metric (``beam`` -1) or one beam's amplitude ``omega^p |y_b|``.

    A vertex that becomes the best point is checked by two points where the parabola
    drops by about ``rtol / 5``; the search ends when the nearest solved points on both
    sides of the best are within ``rtol / 4`` of it. Returns (index of the best point,
    complete): ``complete`` is False if a solve failed or the steps ran out.
    """
    pw = S[0]
    power = P[17]
    verify = False
    # the bracket's width (solved neighbours of the best) before the last two steps: a
    # parabola fitted across a kink (a damper's stick-slip onset, two beams crossing)
    # can creep towards the best from one side by a small fraction a step (Brent's
    # safeguard: where two steps have not halved the bracket, a golden-section step)
    w_prev1 = w_prev2 = math.inf
    for _ in range(max_steps):
        ib, il, ir = best, np.int64(-1), np.int64(-1)
        for p in range(S[4][0]):
            if left <= pw[p] < pw[ib] and (il < 0 or pw[p] > pw[il]):
                il = p
            if pw[ib] < pw[p] <= right and (ir < 0 or pw[p] < pw[ir]):
                ir = p
        # done: the solved neighbours on both sides are within rtol / 4 of the best
        vb = _val(S, ib, beam, power)
        tol_m = 0.25 * rtol * vb
        if (il >= 0 and ir >= 0 and _val(S, il, beam, power) >= vb - tol_m
                and _val(S, ir, beam, power) >= vb - tol_m):
            return best, True
        lo_w = pw[ib] - (pw[il] if il >= 0 else left)
        hi_w = (pw[ir] if ir >= 0 else right) - pw[ib]
        if max(lo_w, hi_w) <= 1e-12 * pw[ib]:
            return best, True
        new1 = new2 = math.nan
        w_now = lo_w + hi_w
        creeping = w_now > 0.5 * w_prev2
        w_prev2, w_prev1 = w_prev1, w_now
        if il >= 0 and ir >= 0 and not creeping:
            # a parabola in g = 1/M^2, nearly quadratic in omega near a resonance peak
            x0, x1, x2 = pw[il], pw[ib], pw[ir]
            g0 = 1.0 / _val(S, il, beam, power) ** 2
            g1 = 1.0 / vb ** 2
            g2 = 1.0 / _val(S, ir, beam, power) ** 2
            d01 = (g1 - g0) / (x1 - x0)
            curv = ((g2 - g1) / (x2 - x1) - d01) / (x2 - x0)
            if curv > 0.0:
                if verify:
                    # the last vertex became the best point: check it with the two points
                    # where the parabola drops by about rtol / 5
                    delta = math.sqrt(0.2 * rtol * 2.0 * g1 / curv)
                    if delta < lo_w:
                        new1 = x1 - delta
                    if delta < hi_w:
                        new2 = x1 + delta
                if not (new1 == new1 or new2 == new2):
                    xv = 0.5 * (x0 + x1) - d01 / (2.0 * curv)
                    if x0 < xv < x2 and abs(xv - x1) > 1e-3 * (x2 - x0):
                        new1 = xv
        if not (new1 == new1 or new2 == new2):
            # no usable parabola: a golden-section step into the larger side
            new1 = (pw[ib] - (1.0 - _INV_PHI) * lo_w if lo_w > hi_w
                    else pw[ib] + (1.0 - _INV_PHI) * hi_w)
            verify = False
        else:
            verify = not (new2 == new2)         # after a vertex step, verify next time
        for new in (new1, new2):
            if new == new:
                _guess(new, from_below, S, start, P[18])
                n = _add_point(new, P[18], P, S)
                if n < 0:
                    return best, False
                if _val(S, n, beam, power) > _val(S, best, beam, power):
                    best = n
        if verify and best != S[4][0] - 1:
            verify = False                      # the vertex was not an improvement
    return best, False




@jit
def _refine(idx, from_below, P, S, rtol):
    """Largest ``M`` on the bracket ``pw[idx[0]] .. pw[idx[N_SUB]]``, continued from below
    or from above.

    ``idx[t]`` is the stored point at sub-position ``t`` (``-1``: not solved yet; the
    ends, and the middle for an interior grid maximum, are seeded from the sweep). A
    broad interior grid maximum (both neighbours above half of it) is first climbed from
    its grid neighbours alone (a few steps); otherwise, or if that does not
    converge, the missing sub-points are solved in the direction of continuation and the
    best sub-interval is climbed (:func:`_climb`). Returns (index of the best point
    solved, complete).
    """
    pw, pm, px = S[0], S[1], S[2]
    lo, hi = pw[idx[0]], pw[idx[N_SUB]]
    start = idx[0] if from_below else idx[N_SUB]
    mid = idx[N_SUB // 2]
    # a broad peak (the grid neighbours above half of it): climb from the grid alone
    if mid >= 0 and min(pm[idx[0]], pm[idx[N_SUB]]) >= 0.5 * pm[mid]:
        best, ok = _climb(mid, lo, hi, start, from_below, P, S, rtol, np.int64(QUICK_STEPS),
                          np.int64(-1))
        if ok:
            return _beam_peaks(best, lo, hi, start, from_below, P, S, rtol)
    for step in range(1, N_SUB):
        t = step if from_below else N_SUB - step
        if idx[t] >= 0:
            continue
        prev = idx[t - 1] if from_below else idx[t + 1]
        idx[t] = _add_point(lo + (hi - lo) * t / N_SUB, px[prev], P, S)
        if idx[t] < 0:
            return -1, False
    tb = 0
    for t in range(1, N_SUB + 1):
        if pm[idx[t]] > pm[idx[tb]]:
            tb = t
    best = idx[tb]
    for p in range(S[4][0]):                   # points of the quick climb count too
        if pm[p] > pm[best]:
            best = p
    left = min(pw[idx[max(tb - 1, 0)]], pw[best])
    right = max(pw[idx[min(tb + 1, N_SUB)]], pw[best])
    best, ok = _climb(best, left, right, start, from_below, P, S, rtol, np.int64(MAX_STEPS),
                      np.int64(-1))
    if not ok:
        return best, False
    return _beam_peaks(best, lo, hi, start, from_below, P, S, rtol)


@jit
def _beam_peaks(best, lo, hi, start, from_below, P, S, rtol):
    """The metric is a maximum over beams, so its peak can be a kink where two beams
    cross, with another beam's own (smooth) peak higher nearby: each beam within 2 % of
    the metric at ``best`` is climbed on its own amplitude, and the best point for the
    metric among all points solved is returned, (index, complete)."""
    beams, power = P[16], P[17]
    pm = S[1]
    m_best = pm[best]
    for bb in beams:
        if _val(S, best, bb, power) < 0.98 * m_best:
            continue
        start_b = best
        for p in range(S[4][0]):
            if lo <= S[0][p] <= hi and _val(S, p, bb, power) > _val(S, start_b, bb, power):
                start_b = p
        _, ok = _climb(start_b, lo, hi, start, from_below, P, S, rtol, np.int64(MAX_STEPS), bb)
        if not ok:
            return best, False
    for p in range(S[4][0]):
        if lo <= S[0][p] <= hi and pm[p] > pm[best]:
            best = p
    return best, True


@jit
def _flanks(g_from, g_to, i, omega, y, s, status, M, P, S, rtol, x, top, top_y, width,
            v_floor):
    """The best point of the resonances hidden between grid points in the grid intervals
    ``g_from .. g_to - 1`` (a bracket and ``FLANK`` intervals on each side of it, or a
    stretch of the gap search; see the module docstring), written to ``top`` (omega, M)
    and ``top_y`` (responses) where it is above ``top[1]`` (``top[0]`` -1: no refined
    peak). ``width``: the narrowest mode's half-power width, rad/s; ``v_floor``: the
    least peak worth climbing (0: any), so that a sample too low to belong to a peak of
    at least ``v_floor`` (the width rule at twice the spacing) is not climbed. A sample above
    its neighbours (at an interval's end, above its one neighbour inside) whose
    neighbours' span holds the refined peak has each side within the interval searched
    finer (:func:`_split_half`); any other inner sample is climbed (:func:`_raise`), and
    so is a grid point between two searched intervals that lies above the samples on
    both sides of it (the range's two end grid points have no sample beyond them).

    Returns (found, complete): ``found`` if ``top`` was raised; ``complete`` is False if
    an interval could not be solved, a climb did not converge, or the grid step is more
    than ``N_FLANK_MAX`` widths.
    """
    nd = x.shape[0]
    pw, pm = S[0], S[1]
    found = False
    idx = np.empty(FLANK_DENSITY * N_FLANK_MAX + 1, np.int64)
    # the last inner sample of the interval searched before (omega, M, state, response):
    # a grid point between two intervals is compared with the samples on both sides
    keep = np.empty(2)
    keep_x = np.empty(nd)
    keep_y = np.empty(top_y.shape[0], np.complex128)
    have_prev = False
    for g in range(g_from, g_to):
        if status[i, g] < 0 or status[i, g + 1] < 0:
            return found, False                   # a gap beside the peak: not searched
        step = omega[g + 1] - omega[g]
        if not step <= N_FLANK_MAX * width:
            return found, False                   # a grid too coarse to search
        n = max(int(math.ceil(FLANK_DENSITY * step / width)), N_FLANK)
        floor = v_floor * _hidden_fraction(2.0 * step / n, width)
        S[4][0] = 0                               # each interval afresh
        _log_s(s, i, g, nd, x)
        idx[0] = _seed(omega[g], x, y[i, g], M[g], S)
        for t in range(1, n):
            idx[t] = _add_point(omega[g] + step * t / n, S[2][idx[t - 1]], P, S)
            if idx[t] < 0:
                return found, False
        _log_s(s, i, g + 1, nd, x)
        idx[n] = _seed(omega[g + 1], x, y[i, g + 1], M[g + 1], S)
        if (have_prev and pm[idx[0]] > keep[1] and pm[idx[0]] > pm[idx[1]]
                and pm[idx[0]] >= floor and _another(pm[idx[0]], keep[0], pw[idx[1]], top)):
            # grid point g above the samples on both sides of it (the interval below's
            # last, this one's first), and not the refined peak's: a resonance peaks
            # beside it (found by a review: 1.1 % low, yet called resolved); climb it
            jp = _seed(keep[0], keep_x, keep_y, keep[1], S)
            ok = _raise(idx[0], keep[0], pw[idx[1]], jp, P, S, rtol, top, top_y)
            if ok < 0:
                return found, False
            found = found or ok > 0
        j = idx[n - 1]
        keep[0], keep[1] = pw[j], pm[j]
        for jj in range(nd):
            keep_x[jj] = S[2][j, jj]
        for bb in range(keep_y.shape[0]):
            keep_y[bb] = S[3][j, bb]
        have_prev = True
        for t in range(0, n + 1):
            v = pm[idx[t]]
            above_l = t == 0 or v > pm[idx[t - 1]]
            above_r = t == n or v > pm[idx[t + 1]]
            if not (above_l and above_r):
                continue
            # the span of the sample's neighbours (an end's neighbour across the grid
            # point is in the next interval: one width there, at most)
            lo = pw[idx[t - 1]] if t > 0 else pw[idx[0]] - width
            hi = pw[idx[t + 1]] if t < n else pw[idx[n]] + width
            if 0 < t < n and _another(v, lo, hi, top):
                if v < floor:
                    continue                      # too low for a peak worth climbing
                # an inner local maximum that is not the refined peak's (a sub-point
                # above the refined value is another resonance beside it)
                ok = _raise(idx[t], pw[idx[t - 1]], pw[idx[t + 1]], idx[0], P, S, rtol,
                            top, top_y)
                if ok < 0:
                    return found, False
                found = found or ok > 0
            elif lo <= top[0] <= hi:
                # the refined peak's own sample: a second resonance closer to it than the
                # spacing does not show; each side within this interval is sampled finer
                for a_t in (t - 1, t):
                    if a_t < 0 or a_t + 1 > n:
                        continue                  # that side is the next interval's
                    ok = _split_half(idx[a_t], idx[a_t + 1], P, S, rtol, top, top_y)
                    if ok < 0:
                        return found, False
                    found = found or ok > 0
    return found, True


@jit
def _another(v, lo, hi, top):
    """Whether a sample of value ``v`` above its neighbours at ``lo`` and ``hi`` (rad/s)
    belongs to another resonance than the refined peak's ``top`` (omega, M): it is
    above the refined value, or the refined peak is not between its neighbours."""
    return v > top[1] or not lo <= top[0] <= hi


@jit
def _raise(start, left, right, first, P, S, rtol, top, top_y):
    """Climb from the stored point ``start`` inside ``[left, right]`` (rad/s), continued
    from below (``first``: the interval's first point); raise ``top`` and ``top_y`` to
    the best point where it is higher. As in the refinement, every beam within 2 % of
    the metric at the top is climbed on its own amplitude too (two beams crossing beside
    a resonance make a kink of the metric below another beam's peak: a review found two
    members 0.02-0.05 % low, yet resolved). Returns 1 (raised), 0 (not) or -1 (a climb
    did not converge)."""
    pw, pm = S[0], S[1]
    best, ok = _climb(start, left, right, first, np.bool_(True), P, S, rtol,
                      np.int64(MAX_STEPS), np.int64(-1))
    if not ok:
        return -1
    best, ok = _beam_peaks(best, left, right, first, np.bool_(True), P, S, rtol)
    if not ok:
        return -1
    if pm[best] > top[1]:
        top[0], top[1] = pw[best], pm[best]
        for bb in range(top_y.shape[0]):
            top_y[bb] = S[3][best, bb]
        return 1
    return 0


@jit
def _split_half(a, b, P, S, rtol, top, top_y):
    """Solve ``N_FLANK - 1`` points between the stored points ``a`` < ``b`` (continued
    from ``a``) and climb any above both its neighbours (:func:`_raise`), unless it is
    the refined peak's (``top`` between its neighbours, and above it). Returns 1 (``top``
    raised), 0 or -1 (a solve or a climb failed)."""
    pw, pm = S[0], S[1]
    sub = np.empty(N_FLANK + 1, np.int64)
    sub[0], sub[N_FLANK] = a, b
    for t in range(1, N_FLANK):
        sub[t] = _add_point(pw[a] + (pw[b] - pw[a]) * t / N_FLANK, S[2][sub[t - 1]], P, S)
        if sub[t] < 0:
            return -1
    raised = 0
    for t in range(1, N_FLANK):
        if (pm[sub[t]] > pm[sub[t - 1]] and pm[sub[t]] > pm[sub[t + 1]]
                and _another(pm[sub[t]], pw[sub[t - 1]], pw[sub[t + 1]], top)):
            ok = _raise(sub[t], pw[sub[t - 1]], pw[sub[t + 1]], a, P, S, rtol, top, top_y)
            if ok < 0:
                return -1
            raised = max(raised, ok)
    return raised


@jit
def _kth_largest(v, k):
    """The ``k``-th largest of the values ``v`` that are not NaN (NaN if fewer)."""
    ok = v[~np.isnan(v)]
    if ok.shape[0] < k:
        return math.nan
    return np.sort(ok)[ok.shape[0] - k]


@jit
def _hidden_fraction(step, width):
    """The least grid value, as a fraction of a resonance's peak, of the nearer grid point
    to that peak: a peak of half-power width ``width`` (rad/s) midway between grid points
    ``step`` apart is ``1 / sqrt(1 + (step / width)^2)`` of the way up (the magnitude of a
    single mode's receptance). A grid maximum below this fraction of a value already
    reported cannot hide a higher peak of a resonance at least ``width`` wide."""
    return 1.0 / math.sqrt(1.0 + (step / width) ** 2)


@jit
def _log_s(s, i, k, nd, x):
    """``x = log s`` of sample ``i`` at grid point ``k`` (0 where s is 0 or not finite)."""
    for j in range(nd):
        v = s[i, k, j]
        x[j] = math.log(v) if v > 0.0 and math.isfinite(v) else 0.0


@jit
def _lift(q, top, top_y, sst, sw, sm, sdw, sdm, sy, sfo):
    """Raise the refined slot ``q`` to ``top`` (omega, M) and ``top_y`` where that is
    higher: the same resonance, climbed higher from another search."""
    if not (sst[q] == PEAK_REFINED or sst[q] == PEAK_AT_EDGE) or not top[1] > sm[q]:
        return
    sst[q] = PEAK_REFINED
    sw[q], sm[q] = top[0], top[1]
    sy[q, :] = top_y
    if sfo[q] != FOLD_FOUND and sfo[q] != FOLD_OPEN:
        sdw[q], sdm[q] = sw[q], sm[q]


@jit
def _fold(p, k, i, omega, y, s, status, M, P, S, rtol, window, x, sfo, sdw, sdm):
    """The fold check of slot ``p`` at grid point ``k``: the ``window`` grid points on
    each side swept downward, from the upward state above them; where the downward
    branch differs from the upward one (``FOLD_RTOL``), its own peak refined, continued
    from above, into ``sdw[p]``, ``sdm[p]`` (rad/s, metric). Sets ``sfo[p]`` (left
    ``FOLD_UNCHECKED`` where the check fails; ``FOLD_NONE`` at the band's last point):
    ``FOLD_OPEN`` where that peak is a lower estimate (the largest downward point is the
    lowest one solved, not the band's first, and differs from the upward one there or
    has none to compare with, so the branch goes on below; or the refinement failed)."""
    n_f = omega.shape[0]
    nd = x.shape[0]
    k_top = min(k + window, n_f - 1)
    k_bot = max(k - window, 0)
    if k_top == k:
        # the band's last point (window >= 1): no branch comes from above it in the band
        sfo[p] = FOLD_NONE
        return
    if status[i, k_top] < 0:
        return                            # no upward point to start from: unchecked
    S[4][0] = 0
    _log_s(s, i, k_top, nd, x)
    first = _seed(omega[k_top], x, y[i, k_top], M[k_top], S)
    prev = first
    differs = False
    complete = True
    dn = np.full(k_top - k_bot + 1, -1, np.int64)
    dn[k_top - k_bot] = first
    prev2 = -1
    # the lowest point solved, and whether it differs (or is not compared: counted apart)
    g_end, end_differs = k_top, False
    for g in range(k_top - 1, k_bot - 1, -1):
        # the start: extrapolated linearly from the last two points of the way down
        if prev2 >= 0:
            t = (omega[g] - S[0][prev]) / (S[0][prev] - S[0][prev2])
            for j in range(nd):
                x[j] = S[2][prev, j] + t * (S[2][prev, j] - S[2][prev2, j])
        else:
            for j in range(nd):
                x[j] = S[2][prev, j]
        n = _add_point(omega[g], x, P, S)
        if n < 0:
            complete = False
            break
        dn[g - k_bot] = n
        prev2, prev = prev, n
        g_end, end_differs = g, True
        if status[i, g] < 0:
            complete = False              # no upward point to compare with here
        elif abs(S[1][n] - M[g]) > FOLD_RTOL * max(S[1][n], M[g]):
            differs = True
        else:
            end_differs = False
    if not differs:
        sfo[p] = FOLD_NONE if complete else FOLD_UNCHECKED
        return
    sfo[p] = FOLD_FOUND
    # the downward branch's own peak, refined continued from above
    gb = k_top
    for g in range(k_bot, k_top + 1):
        if dn[g - k_bot] >= 0 and S[1][dn[g - k_bot]] > S[1][dn[gb - k_bot]]:
            gb = g
    if gb == g_end and end_differs and g_end > 0:
        # the branch from above climbs on below (at the band's first point the band cuts
        # it): its peak is not here, and refining towards the end would gain nothing
        sfo[p] = FOLD_OPEN
        sdw[p], sdm[p] = S[0][dn[gb - k_bot]], S[1][dn[gb - k_bot]]
        return
    g_lo = gb - 1 if gb > k_bot and dn[gb - 1 - k_bot] >= 0 else gb
    g_hi = gb + 1 if gb < k_top else gb
    if g_lo == g_hi:
        sdw[p], sdm[p] = S[0][dn[gb - k_bot]], S[1][dn[gb - k_bot]]
        return
    idx = np.full(N_SUB + 1, -1, np.int64)
    idx[0] = dn[g_lo - k_bot]
    idx[N_SUB] = dn[g_hi - k_bot]
    if g_lo < gb < g_hi:
        idx[N_SUB // 2] = dn[gb - k_bot]
    best, ok = _refine(idx, np.bool_(False), P, S, rtol)
    j = best if best >= 0 else dn[gb - k_bot]
    sdw[p], sdm[p] = S[0][j], S[1][j]
    if not ok:
        sfo[p] = FOLD_OPEN


@jit
def _member(i, omega, modal_f, zeta, u, force, a, b, mu0, N0, kc, tol, max_iter, y, s,
            status, beams, power, n_peaks, rtol, window, pk_w, pk_m, pk_y, pk_st, fold,
            pkd_w, pkd_m, law):
    """Peaks and folds of sample ``i`` (see the module docstring)."""
    n_f = omega.shape[0]
    nd = a.shape[0]
    n_beams = force.shape[0]
    r = np.int64(i) if modal_f.shape[0] > 1 else np.int64(0)
    kc1 = np.empty(nd)
    c1 = np.empty(nd)
    act = np.empty(nd, dtype=np.bool_)
    for j in range(nd):
        mn = mu0[i, j] * N0[i, j]
        act[j] = mn > 0.0 and kc[i, j] > 0.0
        c1[j] = math.log(mn / kc[i, j]) if act[j] else 0.0
        kc1[j] = kc[i, j]
    # a chain or a ring of friction dampers: the O(nd) lockstep Newton, one lane
    lanes = law == LAW_COULOMB and nd >= 2
    for j in range(nd):
        lanes = lanes and a[j] == j and b[j] == (j + 1) % n_beams
    P = (r, modal_f, zeta, u, force, a, b, kc1, c1, act, tol, max_iter, workspace(nd),
         np.empty((4, n_beams), np.complex128), np.empty((nd, nd), np.complex128),
         np.empty(nd, np.complex128), beams, power, np.empty(nd),
         np.empty(n_beams, np.complex128), law, cn.workspace(nd), lanes)
    # the refinement's points, or one flank interval's, its finer sides and their climbs,
    # and the climb of the grid point below it (the previous interval's last point again)
    cap = (2 * N_SUB + 8 * MAX_STEPS + FLANK_DENSITY * N_FLANK_MAX + N_FLANK + 2 * window
           + 9)
    width = math.inf                      # the narrowest mode's half-power width, rad/s
    for bb in range(modal_f.shape[1]):
        for m in range(modal_f.shape[2]):
            width = min(width, 4.0 * math.pi * zeta[bb, m] * modal_f[r, bb, m])
    S = (np.empty(cap), np.empty(cap), np.empty((cap, nd)),
         np.empty((cap, n_beams), np.complex128), np.zeros(1, np.int64))
    x = np.empty(nd)
    top = np.empty(2)
    top_y = np.empty(n_beams, np.complex128)
    # the metric on the grid; local maxima, largest first
    M = np.empty(n_f)
    for k in range(n_f):
        M[k] = _metric_of(y[i, k], omega[k], beams, power) if status[i, k] >= 0 else math.nan
    cand = np.empty(n_f, np.int64)
    n_c = 0
    for k in range(n_f):
        if not math.isfinite(M[k]):
            continue
        up = k == 0 or not (M[k - 1] >= M[k])          # strictly above the left
        down = k == n_f - 1 or not (M[k + 1] > M[k])   # at least the right
        if up and down:
            cand[n_c] = k
            n_c += 1
    order = np.argsort(-M[cand[:n_c]], kind="mergesort")
    # the width rule's step for each grid interval: between the converged grid points
    # around it (a peak there is at most half of it from the nearer one; twice the
    # distance to the band's end where nothing converged on that side; a review: a grid
    # maximum beside two failed points was measured by one step, skipped, and the member
    # called resolved 15 % low), and the larger value of those two points
    h_eff = np.full(max(n_f - 1, 0), math.inf)
    m_eff = np.full(max(n_f - 1, 0), math.nan)
    cl = -1
    for g in range(n_f - 1):
        if M[g] == M[g]:
            cl = g
        ch = g + 1
        while ch < n_f and not M[ch] == M[ch]:
            ch += 1
        if cl >= 0 and ch < n_f:
            h_eff[g], m_eff[g] = omega[ch] - omega[cl], max(M[cl], M[ch])
        elif ch < n_f:
            h_eff[g], m_eff[g] = 2.0 * (omega[ch] - omega[0]), M[ch]
        elif cl >= 0:
            h_eff[g], m_eff[g] = 2.0 * (omega[n_f - 1] - omega[cl]), M[cl]
    # candidates are refined into slots, and the n_peaks largest slots reported: past
    # the n_peaks largest grid maxima, a narrow resonance between grid points may still
    # peak above the n_peaks-th value found, unless its grid value is too low for that
    n_slot = max(n_c, n_peaks)
    sw = np.full(n_slot, math.nan)
    sm = np.full(n_slot, math.nan)
    sdw = np.full(n_slot, math.nan)
    sdm = np.full(n_slot, math.nan)
    sst = np.full(n_slot, PEAK_NONE, np.int64)
    sfo = np.full(n_slot, FOLD_UNCHECKED, np.int64)
    sy = np.full((n_slot, n_beams), complex(math.nan, math.nan))
    # grid intervals searched beside a kept maximum (for the gap search below)
    covered = np.zeros(max(n_f - 1, 0), np.bool_)
    n_done = 0
    for c in range(n_c):
        k = cand[order[c]]
        if n_done >= n_peaks:
            # the n_peaks-th largest value reported so far
            kth = _kth_largest(sm[:n_done], n_peaks)
            step = 0.0
            if k > 0:
                step = max(step, h_eff[k - 1])
            if k < n_f - 1:
                step = max(step, h_eff[k])
            if kth == kth and not M[k] >= kth * _hidden_fraction(step, width):
                continue
        p = n_done
        n_done += 1
        # the bracket between the converged grid neighbours
        k_lo = k - 1 if k > 0 and status[i, k - 1] >= 0 else k
        k_hi = k + 1 if k < n_f - 1 and status[i, k + 1] >= 0 else k
        edge = k == 0 or k == n_f - 1
        # beside a neighbour that did not converge the peak may lie in that gap: the
        # grid value, flagged, not a flank refined as if it were the band's end
        gap = (k_lo == k and k > 0) or (k_hi == k and k < n_f - 1)
        if k_lo == k_hi or gap:
            sst[p] = PEAK_GRID
            sw[p], sm[p] = omega[k], M[k]
            sy[p, :] = y[i, k, :]
            continue
        S[4][0] = 0
        idx = np.full(N_SUB + 1, -1, np.int64)
        for g, t in ((k_lo, 0), (k_hi, N_SUB), (k, N_SUB // 2)):
            if g == k_lo and t != 0 or g == k_hi and t != N_SUB:
                continue                      # k is an end of the bracket
            _log_s(s, i, g, nd, x)
            idx[t] = _seed(omega[g], x, y[i, g], M[g], S)
        best, ok = _refine(idx, np.bool_(True), P, S, rtol)
        if best < 0 or not ok:
            # refinement failed or stopped short: the grid value, as the status says
            sst[p] = PEAK_GRID
            sw[p], sm[p] = omega[k], M[k]
            sy[p, :] = y[i, k, :]
        else:
            sst[p] = PEAK_AT_EDGE if edge else PEAK_REFINED
            sw[p], sm[p] = S[0][best], S[1][best]
            sy[p, :] = S[3][best]
            top[0], top[1] = sw[p], sm[p]
            g_from, g_to = max(k_lo - FLANK, 0), min(k_hi + FLANK, n_f - 1)
            found, complete = _flanks(g_from, g_to, i, omega, y, s, status, M, P, S, rtol,
                                      x, top, top_y, width, 0.0)
            if complete:
                covered[g_from:g_to] = True
            for q in range(p):
                if found and abs(top[0] - sw[q]) < width:
                    # a resonance an earlier peak reported already (their flanks
                    # overlap): that peak takes the point where it is higher
                    found = False
                    _lift(np.int64(q), top, top_y, sst, sw, sm, sdw, sdm, sy, sfo)
            if not complete:
                # a flank where a higher resonance may hide was not searched
                sst[p] = PEAK_GRID
                sw[p], sm[p] = omega[k], M[k]
                sy[p, :] = y[i, k, :]
            elif found:
                # an interior resonance, refined (not the band's end any more)
                sst[p] = PEAK_REFINED
                sw[p], sm[p] = top[0], top[1]
                sy[p, :] = top_y
        sdw[p], sdm[p] = sw[p], sm[p]
        if sst[p] == PEAK_REFINED or sst[p] == PEAK_AT_EDGE:
            dup = False
            for q in range(p):
                # the same resonance as an earlier slot (a lower grid maximum can climb
                # one that another's flank search reported): reported once
                dup = dup or ((sst[q] == PEAK_REFINED or sst[q] == PEAK_AT_EDGE)
                              and abs(sw[p] - sw[q]) < width)
            if dup:
                sst[p] = PEAK_NONE
                sw[p] = sm[p] = sdw[p] = sdm[p] = math.nan
                continue
        _fold(np.int64(p), np.int64(k), i, omega, y, s, status, M, P, S, rtol, window, x,
              sfo, sdw, sdm)
    # the gap search: a resonance more than FLANK intervals from every kept bracket,
    # hidden between grid points on a slope, can peak above the largest value found (a
    # review: 5.4 % low, called resolved). Every other grid interval whose larger end
    # could belong to such a peak (the width rule) is searched as the flanks are, in
    # stretches of consecutive intervals; a member with a peak at its grid value is left so
    flagged = False
    v_max = -math.inf
    for q in range(n_done):
        flagged = flagged or sst[q] == PEAK_GRID
        v = max(sm[q], sdm[q]) if sdm[q] == sdm[q] else sm[q]
        if v > v_max:
            v_max = v
    need = np.zeros(max(n_f - 1, 0), np.bool_)
    n_run = 0
    for g in range(n_f - 1):
        if flagged or not v_max > 0.0 or covered[g]:
            continue
        need[g] = m_eff[g] >= v_max * _hidden_fraction(h_eff[g], width)
        if need[g] and (g == 0 or not need[g - 1]):
            n_run += 1
    if n_run > 0:
        # one slot more for each stretch at most
        sw = np.concatenate((sw, np.full(n_run, math.nan)))
        sm = np.concatenate((sm, np.full(n_run, math.nan)))
        sdw = np.concatenate((sdw, np.full(n_run, math.nan)))
        sdm = np.concatenate((sdm, np.full(n_run, math.nan)))
        sst = np.concatenate((sst, np.full(n_run, PEAK_NONE, np.int64)))
        sfo = np.concatenate((sfo, np.full(n_run, FOLD_UNCHECKED, np.int64)))
        sy = np.concatenate((sy, np.full((n_run, n_beams), complex(math.nan, math.nan))))
        n_slot += n_run
    g = 0
    while g < n_f - 1:
        if not need[g]:
            g += 1
            continue
        g_end = g
        while g_end < n_f - 1 and need[g_end]:
            g_end += 1
        # and one searched interval on each side: the grid point between is then
        # compared with the samples on both sides of it
        g_from = g - 1 if g > 0 and covered[g - 1] else g
        g_to = g_end + 1 if g_end < n_f - 1 and covered[g_end] else g_end
        top[0], top[1] = -1.0, v_max
        found, complete = _flanks(g_from, g_to, i, omega, y, s, status, M, P, S, rtol,
                                  x, top, top_y, width, v_max)
        p = n_done
        if not complete:
            # not searched: the stretch's largest grid value, a lower estimate
            k = -1
            for kk in range(g, g_end + 1):
                if M[kk] == M[kk] and (k < 0 or M[kk] > M[k]):
                    k = kk
            n_done += 1
            sst[p] = PEAK_GRID
            sw[p], sm[p] = omega[k], M[k]
            sdw[p], sdm[p] = sw[p], sm[p]
            sy[p, :] = y[i, k, :]
            break
        dup = False
        for q in range(n_done):
            if found and not dup and abs(top[0] - sw[q]) < width:
                # a kept resonance climbed again from the interval searched twice: it
                # takes the point where it is higher (never below a point solved)
                dup = True
                _lift(np.int64(q), top, top_y, sst, sw, sm, sdw, sdm, sy, sfo)
                v_max = max(v_max, sm[q])
        if found and not dup:
            n_done += 1
            sst[p] = PEAK_REFINED
            sw[p], sm[p] = top[0], top[1]
            sdw[p], sdm[p] = sw[p], sm[p]
            sy[p, :] = top_y
            k = g_from
            for kk in range(g_from, g_to + 1):
                if abs(omega[kk] - top[0]) < abs(omega[k] - top[0]):
                    k = kk
            _fold(np.int64(p), np.int64(k), i, omega, y, s, status, M, P, S, rtol, window,
                  x, sfo, sdw, sdm)
            v_max = max(v_max, sm[p], sdm[p]) if sdm[p] == sdm[p] else max(v_max, sm[p])
        g = g_end
    rank = report_order(sst, sfo, sm, sdm, n_peaks)
    for p in range(n_peaks):
        q = rank[p]
        pk_st[i, p], fold[i, p] = sst[q], sfo[q]
        pk_w[i, p], pk_m[i, p], pkd_w[i, p], pkd_m[i, p] = sw[q], sm[q], sdw[q], sdm[q]
        for bb in range(n_beams):
            pk_y[i, p, bb] = sy[q, bb]


@jit
def report_order(sst, sfo, sm, sdm, n_peaks):
    """The order in which a member's peak slots are reported (the first ``n_peaks``).

    First the largest value, by the larger of the two branches (what ``largest()``
    reports, never below a peak the member solved); then the unrefined slots and the open
    or unchecked folds whatever their values (lower estimates: dropping all would call
    the member resolved); then the rest, largest first, slot order among equals. With one place a
    lower-estimate slot takes it, unless the largest is itself one.

    Parameters
    ----------
    sst, sfo : ndarray of int64, shape (n_slot,)
        Each slot's peak status and fold flag.
    sm, sdm : ndarray, shape (n_slot,)
        Each slot's metric on the upward and downward branch (NaN: none), m.
    n_peaks : int
        Places in the report.

    Returns
    -------
    ndarray of int64, shape (n_slot,)
        Slot indices, reported first to last.
    """
    n_slot = sst.size
    key = np.empty(n_slot)
    q_max, v_max = -1, -math.inf
    for q in range(n_slot):
        v = max(sm[q], sdm[q]) if sdm[q] == sdm[q] else sm[q]
        open_ = (sst[q] == PEAK_GRID or sfo[q] == FOLD_OPEN
                 or (sfo[q] == FOLD_UNCHECKED and sst[q] != PEAK_NONE))
        key[q] = _GRID_KEY if open_ else (v if v == v else -math.inf)
        if v > v_max:
            q_max, v_max = q, v
    if q_max >= 0 and (n_peaks > 1 or key[q_max] == _GRID_KEY):
        key[q_max] = math.inf
    return np.argsort(-key, kind="mergesort")


@jit(parallel=True, nogil=True)
def refine_peaks(omega, modal_f, zeta, u, force, a, b, mu0, N0, kc, tol, max_iter, y, s,
                 status, beams, power, n_peaks, rtol, window, pk_w, pk_m, pk_y, pk_st, fold,
                 pkd_w, pkd_m, law):
    """Resolved peaks and fold checks of every sample, after its sweep.

    Parameters
    ----------
    omega : ndarray, shape (n_f,)
        The sweep's frequencies, increasing, rad/s.
    modal_f : ndarray, shape (n_r, n_beams, n_modes)
        Modal frequencies, Hz (``n_r``: 1, or one rig per sample).
    zeta : ndarray, shape (n_beams, n_modes)
    u : ndarray, shape (n_beams, n_modes, 3)
        Mode shapes at the contact, output and drive positions, kg^-1/2.
    force : ndarray of complex, shape (n_beams,)
        Drive amplitudes, N.
    a, b : ndarray of int64, shape (nd,)
    mu0, N0, kc : ndarray, shape (n_s, nd)
    tol, max_iter :
        As for the sweep.
    y, s, status : ndarray
        The sweep's outputs (n_s, n_f, n_beams), (n_s, n_f, nd), (n_s, n_f).
    beams : ndarray of int64
        0-based beams of the metric.
    power : int
        0, 1, 2: displacement, velocity, acceleration.
    n_peaks : int
    rtol : float
        Relative tolerance of the peak amplitudes.
    window : int
        Grid points on each side of a peak swept downward.
    pk_w, pk_m, pk_y, pk_st, fold, pkd_w, pkd_m : ndarray
        Outputs per (sample, peak): frequency (rad/s), metric and responses (m) of the
        upward branch's peak, its status, the fold flag, and the downward branch's peak
        frequency and metric.
    law : int
        The contact law (:mod:`.friction`).
    """
    for i in prange(mu0.shape[0]):
        _member(np.int64(i), omega, modal_f, zeta, u, force, a, b, mu0, N0, kc, tol, max_iter, y, s,
                status, beams, power, n_peaks, rtol, window, pk_w, pk_m, pk_y, pk_st, fold,
                pkd_w, pkd_m, law)
