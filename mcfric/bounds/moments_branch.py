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
"""

from __future__ import annotations

import heapq
import itertools
import math

from . import moments

#: A split that leaves more than ``1 - PROGRESS`` of the split part's excess over the goal
#: ends the branch and bound.
PROGRESS = 0.25
#: Each axis is cut at the witness's value, kept this fraction of the interval inside it.
INSET = 0.1


def own_dampers(beam, nd):
    """The dampers on either side of beam ``beam`` of a chain of ``nd`` dampers."""
    return [d for d in (beam - 1, beam) if 0 <= d < nd]


def _cut(lo, hi, at):
    return min(max(at, lo + INSET * (hi - lo)), hi - INSET * (hi - lo))


def children(part, own, K_cut):
    """The parts of ``part`` (a pair ``(lo, hi)``, N/m) with each of the ``own`` dampers'
    rectangles cut in four at ``K_cut`` (N/m, clamped inside; 4 or 16 parts)."""
    lo, hi = part
    pieces = []
    for d in own:
        cr = _cut(lo[d].real, hi[d].real, K_cut[d].real)
        ci = _cut(lo[d].imag, hi[d].imag, K_cut[d].imag)
        pieces.append([(complex(a, c), complex(b, e))
                       for a, b in ((lo[d].real, cr), (cr, hi[d].real))
                       for c, e in ((lo[d].imag, ci), (ci, hi[d].imag))])
    for combo in itertools.product(*pieces):
        lo_, hi_ = lo.copy(), hi.copy()
        for d, (a, b) in zip(own, combo):
            lo_[d], hi_[d] = a, b
        yield lo_, hi_


def branch_bound(G, q0, ylin, H, kr, ki, F_lim, beam, limits, value, z, K_cut, goal,
                 budget):
    """A verified bound of ``|y_beam|`` (m) over the admissible set by relaxing parts of
    the beam's own dampers' rectangles, starting from the whole box's ``value`` and dual
    ``z`` (:func:`.moments.beam_bound`).

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        One frequency's contact-space arrays of a chain.
    kr, ki, F_lim : float
        The box (N/m) and the force limit (N).
    beam : int
    limits : ndarray of float
        Proven force limits (N, :func:`.moments.force_limits`).
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

    Returns
    -------
    bound : float
        The largest of the leaves' bounds (m; each at most its parent's).
    used : int
        Relaxations solved.
    leaves : list of tuple
        ``((lo, hi), z, bound)`` per leaf: the part whose dual ``z`` proves the leaf's
        bound (the leaf or an ancestor; together they cover the box), for the mirror
        beam.
    stalled : bool
        Whether it stopped because a split did not make ``PROGRESS``.
    """
    nd = q0.shape[0]
    own = own_dampers(beam, nd)
    whole = moments.box(nd, kr, ki)
    # each entry: a part, and the part (itself or an ancestor) whose dual proves its bound
    heap = [(-value, 0, whole, (whole, z))]
    count = 1
    used = 0
    stalled = False
    n_kids = 4 ** len(own)
    while -heap[0][0] > goal and used + n_kids <= budget:
        neg, _, part, proof = heapq.heappop(heap)
        worst = -math.inf
        for kid in children(part, own, K_cut):
            v, _, zk = moments.beam_bound(G, q0, ylin, H, kr, ki, F_lim, beam, limits, kid)
            used += 1
            # a part's maximum is at most its parent's
            v, kid_proof = (v, (kid, zk)) if v <= -neg else (-neg, proof)
            heapq.heappush(heap, (-v, count, kid, kid_proof))
            count += 1
            worst = max(worst, v)
        if worst - goal > (1 - PROGRESS) * (-neg - goal):
            stalled = True
            break
    leaves = [(proof[0], proof[1], -neg) for neg, _, _, proof in heap]
    return -heap[0][0], used, leaves, stalled


def mirrored_branch(G, q0, ylin, H, kr, ki, F_lim, beam, limits, leaves, sign):
    """The bound of ``|y_beam|`` (m) from the mirror beam's ``leaves``
    (:func:`branch_bound`): each part reversed, its dual verified by
    :func:`.moments.mirrored_bound`; the largest, ``inf`` where a leaf has no dual. Also
    returns the number of duals verified (siblings proved by one ancestor's dual share
    its verification)."""
    worst = -math.inf
    seen = set()
    for (lo, hi), z, _ in leaves:
        if id(z) in seen:
            continue
        seen.add(id(z))
        if z is None:
            return math.inf, len(seen) - 1
        worst = max(worst, moments.mirrored_bound(G, q0, ylin, H, kr, ki, F_lim, beam,
                                                  limits, z, sign,
                                                  (lo[::-1].copy(), hi[::-1].copy())))
    return worst, len(seen)
