"""The upper bound's relaxation on a tuned ring: multipliers free at the dampers near the
beam, tied across the rest.

A beam's upper bound (:mod:`.relaxation`: ``t E - Y_b + sum_i theta_i A_i >= 0`` proves
``|y_b|^2 <= t``) has no turn symmetry to tie its multipliers with, as the lower bound's
has (:mod:`.tied_relaxation`), and tying them all proves little. Tying them only beyond
the ``2 r`` dampers next to the beam proves nearly what the full relaxation does: each
tied form ``f`` gets ``y_f``, a near damper's ``y_f + delta_f``. Then

    Z = Z_c(y, t) + U G(delta) U^H,

``Z_c`` the tied forms and the shift (circulant damper block, the constant's column in
the travelling wave's Fourier mode: diagonal but for one 2 x 2 block in the Fourier
basis) and ``U`` the ``R = 4 r + 2`` functionals the rest touches (each near damper's
``q`` and ``p``, the constant, the beam's ``y_b``), ``U = W T`` with ``W`` an
orthonormal basis of their span (:func:`_basis`). With ``M = W^H Z_c^-1 W = L L^H``
and ``G' = T G T^H``, ``log det Z = log det Z_c + log det (I + L^H G' L)`` and
``Z^-1 = Z_c^-1 - P Q P^H`` (``P = Z_c^-1 W``, ``Q = (I + G' M)^-1 G'``), so a Newton
step of the log-det barrier costs ``O(nd R^2)`` instead of ``O(nd^3)``. The barrier
also keeps ``Z_c`` definite (a restriction: it only finds multipliers). They are
expanded onto the full forms and verified there (:func:`.relaxation.shifted`), so
neither the tying, the Fourier basis nor their rounding can reach the bound.
"""

import math

import numpy as np

from ._jit import jit
from .linalg import lu_factor, lu_solve, ridge_solve
from .relaxation import CENTRED, MU_FACTOR, TOL, cholesky, forms, per_damper, shifted, weights
from .tied_relaxation import MAX_ROUNDS, MAX_STEPS, STEPS_PER_ROUND, _combine, tied_spectra

#: Dampers on each side of the beam whose multipliers are free (``per`` unknowns each):
#: below the first resonance six prove bounds 20-25 % lower than three on 72 blades,
#: elsewhere the same to 4 %, at twice the time (still small beside the checks of the
#: other beams): the docs' bounds page.
NEAR = 6
#: Singular values (of the unit-scaled functionals) below this fraction of the largest
#: are dropped from their basis: where the receptance couples only neighbouring dampers
#: a near damper's ``q`` lies in the span of its neighbours' ``p`` and the constant.
BASIS_TOL = 1e-9


@jit
def near_dampers(beam, nd, r, out):
    """``out``: the ``2 r`` dampers next to ``beam`` (damper ``j`` lies between beams
    ``j`` and ``j + 1``)."""
    for i in range(2 * r):
        out[i] = (beam - r + i) % nd


@jit
def _fourier(V, cols, Uh):
    """``Uh``: the columns ``cols`` of ``V`` in the unitary Fourier basis of the damper
    rows (the constant's row as it is), the basis :func:`.tied_relaxation._spectrum`
    diagonalises the tied forms in."""
    nd = V.shape[0] - 1
    scale = 1.0 / math.sqrt(nd)
    # the nd roots of unity, once: every column's transform takes its factors from them
    roots = np.empty(nd, np.complex128)
    for i in range(nd):
        roots[i] = complex(math.cos(2.0 * math.pi * i / nd), -math.sin(2.0 * math.pi * i / nd))
    for c in range(len(cols)):
        col = cols[c]
        for k in range(nd):
            acc = 0j
            for r in range(nd):
                acc += V[r, col] * roots[(r * k) % nd]
            Uh[k, c] = acc * scale
        Uh[nd, c] = V[nd, col]


