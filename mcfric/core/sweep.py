"""Parallel sweeps: ``prange`` over samples, a warm-started frequency sweep inside each.

Each sample sweeps its frequencies in the given order, starting each point from a cubic
extrapolation in ``log s`` of its previous solutions (a warm start needs far fewer Newton
steps than a cold one); the extrapolation weights depend only on the
frequencies and are computed once per call (:func:`predict_weights`). A sample's results
depend only on its own inputs, never on which thread ran it or which other samples shared
the call: results are bitwise identical for any thread count and any chunking of the
samples.

Three kernels, one per structure:

* :func:`sweep_one_damper`: two beams, ``ONE_LANES`` samples per batch: the stuck
  candidate of all lanes in one SIMD loop (the exact solution at most points), scalar
  Newton with a bracketing fallback for the rest;
* :func:`sweep_chain`: a linear array or a ring, ``LANES`` samples in lockstep with O(nd)
  algebra (:mod:`mcfric.core.chain_newton`);
* :func:`sweep_dense`: any damper graph and any contact law, dense LU per sample.

The last two fall back per point to Newton restarted from ``s = 1`` and then
Levenberg-Marquardt, both dense. Outputs are preallocated by the caller; for a point
that did not converge the response and ``s`` are NaN and its status is negative.

Arguments common to the kernels
-------------------------------
rec : ndarray of complex128, shape (n_r, n_f, 4, n_beams)
    Receptances (d11, d13, d21, d23 per beam), m/N; ``n_r`` is 1 (shared rig) or n_s.
force : ndarray of complex128, shape (n_beams,)
    Drive force amplitudes, N.
a, b : ndarray of int64, shape (nd,)
    Beams coupled by each damper (``sweep_chain`` requires ``a_j = j`` and
    ``b_j = (j + 1) mod n_beams``: a chain, or a ring when ``nd = n_beams``).
omega : ndarray of float64, shape (n_f,)
    Angular frequencies, rad/s, in sweep order.
mu0, N0, kc : ndarray of float64, shape (n_s, nd)
    Friction coefficient (-), normal preload (N), tangential stiffness (N/m).
tol : float
    Accepted relative residual ``|s kc A / (mu0 N0) - 1|``; iterations aim 10x lower.
max_iter : int
    Newton iterations per attempt.
y : ndarray of complex128, shape (n_s, n_f, n_beams)
    Out: displacement amplitude at the output position of every beam, m.
s : ndarray of float64, shape (n_s, n_f, nd)
    Out: slip ratio per damper (0 if ``mu0 N0 = 0``, inf if ``kc = 0``).
status : ndarray of int8, shape (n_s, n_f)
    Out: 0 converged, 1 after a restart from s = 1, 2 by the last-resort solver,
    -1 not converged (``y`` and ``s`` NaN).
iterations : ndarray of int16, shape (n_s, n_f)
    Out: iterations used, all attempts together.
residual : ndarray of float64, shape (n_s, n_f)
    Out: ``max_j |s_j kc_j A_j / (mu0_j N0_j) - 1|`` over the sliding dampers at the
    returned point; ``inf`` where not finite, and at a point that did not converge
    whose last iterate would pass (it never reads as converged).
"""

import math

import numpy as np
from numba import prange

from . import chain_newton
from ._jit import inline_jit, jit
from .friction import LAW_COULOMB, MIN_NORMAL, log_normal
from .linalg import LANES
from .newton import (
    CONVERGED,
    CONVERGED_LM,
    CONVERGED_RESTART,
    NOT_CONVERGED,
    abs_q,
    bracket_scalar,
    levenberg_marquardt,
    newton,
    newton_scalar,
    workspace,
)
from .receptance import D11, D13, D21, D23

#: Points of the frequency sweep the warm start extrapolates from (a cubic: each order
#: cuts the error of the predicted log s about tenfold, see the performance page).
N_PREDICT = 4

