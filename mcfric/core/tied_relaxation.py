"""The lower bound's relaxation on a tuned ring, with its multipliers tied across dampers.

On a tuned ring under a travelling wave, turning the ring by one blade maps the
admissible set onto itself and permutes the beams' responses (a unitary map of
``z = (p, 1)``: a permutation of the dampers times a phase). The relaxation of the lower
bound (:mod:`.relaxation`: ``sum_b lambda_b Y_b - s E + sum_i theta_i A_i >= 0`` proves
``max_b |y_b|^2 >= s``) is carried into itself, and its feasible multipliers form a
convex set, so the average of any feasible point's ``nd`` turns is feasible with the same
``s``: an optimum exists with each damper's multipliers equal (unscaled, see
:func:`.relaxation.weights`) and every ``lambda_b = 1 / nb``. That leaves ``per + 1``
unknowns (six multipliers and ``s``) instead of ``nd per + nb``, solved here with a dense
log-det barrier on ``Z = C_0 + sum_f u_f B_f``. The tying only finds multipliers: they are
expanded onto the full forms and verified there (:func:`.relaxation.shifted`).
"""

import math

import numpy as np

from ._jit import jit
from .linalg import ridge_solve
from .relaxation import (
    CENTRED,
    MU_FACTOR,
    TOL,
    _assemble,
    _inverse,
    _schur,
    cholesky,
    forms,
    per_damper,
    shifted,
    weights,
)

#: Newton steps per barrier weight and in all at most: steps are cheap here, and with
#: relaxation's 40 per weight the iterates of 72-blade rings near the first
#: resonance were left uncentred and proved only 0.
STEPS_PER_ROUND = 100
MAX_STEPS = 600


@jit
def _z(y, B, C0, Z):
    """``Z = C0 + sum_f y_f B_f``."""
    Z[:, :] = C0
    for f in range(len(y)):
        Z += y[f] * B[f]


@jit
def _value(y, mu, c, npos, B, C0, Z, L):
    """The barrier ``c.y / mu - log det Z - sum log y_pos`` (``inf`` outside)."""
    f = 0.0
    for i in range(len(y)):
        f += c[i] * y[i] / mu
        if i < npos:
            if not y[i] > 0.0:
                return np.inf
            f -= math.log(y[i])
    _z(y, B, C0, Z)
    logdet = cholesky(Z, L, Z.shape[0])
    return np.inf if np.isnan(logdet) else f - logdet


@jit
def _expand(y, w, nd, per, nb, shift, simplex, x):
    """The full forms' multipliers from the tied ones: damper ``j``'s form ``f`` gets
    ``y_f / w``, every simplex weight ``1 / nb``, the shift ``y[per]``."""
    x[:] = 0.0
    for j in range(nd):
        for f in range(per):
            x[j * per + f] = y[f] / w[j * per + f]
    for i in range(len(x)):
        if simplex[i]:
            x[i] = 1.0 / nb
    x[shift] = y[per]


