"""Branch and bound over the damper rectangles: certified extremes of the metric.

At one frequency, :func:`certify` encloses the largest (or smallest) value of
``M = max_b |y_b|`` over the admissible set: every ``K_j`` in its rectangle and
``|K_j q_j| <= F_lim``. Sub-boxes are kept in a heap by their bound from
:func:`.enclosure.enclosure`; the most promising one is halved (the damper that widens
its bound most, along the longer side of its rectangle), sub-boxes that cannot beat the
best admissible point found (the witness) or that violate the force limit everywhere are
dropped. The certified value is the witness or the best bound still open, whichever is
further out: valid at any stop, and as tight as the budget of enclosures allows.
"""

import math

import numpy as np

from ._jit import jit
from .enclosure import INFEASIBLE, OK, enclosure, workspace
from .linalg import contact_solve


@jit
def force_bounds(ylin, H, F_lim, out):
    """Each beam's force-only bound (Eq. 10) at one frequency, ``|ylin_b| + F_lim
    sum_j |H_bj|`` (m), into ``out``: no admissible point has a larger ``|y_b|``."""
    # rounded outwards: each modulus, product and sum errs by at most an ulp, and the
    # bound can be exact (a saturated end damper), so it is proved only when widened
    widen = 1.0 + 4.0 * (H.shape[1] + 2) * 2.0 ** -53
    for b in range(len(ylin)):
        acc = abs(ylin[b])
        for j in range(H.shape[1]):
            acc += F_lim * abs(H[b, j])
        out[b] = acc * widen


@jit(nogil=True)
def admissible_value(G, q0, ylin, H, K, F_lim, T, piv, q):
    """``M`` at ``K`` (m), and whether ``K`` satisfies the force limit (the box is the
    caller's); ``nan`` if the system is singular."""
    nd = q0.shape[0]
    if contact_solve(G, K, q0, T, piv, q, nd) != 0:
        return math.nan, False
    ok = True
    for j in range(nd):
        if not abs(K[j] * q[j]) <= F_lim:
            ok = False
    m = 0.0
    for b in range(ylin.shape[0]):
        y = ylin[b]
        for j in range(nd):
            y -= H[b, j] * K[j] * q[j]
        m = max(m, abs(y))
    return m, ok


@jit(nogil=True)
def _push(heap, key, n, slot):
    """Add ``slot`` to the max-heap ``heap[:n]`` ordered by ``key``; returns ``n + 1``."""
    i = n
    heap[i] = slot
    while i > 0:
        p = (i - 1) // 2
        if key[heap[p]] >= key[heap[i]]:
            break
        t = heap[p]
        heap[p] = heap[i]
        heap[i] = t
        i = p
    return n + 1


@jit(nogil=True)
def _pop(heap, key, n):
    """Remove the top of the max-heap ``heap[:n]``; returns its slot."""
    top = heap[0]
    n -= 1
    heap[0] = heap[n]
    i = 0
    while True:
        lft = 2 * i + 1
        if lft >= n:
            break
        m = lft
        if lft + 1 < n and key[heap[lft + 1]] > key[heap[lft]]:
            m = lft + 1
        if key[heap[i]] >= key[heap[m]]:
            break
        t = heap[m]
        heap[m] = heap[i]
        heap[i] = t
        i = m
    return top


