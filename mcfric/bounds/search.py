"""The box search of the bounds, driven over frequencies: starts, settings and phases.

The kernels of :mod:`mcfric.core.box_search` run on Python threads
(:func:`mcfric.threads.in_threads`), each task a block of frequencies or one
continuation chain; every task writes its own part of the outputs, so the result does
not depend on the number of threads.
"""

from __future__ import annotations

import numpy as np

from ..core.box_search import continuation, evaluate, multistart, polish
from ..threads import in_threads

#: Tasks per phase over the frequencies: several per thread, so that a thread that
#: finishes early takes another.
_CHUNKS = 32
#: Exploration (multistart, continuation) stops sweeps at this relative change; the final
#: polish at POLISH_TOL, so that members touching a bound are not cut off by rounding.
EXPLORE_TOL = 1e-6
POLISH_TOL = 1e-11
#: Iterations per smoothing stage of the projected gradient in the minimum's local
#: searches (the continuation takes shorter ones than the polish); the maximum's take
#: none: its coordinate search's pattern move takes the long steps along resonance
#: ridges. Chosen by measurement: see the docs' performance page, "Response bounds".
#: Passed at run time: a constant inside the jitted code would compile another
#: specialisation of the search.
SPG_ITER = 40
SPG_ITER_CONTINUATION = 12


def sparsity(G, H):
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
    """The frequency indices in tasks of :func:`in_threads`: ``_CHUNKS`` blocks of a
    permutation that spreads each block over the band (the search costs vary across
    it), so the tasks cost about the same."""
    order = np.argsort((np.arange(n_f) * 0.6180339887498949) % 1.0, kind="stable")
    return np.array_split(order, min(n_f, _CHUNKS))


def starts(n_f, nd, n_starts, seed):
    """Starting points in normalised box coordinates, shape (n_f, n_starts, nd) each.

    Max: the four uniform corners, then random corners (the box maximum lies on the
    perimeter of every damper's rectangle). Min: the centre, the uniform corners (no
    friction first, then fully stuck), then random interior points and corners. The
    random starts differ from frequency to frequency; the continuation along frequency
    shares what each of them finds.
    """
    rng = np.random.default_rng(seed)
    corners = np.array([0, 1, 1 + 1j, 1j])
    uniform = np.broadcast_to(corners[None, :, None], (n_f, 4, nd))
    n_rand = max(n_starts - 4, 0)
    starts_max = np.concatenate([uniform, corners[rng.integers(0, 4, (n_f, n_rand, nd))]],
                                axis=1)[:, :n_starts]
    centre = np.full((n_f, 1, nd), 0.5 + 0.5j)
    n_rand = max(n_starts - 5, 0)
    n_int = n_rand // 2
    interior = rng.uniform(0, 1, (n_f, n_int, nd)) + 1j * rng.uniform(0, 1, (n_f, n_int, nd))
    starts_min = np.concatenate([centre, uniform, interior,
                                 corners[rng.integers(0, 4, (n_f, n_rand - n_int, nd))]],
                                axis=1)[:, :n_starts]
    return (np.ascontiguousarray(starts_max, dtype=complex),
            np.ascontiguousarray(starts_min, dtype=complex))


def box_extreme(G, q0, ylin, H, kr, ki, starts, want_max, cap=None, max_sweeps=20, rounds=2,
                gradient=True):
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
    gradient : bool
        The minimum's local searches include the smoothed-gradient stage (``SPG_ITER``);
        False leaves it out (coordinate searches and the minimax search alone).

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
    hr, gr = sparsity(G, H)
    in_threads(lambda freqs: multistart(G, q0, ylin, H, hr, gr, kr, ki, starts, want_max,
                                          objectives, cap, max_sweeps, EXPLORE_TOL, best,
                                          K_best, freqs), chunks)
    cand = np.empty((2, n_o, n_f))
    K_cand = np.empty((2, n_o, n_f, nd), complex)
    pick = np.nanargmax if want_max else np.nanargmin
    idx = np.arange(n_f)
    ran = np.zeros((2, n_o, n_f), dtype=np.bool_)
    # the maximum's local searches are coordinate searches alone (see SPG_ITER)
    spg_continuation = SPG_ITER_CONTINUATION if gradient and not want_max else 0
    for r in range(rounds):
        # one chain per direction and objective, interleaved by direction
        in_threads(lambda t: continuation(t % 2, t // 2, G, q0, ylin, H, hr, gr, kr, ki, want_max,
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
        # explore, then one tight sweep, then the minimax search (measured against 100
        # tight sweeps: the docs' performance page)
        sweeps, tol, end_sweeps, end_tol = max_sweeps, EXPLORE_TOL, 1, POLISH_TOL
        spg_iter = SPG_ITER if gradient else 0
    in_threads(lambda freqs: polish(G, q0, ylin, H, hr, gr, kr, ki, want_max, objectives, cap,
                                      sweeps, tol, spg_iter, best, K_best, freqs, end_sweeps,
                                      end_tol), chunks)
    evaluate(G, q0, ylin, H, objectives, best, K_best)
    return best, K_best
