"""Spectral projected gradient on a smoothed maximum of ``log |y_b|`` over the box.

Coordinate searches move one damper at a time and stall where several beams are equal
(a ridge of the minimum); a joint gradient step does not. The gradient of the smoothed
maximum comes from one adjoint solve (:func:`smooth_max`).
"""

import math

import numpy as np

from ._jit import jit
from .coordinate_search import contact_q
from .linalg import banded, cyclic_solve_transposed, lu_solve_transposed, tri_solve_transposed

_TINY = 1e-300


#: Memory of the nonmonotone line search of :func:`projected_gradient`
#: (Grippo-Lampariello-Lucidi): a step is accepted against the worst of the last ``_GLL``
#: values, so the spectral (Barzilai-Borwein) step is rarely cut back.
_GLL = 8


@jit
def smooth_max(G, q0, ylin, H, K, mu, b0, b1, grad, w):
    """``mu log sum_b exp(log|y_b| / mu)`` (a smooth max of log|y_b|) and its gradient
    with respect to (Re K_j, Im K_j), stored as ``grad[j] = d/dRe + i d/dIm``.
    Returns (value, log M); value = inf if the system is singular."""
    T, piv, q, y, u, r, lb = w[1], w[2], w[3], w[4], w[5], w[9], w[10]
    hr, gr = w[12], w[13]
    nd = K.shape[0]
    # a chain or a ring: O(nd) elimination; else (or at a tiny pivot) LU with pivoting.
    # Only the search path depends on this: values are taken from the coordinate search's
    mode = contact_q(G, K, q0, T, piv, q, nd, w[14][0])
    if mode < 0:
        return math.inf, math.inf
    lmax = -math.inf
    for b in range(b0, b1):
        acc = ylin[b]
        for m in range(hr[b, 0], hr[b, 1]):
            acc -= H[b, m] * K[m] * q[m]
        y[b] = acc
        lb[b] = 0.5 * math.log(max(acc.real * acc.real + acc.imag * acc.imag, _TINY))
        lmax = max(lmax, lb[b])
    if not math.isfinite(lmax):
        return math.inf, math.inf
    tot = 0.0
    for b in range(b0, b1):
        lb[b] = math.exp((lb[b] - lmax) / mu)      # from here on: unnormalised weights
        tot += lb[b]
    val = lmax + mu * math.log(tot)
    # v_b = w_b / y_b with softmax weights w_b; r = v^T H; g_j = -q_j (r_j - (s^T G)_j)
    # where T^T s = r o K (adjoint solve; G symmetric, T^T = I + diag(K) G)
    for m in range(nd):
        r[m] = 0.0j
    for b in range(b0, b1):
        yb = y[b]
        a2 = max(yb.real * yb.real + yb.imag * yb.imag, _TINY)   # an exact zero (undriven beam)
        wb = lb[b] / tot
        vb = wb * yb.conjugate() / a2
        for m in range(hr[b, 0], hr[b, 1]):
            r[m] += vb * H[b, m]
    # solve (I + diag(K) G) s = r o K by the transpose of the LU of I + G diag(K)
    for m in range(nd):
        u[m] = r[m] * K[m]
    if mode == 1:
        tri_solve_transposed(T, u, nd)
    elif mode == 2:
        cyclic_solve_transposed(G, K, T, u, nd)
    else:
        lu_solve_transposed(T, piv, u, nd)
    for j in range(nd):
        sg = 0.0j
        for m in range(gr[j, 0], gr[j, 1]):
            sg += u[m] * G[m, j]
        gj = -q[j] * (r[j] - sg)      # d(sum w_b log|y_b|)/dK_j as a complex derivative
        grad[j] = complex(gj.real, -gj.imag)
    return val, lmax