@jit
def tied_lower(G, q0, ylin, H, lo, hi, F_lim, goal, V, idx, S, x, cvec, pos, simplex, grow,
               ws, stats):
    """The verified lower bound of ``max_b |y_b|`` (m) over the dampers in ``[lo_j, hi_j]``
    (N/m) and the force limit, for the arrays of a tuned ring under a travelling wave
    (every beam in order, ``nb == nd``); ``nan`` where nothing verified. Stops once it
    proves ``goal`` (m). ``x`` receives the verified full multipliers (for
    :func:`.relaxation.rounded`); ``stats`` as for :func:`.relaxation.solve` (Newton
    steps, rounds, and the relaxation where it verified: a failure is left uncounted to
    the caller's fallback)."""
    shift, ys = forms(G, q0, ylin, H, lo, hi, F_lim, np.int64(-1), V, idx, S, x, cvec, pos,
                      simplex, grow)
    nd, nb, m, nn = len(q0), len(ylin), len(x), V.shape[0]
    per = per_damper(np.isfinite(F_lim))
    w = np.empty(m)
    weights(S, nd, per, w)
    C, T, Z, L, Zi, W = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
    k = per + 1
    B = np.empty((k, nn, nn), np.complex128)
    C0 = np.empty((nn, nn), np.complex128)
    y = np.zeros(k)
    # the constant part (1/nb sum_b Y_b), the shift's form and each tied form, assembled
    # as the full forms are
    _expand(y, w, nd, per, nb, shift, simplex, x)
    _assemble(x, 1.0, V, idx, S, C, T, Z, m)
    C0[:, :] = Z
    x[:] = 0.0
    x[shift] = 1.0
    _assemble(x, 0.0, V, idx, S, C, T, Z, m)
    B[per] = Z
    for f in range(per):
        y[:] = 0.0
        y[f] = 1.0
        _expand(y, w, nd, per, nb, shift, simplex, x)
        x[shift] = 0.0
        for i in range(m):
            if simplex[i]:
                x[i] = 0.0
        _assemble(x, 0.0, V, idx, S, C, T, Z, m)
        B[f] = Z
    # start: damper 0's multipliers, the force limit's grown until the leading block is
    # definite, then s from the Schur complement (as relaxation.solve)
    for f in range(per):
        y[f] = 1.0 if f >= 4 else 1e-2
        y[f] *= w[f]
    y[per] = 0.0
    found = False
    for attempt in range(200):
        _z(y, B, C0, Z)
        if not np.isnan(cholesky(Z, L, nn - 1)):
            found = True
            break
        if per == 6:
            y[5] *= 2.0
        else:
            y[:per] *= 2.0
    if not found:
        return np.nan
    r = _schur(Z, L, W, nn)
    sgn = S[shift, 0, 0].real
    y[per] = (1.0 + abs(r) - r) / sgn
    c = np.zeros(k)
    c[per] = cvec[shift]
    target = -goal * goal / ys
    nu = float(nn + per)
    mu = abs(y[per]) / nu
    M = np.empty((k, nn, nn), np.complex128)
    g = np.empty(k)
    Hm = np.empty((k, k))
    Lh = np.zeros((k, k))
    dy = np.empty(k)
    yn = np.empty(k)
    xb = np.empty(m)
    best = np.nan
    steps = 0
    while steps < MAX_STEPS:
        for inner in range(STEPS_PER_ROUND):
            f0 = _value(y, mu, c, per, B, C0, Z, L)
            if not f0 < np.inf:
                steps = MAX_STEPS
                break
            _inverse(L, Zi, W, nn)
            for f in range(k):
                M[f] = Zi @ B[f]
            for a in range(k):
                tr = 0.0
                for i in range(nn):
                    tr += M[a, i, i].real
                g[a] = c[a] / mu - tr - (1.0 / y[a] if a < per else 0.0)
                for b in range(a, k):
                    h = 0.0
                    for i in range(nn):
                        for j in range(nn):
                            h += (M[a, i, j] * M[b, j, i]).real
                    if a == b and a < per:
                        h += 1.0 / y[a] ** 2
                    Hm[a, b] = h
                    Hm[b, a] = h
            steps += 1
            stats[0] += 1
            for a in range(k):
                yn[a] = -g[a]
            if not ridge_solve(Hm, Lh, yn, dy, k, 1e-12, 100.0, np.int64(8)):
                steps = MAX_STEPS
                break
            lam2 = -(g * dy).sum()
            if not lam2 > 0.0:
                steps = MAX_STEPS
                break
            step = 1.0
            moved = False
            for back in range(40):
                for a in range(k):
                    yn[a] = y[a] + step * dy[a]
                if _value(yn, mu, c, per, B, C0, Z, L) <= f0 - 0.25 * step * lam2:
                    moved = True
                    break
                step *= 0.5
            if moved:
                y[:] = yn
            if not moved or lam2 < CENTRED ** 2 or steps >= MAX_STEPS:
                break
        stats[1] += 1
        # verified on the full forms, with the least shift that makes Z definite
        _expand(y, w, nd, per, nb, shift, simplex, x)
        val = shifted(x, shift, V, idx, S, pos, simplex, ws)
        if not np.isnan(val) and (np.isnan(best) or val < best):
            best = val
            xb[:] = x
        if best <= target or mu * nu <= TOL * abs(y[per]):
            break
        mu *= MU_FACTOR
    if np.isnan(best):
        return np.nan
    stats[2] += 1                   # a failure is the caller's: the full relaxation runs
    x[:] = xb
    return math.sqrt(max(-best * ys, 0.0)) * (1.0 - 1e-14)
