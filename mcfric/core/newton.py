"""One fixed-point solve of the single-harmonic balance.

The equations are those of the docs' theory page, section "Single-harmonic balance".

Unknowns are ``x_j = log s_j`` for the active dampers (``mu0 N0 > 0`` and ``kc > 0``);
the residual is ``f_j = log(s_j kc_j |q_j| / (mu0_j N0_j))`` with the relative contact
displacement ``q`` solving ``(I + G diag(K)) q = q0``. Working in ``log s`` keeps
``s > 0`` and has the same roots as ``r_j = s_j kc_j A_j - mu0_j N0_j``
(``|r_j| / (mu0_j N0_j) = |expm1(f_j)|``).

Stuck dampers (``s >= 1``) do not change ``K``; their equation is solved exactly in every
residual evaluation (``x_j = log(mu0 N0 / (kc |q_j|))``), which keeps a stuck damper with
tiny ``|q_j|`` from stalling the line search.

This module holds the per-point solvers: a dense Newton (any damper graph, LU with
partial pivoting, O(nd^3)), Levenberg-Marquardt, and a scalar Newton with a bracketing
fallback for one damper. The fast path for chains, several samples in lockstep with O(nd)
linear algebra, is :mod:`mcfric.core.chain_newton`; it falls back to the solvers here.

Fallback chain per point: Newton from the warm start -> Newton (dense) restarted from the
stick limit ``s = 1`` -> Levenberg-Marquardt (dense) from ``s = 1``.
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .friction import LAW_COULOMB, kappa_law_logs, kappa_slip
from .linalg import cinv, contact_solve, lm_step, lu_factor, lu_solve

#: Status codes of one solve.
CONVERGED = 0           # Newton from the initial guess
CONVERGED_RESTART = 1   # Newton restarted from the stick limit s = 1
CONVERGED_LM = 2        # Levenberg-Marquardt
NOT_CONVERGED = -1      # every attempt failed: outputs are NaN

_ARMIJO = 1e-4
_MAX_HALVINGS = 30
_MAX_STEP = 5.0          # largest change of log s in one Newton step
_LM_MAX_ITER = 200
# Iterate towards tol * _TARGET; a solve that stalls (rounding floor near a lightly
# damped resonance) is still converged if it is within tol.
_TARGET = 1e-1


#: Below this ``|q|^2`` (``|q| < 1e-140`` m: a response that died out along a long array)
#: the square loses its digits (subnormal from 2e-308, 0 below 5e-324): ``log|q|`` and
#: ``1/q`` are then taken from ``q`` scaled by its larger component instead.
_TINY_Q2 = 1e-280
#: Below this larger component ``q`` counts as 0 (its reciprocal would overflow).
_TINY_Q = 1e-300


@inline_jit
def log_abs(q, q2):
    """``log|q|`` given ``q2 = |q|^2``; finite for every ``q != 0`` (``-inf`` for 0)."""
    if not q2 < _TINY_Q2:            # NaN and inf too: they stay NaN and inf
        return 0.5 * math.log(q2)
    a = max(abs(q.real), abs(q.imag))
    if a == 0.0:
        return -math.inf
    u = q.real / a
    v = q.imag / a
    return math.log(a) + 0.5 * math.log(u * u + v * v)


@inline_jit
def abs_q(q, q2):
    """``|q|`` given ``q2 = |q|^2``: ``sqrt(q2)``, or where that lost its digits the
    scaled ``hypot`` (the slip ratio of a stuck damper far down a long array)."""
    if not q2 < _TINY_Q2:
        return math.sqrt(q2)
    return math.hypot(q.real, q.imag)


@inline_jit
def reciprocal(q, q2):
    """``1 / q = conj(q) / |q|^2`` given ``q2 = |q|^2``, without the overflow of
    ``1 / q2`` where ``q2`` is subnormal; 0 where ``q`` counts as 0."""
    if not q2 < _TINY_Q2:            # NaN and inf too: they stay NaN and 0
        r2 = 1.0 / q2
        return complex(q.real * r2, -q.imag * r2)
    a = max(abs(q.real), abs(q.imag))
    if a < _TINY_Q:
        return 0.0j
    u = q.real / a
    v = q.imag / a
    r = 1.0 / (a * (u * u + v * v))
    return complex(u * r, -v * r)


@inline_jit
def _log_residual(x, c, active, q, f, nd, law):
    """Residual ``f`` from ``q``; solves stuck Coulomb dampers exactly (updates ``x``).

    Returns ``sum f^2``, or ``inf`` when it is not finite.
    """
    phi = 0.0
    for j in range(nd):
        if not active[j]:
            f[j] = 0.0
            continue
        q2 = q[j].real * q[j].real + q[j].imag * q[j].imag
        lq = log_abs(q[j], q2)
        if x[j] >= 0.0 and law == LAW_COULOMB:
            t = c[j] - lq           # log s that makes damper j consistent with this q
            if t >= 0.0:
                x[j] = t
                f[j] = 0.0
            else:                   # no longer stuck: park at s = 1, K unchanged
                x[j] = 0.0
                f[j] = -t
        else:
            f[j] = x[j] + lq - c[j]
        phi += f[j] * f[j]
    if not math.isfinite(phi):
        return math.inf
    return phi


@inline_jit
def _damper_K(x, kc, active, K, nd, law):
    for j in range(nd):
        K[j] = kc[j] * kappa_law_logs(x[j], law)[0] if active[j] else 0.0j


@inline_jit
def _residual_dense(x, kc, c, active, G, q0, K, q, f, T, piv, nd, law):
    """Residual on the dense path; leaves the LU factors of ``I + G K`` in ``T``."""
    _damper_K(x, kc, active, K, nd, law)
    if contact_solve(G, K, q0, T, piv, q, nd) != 0:
        return math.inf
    return _log_residual(x, c, active, q, f, nd, law)


@inline_jit
def _sensitivities(x, kc, active, q, h, e, nd, law):
    """``h_j = dK_j/dx_j q_j`` and ``e_j = conj(q_j)/|q_j|^2`` (0 where undefined)."""
    for j in range(nd):
        q2 = q[j].real * q[j].real + q[j].imag * q[j].imag
        if active[j] and q[j] != 0.0:
            h[j] = kc[j] * kappa_law_logs(x[j], law)[1] * q[j]
            e[j] = reciprocal(q[j], q2)
        else:
            h[j] = 0.0j
            e[j] = 0.0j


@inline_jit
def _jacobian_dense(x, kc, active, G, T, piv, q, h, e, X, J, nd, law):
    """Dense Jacobian ``J = df/dx`` using the LU factors of ``I + G K`` held in ``T``.

    ``X`` (nd,) is scratch for one column of ``(I + G K)^-1 G diag(h)``.
    """
    _sensitivities(x, kc, active, q, h, e, nd, law)
    for j in range(nd):
        # column j of X = (I + G K)^-1 G e_j h_j
        for i in range(nd):
            X[i] = G[i, j] * h[j]
        lu_solve(T, piv, X, nd)
        for i in range(nd):
            J[i, j] = (1.0 if i == j else 0.0) - (e[i] * X[i]).real


@inline_jit
def _step_dense(x, kc, active, G, T, piv, q, f, dx, h, e, X, J, rpiv, nd, law):
    _jacobian_dense(x, kc, active, G, T, piv, q, h, e, X, J, nd, law)
    for j in range(nd):
        dx[j] = -f[j]
    info = lu_factor(J, rpiv, nd)
    if info != 0:
        return info
    lu_solve(J, rpiv, dx, nd)
    return 0


@inline_jit
def _limit_step(dx, nd):
    big = 0.0
    for j in range(nd):
        big = max(big, abs(dx[j]))
    if not math.isfinite(big):
        return False
    if big > _MAX_STEP:
        sc = _MAX_STEP / big
        for j in range(nd):
            dx[j] *= sc
    return True


@inline_jit
def _max_abs(f, nd):
    m = 0.0
    for j in range(nd):
        m = max(m, abs(f[j]))
    return m


@inline_jit
def _copy_state(src_x, src_q, src_K, src_f, x, q, K, f, nd):
    for j in range(nd):
        x[j] = src_x[j]
        q[j] = src_q[j]
        K[j] = src_K[j]
        f[j] = src_f[j]


@jit
def newton(x, kc, c, active, G, q0, tol, max_iter, w, law):
    """Damped Newton iteration in ``x = log s`` from the guess in ``x`` (dense path).

    Parameters
    ----------
    x : ndarray, shape (nd,)
        In: initial guess of ``log s``; out: the last accepted iterate.
    kc : ndarray, shape (nd,)
        Tangential stiffness per damper, N/m.
    c : ndarray, shape (nd,)
        ``log(mu0 N0 / kc)`` per active damper, log(m).
    active : ndarray of bool, shape (nd,)
        Dampers that transmit force (``mu0 N0 > 0`` and ``kc > 0``).
    G : ndarray of complex, shape (nd, nd)
        ``B D11 B^T`` at this frequency, m/N.
    q0 : ndarray of complex, shape (nd,)
        Relative contact displacement of the uncoupled array, m.
    tol : float
        Accepted relative force residual ``max |f_j|``; iterations aim at ``tol / 10``
        and stop early only at a stall within ``tol``.
    max_iter : int
        Newton iterations allowed.
    w : tuple
        Workspace from :func:`workspace`; on return ``w[0]``, ``w[1]``, ``w[2]`` hold
        ``K``, ``q`` and ``f`` at ``x``.
    law : int
        The contact law (:data:`~mcfric.core.friction.LAW_COULOMB`, the paper's, or
        :data:`~mcfric.core.friction.LAW_CUBIC`).

    Returns
    -------
    ok : bool
    iterations : int
    """
    (K, q, f, xt, qt, Kt, ft, dx, h, e, T, piv, X, J, rpiv) = w
    nd = x.shape[0]
    target = _TARGET * tol
    phi = _residual_dense(x, kc, c, active, G, q0, K, q, f, T, piv, nd, law)
    if not math.isfinite(phi):
        return False, 0
    for it in range(max_iter + 1):
        if _max_abs(f, nd) <= target:
            return True, it
        if it == max_iter:
            break
        info = _step_dense(x, kc, active, G, T, piv, q, f, dx, h, e, X, J, rpiv, nd, law)
        if info != 0 or not _limit_step(dx, nd):
            return _max_abs(f, nd) <= tol, it
        lam = 1.0
        accepted = False
        for _ in range(_MAX_HALVINGS):
            for j in range(nd):
                xt[j] = x[j] + lam * dx[j]
            phit = _residual_dense(xt, kc, c, active, G, q0, Kt, qt, ft, T, piv, nd, law)
            if phit <= (1.0 - 2.0 * _ARMIJO * lam) * phi:
                accepted = True
                break
            lam *= 0.5
        if not accepted:            # stalled at the rounding floor, or a genuine failure
            return _max_abs(f, nd) <= tol, it + 1
        _copy_state(xt, qt, Kt, ft, x, q, K, f, nd)
        phi = phit
    return _max_abs(f, nd) <= tol, max_iter


@jit
def levenberg_marquardt(x, kc, c, active, G, q0, tol, w, law):
    """Levenberg-Marquardt on ``0.5 |f|^2`` in ``x = log s`` (dense), the last resort.

    Same arguments and returns as :func:`newton` (always the dense path).
    """
    (K, q, f, xt, qt, Kt, ft, dx, h, e, T, piv, X, J, rpiv) = w
    nd = x.shape[0]
    A = np.empty((nd, nd))
    g = np.empty(nd)
    phi = _residual_dense(x, kc, c, active, G, q0, K, q, f, T, piv, nd, law)
    if not math.isfinite(phi):
        return False, 0
    lam = 1e-3
    target = _TARGET * tol
    for it in range(_LM_MAX_ITER + 1):
        if _max_abs(f, nd) <= target:
            return True, it
        if it == _LM_MAX_ITER:
            break
        # T holds the LU of the accepted point: build J there
        _jacobian_dense(x, kc, active, G, T, piv, q, h, e, X, J, nd, law)
        for i in range(nd):
            acc = 0.0
            for k in range(nd):
                acc += J[k, i] * f[k]
            g[i] = acc
        improved = False
        for _ in range(40):
            if lm_step(J, g, lam, A, rpiv, dx, nd, nd) != 0:
                lam *= 10.0
                continue
            if not _limit_step(dx, nd):
                lam *= 10.0
                continue
            for j in range(nd):
                xt[j] = x[j] + dx[j]
            phit = _residual_dense(xt, kc, c, active, G, q0, Kt, qt, ft, T, piv, nd, law)
            if phit < phi:
                improved = True
                break
            lam *= 4.0
        if not improved:
            return _max_abs(f, nd) <= tol, it + 1
        _copy_state(xt, qt, Kt, ft, x, q, K, f, nd)
        phi = phit
        lam = max(lam / 3.0, 1e-12)
        # T now holds the LU at the accepted point (it was the last evaluation)
    return _max_abs(f, nd) <= tol, _LM_MAX_ITER


@jit
def workspace(nd):
    """Scratch arrays for :func:`newton` and :func:`levenberg_marquardt` (one per thread)."""
    c16 = np.complex128
    return (np.zeros(nd, c16), np.zeros(nd, c16), np.zeros(nd), np.zeros(nd),
            np.zeros(nd, c16), np.zeros(nd, c16), np.zeros(nd), np.zeros(nd),
            np.zeros(nd, c16), np.zeros(nd, c16),
            np.zeros((nd, nd), c16), np.zeros(nd, np.int64), np.zeros(nd, c16),
            np.zeros((nd, nd)), np.zeros(nd, np.int64))


# --- one damper (two beams): a scalar specialisation, faster than the general path ---

_SLIP_SIDE = complex(0.0, -4.0 / math.pi)   # d(K/kc)/dlog s at s = 1 from the slip side


@inline_jit
def _scalar_eval(x, kc, c, g, q0):
    """Residual of the one-damper problem at ``x = log s``, with its derivative.

    Returns ``(f, x, s, q, K, d)``: ``x`` is updated when stuck (solved exactly),
    ``s = exp(x)``, and ``d = df/dx`` at the returned ``x`` (slip-side at ``x = 0``),
    so that the Newton step needs no second evaluation of ``K``.
    """
    if x >= 0.0:
        K = complex(kc, 0.0)
        Kp = 0.0j
        s = 1.0
    else:
        s = math.exp(x)
        if s > 0.0:
            k, dk = kappa_slip(s)
            K = kc * k
            Kp = kc * dk
        else:
            K = 0.0j
            Kp = 0.0j
    inv = cinv(1.0 + g * K)
    q = q0 * inv
    q2 = q.real * q.real + q.imag * q.imag
    lq = 0.5 * math.log(q2)
    if x >= 0.0:
        t = c - lq
        if t >= 0.0:                # stuck and consistent: an exact root
            # s = e^t = (mu0 N0 / kc) / |q|: a sqrt instead of a call to exp
            return 0.0, t, math.exp(c) / math.sqrt(q2), q, K, 1.0
        f = -t                      # no longer stuck: park at s = 1, K unchanged
        x = 0.0
        Kp = kc * _SLIP_SIDE
    else:
        f = x + lq - c
    return f, x, s, q, K, 1.0 - (g * Kp * inv).real


@inline_jit
def newton_scalar(x, kc, c, g, q0, tol, max_iter):
    """Damped Newton for one damper: ``f(x) = x + log|q0 / (1 + g K(e^x))| - log(mu0 N0/kc)``.

    Parameters
    ----------
    x : float
        Initial guess of ``log s``.
    kc : float
        Tangential stiffness, N/m (> 0).
    c : float
        ``log(mu0 N0 / kc)``.
    g : complex
        ``G = d11_a + d11_b``, m/N.
    q0 : complex
        Relative contact displacement of the uncoupled beams, m.
    tol, max_iter : float, int
        As :func:`newton`.

    Returns
    -------
    ok, iterations, x, s, q, K, f
        ``s = exp(x)``; ``q``, ``K`` and ``f`` at ``x``.
    """
    f, x, s, q, K, d = _scalar_eval(x, kc, c, g, q0)
    if not math.isfinite(f):
        return False, 0, x, s, q, K, f
    target = _TARGET * tol
    for it in range(max_iter + 1):
        if abs(f) <= target:
            return True, it, x, s, q, K, f
        if it == max_iter:
            break
        dx = -f / d
        if not math.isfinite(dx):
            return abs(f) <= tol, it, x, s, q, K, f
        dx = max(-_MAX_STEP, min(_MAX_STEP, dx))
        lam = 1.0
        accepted = False
        for _ in range(_MAX_HALVINGS):
            ft, xt, st, qt, Kt, dt = _scalar_eval(x + lam * dx, kc, c, g, q0)
            if ft * ft <= (1.0 - 2.0 * _ARMIJO * lam) * f * f:
                accepted = True
                break
            lam *= 0.5
        if not accepted:
            return abs(f) <= tol, it + 1, x, s, q, K, f
        f, x, s, q, K, d = ft, xt, st, qt, Kt, dt
    return abs(f) <= tol, max_iter, x, s, q, K, f


@jit
def bracket_scalar(kc, c, g, q0, tol):
    """Last resort for one damper: bisection-safeguarded secant on a sign bracket.

    ``f`` is continuous in ``x``; ``f(0) > 0`` when the stuck state is inconsistent
    and ``f -> -inf`` as ``x -> -inf`` (``K -> 0``), so a bracket always exists.

    Returns
    -------
    ok, iterations, x, s, q, K, f
    """
    fh, xh, sh, qh, Kh, _ = _scalar_eval(0.0, kc, c, g, q0)
    if fh <= tol:                       # stuck solution (f == 0 after the exact update)
        return math.isfinite(fh), 0, xh, sh, qh, Kh, fh
    lo = -1.0
    fl, _, sl, ql, Kl, _ = _scalar_eval(lo, kc, c, g, q0)
    it = 0
    while fl > 0.0 and it < 200:       # walk down until the sign changes
        lo *= 2.0
        fl, _, sl, ql, Kl, _ = _scalar_eval(lo, kc, c, g, q0)
        it += 1
    if not (fl <= 0.0):
        return False, it, lo, sl, ql, Kl, fl
    hi = 0.0
    target = _TARGET * tol
    for k in range(300):
        mid = 0.5 * (lo + hi)
        fm, _, sm, qm, Km, _ = _scalar_eval(mid, kc, c, g, q0)
        if abs(fm) <= target:
            return True, it + k + 1, mid, sm, qm, Km, fm
        if not math.isfinite(fm):
            return False, it + k + 1, mid, sm, qm, Km, fm
        if fm > 0.0:
            hi = mid
        else:
            lo = mid
        if hi - lo <= 4e-16 * max(1.0, abs(lo)):
            return abs(fm) <= tol, it + k + 1, mid, sm, qm, Km, fm
    return abs(fm) <= tol, it + 300, mid, sm, qm, Km, fm