#: Samples per batch of the one-damper kernel (two SIMD vectors of four doubles).
ONE_LANES = 8

# Index rec and y in full, never through views such as rec[r, k]: a view's refcount is
# shared by all threads, and its atomic updates stopped the prange from scaling.


@inline_jit
def _damper_constants(mu0, N0, kc, i, j):
    """(active, c = log(mu0 N0 / kc), s reported if inactive) of damper j of sample i."""
    mn = mu0[i, j] * N0[i, j]
    if mn > 0.0 and kc[i, j] > 0.0:
        return True, math.log(mn / kc[i, j]), 0.0
    return False, 0.0, 0.0 if mn == 0.0 else math.inf


@jit
def predict_weights(omega):
    """Lagrange extrapolation weights of the warm start, shared by every sample.

    Parameters
    ----------
    omega : ndarray, shape (n_f,)
        Angular frequencies in sweep order, rad/s.

    Returns
    -------
    ndarray, shape (N_PREDICT + 1, n_f, N_PREDICT)
        ``W[h, k, m]``: weight of the solution at frequency ``k - 1 - m`` in the
        polynomial through the ``h`` previous points, evaluated at ``omega[k]``
        (zero for ``m >= h``). A repeated frequency gives non-finite weights, and the
        prediction then falls back to the stick limit.
    """
    n_f = omega.shape[0]
    W = np.zeros((N_PREDICT + 1, n_f, N_PREDICT))
    for h in range(1, N_PREDICT + 1):
        for k in range(h, n_f):
            for m in range(h):
                cm = 1.0
                for n in range(h):
                    if n != m:
                        cm *= (omega[k] - omega[k - 1 - n]) / (omega[k - 1 - m] - omega[k - 1 - n])
                W[h, k, m] = cm
    return W


@inline_jit
def _predict(x, xp, W, l, k, have, nd):
    """Warm start of column ``l`` at frequency ``k``: polynomial extrapolation in log s.

    ``xp[m, j, l]`` holds the last ``have`` converged points (newest first, at most
    :data:`N_PREDICT`, consecutive frequencies); ``W`` is from :func:`predict_weights`.
    """
    for j in range(nd):
        v = 0.0                     # summed in a register, in the order of m
        for m in range(have):
            v += W[have, k, m] * xp[m, j, l]
        # a damper with no relative motion has s = inf: restart it from the stick limit
        x[j, l] = v if math.isfinite(v) else 0.0


@inline_jit
def _remember(xp, l, x, have, nd):
    """Push column ``l`` of ``x`` into the predictor history; returns the new ``have``."""
    for m in range(N_PREDICT - 1, 0, -1):
        for j in range(nd):
            xp[m, j, l] = xp[m - 1, j, l]
    for j in range(nd):
        xp[0, j, l] = x[j, l]
    return min(have + 1, N_PREDICT)


@inline_jit
def _q0(rec, r, k, force, a, b, j):
    """Relative contact displacement of damper j of the uncoupled array, m."""
    return rec[r, k, D13, a[j]] * force[a[j]] - rec[r, k, D13, b[j]] * force[b[j]]


@inline_jit
def _dense_G(rec, r, k, a, b, G, nd):
    """``G = B diag(d11) B^T`` for any damper graph."""
    d11 = rec[r, k, D11]
    for j in range(nd):
        for m in range(nd):
            G[j, m] = g_entry(d11, a, b, j, m)


@inline_jit
def g_entry(d11, a, b, j, m):
    """Entry ``(j, m)`` of ``G = B diag(d11) B^T``: damper ``m``'s force at damper ``j``'s
    relative displacement (m/N), from the beams' contact receptances ``d11``."""
    g = 0.0j
    if a[j] == a[m]:
        g += d11[a[j]]
    if a[j] == b[m]:
        g -= d11[a[j]]
    if b[j] == b[m]:
        g += d11[b[j]]
    if b[j] == a[m]:
        g -= d11[b[j]]
    return g


