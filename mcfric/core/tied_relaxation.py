"""The lower bound's relaxation on a tuned ring, with its multipliers tied across dampers.

On a tuned ring under a travelling wave, turning the ring by one blade maps the
admissible set onto itself and permutes the beams' responses (a unitary map of
``z = (p, 1)``: a permutation of the dampers times a phase). The relaxation of the lower
bound (:mod:`.relaxation`: ``sum_b lambda_b Y_b - s E + sum_i theta_i A_i >= 0`` proves
``max_b |y_b|^2 >= s``) is carried into itself, and its feasible multipliers form a
convex set, so the average of any feasible point's ``nd`` turns is feasible with the same
``s``: an optimum exists with each damper's multipliers equal (unscaled, see
:func:`.relaxation.weights`) and every ``lambda_b = 1 / nb``. That leaves ``per + 1``
unknowns (six multipliers and ``s``) instead of ``nd per + nb``.

With the multipliers tied, ``Z = C_0 + sum_f u_f B_f`` commutes with the turn: its
damper block is circulant, so the discrete Fourier basis diagonalises it, and its last
column (the constant's) lies in the one Fourier mode of the travelling wave. ``log det
Z`` is then a sum of ``nd - 1`` logarithms of linear functions and one of a 2 x 2
determinant, and a Newton step of the log-det barrier costs ``O(nd)`` instead of
``O(nd^3)``. The tying and the Fourier basis only find multipliers: they are expanded
onto the full forms and verified there (:func:`.relaxation.shifted`), so rounding in the
transform cannot reach the bound. Arrays that are not a tuned ring's (the damper block
not circulant to ``CIRCULANT_TOL``) verify nothing here.
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
    forms,
    per_damper,
    scatter,
    shifted,
    weights,
)

#: Newton steps per barrier weight and in all at most: steps are cheap here, and with
#: relaxation's 40 per weight the iterates of 72-blade rings near the first
#: resonance were left uncentred and proved only 0.
STEPS_PER_ROUND = 100
MAX_STEPS = 600
#: Barrier rounds at most (each shrinks the weight tenfold: far more than needed).
MAX_ROUNDS = 40
#: Largest departure taken as a tuned ring's: of ``Z``'s damper block from a circulant
#: (relative to ``Z``'s largest entry), and of each form's last column from one Fourier
#: mode (relative to the form's largest eigenvalue or Fourier coefficient).
CIRCULANT_TOL = 1e-9


@jit
def _departure(Z, nd):
    """The largest departure of ``Z``'s damper block from a circulant, relative to
    ``Z``'s largest entry."""
    big = 0.0
    for i in range(nd + 1):
        for j in range(nd + 1):
            big = max(big, abs(Z[i, j]))
    off = 0.0
    for i in range(nd):
        for j in range(nd):
            off = max(off, abs(Z[i, j] - Z[(i - j) % nd, 0]))
    return off / big if big > 0.0 else 0.0


@jit
def _spectrum(x, coef_const, V, idx, S, C, T, m, lam, beta):
    """For ``Z`` of the multipliers ``x`` (as :func:`.relaxation._assemble`) with a
    circulant damper block: ``lam[k]`` its eigenvalue on Fourier mode ``k`` (from the
    first column) and ``beta[k]`` the unitary Fourier coefficients of the last column;
    returns ``Z``'s last diagonal entry. ``O(nd nv)``: two columns of ``Z``."""
    nd = V.shape[0] - 1
    scatter(x, coef_const, V, idx, S, C, T, m)
    first = np.empty(nd, np.complex128)
    last = np.empty(nd + 1, np.complex128)
    for j in range(nd + 1):
        a = 0j
        b = 0j
        for v in range(V.shape[1]):
            if j < nd:
                a += T[j, v] * V[0, v].conjugate()
            b += T[j, v] * V[nd, v].conjugate()
        if j < nd:
            first[j] = a
        last[j] = b
    scale = 1.0 / math.sqrt(nd)
    for k in range(nd):
        acc = 0j
        accb = 0j
        for r in range(nd):
            e = complex(math.cos(2.0 * math.pi * r * k / nd),
                        -math.sin(2.0 * math.pi * r * k / nd))
            acc += first[r] * e
            accb += last[r] * e
        lam[k] = acc.real
        beta[k] = accb * scale
    return last[nd].real


@jit
def _combine(y, LA, GA, BE, lam):
    """The spectrum at ``y``: ``lam`` (per mode) filled, ``(gamma, beta)`` returned:
    the constant's diagonal entry and its coupling to the travelling wave's mode."""
    nk = len(y)
    lam[:] = LA[0]
    gam = GA[0]
    bet = BE[0]
    for f in range(nk):
        for i in range(len(lam)):
            lam[i] += y[f] * LA[f + 1, i]
        gam += y[f] * GA[f + 1]
        bet += y[f] * BE[f + 1]
    return gam, bet


