"""Certified bounds over the whole box at every frequency, from the relaxation of
:mod:`.relaxation`: the upper bound beam by beam, the lower bound at once (on a tuned
ring with the multipliers tied across dampers, :mod:`.tied_relaxation`; on a large one
the upper bound's tied but near the beam, :mod:`.partly_tied_relaxation`)."""

import math

import numpy as np

from ._jit import jit
from .branch_bound import force_bounds
from .partly_tied_relaxation import partly_tied_upper
from .relaxation import (
    buffers,
    forms,
    per_damper,
    relaxed_bound,
    rounded,
    shifted,
    solve,
    turned,
    verified,
    weights,
)
from .tied_relaxation import tied_lower

#: On a ring, a beam's turned multipliers are taken where they prove it at most this far
#: (relative) above the last solved beam's bound: on a tuned ring they prove the same
#: bound but for the margin :func:`shifted` adds to make ``Z`` definite.
TURN_SLACK = 1e-6


@jit(nogil=True)
def relax_frequencies(G, q0, ylin, H, kr, ki, F_lim, want_max, floor, target, freqs, out,
                      K_round, beam_bounds, stats, turn, near):
    """Certified bounds over the whole box ``[0, kr] x [0, ki]`` at ``freqs``: ``out[k]``
    the upper bound of ``max_b |y_b|`` (``want_max``) or the lower one (m).

    The upper bound takes the beams in decreasing order of their force bound (Eq. 10)
    and stops at the first below the running maximum (``floor[k]`` to begin, a witness);
    each relaxation stops once it proves its beam below ``max(running maximum,
    target[k])``. The lower bound stops once it reaches ``target[k]``. ``stats``
    (int64, shape (4,)): Newton steps, barrier rounds, relaxations and failed relaxations
    (nothing verified: the bound before them kept) are added to it.
    ``K_round[k]`` (shape (2, nd)): the :func:`rounded` candidates of the minimum's
    relaxation, or of the beam with the largest upper bound (N/m; left as they are
    where none was solved);
    ``beam_bounds[k]`` (shape (nb,), m; upper bound only): a proven bound of each beam's
    ``|y_b|``, its force bound where it was not relaxed.

    ``turn``: the arrays are a tuned ring's under a travelling wave, every beam in
    order (``nb == nd``, damper ``j`` between beams ``j`` and ``j + 1``). A beam is then
    first tried with the last solved beam's multipliers turned by the beams between them
    (:func:`turned`): turning such a ring maps the admissible set onto itself and one
    beam's response onto another's, so they prove the same bound (verified here on each
    beam's own forms, like any start). The lower bound then ties each damper's
    multipliers across dampers (:func:`.tied_relaxation.tied_lower`; the full relaxation
    where that verifies nothing). ``near > 0``: the upper bound's relaxation ties them
    but at the ``2 near`` dampers next to the beam
    (:func:`.partly_tied_relaxation.partly_tied_upper`; its forms' ``Z`` is Fourier
    diagonal but for a low-rank part: for rings too large for the full relaxation,
    where that verifies nothing the beam keeps its force bound; the full relaxation
    where ``2 near >= nd``).
    """
    n_f, nd = q0.shape
    nb = ylin.shape[1]
    V, idx, S, x, cvec, pos, simplex, grow, ws = buffers(nd, nb, np.isfinite(F_lim),
                                                         not want_max)
    m = len(x)
    ring = turn and nb == nd
    per = per_damper(np.isfinite(F_lim))
    wprev = np.empty(m)
    wcur = np.empty(m)
    xun = np.empty(m)
    lo = np.zeros(nd, np.complex128)
    hi = np.full(nd, complex(kr, ki))
    eq10 = np.empty(nb)
    xprev = np.empty(m)
    xw = np.empty(m)
    save = np.empty(m + 1)
    cold = np.full(m + 1, np.nan)
    Kc = np.empty((2, nd), np.complex128)
    for k in freqs:
        if want_max:
            force_bounds(ylin[k], H[k], F_lim, eq10)
            beam_bounds[k, :] = eq10
            R = floor[k]
            have = False
            bprev = 0
            ref = 0.0
            for b in np.argsort(-eq10):
                if eq10[b] <= R:
                    break
                shift, ys = forms(G[k], q0[k], ylin[k], H[k], lo, hi, F_lim, b, V, idx,
                                  S, x, cvec, pos, simplex, grow)
                goal = max(R, target[k])
                t = np.nan
                if have:
                    # the multipliers of the beam before (on a ring, turned) often prove
                    # this one below the running maximum already; if not, a cold start
                    # from x (one from these multipliers often stalls higher)
                    lim = goal
                    if ring:
                        weights(S, nd, per, wcur)
                        for i in range(m):
                            xun[i] = xprev[i] * wprev[i]
                        turned(xun, nd, per, (b - bprev) % nd, xw)
                        for i in range(m):
                            xw[i] /= wcur[i]
                        lim = max(goal, ref * (1.0 + TURN_SLACK))
                        # on a tuned ring they prove the solved beam's bound: checked
                        # at that shift (one factorisation), the least shift sought
                        # (two) only where that fails
                        xw[shift] = (ref * (1.0 + TURN_SLACK)) ** 2 / ys
                        if verified(xw, V, idx, S, m, pos, simplex, ws):
                            t = xw[shift]
                    else:
                        xw[:] = xprev
                    if np.isnan(t):
                        t = shifted(xw, shift, V, idx, S, pos, simplex, ws)
                    if t <= lim * lim / ys:
                        x[:] = xw
                    else:
                        t = np.nan
                if np.isnan(t):
                    if ring and 0 < 2 * near < nd:
                        t = partly_tied_upper(G[k], q0[k], ylin[k], H[k], lo, hi, F_lim, b,
                                              goal, V, idx, S, x, cvec, pos, simplex, grow,
                                              ws, stats, near)
                        if np.isnan(t):
                            stats[2] += 1       # it counts only the verified ones
                    else:
                        stats[2] += 1
                        t = solve(x, shift, V, idx, S, cvec, pos, simplex, grow,
                                  goal * goal / ys, ws, stats, 0.0, save)
                    if not np.isnan(t):
                        xprev[:] = x
                        have = True
                        if ring:
                            weights(S, nd, per, wprev)
                            bprev = b
                            ref = math.sqrt(max(t, 0.0) * ys)
                    else:
                        stats[3] += 1
                bound = eq10[b]
                if not np.isnan(t):
                    bound = min(bound, math.sqrt(max(t, 0.0) * ys) * (1.0 + 1e-14))
                    if bound > R and rounded(x, V, idx, S, kr, ki, F_lim, ws, Kc):
                        K_round[k] = Kc
                beam_bounds[k, b] = bound
                R = max(R, bound)
            out[k] = R
        else:
            b = np.nan
            if ring:
                # the turns' average of any dual is a dual: solve for the tied one
                b = tied_lower(G[k], q0[k], ylin[k], H[k], lo, hi, F_lim, target[k], V, idx,
                               S, x, cvec, pos, simplex, grow, ws, stats)
            if np.isnan(b):
                cold[0] = np.nan
                b = relaxed_bound(G[k], q0[k], ylin[k], H[k], lo, hi, F_lim, np.int64(-1),
                                  target[k], V, idx, S, x, cvec, pos, simplex, grow, ws,
                                  stats, cold, lo, hi)
            out[k] = 0.0 if np.isnan(b) else b
            if not np.isnan(b) and rounded(x, V, idx, S, kr, ki, F_lim, ws, Kc):
                K_round[k] = Kc