@jit
def _fallback(rec, r, k, a, b, kc, c, active, q0, G, x, tol, max_iter, w, law):
    """Dense Newton restarted from s = 1, then Levenberg-Marquardt from s = 1.

    Returns (ok, iterations, status); ``x`` and the workspace hold the final state.
    """
    nd = x.shape[0]
    _dense_G(rec, r, k, a, b, G, nd)
    for j in range(nd):
        x[j] = 0.0
    ok, its = newton(x, kc, c, active, G, q0, tol, max_iter, w, law)
    if ok:
        return True, its, CONVERGED_RESTART
    for j in range(nd):
        x[j] = 0.0
    ok, its2 = levenberg_marquardt(x, kc, c, active, G, q0, tol, w, law)
    return ok, its + its2, CONVERGED_LM


@inline_jit
def _abs_expm1(f):
    """``|expm1(f)|``, the relative force residual of a damper with log residual ``f``.

    Converged points have ``|f| <= 1e-10``, where three terms of the series are exact to
    rounding (truncation ``f^3/24`` relative), which saves a libm call per point.
    ``inf`` for a NaN ``f``.
    """
    if abs(f) < 1e-5:
        return abs(f * (1.0 + f * (0.5 + f * (1.0 / 6.0))))
    r = abs(math.expm1(f))
    # NaN as inf: a max over dampers would drop it (max(0.0, nan) is 0.0)
    return r if r == r else math.inf


@inline_jit
def _reported(res, ok, tol):
    """The residual written for a point: ``inf`` where it is not finite, or where a point
    that failed would show a passing one (no sliding damper to measure, say): a failed
    point never reads as converged."""
    if not math.isfinite(res) or (not ok and res <= tol):
        return math.inf
    return res


@inline_jit
def _write_point(rec, r, k, force, a, b, K, q, f, x, active, s_off, sq, l, ok, st, its,
                 i, y, s, status, iterations, residual, fb, nd, n_beams, tol):
    """Outputs of one (sample, frequency): ``y2 = D23 F + D21 B^T f``, ``f_j = -K_j q_j``.

    The state is column ``l`` of the (nd, lanes) arrays ``K``, ``q``, ``f``, ``x``,
    ``active``, ``s_off`` (s of an inactive damper) and ``sq = mu0 N0 / kc`` (m).
    """
    iterations[i, k] = min(its, 32767)
    res = 0.0
    for j in range(nd):
        if active[j, l]:
            res = max(res, _abs_expm1(f[j, l]))
    residual[i, k] = _reported(res, ok, tol)
    if not ok:
        status[i, k] = NOT_CONVERGED
        for bb in range(n_beams):
            y[i, k, bb] = complex(math.nan, math.nan)
        for j in range(nd):
            s[i, k, j] = math.nan
        return
    status[i, k] = st
    for bb in range(n_beams):
        fb[bb] = 0.0j
    for j in range(nd):
        fj = -K[j, l] * q[j, l]
        fb[a[j]] += fj
        fb[b[j]] -= fj
    for bb in range(n_beams):
        y[i, k, bb] = rec[r, k, D23, bb] * force[bb] + rec[r, k, D21, bb] * fb[bb]
    for j in range(nd):
        if not active[j, l]:
            s[i, k, j] = s_off[j, l]
        elif x[j, l] > 0.0:
            # stuck, x = log(mu0 N0 / (kc |q|)) exactly: s without a call to exp
            qq = q[j, l]
            s[i, k, j] = sq[j, l] / abs_q(qq, qq.real * qq.real + qq.imag * qq.imag)
        else:
            s[i, k, j] = math.exp(x[j, l])


