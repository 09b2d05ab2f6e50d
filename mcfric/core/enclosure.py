"""A guaranteed enclosure of the response over a product of damper rectangles.

Over the sub-box ``K_j in [lo_j, hi_j]`` (real and imaginary parts) of every damper,
:func:`enclosure` bounds each beam's ``|y_b|`` from above and below, says whether the
force limit ``|K_j q_j| <= F_lim`` is violated everywhere in it; the width each damper
adds to each bound is left in the workspace (``Pb``) to choose which rectangle to halve.

The argument (the docs' bounds page, "Certified bounds"): with ``Kc`` the centre,
``r_j`` the radius of a disc holding rectangle j and ``X`` any approximate inverse of
``A = I + G diag(Kc)``, the exact identity

    q = X q0 + E q - X G diag(K - Kc) q,        E = I - X A,

gives ``|q| <= a`` componentwise for any ``a >= b + N a`` with ``b = |X q0|`` and
``N = |E| + |X G| diag(r)``; a positive ``a`` satisfying it (checked, not assumed)
also proves ``rho(N) < 1``, so ``I + G diag(K)`` is regular over the whole sub-box. The
output obeys ``y = ylin - H Kc X q0 - H Kc E q - P diag(K - Kc) q`` with
``P = H - H Kc X G``, which bounds ``|y_b - y_b(Kc)|`` to first order exactly for
discs. Every floating-point product and sum enters with its standard componentwise
error bound (``n u |x||y|``), majorised by ``c = 8 (nd + 4) u``, and the results are
widened by ``1 + c``: rounding cannot break the enclosure.
"""

import math

import numpy as np

from ._jit import jit
from .linalg import lu_factor, lu_solve

#: Unit roundoff of float64.
U_ROUND = 2.0 ** -53
#: Relative slack in the verified bound on |q|: the candidate solves (I - N) a = b (1 + t).
SLACK = 1e-7
#: Status codes of :func:`enclosure`.
OK, INFEASIBLE, UNVERIFIED = 0, 1, 2


@jit
def workspace(nd, nb):
    """Scratch arrays of :func:`enclosure` for ``nd`` dampers and ``nb`` beams."""
    c = np.complex128
    return (np.empty((nd, nd), c), np.empty((nd, nd), c), np.empty((nd, nd), c),
            np.empty(nd, np.int64), np.empty(nd, c), np.empty(nd, c),
            np.empty((nd, nd)), np.empty((nd, nd)), np.empty((nd, nd)), np.empty((nd, nd)),
            np.empty(nd), np.empty(nd), np.empty(nd), np.empty(nd), np.empty(nd),
            np.empty(nd), np.empty(nd), np.empty(nd), np.empty(nd, c), np.empty(nd, c),
            np.empty((nb, nd)), np.empty(nb))


@jit(nogil=True)
def _force_bound(ylin, H, Kc, qh, eq, r, kabs, F_lim, U, cen, rad, c):
    """Lower ``U`` to the force bound over the sub-box; False if the limit is violated
    everywhere.

    Each damper force ``f_j = K_j q_j`` lies in the disc ``|f - Kc_j qh_j| <= rho_j`` and,
    where admissible, in ``|f| <= F_lim``; the smallest of three discs holding that lens
    (either disc, or the one centred on the chord's axis) bounds it, and
    ``|y_b| <= |ylin_b - sum_j H_bj cen_j| + sum_j |H_bj| rad_j``.
    """
    nd = Kc.shape[0]
    nb = ylin.shape[0]
    for j in range(nd):
        fh = Kc[j] * qh[j]
        d = abs(fh)
        rho = (kabs[j] * eq[j] + r[j] * (abs(qh[j]) + eq[j])) * (1.0 + 2.0 * c) + c * d
        if (d - rho) * (1.0 - c) > F_lim:
            return False
        cen[j] = fh
        rad[j] = rho
        if F_lim < rad[j]:
            cen[j] = 0.0j
            rad[j] = F_lim
        if d > 0.0:
            # the disc centred where the chord crosses the axis, at x from the origin:
            # its radius reaches the chord ends (h) and both caps' apexes
            # (only where the circles cross: otherwise one disc holds the other)
            x = (d * d + F_lim * F_lim - rho * rho) / (2.0 * d)
            h2 = F_lim * F_lim - x * x
            R = math.inf
            if h2 > 0.0 and abs(F_lim - rho) < d < F_lim + rho:
                R = max(math.sqrt(h2), abs(F_lim - x), abs(rho - (d - x)))
                R += 8.0 * c * (d * d + F_lim * F_lim + rho * rho) / d
            if R < rad[j]:
                cen[j] = fh * (x / d)
                rad[j] = R
    for b in range(nb):
        acc = ylin[b]
        err = abs(ylin[b])
        sr = 0.0
        for j in range(nd):
            acc -= H[b, j] * cen[j]
            err += abs(H[b, j]) * abs(cen[j])
            sr += abs(H[b, j]) * rad[j]
        Uf = (abs(acc) + c * err + sr) * (1.0 + 2.0 * c)
        if Uf < U[b]:
            U[b] = Uf
    return True