@jit
def _basis(Uh):
    """``(W, T)``: orthonormal columns ``W`` spanning ``Uh``'s and ``T`` with
    ``Uh = W T`` (to ``BASIS_TOL``); no columns where ``Uh`` is not finite."""
    R = Uh.shape[1]
    norms = np.ones(R)
    Un = np.empty_like(Uh)
    for c in range(R):
        s = 0.0
        for k in range(Uh.shape[0]):
            s += Uh[k, c].real ** 2 + Uh[k, c].imag ** 2
        if s > 0.0:
            norms[c] = math.sqrt(s)
        for k in range(Uh.shape[0]):
            Un[k, c] = Uh[k, c] / norms[c]
    if not np.isfinite(Un).all():
        return np.empty((Uh.shape[0], 0), np.complex128), np.empty((0, R), np.complex128)
    u, sv, vh = np.linalg.svd(Un, full_matrices=False)
    rho = 0
    for i in range(len(sv)):
        if sv[i] > BASIS_TOL * sv[0]:
            rho += 1
    W = np.ascontiguousarray(u[:, :rho])
    T = np.empty((rho, R), np.complex128)
    for i in range(rho):
        for c in range(R):
            T[i, c] = sv[i] * vh[i, c] * norms[c]
    return W, T


@jit
def _low_rank(v, per, gconst, pa, pb, Sd, Gm):
    """``G(delta)``: the constant form's entry and each near form's ``delta_d Sd[d]`` at
    the positions ``(pa[d], pb[d])`` of its two functionals."""
    Gm[:, :] = 0.0
    R = Gm.shape[0]
    Gm[R - 1, R - 1] = gconst
    for d in range(len(pa)):
        dv = v[per + 1 + d]
        p = (pa[d], pb[d])
        for i in range(2):
            for j in range(2):
                Gm[p[i], p[j]] += dv * Sd[d, i, j]


@jit
def _factor(v, per, LA, GA, BE, k0, W, T, gconst, pa, pb, Sd, lam, blk, P, M, Lm, Gm, Gp,
            H2, L2, yt):
    """``log det Z`` at ``v`` (``nan`` where ``Z`` or ``Z_c`` is not definite), and in the
    arrays: ``lam`` (``Z_c``'s eigenvalues), ``blk`` (the inverse of its 2 x 2 block,
    modes ``k0`` and the constant), ``P = Z_c^-1 W``, ``M = W^H P`` and its Cholesky
    factor ``Lm``, ``Gm = G`` and ``Gp = T G T^H`` (``U = W T``), ``H2 = I + Lm^H Gp Lm``
    and its factor ``L2``."""
    nd = len(lam)
    rho = W.shape[1]
    R = T.shape[1]
    yt[:] = v[:per + 1]
    gam, bet = _combine(yt, LA, GA, BE, lam)
    logdet = 0.0
    for k in range(nd):
        if not lam[k] > 0.0:
            return np.nan
        if k != k0:
            logdet += math.log(lam[k])
    lk = lam[k0]
    det = lk * gam - (bet.real ** 2 + bet.imag ** 2)
    if not det > 0.0:
        return np.nan
    logdet += math.log(det)
    blk[0, 0] = gam / det
    blk[0, 1] = -bet / det
    blk[1, 0] = -bet.conjugate() / det
    blk[1, 1] = lk / det
    for k in range(nd):
        if k != k0:
            inv = 1.0 / lam[k]
            for s in range(rho):
                P[k, s] = W[k, s] * inv
    for s in range(rho):
        a, c = W[k0, s], W[nd, s]
        P[k0, s] = blk[0, 0] * a + blk[0, 1] * c
        P[nd, s] = blk[1, 0] * a + blk[1, 1] * c
    for r in range(rho):
        for s in range(r, rho):
            acc = 0j
            for k in range(nd + 1):
                acc += W[k, r].conjugate() * P[k, s]
            M[r, s] = acc
            M[s, r] = acc.conjugate()
        M[r, r] = M[r, r].real
    if not np.isfinite(cholesky(M, Lm, rho)):
        return np.nan
    _low_rank(v, per, gconst, pa, pb, Sd, Gm)
    # Gp = T G T^H with G sparse (a few entries per row)
    TG = np.zeros((rho, R), np.complex128)
    for i in range(R):
        for j in range(R):
            gij = Gm[i, j]
            if gij != 0:
                for r in range(rho):
                    TG[r, j] += T[r, i] * gij
    for r in range(rho):
        for s in range(r, rho):
            acc = 0j
            for j in range(R):
                acc += TG[r, j] * T[s, j].conjugate()
            Gp[r, s] = acc
            Gp[s, r] = acc.conjugate()
        Gp[r, r] = Gp[r, r].real
    LG = Lm.conj().T @ Gp @ Lm
    for r in range(rho):
        for s in range(r, rho):
            acc = 0.5 * (LG[r, s] + LG[s, r].conjugate())
            H2[r, s] = acc
            H2[s, r] = acc.conjugate()
        H2[r, r] = H2[r, r].real + 1.0
    l2 = cholesky(H2, L2, rho)
    if not np.isfinite(l2):
        return np.nan
    return logdet + l2