@jit(parallel=True, nogil=True)
def sweep_chain(rec, force, a, b, omega, mu0, N0, kc, tol, max_iter,
                y, s, status, iterations, residual):
    """Harmonic balance of a chain or a ring, ``LANES`` samples per batch (module doc)."""
    n_batches = (mu0.shape[0] + LANES - 1) // LANES
    W = predict_weights(omega)
    for g in prange(n_batches):
        _chain_batch(np.int64(g), rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                     y, s, status, iterations, residual)


# The prange bodies live in plain jitted functions: numba's parfor passes then see a
# small loop body, which keeps the compile time down.

@jit(fastmath=chain_newton.FASTMATH)
def _chain_batch(g, rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                 y, s, status, iterations, residual):
    """Samples ``g * LANES ...`` of :func:`sweep_chain`, all frequencies."""
    n_s = mu0.shape[0]
    n_r = rec.shape[0]
    n_f = W.shape[1]
    nd = a.shape[0]
    n_beams = force.shape[0]
    ring = nd == n_beams            # the last damper couples the last beam and the first
    C, R, B, V, M = chain_newton.workspace(nd)
    # the state at the solution, as views made once per batch (a view's reference
    # count is this thread's own: no contention, unlike views of rec)
    K = C[chain_newton.K_]
    q = C[chain_newton.Q_]
    f = R[chain_newton.F_]
    # and the inputs of chain_newton.newton_lanes, which takes no other arrays
    x = R[chain_newton.X_]
    kcl = R[chain_newton.KC_]
    cl = R[chain_newton.CC_]
    actl = M[chain_newton.ACT_:]
    Gd = C[chain_newton.GD_]
    Gu = C[chain_newton.GU_]
    q0 = C[chain_newton.Q0_]
    need = M[chain_newton.NEED_]
    ok = M[chain_newton.OK_]
    s_off = np.zeros((nd, LANES))
    sq = np.zeros((nd, LANES))
    xp = np.zeros((N_PREDICT, nd, LANES))
    have = np.zeros(LANES, dtype=np.int64)
    rl = np.zeros(LANES, dtype=np.int64)
    ok0 = np.zeros(LANES, dtype=np.bool_)
    need0 = np.zeros(LANES, dtype=np.bool_)
    its0 = np.zeros(LANES)
    restarted = np.zeros(LANES, dtype=np.bool_)
    # one sample's copy for the dense fallback
    wd = workspace(nd)
    G = np.zeros((nd, nd), dtype=np.complex128)
    xs = np.zeros(nd)
    kc1 = np.zeros(nd)
    c1 = np.zeros(nd)
    act1 = np.zeros(nd, dtype=np.bool_)
    q01 = np.zeros(nd, dtype=np.complex128)
    fb = np.zeros(n_beams, dtype=np.complex128)
    yf = np.zeros(n_beams, dtype=np.complex128)   # the drive's part of y, D23 F
    for l in range(LANES):
        i = g * LANES + l
        need[l] = i < n_s
        if need[l]:
            if n_r > 1:             # one receptance set per sample (mistuned rigs)
                rl[l] = i
            for j in range(nd):
                actl[j, l], cl[j, l], s_off[j, l] = _damper_constants(mu0, N0, kc, i, j)
                kcl[j, l] = kc[i, j]
                sq[j, l] = mu0[i, j] * N0[i, j] / kc[i, j] if actl[j, l] else 0.0
    for k in range(n_f):
        for l in range(LANES):
            if not need[l]:
                continue
            if n_r > 1 or l == 0:   # lane 0 always holds a sample
                r = rl[l]
                # damper j couples beams a_j = j and b_j = j + 1 (mod n_beams): read
                # each beam's d11 and d13 F once (same products as _q0, so the same bits)
                ua = rec[r, k, D13, 0] * force[0]
                da = rec[r, k, D11, 0]
                for j in range(nd):
                    jb = j + 1 if j + 1 < n_beams else 0
                    ub = rec[r, k, D13, jb] * force[jb]
                    db = rec[r, k, D11, jb]
                    q0[j, l] = ua - ub
                    Gd[j, l] = da + db
                    # dampers j and j + 1 share beam j + 1; on a ring the last and the
                    # first share beam 0 (on a chain the last entry is unused)
                    Gu[j, l] = -db
                    ua = ub
                    da = db
                if n_r == 1:
                    for bb in range(n_beams):
                        yf[bb] = rec[0, k, D23, bb] * force[bb]
            else:                   # a shared rig (n_r = 1): once per frequency, lane 0's
                for j in range(nd):
                    q0[j, l] = q0[j, 0]
                    Gd[j, l] = Gd[j, 0]
                    Gu[j, l] = Gu[j, 0]
            # _predict, written out (see below)
            h = have[l]
            for j in range(nd):
                v = 0.0
                for m in range(h):
                    v += W[h, k, m] * xp[m, j, l]
                x[j, l] = v if math.isfinite(v) else 0.0
        chain_newton.newton_lanes(tol, max_iter, C, R, B, V, M, nd, ring)
        # a failed lane is restarted from s = 1 on this O(nd) Newton before the dense
        # fallback, whose first attempt is that very restart at O(nd^3) a step (seconds
        # on hundreds of dampers); the other lanes keep their solutions (newton_lanes
        # writes only the lanes it runs, but resets every lane's OK_ and ITS_)
        n_fail = 0
        for l in range(LANES):
            restarted[l] = False
            n_fail += need[l] and not ok[l]
        if n_fail > 0:
            for l in range(LANES):
                ok0[l] = ok[l]
                its0[l] = V[chain_newton.ITS_, l]
                need0[l] = need[l]
                need[l] = need0[l] and not ok0[l]
                if need[l]:
                    for j in range(nd):
                        x[j, l] = 0.0
            chain_newton.newton_lanes(tol, max_iter, C, R, B, V, M, nd, ring)
            for l in range(LANES):
                if need[l]:
                    V[chain_newton.ITS_, l] += its0[l]
                    restarted[l] = ok[l]
                else:
                    ok[l] = ok0[l]
                    V[chain_newton.ITS_, l] = its0[l]
                need[l] = need0[l]
        for l in range(LANES):
            if not need[l]:
                continue
            i = g * LANES + l
            r = rl[l]
            st = CONVERGED_RESTART if restarted[l] else CONVERGED
            n_it = int(V[chain_newton.ITS_, l])
            good = ok[l]
            if not good:            # rare: one sample's copy through the dense solvers
                for j in range(nd):
                    kc1[j] = kcl[j, l]
                    c1[j] = cl[j, l]
                    act1[j] = actl[j, l]
                    q01[j] = q0[j, l]
                good, n2, st = _fallback(rec, r, k, a, b, kc1, c1, act1, q01, G, xs,
                                         tol, max_iter, wd, np.int64(LAW_COULOMB))
                n_it += n2
                for j in range(nd):
                    x[j, l] = xs[j]
                    K[j, l] = wd[0][j]
                    q[j, l] = wd[1][j]
                    f[j, l] = wd[2][j]
            # _write_point and _remember, written out: an inlined helper that takes arrays
            # costs two atomic reference counts per array and call
            iterations[i, k] = min(n_it, 32767)
            res = 0.0
            for j in range(nd):
                if actl[j, l]:
                    res = max(res, _abs_expm1(f[j, l]))
            residual[i, k] = _reported(res, good, tol)
            if not good:
                status[i, k] = NOT_CONVERGED
                for bb in range(n_beams):
                    y[i, k, bb] = complex(math.nan, math.nan)
                for j in range(nd):
                    s[i, k, j] = math.nan
                have[l] = 0
                continue
            status[i, k] = st
            for bb in range(n_beams):
                fb[bb] = 0.0j
            for j in range(nd):
                fj = -K[j, l] * q[j, l]
                fb[j] += fj             # a_j = j, b_j = j + 1 (mod n_beams)
                fb[j + 1 if j + 1 < n_beams else 0] -= fj
            if n_r > 1:
                for bb in range(n_beams):
                    yf[bb] = rec[r, k, D23, bb] * force[bb]
            for bb in range(n_beams):
                y[i, k, bb] = yf[bb] + rec[r, k, D21, bb] * fb[bb]
            for j in range(nd):
                if not actl[j, l]:
                    s[i, k, j] = s_off[j, l]
                elif x[j, l] > 0.0:
                    qq = q[j, l]
                    s[i, k, j] = sq[j, l] / abs_q(qq, qq.real * qq.real + qq.imag * qq.imag)
                else:
                    s[i, k, j] = math.exp(x[j, l])
            for m in range(N_PREDICT - 1, 0, -1):
                for j in range(nd):
                    xp[m, j, l] = xp[m - 1, j, l]
            for j in range(nd):
                xp[0, j, l] = x[j, l]
            have[l] = min(have[l] + 1, N_PREDICT)


