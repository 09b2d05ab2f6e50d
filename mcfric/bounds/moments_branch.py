"""Branch and bound of the second-order relaxation over parts of a beam's own dampers.

Where the second-order relaxation (:mod:`.moments`) stays a little above the witness,
the largest response can sit on a face of the box in the beam's own two dampers (on the
eight-beam rig at 104-105 Hz, 1.1 N: both near ``K = 0``, the relaxation 2.4 % above the
witness, and scipy SLSQP from 150 starts finds nothing higher). Splitting those two
dampers' rectangles, each into four at the witness's value, and relaxing every part
(the same relaxation with each damper's own rectangle, :func:`.moments.beam_bound`'s
``part``) closes it: the maximum over the box is the largest of the parts' maxima, so the
largest of their verified bounds is a verified bound. The part of largest bound is split
again, until the bound is within the goal, a split takes the excess over the goal down
by less than ``PROGRESS`` (the looseness is elsewhere: the coupling with farther dampers,
as at 117-123 Hz at 0.25 N), or the budget is spent.

A part whose first-order bound (:func:`.moments.first_order_bound`, milliseconds) is
already at most the goal needs no second-order relaxation (about a second): its leaf is
proved by the first order (``FIRST_ORDER`` in place of a dual), and so is the mirror
beam's reversed part.

Each part's relaxation scales its variables by force limits proven over that part
(:func:`part_limits`), not over the box: a smaller proven ``|p_j|`` is a tighter
constraint and a better scaled problem (eight beams, 0.25 N, 73.3 Hz, beam 4: the goal
in 32 relaxations instead of stalling 0.1 % short of it after 64).

Where the witness leaves many dampers nearly open (``K`` a few N/m, near the first
resonance: eight beams, 16.17 Hz, dampers 0-4 within 20 N/m of zero and the whole box's
bound 3.2 % above the witness), cutting at ``INSET`` of the interval cannot isolate them
and the own dampers are not enough. :func:`branch_bound` with ``geometric`` then splits
one damper per step, into four at a point's value or, near ``K = 0``, at
``GEOMETRIC_FACTOR`` times it (at least ``GEOMETRIC_FLOOR`` of the box): the damper
split fewest times in that part, the nearest the beam first (the own dampers, then
outward), the most nearly open at the point among equals. The point is the whole box's
relaxation's describing functions (:func:`geometric_cuts`), not the witness's: at
16.17 Hz, 0.22 N, the witness is another local maximum with dampers at exactly
``K = 0`` (every cut at the floor) and one at ``2574 + 15000j`` N/m where the relaxation
puts a few N/m; cut there the branch stalled 1.25 % above it, cut at the relaxation's
point it ends within 1 % in 24 relaxations (docs/bounds.md).
"""

from __future__ import annotations

import heapq
import itertools
import math

import numpy as np

from . import moments

#: A split that leaves more than ``1 - PROGRESS`` of the split part's excess over the goal
#: ends the branch and bound.
PROGRESS = 0.25
#: Each axis is cut at the witness's value, kept this fraction of the interval inside it.
INSET = 0.1
#: In place of a leaf's dual: the first-order relaxation proves its bound.
FIRST_ORDER = object()
#: The geometric branch's cut near ``K = 0``: this times the witness's value, at least
#: ``GEOMETRIC_FLOOR`` of the box's side (and at most the ``INSET`` cut).
GEOMETRIC_FACTOR = 3.0
GEOMETRIC_FLOOR = 1e-4


def own_dampers(beam, nd):
    """The dampers on either side of beam ``beam`` of a chain of ``nd`` dampers."""
    return [d for d in (beam - 1, beam) if 0 <= d < nd]


def _cut(lo, hi, at):
    return min(max(at, lo + INSET * (hi - lo)), hi - INSET * (hi - lo))


def _geometric_cut(lo, hi, at, side):
    """The cut of ``[lo, hi]`` for the witness's value ``at``: :func:`_cut`, except on an
    interval from 0 with ``at`` below its ``INSET`` cut, then ``GEOMETRIC_FACTOR at``
    (at least ``GEOMETRIC_FLOOR side``): splits that close in on a nearly open damper
    by a factor of ten or more each."""
    inset = lo + INSET * (hi - lo)
    if lo == 0.0 and at < inset:
        return min(max(GEOMETRIC_FACTOR * at, GEOMETRIC_FLOOR * side), inset)
    return _cut(lo, hi, at)


