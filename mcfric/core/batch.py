"""Newton for a batch of samples in lockstep on a chain of dampers (the fast path).

``LANES`` samples handled by one thread advance through the same frequency together.
Every array has the lane index last, and every loop over dampers has an inner loop over
lanes. The point is instruction-level parallelism: the O(nd) eliminations of a chain
(tridiagonal ``I + G K``; block-tridiagonal Newton step with real 2x2 blocks in
``w = dq``) are chains of dependent divisions, and interleaving independent samples keeps
the pipeline full (~3.5x on the eliminations with 4 lanes, measured).

Each lane runs exactly the single-sample algorithm of :mod:`mcfric.core.newton` in its own
arithmetic (damped Newton in ``x = log s`` with an Armijo line search, stuck dampers
solved exactly in each evaluation); lanes never exchange values, so a sample's result
does not depend on which samples share its batch, its thread, or its chunk.
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .friction import kappa_logs
from .linalg import LANES, block2_tridiag_solve_lanes, tridiag_solve_lanes
from .newton import _ARMIJO, _MAX_HALVINGS, _MAX_STEP, _TARGET

_SLIP_SIDE = complex(0.0, -4.0 / math.pi)   # d(K/kc)/dlog s at s = 1 from the slip side


@jit
def _eval(x, K, Kp, q, f, phi, mask, bad, kc, c, active, Gd, Gu, q0, lo, di, up, nd):
    """Residual of the lanes in ``mask``: fills K, dK/dlog s, q, f and ``phi = |f|^2``.

    Stuck dampers are solved exactly (``x`` is updated); ``phi`` is inf for a lane whose
    linear solve failed or whose residual is not finite.
    """
    for j in range(nd):
        for l in range(LANES):
            if mask[l]:
                if active[j, l]:
                    k, d = kappa_logs(x[j, l])
                    K[j, l] = kc[j, l] * k
                    Kp[j, l] = kc[j, l] * d
                else:
                    K[j, l] = 0.0j
                    Kp[j, l] = 0.0j
    for j in range(nd):
        for l in range(LANES):
            if mask[l]:
                di[j, l] = 1.0 + Gd[j, l] * K[j, l]
                q[j, l] = q0[j, l]
                if j > 0:
                    lo[j, l] = Gu[j - 1, l] * K[j - 1, l]
                if j < nd - 1:
                    up[j, l] = Gu[j, l] * K[j + 1, l]
    tridiag_solve_lanes(lo, di, up, q, mask, bad, nd)
    for l in range(LANES):
        phi[l] = 0.0
    for j in range(nd):
        for l in range(LANES):
            if not mask[l]:
                continue
            if not active[j, l]:
                f[j, l] = 0.0
                continue
            qq = q[j, l]
            lq = 0.5 * math.log(qq.real * qq.real + qq.imag * qq.imag)
            if x[j, l] >= 0.0:
                t = c[j, l] - lq        # log s that makes damper j consistent with this q
                if t > 0.0:
                    x[j, l] = t
                    f[j, l] = 0.0
                    Kp[j, l] = 0.0j
                else:                   # no longer stuck: park at s = 1, K unchanged
                    x[j, l] = 0.0
                    f[j, l] = -t
                    Kp[j, l] = kc[j, l] * _SLIP_SIDE
            else:
                f[j, l] = x[j, l] + lq - c[j, l]
            phi[l] += f[j, l] * f[j, l]
    for l in range(LANES):
        if mask[l] and (bad[l] or not math.isfinite(phi[l])):
            phi[l] = math.inf


@inline_jit
def _put_block(B, i, l, t, m, e):
    """Real 2x2 block of ``w -> t w - m Re(e w)`` (complex t, m, e) at ``B[i, :, l]``."""
    B[i, 0, l] = t.real - m.real * e.real
    B[i, 1, l] = -t.imag + m.real * e.imag
    B[i, 2, l] = t.imag - m.imag * e.real
    B[i, 3, l] = t.real + m.imag * e.imag


@jit
def _step(K, Kp, q, f, dx, mask, bad, active, Gd, Gu, h, e, Lb, Db, Ub, rb, nd):
    """Newton step ``dx`` of the lanes in ``mask`` (``bad[l]`` if it could not be formed).

    Linearising ``(I + G K) q = q0`` and ``f = x + log|q| - c`` gives, with
    ``h_j = dK_j/dx_j q_j``, ``e_j = conj(q_j)/|q_j|^2`` and ``w = dq``:
    ``(I + G K) w - G diag(h) Re(e w) = G diag(h) f`` and ``dx = -f - Re(e w)``.
    """
    for j in range(nd):
        for l in range(LANES):
            if mask[l]:
                qq = q[j, l]
                q2 = qq.real * qq.real + qq.imag * qq.imag
                if active[j, l] and q2 > 0.0:
                    h[j, l] = Kp[j, l] * qq
                    r2 = 1.0 / q2
                    e[j, l] = complex(qq.real * r2, -qq.imag * r2)
                else:
                    h[j, l] = 0.0j
                    e[j, l] = 0.0j
    for i in range(nd):
        for l in range(LANES):
            if not mask[l]:
                continue
            _put_block(Db, i, l, 1.0 + Gd[i, l] * K[i, l], Gd[i, l] * h[i, l], e[i, l])
            rhs = Gd[i, l] * h[i, l] * f[i, l]
            if i > 0:
                g = Gu[i - 1, l]
                _put_block(Lb, i, l, g * K[i - 1, l], g * h[i - 1, l], e[i - 1, l])
                rhs += g * h[i - 1, l] * f[i - 1, l]
            if i < nd - 1:
                g = Gu[i, l]
                _put_block(Ub, i, l, g * K[i + 1, l], g * h[i + 1, l], e[i + 1, l])
                rhs += g * h[i + 1, l] * f[i + 1, l]
            rb[i, 0, l] = rhs.real
            rb[i, 1, l] = rhs.imag
    block2_tridiag_solve_lanes(Lb, Db, Ub, rb, mask, bad, nd)
    for l in range(LANES):
        if not mask[l]:
            continue
        big = 0.0
        for j in range(nd):
            ee = e[j, l]
            dx[j, l] = -f[j, l] - (ee.real * rb[j, 0, l] - ee.imag * rb[j, 1, l])
            big = max(big, abs(dx[j, l]))
        if not math.isfinite(big):
            bad[l] = True
        elif big > _MAX_STEP:
            sc = _MAX_STEP / big
            for j in range(nd):
                dx[j, l] *= sc


@inline_jit
def _max_abs(f, l, nd):
    m = 0.0
    for j in range(nd):
        m = max(m, abs(f[j, l]))
    return m


@jit
def newton_lanes(x, need, ok, its, kc, c, active, Gd, Gu, q0, tol, max_iter, w, nd):
    """Damped Newton in ``x = log s`` for the lanes in ``need``, from the guesses in ``x``.

    Every lane runs its own iteration (evaluate, accept or halve the step, new step),
    asynchronously; one loop drives all lanes so that the evaluation and the step each
    appear once in the compiled code.

    Parameters
    ----------
    x : ndarray, shape (nd, LANES)
        In: initial guesses; out: the last accepted iterates.
    need : ndarray of bool, shape (LANES,)
        Lanes that hold a sample.
    ok : ndarray of bool, shape (LANES,)
        Out: converged (``max |f| <= tol / 100``, or a stall within ``tol``).
    its : ndarray of int64, shape (LANES,)
        Out: Newton steps taken.
    kc, c, active : ndarray, shape (nd, LANES)
        Per damper: stiffness (N/m), ``log(mu0 N0 / kc)``, force-transmitting mask.
    Gd, Gu, q0 : ndarray of complex, shape (nd, LANES)
        Diagonal and super-diagonal of ``G = B D11 B^T`` (m/N) and ``q0`` (m).
    tol, max_iter : float, int
        As :func:`mcfric.core.newton.newton`.
    w : tuple
        Workspace from :func:`workspace`; on return ``w[0]`` (K), ``w[2]`` (q) and
        ``w[3]`` (f) hold the state at ``x``.
    """
    (K, Kp, q, f, xt, Kt, Kpt, qt, ft, dx, h, e, lo, di, up, Lb, Db, Ub, rb,
     phi, phit, lam, run, pend, bad) = w
    target = _TARGET * tol
    n_pend = 0
    for l in range(LANES):
        its[l] = 0
        ok[l] = False
        run[l] = False              # lanes that need a new Newton step
        pend[l] = need[l]           # lanes with a trial point to evaluate
        lam[l] = 0.0                # lam = 0 marks the initial point: always accepted
        n_pend += pend[l]
        for j in range(nd):
            xt[j, l] = x[j, l]
    while n_pend > 0:
        _eval(xt, Kt, Kpt, qt, ft, phit, pend, bad, kc, c, active, Gd, Gu, q0,
              lo, di, up, nd)
        n_run = 0
        for l in range(LANES):
            if not pend[l]:
                continue
            first = lam[l] == 0.0
            if first or phit[l] <= (1.0 - 2.0 * _ARMIJO * lam[l]) * phi[l]:
                pend[l] = False
                if first and not math.isfinite(phit[l]):
                    continue        # no finite start: ok stays False
                for j in range(nd):
                    x[j, l] = xt[j, l]
                    K[j, l] = Kt[j, l]
                    Kp[j, l] = Kpt[j, l]
                    q[j, l] = qt[j, l]
                    f[j, l] = ft[j, l]
                phi[l] = phit[l]
                if _max_abs(f, l, nd) <= target:
                    ok[l] = True
                elif its[l] >= max_iter:
                    ok[l] = _max_abs(f, l, nd) <= tol
                else:
                    run[l] = True
                    n_run += 1
            elif lam[l] > 0.5 ** (_MAX_HALVINGS - 1):
                lam[l] *= 0.5
                for j in range(nd):
                    xt[j, l] = x[j, l] + lam[l] * dx[j, l]
            else:                   # no acceptable step: a stall at the rounding floor?
                pend[l] = False
                ok[l] = _max_abs(f, l, nd) <= tol
        if n_run > 0:
            _step(K, Kp, q, f, dx, run, bad, active, Gd, Gu, h, e, Lb, Db, Ub, rb, nd)
            for l in range(LANES):
                if not run[l]:
                    continue
                run[l] = False
                if bad[l]:
                    ok[l] = _max_abs(f, l, nd) <= tol
                    continue
                its[l] += 1
                lam[l] = 1.0
                pend[l] = True
                for j in range(nd):
                    xt[j, l] = x[j, l] + dx[j, l]
        n_pend = 0
        for l in range(LANES):
            n_pend += pend[l]


@jit
def workspace(nd):
    """Scratch arrays for :func:`newton_lanes` (one set per batch)."""
    c16 = np.complex128
    n = LANES
    return (np.zeros((nd, n), c16), np.zeros((nd, n), c16), np.zeros((nd, n), c16),
            np.zeros((nd, n)),
            np.zeros((nd, n)), np.zeros((nd, n), c16), np.zeros((nd, n), c16),
            np.zeros((nd, n), c16), np.zeros((nd, n)),
            np.zeros((nd, n)), np.zeros((nd, n), c16), np.zeros((nd, n), c16),
            np.zeros((nd, n), c16), np.zeros((nd, n), c16), np.zeros((nd, n), c16),
            np.zeros((nd, 4, n)), np.zeros((nd, 4, n)), np.zeros((nd, 4, n)),
            np.zeros((nd, 2, n)),
            np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n, np.bool_),
            np.zeros(n, np.bool_), np.zeros(n, np.bool_))