@jit(parallel=True, nogil=True)
def sweep_dense(rec, force, a, b, omega, mu0, N0, kc, tol, max_iter,
                y, s, status, iterations, residual, law):
    """Harmonic balance of any damper graph (rings), or any contact law (``law``, see
    :mod:`mcfric.core.friction`), one sample at a time, dense LU."""
    W = predict_weights(omega)
    for i in prange(mu0.shape[0]):
        _dense_sample(np.int64(i), rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                      y, s, status, iterations, residual, law)


@jit
def _dense_sample(i, rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                  y, s, status, iterations, residual, law):
    """Sample ``i`` of :func:`sweep_dense`, all frequencies."""
    n_r = rec.shape[0]
    n_f = W.shape[1]
    nd = a.shape[0]
    n_beams = force.shape[0]
    r = 0
    if n_r > 1:
        r = np.int64(i)
    w = workspace(nd)
    kc1 = np.empty(nd)
    c1 = np.empty(nd)
    act1 = np.empty(nd, dtype=np.bool_)
    # the state as one-lane columns for _write_point
    act2 = np.zeros((nd, 1), dtype=np.bool_)
    off2 = np.zeros((nd, 1))
    sq2 = np.zeros((nd, 1))
    K2 = np.zeros((nd, 1), dtype=np.complex128)
    q2 = np.zeros((nd, 1), dtype=np.complex128)
    f2 = np.zeros((nd, 1))
    for j in range(nd):
        act1[j], c1[j], off2[j, 0] = _damper_constants(mu0, N0, kc, i, j)
        act2[j, 0] = act1[j]
        kc1[j] = kc[i, j]
        sq2[j, 0] = mu0[i, j] * N0[i, j] / kc[i, j] if act1[j] else 0.0
    x = np.zeros(nd)
    xg = np.zeros((nd, 1))
    xp = np.zeros((N_PREDICT, nd, 1))
    G = np.empty((nd, nd), dtype=np.complex128)
    q0 = np.empty(nd, dtype=np.complex128)
    fb = np.empty(n_beams, dtype=np.complex128)
    have = 0
    for k in range(n_f):
        for j in range(nd):
            q0[j] = _q0(rec, r, k, force, a, b, j)
        _dense_G(rec, r, k, a, b, G, nd)
        _predict(xg, xp, W, 0, k, have, nd)
        for j in range(nd):
            x[j] = xg[j, 0]
        ok, its = newton(x, kc1, c1, act1, G, q0, tol, max_iter, w, law)
        st = CONVERGED
        if not ok:
            ok, its2, st = _fallback(rec, r, k, a, b, kc1, c1, act1, q0, G, x, tol,
                                     max_iter, w, law)
            its += its2
        for j in range(nd):
            xg[j, 0] = x[j]
            K2[j, 0] = w[0][j]
            q2[j, 0] = w[1][j]
            f2[j, 0] = w[2][j]
        _write_point(rec, r, k, force, a, b, K2, q2, f2, xg, act2, off2, sq2, 0, ok, st,
                     its, i, y, s, status, iterations, residual, fb, nd, n_beams, tol)
        if ok:
            have = _remember(xp, 0, xg, have, nd)
        else:
            have = 0