@jit(nogil=True)
def enclosure(G, q0, ylin, H, lo, hi, F_lim, U, L, ws):
    """Bounds on ``|y_b|`` over the sub-box ``lo <= K <= hi`` (parts), m.

    Parameters
    ----------
    G : ndarray of complex, shape (nd, nd)
        Contact-space receptance, m/N.
    q0 : ndarray of complex, shape (nd,)
        Uncoupled relative contact displacement, m.
    ylin : ndarray of complex, shape (nb,)
        Uncoupled output displacement, m.
    H : ndarray of complex, shape (nb, nd)
        Output displacement per unit damper force, m/N.
    lo, hi : ndarray of complex, shape (nd,)
        Corners of each damper's rectangle (``lo.real <= Re K <= hi.real``, same for
        the imaginary parts), N/m; ``lo >= 0``.
    F_lim : float
        Force limit, N (``inf``: none).
    U, L : ndarray, shape (nb,)
        Out: upper and lower bounds of ``|y_b|`` over the admissible part of the sub-box
        (the lower bound over all of it).
    ws : tuple
        From :func:`workspace`.

    Returns
    -------
    status : int
        ``OK``; ``INFEASIBLE`` when the force limit is violated everywhere in the sub-box
        (``U``, ``L`` then unset); ``UNVERIFIED`` when the bound could not be proved
        (``U = inf``, ``L = 0``: halve the sub-box).
    centre_value : float
        ``M = max_b |y_b|`` at the centre, m.
    centre_admissible : bool
        Whether the centre satisfies the force limit.
    """
    (A, X, XG, piv, qh, col, absX, Eb, XGb, N, r, kabs, e0, abar, rhs, eq, Ea, rad, cen,
     hw, Pb, yabs) = ws
    nd = q0.shape[0]
    nb = ylin.shape[0]
    c = 8.0 * (nd + 4) * U_ROUND
    Kc = col
    for j in range(nd):
        cr = 0.5 * (lo[j].real + hi[j].real)
        ci = 0.5 * (lo[j].imag + hi[j].imag)
        Kc[j] = complex(cr, ci)
        dr = max(hi[j].real - cr, cr - lo[j].real)
        di = max(hi[j].imag - ci, ci - lo[j].imag)
        r[j] = math.sqrt(dr * dr + di * di) * (1.0 + c)
        hw[j] = complex(dr * (1.0 + c), di * (1.0 + c))
        kabs[j] = abs(Kc[j])
    for i in range(nd):
        for j in range(nd):
            A[i, j] = G[i, j] * Kc[j]
            X[i, j] = A[i, j]
        A[i, i] += 1.0
        X[i, i] += 1.0
    for b in range(nb):
        U[b] = math.inf
        L[b] = 0.0
    if lu_factor(X, piv, nd) != 0:
        return UNVERIFIED, math.nan, False
    # X becomes the inverse, column by column (A keeps I + G Kc)
    for j in range(nd):
        for i in range(nd):
            XG[i, j] = 1.0 if i == j else 0.0
    for j in range(nd):
        qh[:] = XG[:, j]
        lu_solve(X, piv, qh, nd)
        for i in range(nd):
            XG[i, j] = qh[i]
    for i in range(nd):
        for j in range(nd):
            X[i, j] = XG[i, j]
            absX[i, j] = abs(X[i, j])
    for i in range(nd):
        acc = 0.0j
        err = 0.0
        for k in range(nd):
            acc += X[i, k] * q0[k]
            err += absX[i, k] * abs(q0[k])
        qh[i] = acc
        e0[i] = c * err
        for j in range(nd):
            ea = 0.0j
            eg = 0.0j
            sa = 0.0
            sg = 0.0
            for k in range(nd):
                ea += X[i, k] * A[k, j]
                eg += X[i, k] * G[k, j]
                sa += absX[i, k] * (abs(A[k, j]) + abs(G[k, j]) * kabs[j])
                sg += absX[i, k] * abs(G[k, j])
            XG[i, j] = eg
            Eb[i, j] = abs((1.0 if i == j else 0.0) - ea) + c * (sa + 1.0)
            XGb[i, j] = abs(eg) + c * sg
    # verified a >= |q| over the sub-box: a >= b + N a, a > 0
    for i in range(nd):
        rhs[i] = (abs(qh[i]) + e0[i]) * (1.0 + c) + 1e-300
        for j in range(nd):
            N[i, j] = Eb[i, j] + XGb[i, j] * r[j]
            absX[i, j] = (1.0 if i == j else 0.0) - N[i, j]
        abar[i] = rhs[i] * (1.0 + SLACK)
    if lu_factor(absX, piv, nd) != 0:
        return UNVERIFIED, math.nan, False
    lu_solve(absX, piv, abar, nd)
    for i in range(nd):
        if not (abar[i] > 0.0) or not math.isfinite(abar[i]):
            return UNVERIFIED, math.nan, False
    for i in range(nd):
        s = rhs[i]
        for j in range(nd):
            s += N[i, j] * abar[j]
        if not s * (1.0 + c) <= abar[i]:
            return UNVERIFIED, math.nan, False
    # eq: the bound on |q - qh|, e0 + N a; Ea: on |E q|
    for i in range(nd):
        s = 0.0
        se = 0.0
        for j in range(nd):
            s += N[i, j] * abar[j]
            se += Eb[i, j] * abar[j]
        eq[i] = (e0[i] + s) * (1.0 + c)
        Ea[i] = se * (1.0 + c)
    # the force limit: violated everywhere if min |K_j| min |q_j| > F_lim
    for j in range(nd):
        kmin = math.sqrt(lo[j].real ** 2 + lo[j].imag ** 2) * (1.0 - c)
        qmin = (abs(qh[j]) - eq[j]) * (1.0 - c)
        if qmin > 0.0 and kmin * qmin > F_lim:
            return INFEASIBLE, math.nan, False
    centre_value = 0.0
    centre_admissible = True
    for j in range(nd):
        if not abs(Kc[j] * qh[j]) <= F_lim:
            centre_admissible = False
    for b in range(nb):
        yc = ylin[b]
        ex = c * abs(ylin[b])
        for j in range(nd):
            hk = H[b, j] * Kc[j]
            yc -= hk * qh[j]
            # the E q term, the error of X q0 and that of forming yc
            ex += abs(hk) * (Ea[j] + e0[j] + c * abs(qh[j]))
        yabs[b] = abs(yc)
        centre_value = max(centre_value, yabs[b])
        # y - yc = -sum_j P_bj dK_j qh_j + remainder: the linear part is bounded exactly
        # over the rectangles along and across u = yc / |yc|, the rest (second order:
        # P dK (q - qh)) and every rounding error go to ex
        ur = 1.0
        ui = 0.0
        if yabs[b] > 0.0:
            ur = yc.real / yabs[b]
            ui = yc.imag / yabs[b]
        vp = 0.0
        vq = 0.0
        for j in range(nd):
            p = H[b, j]
            pe = abs(H[b, j])
            for i in range(nd):
                hk = H[b, i] * Kc[i]
                p -= hk * XG[i, j]
                pe += abs(hk) * XGb[i, j]
            pe *= 2.0 * c
            pq = p * qh[j]
            along = ur * pq.real + ui * pq.imag
            across = ur * pq.imag - ui * pq.real
            lp = hw[j].real * abs(along) + hw[j].imag * abs(across)
            lq = hw[j].real * abs(across) + hw[j].imag * abs(along)
            rem = ((abs(p) + pe) * eq[j] + pe * abs(qh[j]) + c * abs(pq)) * r[j]
            vp += lp
            vq += lq
            ex += rem
            Pb[b, j] = lp + lq + rem
        ex += c * (vp + vq)
        U[b] = (math.sqrt((yabs[b] + vp) ** 2 + vq * vq) + ex) * (1.0 + 2.0 * c)
        L[b] = max(0.0, (yabs[b] - vp - ex) * (1.0 - 2.0 * c))
    if math.isfinite(F_lim):
        if not _force_bound(ylin, H, Kc, qh, eq, r, kabs, F_lim, U, cen, rad, c):
            return INFEASIBLE, math.nan, False
    return OK, centre_value, centre_admissible