@jit
def _at(y, mu, c, npos, lam, gam, bet, k0):
    """The barrier ``c.y / mu - log det Z - sum log y_pos`` (``inf`` outside) from the
    spectrum at ``y`` (:func:`_combine`)."""
    f = 0.0
    for i in range(len(y)):
        f += c[i] * y[i] / mu
        if i < npos:
            if not y[i] > 0.0:
                return np.inf
            f -= math.log(y[i])
    for i in range(len(lam)):
        if not lam[i] > 0.0:
            return np.inf
        if i != k0:
            f -= math.log(lam[i])
    det = lam[k0] * gam - (bet.real ** 2 + bet.imag ** 2)
    if not det > 0.0:
        return np.inf
    return f - math.log(det)


@jit
def _value(y, mu, c, npos, LA, GA, BE, k0, lam):
    """The barrier at ``y`` (:func:`_at`), its spectrum formed into ``lam``."""
    gam, bet = _combine(y, LA, GA, BE, lam)
    return _at(y, mu, c, npos, lam, gam, bet, k0)


@jit
def _complement(y, per, LA, GA, BE, k0, lam, yz):
    """``Z``'s Schur complement at the constant, ``gamma - |beta|^2 / lam_k0``, for the
    tied multipliers ``y`` with the shift's (``y[per]``) set to 0: minus the least shift
    that makes ``Z`` definite (``yz``: scratch)."""
    yz[:] = y
    yz[per] = 0.0
    gam, bet = _combine(yz, LA, GA, BE, lam)
    return gam - (bet.real ** 2 + bet.imag ** 2) / lam[k0]


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
def tied_spectra(w, nd, per, nb, shift, coef, V, idx, S, x, simplex, ws):
    """The spectra (:func:`_spectrum`) of the parts of ``Z`` with every damper's
    multipliers tied, on a tuned ring: row 0 the constant part (the constant form with
    weight ``coef``, every simplex weight ``1 / nb``), rows ``1 .. per`` each tied form,
    row ``per + 1`` the shift's form. Returns ``(LA, GA, BE0, k0)``: the eigenvalues
    (``per + 2``, ``nd``), the constant's diagonal entries, their couplings to mode
    ``k0`` (the travelling wave's); ``k0 = -1`` where the arrays are not a tuned ring's
    (``x``: scratch)."""
    m = len(x)
    C, T, Z = ws[0], ws[1], ws[2]
    k = per + 1
    # each part assembled as the full forms are
    LA = np.empty((k + 1, nd))
    GA = np.empty(k + 1)
    BE = np.empty((k + 1, nd), np.complex128)
    y = np.zeros(k)
    for a in range(k + 1):
        y[:] = 0.0
        if a > 0:
            y[a - 1] = 1.0
        _expand(y, w, nd, per, nb, shift, simplex, x)
        if a > 0:
            for i in range(m):
                if simplex[i]:
                    x[i] = 0.0
        GA[a] = _spectrum(x, coef if a == 0 else 0.0, V, idx, S, C, T, m, LA[a], BE[a])
    # a tuned ring's? The damper block of Z with every tied multiplier 1 (the constant
    # part and every form at once) must be circulant
    y[:] = 1.0
    y[per] = 0.0
    _expand(y, w, nd, per, nb, shift, simplex, x)
    _assemble(x, coef, V, idx, S, C, T, Z, m)
    worst = _departure(Z, nd)
    # the constant's column in one mode, the travelling wave's: the other modes' parts
    # measured against each form's largest eigenvalue or Fourier coefficient (the forms'
    # scales differ by powers of two)
    size = np.empty(k + 1)
    for a in range(k + 1):
        size[a] = max(np.abs(LA[a]).max(), np.abs(BE[a]).max(), abs(GA[a])) + 1e-300
    k0 = np.int64(0)
    bmax = 0.0
    for i in range(nd):
        s = 0.0
        for a in range(k + 1):
            s += abs(BE[a, i]) / size[a]
        if s > bmax:
            bmax = s
            k0 = i
    for a in range(k + 1):
        for i in range(nd):
            if i != k0:
                worst = max(worst, abs(BE[a, i]) / size[a])
    if (not worst <= CIRCULANT_TOL or not np.isfinite(LA).all()
            or not np.isfinite(BE).all() or not np.isfinite(GA).all()):
        k0 = np.int64(-1)
    return LA, GA, BE[:, k0].copy(), k0