def geometric_cuts(K_cut, p, G, q0, kr, ki):
    """Where the geometric branch cuts (N/m): at the describing functions of the whole
    box's relaxation, its first moments ``p`` (N) as ``p / (q0 - G p)`` clipped to the
    box (``kr``, ``ki``, N/m), or where ``p`` is NaN at ``K_cut`` (the witness's). A
    witness that leaves a damper exactly open puts every cut of it at the floor, and one
    at another local maximum puts them where they serve less (module docstring)."""
    return np.where(np.isfinite(p), moments.describing_functions(p, G, q0, kr, ki), K_cut)


def geometric_children(part, d, K_cut, kr, ki):
    """The four parts of ``part`` with damper ``d``'s rectangle cut at
    :func:`_geometric_cut` of ``K_cut[d]`` (N/m; ``kr``, ``ki``: the box's sides)."""
    return children(part, [d], K_cut, sides=(kr, ki))


def children(part, own, K_cut, sides=None):
    """The parts of ``part`` (a pair ``(lo, hi)``, N/m) with each of the ``own`` dampers'
    rectangles cut in four at ``K_cut`` (N/m, clamped inside; 4 or 16 parts); with
    ``sides`` (the box's, N/m), at :func:`_geometric_cut` instead."""
    lo, hi = part
    pieces = []
    for d in own:
        if sides is None:
            cr = _cut(lo[d].real, hi[d].real, K_cut[d].real)
            ci = _cut(lo[d].imag, hi[d].imag, K_cut[d].imag)
        else:
            cr = _geometric_cut(lo[d].real, hi[d].real, K_cut[d].real, sides[0])
            ci = _geometric_cut(lo[d].imag, hi[d].imag, K_cut[d].imag, sides[1])
        pieces.append([(complex(a, c), complex(b, e))
                       for a, b in ((lo[d].real, cr), (cr, hi[d].real))
                       for c, e in ((lo[d].imag, ci), (ci, hi[d].imag))])
    for combo in itertools.product(*pieces):
        lo_, hi_ = lo.copy(), hi.copy()
        for d, (a, b) in zip(own, combo):
            lo_[d], hi_[d] = a, b
        yield lo_, hi_


def part_limits(G, q0, kr, ki, F_lim, limits, part, sign=0):
    """Proven bounds of the damper forces (N) over ``part`` (``(lo, hi)``, N/m): the
    smaller of ``limits`` (proven over the box) and the part's own
    (:func:`.moments.force_limits`). Where the chain is its own mirror image (``sign``
    nonzero, ``limits`` symmetric) each is the larger of the part's and the mirrored
    part's, reversed, so that the mirrored part's limits are these reversed (the
    mirror beam's problem is then this one's image, :func:`mirrored_branch`): a larger
    bound is still one."""
    own = np.minimum(limits, moments.force_limits(G, q0, kr, ki, F_lim, part))
    if not sign:
        return own
    lo, hi = part
    mirror = np.minimum(limits, moments.force_limits(G, q0, kr, ki, F_lim,
                                                     (lo[::-1].copy(), hi[::-1].copy())))
    return np.maximum(own, mirror[::-1])