@jit(nogil=True)
def certify(G, q0, ylin, H, kr, ki, F_lim, want_max, K_init, budget, rtol, atol, K_best):
    """Certified maximum (``want_max``) or minimum of ``M`` over the admissible set.

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        Contact-space arrays at one frequency (see :mod:`.enclosure`).
    kr, ki : float
        Box limits of Re K and Im K, N/m.
    F_lim : float
        Force limit, N (``inf``: none).
    want_max : bool
    K_init : ndarray of complex, shape (n_init, nd)
        Candidate witnesses, N/m (for example a search's optimum), used if admissible.
    budget : int
        Enclosures to evaluate at most; 0: none (only the witness is sought).
    rtol, atol : float
        Stop when the best open bound is within ``rtol`` (relative) or ``atol`` (m) of the
        witness.
    K_best : ndarray of complex, shape (nd,)
        Out: the witness, N/m.

    Returns
    -------
    certified : float
        ``>= max M`` over the admissible set (``<= min M`` for the minimum), m.
    witness : float
        ``M`` at ``K_best``, an admissible point, m.
    evaluations : int
    converged : bool
        Whether the tolerance was met within the budget.
    """
    nd = q0.shape[0]
    nb = ylin.shape[0]
    sign = 1.0 if want_max else -1.0
    T = np.empty((nd, nd), np.complex128)
    piv = np.empty(nd, np.int64)
    q = np.empty(nd, np.complex128)
    Kmid = np.empty(nd, np.complex128)
    witness = -math.inf if want_max else math.inf
    for s in range(K_init.shape[0]):
        v, ok = admissible_value(G, q0, ylin, H, K_init[s], F_lim, T, piv, q)
        if ok and math.isfinite(v) and sign * v > sign * witness:
            witness = v
            K_best[:] = K_init[s]
    if budget <= 0:
        # no enclosure: the whole box is not bounded here (the caller caps it)
        return (math.inf if want_max else 0.0), witness, 0, False
    cap = budget + 2
    lo = np.zeros((cap, nd), np.complex128)
    hi = np.zeros((cap, nd), np.complex128)
    key = np.empty(cap)
    split = np.zeros(cap, np.int64)
    heap = np.empty(cap, np.int64)
    free = np.arange(cap)[::-1].copy()
    n_free = cap
    ws = workspace(nd, nb)
    Pb, yabs = ws[-2], ws[-1]
    U = np.empty(nb)
    L = np.empty(nb)
    n = np.int64(0)
    evaluations = 0
    root = math.inf if want_max else 0.0
    converged = False
    # the root: the whole box
    n_free -= 1
    slot = free[n_free]
    for j in range(nd):
        hi[slot, j] = complex(kr, ki)
    pending = np.empty(2, np.int64)
    pending[0] = slot
    n_pending = 1
    # a sub-box's extreme is bounded by its parent's bound as well (enclosures of the
    # halves can come out looser than the whole's)
    parent = math.inf if want_max else 0.0
    while True:
        for p in range(n_pending):
            slot = pending[p]
            st, cv, cadm = enclosure(G, q0, ylin, H, lo[slot], hi[slot], F_lim, U, L, ws)
            evaluations += 1
            if st == INFEASIBLE:
                free[n_free] = slot
                n_free += 1
                continue
            if cadm and math.isfinite(cv) and sign * cv > sign * witness:
                # the enclosure's centre value rests on an approximate inverse: the
                # witness is the centre evaluated by a solve, and kept if admissible
                for j in range(nd):
                    Kmid[j] = 0.5 * (lo[slot, j] + hi[slot, j])
                v, ok = admissible_value(G, q0, ylin, H, Kmid, F_lim, T, piv, q)
                if ok and math.isfinite(v) and sign * v > sign * witness:
                    witness = v
                    K_best[:] = Kmid
            bnd = -math.inf if want_max else 0.0
            for b in range(nb):
                bnd = max(bnd, U[b] if want_max else L[b])
            bnd = min(bnd, parent) if want_max else max(bnd, parent)
            if (bnd <= witness) if want_max else (bnd >= witness):
                free[n_free] = slot
                n_free += 1
                continue
            # halve the rectangle that widens the bound of the deciding beam most
            b_star = 0
            j_star = 0
            if st == OK:
                for b in range(nb):
                    if (U[b] > U[b_star]) if want_max else (yabs[b] > yabs[b_star]):
                        b_star = b
                for j in range(nd):
                    if Pb[b_star, j] > Pb[b_star, j_star]:
                        j_star = j
            else:
                # unverified: the widest rectangle
                w_star = -1.0
                for j in range(nd):
                    w = ((hi[slot, j].real - lo[slot, j].real) / kr
                         + (hi[slot, j].imag - lo[slot, j].imag) / ki)
                    if w > w_star:
                        w_star = w
                        j_star = j
            split[slot] = j_star
            key[slot] = sign * bnd
            if evaluations == 1:
                root = bnd
            n = _push(heap, key, n, slot)
        if n == 0:
            converged = True
            break
        top = sign * key[heap[0]]
        if want_max:
            done = top <= max(witness * (1.0 + rtol), witness + atol)
        else:
            done = top >= min(witness / (1.0 + rtol), witness - atol)
        if done:
            converged = True
            break
        if evaluations + 2 > budget:
            break
        # budget / (2 nd) enclosures spent (one per real dimension and halving of the
        # budget) and the best open bound no better than the whole box's (for the maximum
        # its force bound, Eq. 10, or none; for the minimum 0): too many sub-boxes would
        # have to shrink before any proves more, so stop (the result stays valid, only
        # loose)
        if (evaluations >= max(4, budget // (2 * nd))
                and ((top >= root * (1.0 - 1e-3)) if want_max else (top <= root))):
            break
        slot = _pop(heap, key, n)
        n -= 1
        parent = sign * key[slot]
        j = split[slot]
        a = lo[slot, j]
        z = hi[slot, j]
        n_free -= 1
        other = free[n_free]
        lo[other, :] = lo[slot, :]
        hi[other, :] = hi[slot, :]
        if (z.real - a.real) / kr >= (z.imag - a.imag) / ki:
            mid = 0.5 * (a.real + z.real)
            hi[slot, j] = complex(mid, z.imag)
            lo[other, j] = complex(mid, a.imag)
        else:
            mid = 0.5 * (a.imag + z.imag)
            hi[slot, j] = complex(z.real, mid)
            lo[other, j] = complex(a.real, mid)
        pending[0] = slot
        pending[1] = other
        n_pending = 2
    if n == 0:
        certified = witness
    else:
        top = sign * key[heap[0]]
        certified = max(top, witness) if want_max else min(top, witness)
    return certified, witness, evaluations, converged


@jit(nogil=True)
def certify_frequencies(G, q0, ylin, H, kr, ki, F_lim, want_max, K_init, budget, rtol, atol,
                        freqs, certified, witness, K_best, evaluations, converged):
    """:func:`certify` at the frequencies ``freqs`` (indices), writing their entries of
    the outputs (shape (n_f,), ``K_best`` (n_f, nd)); ``K_init`` is (n_f, n_init, nd)
    and ``atol`` (n_f,)."""
    for k in freqs:
        c, w, e, ok = certify(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, want_max, K_init[k],
                              budget, rtol, atol[k], K_best[k])
        certified[k] = c
        witness[k] = w
        evaluations[k] = e
        converged[k] = ok