@jit
def projected_gradient(G, q0, ylin, H, kr, ki, K, sign, b0, b1, w, max_iter):
    """Spectral projected gradient on ``sign`` times a smoothed max of ``log|y_b|``
    (sign = 1: the minimum of M; sign = -1: the maximum).

    Coordinate searches move one damper at a time: they stall where beams are equal (a
    ridge of the minimum); a joint gradient step does not. (The bounds use it for the
    minimum only; for the maximum the pattern move of :func:`coordinate_search` does as well, see
    ``SPG_ITER``.) The
    smoothing ``mu`` is reduced in two stages of at most ``max_iter`` iterations; the line
    search is nonmonotone (``_GLL``), so the best point evaluated (by M itself) is the
    one returned. Returns M at ``K``. (The smoothed max exceeds the max by up to
    ``mu log(n_beams)``: where many beams are equal at the minimum it stops short of it;
    :func:`.minimax.minimax_barrier` finishes the minimum.)
    """
    nd = K.shape[0]
    w[14][0] = banded(G, w[13], nd)
    g = np.zeros(nd, dtype=np.complex128)
    x = np.zeros(nd, dtype=np.complex128)      # K scaled to the unit box
    xt = np.zeros(nd, dtype=np.complex128)
    Kt = np.zeros(nd, dtype=np.complex128)
    d = np.zeros(nd, dtype=np.complex128)
    gt = np.zeros(nd, dtype=np.complex128)
    x_best = np.zeros(nd, dtype=np.complex128)
    hist = np.empty(_GLL)
    for j in range(nd):
        x[j] = complex(K[j].real / kr, K[j].imag / ki)
        x_best[j] = x[j]
    l_best = math.nan                           # sign * log M at x_best
    for mu in (0.01, 0.002):
        for j in range(nd):
            K[j] = complex(kr * x[j].real, ki * x[j].imag)
        f, lm = smooth_max(G, q0, ylin, H, K, mu, b0, b1, g, w)
        if not math.isfinite(f):
            break
        f *= sign
        if math.isnan(l_best) or sign * lm < l_best:
            l_best = sign * lm
            for j in range(nd):
                x_best[j] = x[j]
        for m in range(_GLL):
            hist[m] = f
        for j in range(nd):
            g[j] = complex(sign * g[j].real * kr, sign * g[j].imag * ki)
        alpha = 0.1
        for it in range(max_iter):
            gd = 0.0
            for j in range(nd):
                v = x[j] - alpha * g[j]
                v = complex(min(max(v.real, 0.0), 1.0), min(max(v.imag, 0.0), 1.0))
                d[j] = v - x[j]
                gd += g[j].real * d[j].real + g[j].imag * d[j].imag
            if gd >= -1e-14:
                break
            f_ref = hist[0]
            for m in range(1, _GLL):
                f_ref = max(f_ref, hist[m])
            lam = 1.0
            ok = False
            for _ in range(20):
                for j in range(nd):
                    xt[j] = x[j] + lam * d[j]
                    Kt[j] = complex(kr * xt[j].real, ki * xt[j].imag)
                ft, lt = smooth_max(G, q0, ylin, H, Kt, mu, b0, b1, gt, w)
                ft *= sign
                if ft <= f_ref + 1e-4 * lam * gd:
                    ok = True
                    break
                lam *= 0.5
            if not ok:
                break
            if sign * lt < l_best:
                l_best = sign * lt
                for j in range(nd):
                    x_best[j] = xt[j]
            ss = 0.0
            sy = 0.0
            for j in range(nd):
                gt[j] = complex(sign * gt[j].real * kr, sign * gt[j].imag * ki)
                sj = xt[j] - x[j]
                yj = gt[j] - g[j]
                ss += sj.real * sj.real + sj.imag * sj.imag
                sy += sj.real * yj.real + sj.imag * yj.imag
                x[j] = xt[j]
                g[j] = gt[j]
            f = ft
            hist[(it + 1) % _GLL] = f
            alpha = min(max(ss / sy, 1e-6), 10.0) if sy > 0.0 else 1.0
        # the next stage starts from the best point so far
        for j in range(nd):
            x[j] = x_best[j]
    for j in range(nd):
        K[j] = complex(kr * x_best[j].real, ki * x_best[j].imag)
    _, lm = smooth_max(G, q0, ylin, H, K, 1.0, b0, b1, g, w)
    return math.exp(lm)