@jit(parallel=True, nogil=True)
def sweep_one_damper(rec, force, a, b, omega, mu0, N0, kc, tol, max_iter,
                     y, s, status, iterations, residual):
    """Harmonic balance of two beams and one damper: scalar Newton (~2x the general path),
    ``ONE_LANES`` samples per batch (see :func:`_one_damper_batch`)."""
    W = predict_weights(omega)
    n_batches = (mu0.shape[0] + ONE_LANES - 1) // ONE_LANES
    for g in prange(n_batches):
        _one_damper_batch(np.int64(g), rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                          y, s, status, iterations, residual)


# Rows of the lane scratch P (n, ONE_LANES) of _one_damper_batch: per sample kc (N/m),
# c = log(mu0 N0 / kc), e^c (m); per point the warm start x0 = log s, G and q0 (real and
# imaginary parts, m/N and m), and the stuck candidate's q (m), log s and s, and whether
# it is the solution (1.0 or 0.0).
_KC, _C, _EC, _X0, _GR, _GI, _Q0R, _Q0I, _QR, _QI, _XS, _SS, _STK = range(13)


@jit(fastmath={"nsz"})
def _one_damper_batch(g, rec, force, a, b, W, mu0, N0, kc, tol, max_iter,
                      y, s, status, iterations, residual):
    """Samples ``g * ONE_LANES ...`` of :func:`sweep_one_damper`, all frequencies.

    Most points are stuck and predicted stuck (see the performance page): then the
    stuck state ``K = kc`` is the exact solution, found with one complex division and one
    log. That candidate is formed for all lanes in one branch-free loop, which LLVM turns
    into SIMD code (:func:`mcfric.core.friction.log_normal` instead of a libm call per
    point); every other point runs the scalar Newton of :func:`newton_scalar` as before.
    Lanes never exchange values. Only ``nsz`` fastmath (signed zeros): it lets LLVM
    vectorise the loop and leaves every other result bitwise as without it.
    """
    n_s = mu0.shape[0]
    n_r = rec.shape[0]
    n_f = W.shape[1]
    n_beams = force.shape[0]
    ia = a[0]
    ib = b[0]
    L = ONE_LANES
    n_l = min(L, n_s - g * L)
    P = np.zeros((13, L))
    active = np.zeros(L, dtype=np.bool_)
    s_off = np.zeros(L)
    rl = np.zeros(L, dtype=np.int64)
    # log s at the last N_PREDICT converged frequencies, newest first
    xh = np.zeros((N_PREDICT, L))
    have = np.zeros(L, dtype=np.int64)
    for l in range(n_l):
        i = g * L + l
        if n_r > 1:
            rl[l] = i
        active[l], c, s_off[l] = _damper_constants(mu0, N0, kc, i, 0)
        P[_KC, l] = kc[i, 0]
        P[_C, l] = c
        P[_EC, l] = math.exp(c)     # once per sample, not per stuck point
    yf = np.zeros(n_beams, dtype=np.complex128)
    for k in range(n_f):
        # a shared rig (n_r = 1): G, q0 and the drive's part of y once for all lanes
        gg = rec[0, k, D11, ia] + rec[0, k, D11, ib]
        q0 = _q0(rec, 0, k, force, a, b, 0)
        for bb in range(n_beams):
            yf[bb] = rec[0, k, D23, bb] * force[bb]
        for l in range(n_l):
            if n_r > 1:
                r = rl[l]
                gg = rec[r, k, D11, ia] + rec[r, k, D11, ib]
                q0 = _q0(rec, r, k, force, a, b, 0)
            P[_GR, l] = gg.real
            P[_GI, l] = gg.imag
            P[_Q0R, l] = q0.real
            P[_Q0I, l] = q0.imag
            # W[have, k, m] is 0 for m >= have, where the history holds 0
            h = have[l]
            x0 = 0.0
            for m in range(N_PREDICT):
                x0 += W[h, k, m] * xh[m, l]
            P[_X0, l] = x0 if math.isfinite(x0) else 0.0
        # the stuck candidate of every lane, branch-free: q = q0 / (1 + G kc) and its
        # log s = c - log|q|, the same operations as _scalar_eval at x >= 0
        for l in range(L):
            kcl = P[_KC, l]
            dr = 1.0 + P[_GR, l] * kcl
            di = P[_GI, l] * kcl
            rr = 1.0 / (dr * dr + di * di)
            vr = dr * rr
            vi = -di * rr
            qr = P[_Q0R, l] * vr - P[_Q0I, l] * vi
            qi = P[_Q0R, l] * vi + P[_Q0I, l] * vr
            q2 = qr * qr + qi * qi
            t = P[_C, l] - 0.5 * log_normal(q2)
            P[_QR, l] = qr
            P[_QI, l] = qi
            P[_XS, l] = t
            P[_SS, l] = P[_EC, l] / math.sqrt(q2)
            # log_normal needs a normal q2; a lane failing a test takes the scalar path
            ok = (P[_X0, l] >= 0.0) & (t >= 0.0) & (q2 >= MIN_NORMAL) & (q2 < math.inf)
            P[_STK, l] = 1.0 if ok else 0.0
        for l in range(n_l):
            i = g * L + l
            r = rl[l]
            st = CONVERGED
            its = 0
            ok = True
            K = 0.0j
            f = 0.0
            ss = s_off[l]
            xs = 0.0
            if active[l] and P[_STK, l] != 0.0:
                # stuck and consistent: the exact root newton_scalar would return at once
                K = complex(P[_KC, l], 0.0)
                q = complex(P[_QR, l], P[_QI, l])
                ss = P[_SS, l]
                xs = P[_XS, l]
            else:
                q = complex(P[_Q0R, l], P[_Q0I, l])
                if active[l]:
                    gg = complex(P[_GR, l], P[_GI, l])
                    q0 = q
                    kci = P[_KC, l]
                    c = P[_C, l]
                    ok, its, xs, ss, q, K, f = newton_scalar(P[_X0, l], kci, c, gg, q0, tol,
                                                             max_iter)
                    if not ok:
                        st = CONVERGED_RESTART
                        ok, its2, xs, ss, q, K, f = newton_scalar(0.0, kci, c, gg, q0, tol,
                                                                  max_iter)
                        its += its2
                        if not ok:
                            st = CONVERGED_LM
                            ok, its2, xs, ss, q, K, f = bracket_scalar(kci, c, gg, q0, tol)
                            its += its2
            if active[l]:
                if ok:
                    for m in range(N_PREDICT - 1, 0, -1):
                        xh[m, l] = xh[m - 1, l]
                    xh[0, l] = xs
                    have[l] = min(have[l] + 1, N_PREDICT)
                else:
                    have[l] = 0
                    for m in range(N_PREDICT):
                        xh[m, l] = 0.0
            iterations[i, k] = min(its, 32767)
            residual[i, k] = _reported(_abs_expm1(f), ok, tol)
            if not ok:
                status[i, k] = NOT_CONVERGED
                for bb in range(n_beams):
                    y[i, k, bb] = complex(math.nan, math.nan)
                s[i, k, 0] = math.nan
                continue
            status[i, k] = st
            fj = -K * q
            for bb in range(n_beams):
                fb = 0.0j
                if bb == ia:
                    fb += fj
                if bb == ib:
                    fb -= fj
                if n_r > 1:
                    yf[bb] = rec[r, k, D23, bb] * force[bb]
                y[i, k, bb] = yf[bb] + rec[r, k, D21, bb] * fb
            s[i, k, 0] = ss