@jit
def _value(v, mu, per, tnorm, LA, GA, BE, k0, W, T, gconst, pa, pb, Sd, work):
    """The barrier ``t / mu - log det Z - sum log(multipliers)`` at ``v`` (``inf``
    outside)."""
    lam, blk, P, M, Lm, Gm, Gp, H2, L2, yt = work
    f = tnorm * v[per] / mu
    for a in range(per):
        if not v[a] > 0.0:
            return np.inf
        f -= math.log(v[a])
    for d in range(len(pa)):
        s = v[d % per] + v[per + 1 + d]
        if not s > 0.0:
            return np.inf
        f -= math.log(s)
    logdet = _factor(v, per, LA, GA, BE, k0, W, T, gconst, pa, pb, Sd, lam, blk, P, M, Lm,
                     Gm, Gp, H2, L2, yt)
    if not np.isfinite(logdet):
        return np.inf
    return f - logdet


@jit
def _trace_pair(S2, p0, p1, X):
    """``tr(G_d X)`` for ``G_d`` holding ``S2`` at positions ``(p0, p1)``."""
    return (S2[0, 0] * X[p0, p0] + S2[0, 1] * X[p1, p0] + S2[1, 0] * X[p0, p1]
            + S2[1, 1] * X[p1, p1])


@jit
def _derivatives(v, mu, per, tnorm, LA, GA, BE, k0, T, pa, pb, Sd, work, g, Hm):
    """Gradient ``g`` and Hessian ``Hm`` of the barrier at ``v`` (inside it: :func:`_factor`
    has filled ``work`` there)."""
    lam, blk, P, M, Lm, Gm, Gp, H2, L2, yt = work
    nd = len(lam)
    rho, R = T.shape
    nt = per + 1
    nx = len(pa)
    # Q = (I + Gp M)^-1 Gp (Hermitian); U^H Z^-1 U = T^H (M - M Q M) T; A1 = I - Q M
    A = np.empty((rho, rho), np.complex128)
    for r in range(rho):
        for s in range(rho):
            acc = 1.0 + 0j if r == s else 0j
            for i in range(rho):
                acc += Gp[r, i] * M[i, s]
            A[r, s] = acc
    piv = np.zeros(rho, np.int64)
    Q = np.empty((rho, rho), np.complex128)
    col = np.empty(rho, np.complex128)
    if lu_factor(A, piv, rho) != 0:
        g[:] = np.nan                   # the caller's solve then stops
        return
    for s in range(rho):
        col[:] = Gp[:, s]
        lu_solve(A, piv, col, rho)
        Q[:, s] = col
    for r in range(rho):
        for s in range(r, rho):
            q = 0.5 * (Q[r, s] + Q[s, r].conjugate())
            Q[r, s] = q
            Q[s, r] = q.conjugate()
    QM = Q @ M
    Th = np.ascontiguousarray(T.conj().T)
    Km = Th @ (M - M @ QM) @ T
    A1 = -QM
    for r in range(rho):
        A1[r, r] += 1.0
    A1h = np.ascontiguousarray(A1.conj().T)
    # rho_k = P_k Q P_k^H per mode, and the 2 x 2 block's rb[i, j] = P_i Q P_j^H
    PQ = P @ Q
    rk = np.empty(nd)
    for kk in range(nd):
        acc = 0j
        for s in range(rho):
            acc += PQ[kk, s] * P[kk, s].conjugate()
        rk[kk] = acc.real
    bi = (k0, nd)
    rb = np.empty((2, 2), np.complex128)
    for i in range(2):
        for j in range(2):
            acc = 0j
            for s in range(rho):
                acc += PQ[bi[i], s] * P[bi[j], s].conjugate()
            rb[i, j] = acc
    # the tied forms and the shift: Y_a = P^H B_a P, Q Y_a and J_a = T^H A1^H Y_a A1 T
    Ba = np.empty((nt, 2, 2), np.complex128)
    QY = np.empty((nt, rho, rho), np.complex128)
    J = np.empty((nt, R, R), np.complex128)
    tr_ci = np.empty(nt)
    Y = np.empty((rho, rho), np.complex128)
    for a in range(nt):
        la = LA[a + 1]
        Ba[a, 0, 0] = la[k0]
        Ba[a, 0, 1] = BE[a + 1]
        Ba[a, 1, 0] = BE[a + 1].conjugate()
        Ba[a, 1, 1] = GA[a + 1]
        t = 0.0
        for kk in range(nd):
            if kk != k0:
                t += la[kk] / lam[kk]
        for i in range(2):
            for j in range(2):
                t += (blk[i, j] * Ba[a, j, i]).real
        tr_ci[a] = t
        for r in range(rho):
            for s in range(r, rho):
                acc = 0j
                for kk in range(nd):
                    if kk != k0:
                        acc += la[kk] * P[kk, r].conjugate() * P[kk, s]
                for i in range(2):
                    for j in range(2):
                        acc += P[bi[i], r].conjugate() * Ba[a, i, j] * P[bi[j], s]
                Y[r, s] = acc
                Y[s, r] = acc.conjugate()
        QY[a] = Q @ Y
        J[a] = Th @ (A1h @ Y @ A1) @ T
    # gradient of -log det Z: tr(Z^-1 B_a) = tr(Zc^-1 B_a) - tr(Q Y_a); tr(G_d K)
    g[:] = 0.0
    Hm[:, :] = 0.0
    for a in range(nt):
        t = 0j
        for r in range(rho):
            t += QY[a, r, r]
        g[a] = -(tr_ci[a] - t.real)
    g[per] += tnorm / mu
    for d in range(nx):
        g[nt + d] = -_trace_pair(Sd[d], pa[d], pb[d], Km).real
    # its Hessian tr(Z^-1 B_a Z^-1 B_b), Z^-1 = Zc^-1 - P Q P^H
    for a in range(nt):
        for b in range(a, nt):
            la, lb = LA[a + 1], LA[b + 1]
            t1 = 0.0
            t2 = 0.0
            for kk in range(nd):
                if kk != k0:
                    d_ = la[kk] * lb[kk] / lam[kk]
                    t1 += d_ / lam[kk]
                    t2 += d_ * rk[kk]
            CB = blk @ Ba[b]
            CA = blk @ Ba[a]
            t1c = 0j
            for i in range(2):
                for j in range(2):
                    t1c += CA[i, j] * CB[j, i]
            D = Ba[a] @ CB
            t2c = 0j
            for i in range(2):
                for j in range(2):
                    t2c += D[i, j] * rb[j, i]
            t4 = 0j
            for r in range(rho):
                for s in range(rho):
                    t4 += QY[a, r, s] * QY[b, s, r]
            h = t1 + t1c.real - 2.0 * (t2 + t2c.real) + t4.real
            Hm[a, b] = h
            Hm[b, a] = h
        for d in range(nx):
            h = _trace_pair(Sd[d], pa[d], pb[d], J[a]).real
            Hm[a, nt + d] = h
            Hm[nt + d, a] = h
    KGK = np.empty((R, R), np.complex128)
    for e in range(nx):
        # K G_e K: G_e holds two positions
        p = (pa[e], pb[e])
        for r in range(R):
            for s in range(R):
                acc = 0j
                for i in range(2):
                    for j in range(2):
                        acc += Km[r, p[i]] * Sd[e, i, j] * Km[p[j], s]
                KGK[r, s] = acc
        for d in range(e, nx):
            h = _trace_pair(Sd[d], pa[d], pb[d], KGK).real
            Hm[nt + d, nt + e] = h
            Hm[nt + e, nt + d] = h
    # the multipliers' own barrier: -log y_f, -log(y_f + delta_d)
    for a in range(per):
        g[a] -= 1.0 / v[a]
        Hm[a, a] += 1.0 / v[a] ** 2
    for d in range(nx):
        f = d % per
        s = v[f] + v[nt + d]
        g[f] -= 1.0 / s
        g[nt + d] -= 1.0 / s
        h = 1.0 / s ** 2
        Hm[f, f] += h
        Hm[f, nt + d] += h
        Hm[nt + d, f] += h
        Hm[nt + d, nt + d] += h