@jit
def tied_lower(G, q0, ylin, H, lo, hi, F_lim, goal, V, idx, S, x, cvec, pos, simplex, grow,
               ws, stats):
    """The verified lower bound of ``max_b |y_b|`` (m) over the dampers in ``[lo_j, hi_j]``
    (N/m) and the force limit, for the arrays of a tuned ring under a travelling wave
    (every beam in order, ``nb == nd``); ``nan`` where nothing verified (or the arrays
    are not a tuned ring's). Stops once it proves ``goal`` (m). ``x`` receives the
    verified full multipliers (for :func:`.relaxation.rounded`); ``stats`` as for
    :func:`.relaxation.solve` (Newton steps, rounds, and the relaxation where it
    verified: a failure is left uncounted to the caller's fallback)."""
    shift, ys = forms(G, q0, ylin, H, lo, hi, F_lim, np.int64(-1), V, idx, S, x, cvec, pos,
                      simplex, grow)
    nd, nb, m, nn = len(q0), len(ylin), len(x), V.shape[0]
    per = per_damper(np.isfinite(F_lim))
    w = np.empty(m)
    weights(S, nd, per, w)
    k = per + 1
    LA, GA, BE0, k0 = tied_spectra(w, nd, per, nb, shift, 1.0, V, idx, S, x, simplex, ws)
    if k0 < 0:
        return np.nan
    y = np.zeros(k)
    lam = np.empty(nd)
    # start: damper 0's multipliers, the force limit's grown until the damper block is
    # definite, then s from the Schur complement (as relaxation.solve)
    for f in range(per):
        y[f] = 1.0 if f >= 4 else 1e-2
        y[f] *= w[f]
    y[per] = 0.0
    found = False
    for attempt in range(200):
        _combine(y, LA, GA, BE0, lam)
        if (lam > 0.0).all():
            found = True
            break
        if per == 6:
            y[5] *= 2.0
        else:
            y[:per] *= 2.0
    if not found:
        return np.nan
    yn = np.empty(k)
    r = _complement(y, per, LA, GA, BE0, k0, lam, yn)
    sgn = S[shift, 0, 0].real
    y[per] = (1.0 + abs(r) - r) / sgn
    c = np.zeros(k)
    c[per] = cvec[shift]
    target = -goal * goal / ys
    nu = float(nn + per)
    mu = abs(y[per]) / nu
    g = np.empty(k)
    Hm = np.empty((k, k))
    Lh = np.zeros((k, k))
    dy = np.empty(k)
    dD = np.empty(k)
    xb = np.empty(m)
    Y = np.empty((MAX_ROUNDS, k))
    nr = 0
    best = np.nan
    steps = 0
    while steps < MAX_STEPS:
        for inner in range(STEPS_PER_ROUND):
            gam, bet = _combine(y, LA, GA, BE0, lam)
            f0 = _at(y, mu, c, per, lam, gam, bet, k0)
            if not f0 < np.inf:
                steps = MAX_STEPS
                break
            lk = lam[k0]
            det = lk * gam - (bet.real ** 2 + bet.imag ** 2)
            for a in range(k):
                ba = BE0[a + 1]
                dD[a] = (LA[a + 1, k0] * gam + lk * GA[a + 1]
                         - 2.0 * (bet.real * ba.real + bet.imag * ba.imag))
            for a in range(k):
                tr = dD[a] / det
                for i in range(nd):
                    if i != k0:
                        tr += LA[a + 1, i] / lam[i]
                g[a] = c[a] / mu - tr - (1.0 / y[a] if a < per else 0.0)
                for b in range(a, k):
                    h = 0.0
                    for i in range(nd):
                        if i != k0:
                            h += LA[a + 1, i] * LA[b + 1, i] / lam[i] ** 2
                    ba, bb = BE0[a + 1], BE0[b + 1]
                    d2 = (LA[a + 1, k0] * GA[b + 1] + LA[b + 1, k0] * GA[a + 1]
                          - 2.0 * (ba.real * bb.real + ba.imag * bb.imag))
                    h += dD[a] * dD[b] / det ** 2 - d2 / det
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
                if _value(yn, mu, c, per, LA, GA, BE0, k0, lam) <= f0 - 0.25 * step * lam2:
                    moved = True
                    break
                step *= 0.5
            if moved:
                y[:] = yn
            if not moved or lam2 < CENTRED ** 2 or steps >= MAX_STEPS:
                break
        stats[1] += 1
        # verified on the full forms (each check costs O(nd^3)): once the transform says
        # the goal is proved, and at the end (walking back to the rounds before if the
        # last does not verify)
        Y[nr] = y
        nr += 1
        estimate = -_complement(y, per, LA, GA, BE0, k0, lam, yn)
        done = (mu * nu <= TOL * abs(y[per]) or steps >= MAX_STEPS
                or nr == len(Y))
        if estimate <= target or done:
            _expand(y, w, nd, per, nb, shift, simplex, x)
            val = shifted(x, shift, V, idx, S, pos, simplex, ws)
            if not np.isnan(val) and (np.isnan(best) or val < best):
                best = val
                xb[:] = x
            if best <= target or done:
                break
        mu *= MU_FACTOR
    back = nr - 2
    while np.isnan(best) and back >= 0:
        _expand(Y[back], w, nd, per, nb, shift, simplex, x)
        best = shifted(x, shift, V, idx, S, pos, simplex, ws)
        xb[:] = x
        back -= 1
    if np.isnan(best):
        return np.nan
    stats[2] += 1                   # a failure is the caller's: the full relaxation runs
    x[:] = xb
    return math.sqrt(max(-best * ys, 0.0)) * (1.0 - 1e-14)