def branch_bound(G, q0, ylin, H, kr, ki, F_lim, beam, limits, value, z, K_cut, goal,
                 budget, sign=0, geometric=False):
    """A verified bound of ``|y_beam|`` (m) over the admissible set by relaxing parts of
    the beam's own dampers' rectangles (``geometric``: of every damper's, one at a time;
    module docstring), starting from the whole box's ``value`` and dual ``z``
    (:func:`.moments.beam_bound`).

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        One frequency's contact-space arrays of a chain.
    kr, ki, F_lim : float
        The box (N/m) and the force limit (N).
    beam : int
    limits : ndarray of float
        Proven force limits over the box (N, :func:`.moments.force_limits`; symmetric
        where ``sign`` is nonzero).
    value : float
        The whole box's verified bound (m).
    z : ndarray or None
        Its dual.
    K_cut : ndarray of complex
        Where to cut (N/m; the witness's describing functions).
    goal : float
        Stop when the bound is at most this (m).
    budget : int
        Relaxations at most.
    sign : int
        :func:`mcfric.core.relaxation_branch.mirror_sign` of the chain (0: not a mirror
        image; the parts' force limits are then not made symmetric).
    geometric : bool
        Split one damper per step at :func:`_geometric_cut` (four parts) instead of the
        own dampers together at ``INSET`` cuts.

    Returns
    -------
    bound : float
        The largest of the leaves' bounds (m; each at most its parent's).
    used : int
        Second-order relaxations solved (parts the first order proves below ``goal``
        take none).
    leaves : list of tuple
        ``((lo, hi), z, bound, lim)`` per leaf: the part whose dual ``z`` proves the
        leaf's bound (the leaf or an ancestor; together they cover the box; ``z`` is
        ``FIRST_ORDER`` where the first order proves it, its limits then None) and the
        force limits of its problem (N), for the mirror beam.
    stalled : bool
        Whether it stopped because a split did not make ``PROGRESS`` (two in a row with
        ``geometric``).
    failed : int
        Of the ``used``, those that gave no bound (solver or verification; the part's
        first-order bound kept there).
    """
    nd = q0.shape[0]
    own = own_dampers(beam, nd)
    whole = moments.box(nd, kr, ki)
    # the geometric branch's order of dampers: the fewest cuts, then the nearest the beam,
    # then the most nearly open at the witness (the same order for the mirror beam)
    near = np.array([min(abs(j - d) for d in own) for j in range(nd)])
    # each entry: a part, the part (itself or an ancestor) whose dual proves its bound,
    # and each damper's number of cuts
    heap = [(-value, 0, whole, (whole, z, limits), np.zeros(nd, np.int64))]
    count = 1
    used = 0
    failed = 0
    stalled = False
    misses = 0
    n_kids = 4 if geometric else 4 ** len(own)
    # the budget counts second-order relaxations: a split costs at most n_kids of them
    while -heap[0][0] > goal and used + n_kids <= budget:
        neg, _, part, proof, cuts = heapq.heappop(heap)
        worst = -math.inf
        if geometric:
            d = int(np.lexsort((np.abs(K_cut), near, cuts))[0])
            kids = geometric_children(part, d, K_cut, kr, ki)
            cuts = cuts.copy()
            cuts[d] += 1
        else:
            kids = children(part, own, K_cut)
        for kid in kids:
            v = moments.first_order_bound(G, q0, ylin, H, F_lim, beam, kid, goal)
            zk, lim = FIRST_ORDER, None
            if v > goal:
                lim2 = part_limits(G, q0, kr, ki, F_lim, limits, kid, sign)
                v2, _, z2 = moments.beam_bound(G, q0, ylin, H, kr, ki, F_lim, beam, lim2,
                                               kid)
                used += 1
                failed += not np.isfinite(v2)
                # both are bounds: the second order's where it is the tighter
                if v2 < v:
                    v, zk, lim = v2, z2, lim2
            # a part's maximum is at most its parent's
            v, kid_proof = (v, (kid, zk, lim)) if v <= -neg else (-neg, proof)
            heapq.heappush(heap, (-v, count, kid, kid_proof, cuts))
            count += 1
            worst = max(worst, v)
        misses = misses + 1 if worst - goal > (1 - PROGRESS) * (-neg - goal) else 0
        # one damper's four parts are a smaller step than the own dampers' sixteen: the
        # geometric branch stops after two such splits in a row
        if misses >= (2 if geometric else 1):
            stalled = True
            break
    leaves = [(proof[0], proof[1], -neg, proof[2]) for neg, _, _, proof, _ in heap]
    return -heap[0][0], used, leaves, stalled, failed


def mirrored_branch(G, q0, ylin, H, kr, ki, F_lim, beam, limits, leaves, sign):
    """The bound of ``|y_beam|`` (m) from the mirror beam's ``leaves``
    (:func:`branch_bound`): each part and its force limits reversed, its dual verified
    by :func:`.moments.mirrored_bound`; the largest, ``inf`` where a leaf has no dual.
    Also returns the number of duals verified (siblings proved by one ancestor's dual
    share its verification). A leaf the first order proved is proved again by the first
    order over the reversed part, for this beam.

    The reversed limits are raised, where needed, to the mirrored part's own
    (:func:`part_limits` without ``sign``, from the box's ``limits``), so that they are
    proven whatever produced the leaves; where :func:`branch_bound` made them symmetric
    nothing changes and the problem is the exact image of the leaf's."""
    worst = -math.inf
    seen = set()
    for (lo, hi), z, _, lim in leaves:
        part = (lo[::-1].copy(), hi[::-1].copy())
        if z is FIRST_ORDER:
            v = moments.first_order_bound(G, q0, ylin, H, F_lim, beam, part)
        else:
            if id(z) in seen:
                continue
            seen.add(id(z))
            if z is None:
                return math.inf, len(seen) - 1
            lim = np.maximum(lim[::-1], part_limits(G, q0, kr, ki, F_lim, limits, part))
            v = moments.mirrored_bound(G, q0, ylin, H, kr, ki, F_lim, beam, lim, z, sign,
                                       part)
        if not v >= 0.0:
            # a part with no bound (NaN) leaves the beam unbounded, not out of the max
            return math.inf, len(seen)
        worst = max(worst, v)
    return worst, len(seen)