@jit
def _expand(v, w, nd, per, near, shift, x):
    """The full forms' multipliers: damper ``j``'s form ``f`` gets ``y_f / w``, a near
    damper's ``(y_f + delta_f) / w``, the shift ``t``."""
    x[:] = 0.0
    for j in range(nd):
        for f in range(per):
            x[j * per + f] = v[f] / w[j * per + f]
    for n in range(len(near)):
        j = near[n]
        for f in range(per):
            x[j * per + f] = (v[f] + v[per + 1 + n * per + f]) / w[j * per + f]
    x[shift] = v[per]


@jit
def _setup(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos, simplex, grow, ws,
           r):
    """The forms of ``beam``'s upper bound (:func:`.relaxation.forms`) and what the
    barrier needs of them: ``(shift, ys, per, w, LA, GA, BE, k0, near, W, T, pa, pb, Sd,
    gconst)``; ``k0 = -1`` where the arrays are not a tuned ring's or not finite (the
    arrays after it then empty)."""
    shift, ys = forms(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos,
                      simplex, grow)
    nd, nb, m, nn = len(q0), len(ylin), len(x), V.shape[0]
    per = per_damper(np.isfinite(F_lim))
    w = np.empty(m)
    weights(S, nd, per, w)
    LA, GA, BE, k0 = tied_spectra(w, nd, per, nb, shift, 0.0, V, idx, S, x, simplex, ws)
    near = np.empty(2 * r, np.int64)
    nx = 2 * r * per
    pa = np.empty(nx, np.int64)
    pb = np.empty(nx, np.int64)
    Sd = np.empty((nx, 2, 2), np.complex128)
    gconst = S[m, 0, 0].real
    if k0 < 0 or not np.isfinite(V).all():
        empty = np.empty((nn, 0), np.complex128)
        return (shift, ys, per, w, LA, GA, BE, np.int64(-1), near, empty, empty, pa, pb, Sd,
                gconst)
    # the functionals outside the tied part: each near damper's q and p, the constant,
    # the beam's response
    near_dampers(beam, nd, r, near)
    R = 4 * r + 2
    cols = np.empty(R, np.int64)
    for n in range(2 * r):
        cols[2 * n] = near[n]
        cols[2 * n + 1] = nd + near[n]
    cols[R - 2] = 2 * nd
    cols[R - 1] = 2 * nd + 1 + beam
    Uh = np.empty((nn, R), np.complex128)
    _fourier(V, cols, Uh)
    W, T = _basis(Uh)
    if W.shape[1] == 0:
        k0 = np.int64(-1)
    for n in range(2 * r):
        for f in range(per):
            d = n * per + f
            i = near[n] * per + f
            for e in range(2):
                for c in range(R):
                    if cols[c] == idx[i, e]:
                        if e == 0:
                            pa[d] = c
                        else:
                            pb[d] = c
            for a in range(2):
                for b in range(2):
                    Sd[d, a, b] = S[i, a, b] / w[i]
    return shift, ys, per, w, LA, GA, BE, k0, near, W, T, pa, pb, Sd, gconst


