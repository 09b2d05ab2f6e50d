"""The phases of the box search over a list of frequencies: multistart, continuation, polish.

Each phase is a ``nogil`` kernel over frequencies (the Python layer,
:mod:`mcfric.bounds.search`, runs them on threads and chooses the settings):

* :func:`multistart`: a coordinate search from every start, per objective (each beam's
  ``|y_b|`` for the maximum, ``M`` for the minimum, which also starts a least-squares
  valley fit);
* :func:`continuation`: along frequency, upward or downward, each frequency restarting
  from its neighbour's best;
* :func:`polish`: a local search from the best point, ended by a tight one (for the
  minimum then the minimax search of :mod:`.minimax`);
* :func:`evaluate`: the values reported, recomputed by LU with partial pivoting.

A search, not a proof: the extremes found are the best of many local searches.
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .coordinate_search import coordinate_search, max_abs, workspace
from .linalg import contact_solve
from .minimax import lsq_valley, minimax_barrier
from .projected_gradient import projected_gradient


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
    v = coordinate_search(G, q0, ylin, H, kr, ki, K, want_max, b0, b1, max_sweeps, tol, w)
    if not math.isfinite(v) or spg_iter <= 0:
        return v
    nd = K.shape[0]
    K2 = K.copy()
    v2 = projected_gradient(G, q0, ylin, H, kr, ki, K2, -1.0 if want_max else 1.0, b0, b1, w,
                            spg_iter)
    if math.isfinite(v2):
        v2 = coordinate_search(G, q0, ylin, H, kr, ki, K2, want_max, b0, b1, max_sweeps, tol, w)
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
def multistart(G, q0, ylin, H, hr, gr, kr, ki, starts, want_max, objectives, cap, max_sweeps, tol,
                best, K_best, freqs):
    """Phase 1: coordinate search from every start, for every objective, at the
    frequencies ``freqs`` (one task of :func:`mcfric.threads.in_threads`)."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    n_o = objectives.shape[0]
    w = workspace(nd, nb, hr, gr)
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
                v = coordinate_search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                            max_sweeps, tol, w)
                _keep_if_better(v, K, best, K_best, o, k, want_max)
                if want_max and best[o, k] >= cap[k, o]:
                    break               # at the force limit: the box no longer matters
            if not want_max and objectives[o] < 0 and nd > 1:
                # the valley where all beams rest at once: least squares from the centre
                for j in range(nd):
                    K[j] = complex(0.5 * kr, 0.5 * ki)
                v = lsq_valley(G[k], q0[k], ylin[k], H[k], kr, ki, K, w)
                if math.isfinite(v):
                    v = coordinate_search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                                max_sweeps, tol, w)
                _keep_if_better(v, K, best, K_best, o, k, want_max)


@jit(nogil=True)
def continuation(d, o, G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap, max_sweeps,
                 tol, spg_iter, best, K_best, cand, K_cand, first, ran):
    """Phase 2: continuation along frequency, upward (``d = 0``) or downward (``d = 1``),
    for objective ``o`` (one chain per direction and objective, each a task of
    :func:`mcfric.threads.in_threads`); each frequency starts from the neighbour's best
    and keeps what improves, in ``cand[d, o]``.

    Later rounds (``first`` False) search only where the start changed: where the
    decision to search (``ran``) and the neighbour's result (value and describing
    functions, exactly) are those of the previous round, the search would repeat the
    previous round's, whose value is no better than the previous candidate, itself no
    better than ``best`` (the best of the candidates): the candidate is ``best``, without
    searching.
    """
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    w = workspace(nd, nb, hr, gr)
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
def polish(G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap, max_sweeps, tol, spg_iter,
           best, K_best, freqs, polish_sweeps, polish_tol):
    """Phase 3: a local search from the best point of every objective at the frequencies
    ``freqs`` (one task of :func:`mcfric.threads.in_threads`), ended by a tight one
    (``polish_sweeps``, ``polish_tol``); for the minimum then the minimax search of
    :func:`.minimax.minimax_barrier`."""
    nd = q0.shape[1]
    nb = ylin.shape[1]
    w = workspace(nd, nb, hr, gr)
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
                v = coordinate_search(G[k], q0[k], ylin[k], H[k], kr, ki, K, want_max, b0, b1,
                            polish_sweeps, polish_tol, w)
            if not want_max and math.isfinite(v):
                # the minimum's ridges: every beam and damper at once (see .minimax)
                K2 = K.copy()
                v2 = minimax_barrier(G[k], q0[k], ylin[k], H[k], kr, ki, math.inf, K2, w)
                if v2 < v:
                    v = v2
                    for j in range(nd):
                        K[j] = K2[j]
            if math.isfinite(v) and ((v >= best[o, k]) if want_max else (v <= best[o, k])):
                best[o, k] = v
                for j in range(nd):
                    K_best[o, k, j] = K[j]


@jit(nogil=True)
def evaluate(G, q0, ylin, H, objectives, best, K_best):
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
            best[o, k] = max_abs(y, b0, b1)