@jit
def _work(nd, rho, R, nt):
    """Scratch of :func:`_factor` for ``rho`` basis columns of ``R`` functionals."""
    nn = nd + 1
    return (np.empty(nd), np.empty((2, 2), np.complex128),
            np.empty((nn, rho), np.complex128), np.empty((rho, rho), np.complex128),
            np.zeros((rho, rho), np.complex128), np.empty((R, R), np.complex128),
            np.empty((rho, rho), np.complex128), np.empty((rho, rho), np.complex128),
            np.zeros((rho, rho), np.complex128), np.empty(nt))


@jit
def _kept(v, w, nd, per, near, shift, V, idx, S, pos, simplex, ws, x, xb, best):
    """``(verified, best)``: whether the multipliers ``v``, expanded into ``x``, verify
    on the full forms, and the least verified shift so far (``xb`` its multipliers)."""
    _expand(v, w, nd, per, near, shift, x)
    val = shifted(x, shift, V, idx, S, pos, simplex, ws)
    if np.isnan(val):
        return False, best
    if val < best:
        xb[:] = x
        return True, val
    return True, best


@jit
def partly_tied_upper(G, q0, ylin, H, lo, hi, F_lim, beam, goal, V, idx, S, x, cvec, pos,
                      simplex, grow, ws, stats, r):
    """The verified relaxation of ``|y_beam|^2`` from above over the dampers in
    ``[lo_j, hi_j]`` (N/m) and the force limit, for the arrays of a tuned ring under a
    travelling wave (every beam in order, ``nb == nd``), the multipliers tied but at the
    ``2 r`` dampers next to the beam: the shift's verified value (as
    :func:`.relaxation.solve`: times the scale :func:`.relaxation.forms` returns, a
    bound of ``|y_beam|^2``, m^2; at worst its start's), ``nan`` where the start does not
    verify or the arrays are not a tuned ring's. Stops once it proves ``goal`` (m).
    ``x`` receives the verified full multipliers; ``stats`` as for
    :func:`.relaxation.solve` (Newton steps, rounds, and the relaxation where it
    verified)."""
    nd, nb, nn = len(q0), len(ylin), V.shape[0]
    if nb != nd or not 0 < 2 * r < nd:
        return np.nan
    (shift, ys, per, w, LA, GA, BE, k0, near, W, T, pa, pb, Sd,
     gconst) = _setup(G, q0, ylin, H, lo, hi, F_lim, beam, V, idx, S, x, cvec, pos, simplex,
                      grow, ws, r)
    if k0 < 0:
        return np.nan
    nx = len(pa)
    nt = per + 1
    k = nt + nx
    work = _work(nd, W.shape[1], T.shape[1], nt)
    # start: damper 0's tied multipliers, nothing near; the force limit's grown until the
    # damper block is definite, the shift past the least that makes Z definite
    v = np.zeros(k)
    for f in range(per):
        v[f] = (1.0 if f >= 4 else 1e-2) * w[f]
    t0 = np.nan
    for attempt in range(200):
        _expand(v, w, nd, per, near, shift, x)
        t0 = shifted(x, shift, V, idx, S, pos, simplex, ws)
        if not np.isnan(t0):
            break
        if per == 6:
            v[5] *= 2.0
        else:
            v[:per] *= 2.0
    if np.isnan(t0):
        return np.nan
    # the start is verified: a bound already, which the rounds only improve on
    best = t0
    xb = x.copy()
    sgn = S[shift, 0, 0].real
    v[per] = (t0 + 1.0 + abs(t0)) / sgn
    tnorm = cvec[shift]
    target = goal * goal / ys
    nu = float(nn + per + nx)
    mu = abs(v[per]) / nu
    g = np.empty(k)
    Hm = np.empty((k, k))
    Lh = np.zeros((k, k))
    dv = np.empty(k)
    vn = np.empty(k)
    Vs = np.empty((MAX_ROUNDS, k))
    nr = 0
    steps = 0
    found = False
    while steps < MAX_STEPS:
        for inner in range(STEPS_PER_ROUND):
            f0 = _value(v, mu, per, tnorm, LA, GA, BE, k0, W, T, gconst, pa, pb, Sd, work)
            if not f0 < np.inf:
                steps = MAX_STEPS
                break
            _derivatives(v, mu, per, tnorm, LA, GA, BE, k0, T, pa, pb, Sd, work, g, Hm)
            steps += 1
            stats[0] += 1
            for a in range(k):
                vn[a] = -g[a]
            if not ridge_solve(Hm, Lh, vn, dv, k, 1e-12, 100.0, np.int64(8)):
                steps = MAX_STEPS
                break
            lam2 = -(g * dv).sum()
            if not lam2 > 0.0:
                steps = MAX_STEPS
                break
            step = 1.0
            moved = False
            for back in range(40):
                for a in range(k):
                    vn[a] = v[a] + step * dv[a]
                if (_value(vn, mu, per, tnorm, LA, GA, BE, k0, W, T, gconst, pa, pb, Sd, work)
                        <= f0 - 0.25 * step * lam2):
                    moved = True
                    break
                step *= 0.5
            if moved:
                v[:] = vn
            if not moved or lam2 < CENTRED ** 2 or steps >= MAX_STEPS:
                break
        stats[1] += 1
        # verified on the full forms (O(nd^3) each): once the iterate's own shift
        # reaches the goal (the least one is below it), and at the end (walking back to
        # the rounds before if the last does not verify)
        Vs[nr] = v
        nr += 1
        done = mu * nu <= TOL * abs(v[per]) or steps >= MAX_STEPS or nr == len(Vs)
        if sgn * v[per] <= target or done:
            ok, best = _kept(v, w, nd, per, near, shift, V, idx, S, pos, simplex, ws, x,
                             xb, best)
            found = found or ok
            if best <= target or done:
                break
        mu *= MU_FACTOR
    back = nr - 2
    while not found and back >= 0:
        found, best = _kept(Vs[back], w, nd, per, near, shift, V, idx, S, pos, simplex, ws,
                            x, xb, best)
        back -= 1
    stats[2] += 1
    x[:] = xb
    return best
