"""Newton for a batch of samples in lockstep on a chain or a ring of dampers (the fast path).

``LANES`` samples handled by one thread advance through the same frequency together.
Every array has the lane index last, and every loop over dampers has an inner loop over
lanes. The point is instruction-level parallelism: the O(nd) eliminations of a chain
(tridiagonal ``I + G K``; block-tridiagonal Newton step with real 2x2 blocks in
``w = dq``) are chains of dependent divisions, and interleaving independent samples keeps
the pipeline full (measured gains: the docs' performance page).

On a ring (``ring``: the last damper couples the last beam and the first) both systems
are cyclic tridiagonal. They are solved by bordering: rows ``0 .. nd - 2`` are eliminated
as a chain with the last column as a second right-hand side, and the last row then gives
the last unknown, so a ring costs O(nd) too (about 1.5 chains).

Each lane runs exactly the single-sample algorithm of :mod:`mcfric.core.newton` in its own
arithmetic (damped Newton in ``x = log s`` with an Armijo line search, stuck dampers
solved exactly in each evaluation); lanes never exchange values, so a sample's result
does not depend on which samples share its batch, its thread, or its chunk.

The scratch state lives in five arrays indexed by the slot constants below (``C[K_]``,
``R[F_]``, ...) rather than in some twenty separate arrays: every array passed to or
unpacked in a compiled function costs an atomic reference count and a struct copy per
call. The per-point inputs (iterate, damper
constants, ``G`` and ``q0``) and the per-lane results live there too, so that the three
kernels take no other arrays.
"""

import math

import numpy as np

from ._jit import inline_jit, jit
from .friction import kappa_logs
from .linalg import LANES, cinv
from .newton import _ARMIJO, _MAX_HALVINGS, _MAX_STEP, _TARGET, log_abs, reciprocal

#: fastmath flags of the chain kernels: none. Fused multiply-add (``contract``) and
#: ``x * (1 / y)`` for ``x / y`` (``arcp``) gave eight beams 1.06-1.07x, but they make the
#: bits depend on the compile history: a kernel compiled where its callees were compiled
#: too inlines them and fuses across the call, one compiled against callees loaded from
#: numba's cache cannot, so two processes (Dask workers, a resumed run) could differ in
#: the last bits (measured: 407 of 5000 metric values, 1e-15 relative). Without them
#: LLVM keeps IEEE semantics, and inlining cannot change a result.
FASTMATH = False

_SLIP_SIDE = complex(0.0, -4.0 / math.pi)   # d(K/kc)/dlog s at s = 1 from the slip side

# Slots of the complex scratch C (n, nd, LANES): K and dK/dlog s (N/m) and q (m) at the
# accepted point, the same at the trial point, the step's h and e, the eliminated
# tridiagonal system and, on a ring, its second right-hand side (the last column);
# inputs: diagonal of G and its coupling of dampers j and j + 1 (on a ring GU_[nd - 1]
# couples the last damper and the first) (m/N), q0 (m).
K_, KP_, Q_, KT_, KPT_, QT_, H_, E_, DI_, UP_, YV_, GD_, GU_, Q0_ = range(14)
# Slots of the real scratch R (n, nd, LANES): log residual at the accepted point, trial
# x = log s, its residual, the Newton step; the iterate x = log s (in: the guess, out:
# the last accepted point); inputs: kc (N/m) and c = log(mu0 N0 / kc).
F_, XT_, FT_, DX_, X_, KC_, CC_ = range(7)
# Slots of the block scratch B (n, nd, 4, LANES): the eliminated 2x2 super-diagonal
# blocks of the Newton step, its right-hand side (first two columns) and, on a ring, the
# eliminated last block column.
UB_, RB_, WB_ = range(3)
# Slots of the per-lane reals V (n, LANES): |f|^2 accepted and trial, the step length,
# out: the Newton steps taken (a float holding an integer); max_j |f_j| accepted and trial.
PHI_, PHIT_, LAM_, ITS_, FM_, FMT_ = range(6)
# Rows of the flags M (n + nd, LANES): per lane, need a step, have a trial to evaluate, a
# failed solve, in: holds a sample, out: converged; then per damper (row ACT_ + j), in:
# damper j transmits force.
RUN_, PEND_, BAD_, NEED_, OK_, ACT_ = range(6)


@jit(fastmath=FASTMATH)
def _eval(C, R, V, M, nd, ring):
    """Residual at the trial points of the lanes in ``M[PEND_]``.

    Fills ``C[KT_]``, ``C[KPT_]``, ``C[QT_]``, ``R[FT_]``, ``V[PHIT_] = |f|^2`` and
    ``V[FMT_] = max |f_j|``.
    Stuck dampers are solved exactly (``R[XT_]`` is updated); ``V[PHIT_]`` is inf for a
    lane whose linear solve failed or whose residual is not finite.
    """
    for j in range(nd):
        for l in range(LANES):
            if M[PEND_, l]:
                if M[ACT_ + j, l]:
                    k, d = kappa_logs(R[XT_, j, l])
                    C[KT_, j, l] = R[KC_, j, l] * k
                    C[KPT_, j, l] = R[KC_, j, l] * d
                else:
                    C[KT_, j, l] = 0.0j
                    C[KPT_, j, l] = 0.0j
    # (I + G K) q = q0 is tridiagonal: Thomas algorithm (no pivoting; a zero or
    # non-finite pivot flags the lane, whose sample then goes to the pivoting dense
    # solvers), each row eliminated as it is formed. DI_ keeps the pivots' reciprocals.
    # A ring is cyclic tridiagonal: rows 0 .. nd - 2 are eliminated as a chain with the
    # last column as a second right-hand side (YV_), then the last row closes it.
    ne = nd - 1 if ring else nd
    for l in range(LANES):
        M[BAD_, l] = False
    for j in range(ne):
        for l in range(LANES):
            if not M[PEND_, l]:
                continue
            d = 1.0 + C[GD_, j, l] * C[KT_, j, l]
            r = C[Q0_, j, l]
            if ring:
                v = 0.0j
                if j == 0:
                    v += C[GU_, nd - 1, l] * C[KT_, nd - 1, l]
                if j == ne - 1:
                    v += C[GU_, j, l] * C[KT_, nd - 1, l]
            if j > 0:
                m = (C[GU_, j - 1, l] * C[KT_, j - 1, l]) * C[DI_, j - 1, l]
                d -= m * C[UP_, j - 1, l]
                r -= m * C[QT_, j - 1, l]
                if ring:
                    v -= m * C[YV_, j - 1, l]
            a2 = d.real * d.real + d.imag * d.imag
            if not (a2 > 0.0 and a2 < math.inf):
                M[BAD_, l] = True
            C[DI_, j, l] = cinv(d)
            C[QT_, j, l] = r
            if ring:
                C[YV_, j, l] = v
            if j < ne - 1:
                C[UP_, j, l] = C[GU_, j, l] * C[KT_, j + 1, l]
    for l in range(LANES):
        if M[PEND_, l]:
            C[QT_, ne - 1, l] *= C[DI_, ne - 1, l]
            if ring:
                C[YV_, ne - 1, l] *= C[DI_, ne - 1, l]
    for j in range(ne - 2, -1, -1):
        for l in range(LANES):
            if M[PEND_, l]:
                C[QT_, j, l] = (C[QT_, j, l] - C[UP_, j, l] * C[QT_, j + 1, l]) * C[DI_, j, l]
                if ring:
                    C[YV_, j, l] = ((C[YV_, j, l] - C[UP_, j, l] * C[YV_, j + 1, l])
                                    * C[DI_, j, l])
    if ring:
        for l in range(LANES):
            if not M[PEND_, l]:
                continue
            # last row: beta x_0 + lam x_{nd-2} + d x_{nd-1} = q0_{nd-1}, x_j = x'_j - y_j x
            beta = C[GU_, nd - 1, l] * C[KT_, 0, l]
            lam = C[GU_, nd - 2, l] * C[KT_, nd - 2, l]
            d = (1.0 + C[GD_, nd - 1, l] * C[KT_, nd - 1, l]
                 - beta * C[YV_, 0, l] - lam * C[YV_, nd - 2, l])
            a2 = d.real * d.real + d.imag * d.imag
            if not (a2 > 0.0 and a2 < math.inf):
                M[BAD_, l] = True
            xn = ((C[Q0_, nd - 1, l] - beta * C[QT_, 0, l] - lam * C[QT_, nd - 2, l])
                  * cinv(d))
            C[QT_, nd - 1, l] = xn
            for j in range(nd - 1):
                C[QT_, j, l] -= C[YV_, j, l] * xn
    for l in range(LANES):
        V[PHIT_, l] = 0.0
        V[FMT_, l] = 0.0
    for j in range(nd):
        for l in range(LANES):
            if not M[PEND_, l]:
                continue
            if M[ACT_ + j, l]:
                qq = C[QT_, j, l]
                lq = log_abs(qq, qq.real * qq.real + qq.imag * qq.imag)
                if R[XT_, j, l] >= 0.0:
                    t = R[CC_, j, l] - lq   # log s that makes damper j consistent with q
                    if t > 0.0:
                        R[XT_, j, l] = t
                        R[FT_, j, l] = 0.0
                        C[KPT_, j, l] = 0.0j
                    else:               # no longer stuck: park at s = 1, K unchanged
                        R[XT_, j, l] = 0.0
                        R[FT_, j, l] = -t
                        C[KPT_, j, l] = R[KC_, j, l] * _SLIP_SIDE
                else:
                    R[FT_, j, l] = R[XT_, j, l] + lq - R[CC_, j, l]
                V[PHIT_, l] += R[FT_, j, l] * R[FT_, j, l]
            else:
                R[FT_, j, l] = 0.0
            # here rather than a loop over f at acceptance: an inlined helper taking R
            # cost an atomic reference count per call
            V[FMT_, l] = max(V[FMT_, l], abs(R[FT_, j, l]))
    for l in range(LANES):
        if M[PEND_, l] and (M[BAD_, l] or not math.isfinite(V[PHIT_, l])):
            V[PHIT_, l] = math.inf


@inline_jit
def _block(t, m, e):
    """Real 2x2 block (b00, b01, b10, b11) of ``w -> t w - m Re(e w)`` (complex t, m, e)."""
    return (t.real - m.real * e.real, -t.imag + m.real * e.imag,
            t.imag - m.imag * e.real, t.real + m.imag * e.imag)


@inline_jit
def _solve2(d00, d01, d10, d11, r0, r1, inv):
    """``inv(D) r`` for a 2x2 block ``D`` with ``inv = 1 / det D``."""
    return (d11 * r0 - d01 * r1) * inv, (d00 * r1 - d10 * r0) * inv


@jit(fastmath=FASTMATH)
def _step(C, R, B, M, nd, ring):
    """Newton step ``R[DX_]`` of the lanes in ``M[RUN_]`` (``M[BAD_]`` if not formed).

    Linearising ``(I + G K) q = q0`` and ``f = x + log|q| - c`` gives, with
    ``h_j = dK_j/dx_j q_j``, ``e_j = conj(q_j)/|q_j|^2`` and ``w = dq``:
    ``(I + G K) w - G diag(h) Re(e w) = G diag(h) f`` and ``dx = -f - Re(e w)``.
    """
    for j in range(nd):
        for l in range(LANES):
            if M[RUN_, l]:
                qq = C[Q_, j, l]
                q2 = qq.real * qq.real + qq.imag * qq.imag
                if M[ACT_ + j, l] and qq != 0.0:
                    C[H_, j, l] = C[KP_, j, l] * qq
                    C[E_, j, l] = reciprocal(qq, q2)
                else:
                    C[H_, j, l] = 0.0j
                    C[E_, j, l] = 0.0j
    # block Thomas algorithm with real 2x2 blocks (no pivoting; a singular or non-finite
    # block pivot flags the lane), each block row eliminated as it is formed: UB_ keeps
    # inv(D') U and RB_ the forward-substituted right-hand side, then the solution. On a
    # ring, rows 0 .. nd - 2 are a chain bordered by the last block column (WB_ keeps it
    # eliminated, as inv(D') W) and the last block row closes the system.
    ne = nd - 1 if ring else nd
    last = nd - 1
    for l in range(LANES):
        M[BAD_, l] = False
    for i in range(ne):
        for l in range(LANES):
            if not M[RUN_, l]:
                continue
            g = C[GD_, i, l]
            m = g * C[H_, i, l]
            d00, d01, d10, d11 = _block(1.0 + g * C[K_, i, l], m, C[E_, i, l])
            rhs = m * R[F_, i, l]
            l00 = l01 = l10 = l11 = 0.0
            u00 = u01 = u10 = u11 = 0.0
            w00 = w01 = w10 = w11 = 0.0
            if i > 0:
                g = C[GU_, i - 1, l]
                m = g * C[H_, i - 1, l]
                l00, l01, l10, l11 = _block(g * C[K_, i - 1, l], m, C[E_, i - 1, l])
                rhs += m * R[F_, i - 1, l]
            elif ring:              # row 0 meets the last damper
                g = C[GU_, last, l]
                m = g * C[H_, last, l]
                w00, w01, w10, w11 = _block(g * C[K_, last, l], m, C[E_, last, l])
                rhs += m * R[F_, last, l]
            if i < nd - 1:
                g = C[GU_, i, l]
                m = g * C[H_, i + 1, l]
                u00, u01, u10, u11 = _block(g * C[K_, i + 1, l], m, C[E_, i + 1, l])
                rhs += m * R[F_, i + 1, l]
                if ring and i == ne - 1:    # the coupling to the last damper: a border
                    w00 += u00
                    w01 += u01
                    w10 += u10
                    w11 += u11
                    u00 = u01 = u10 = u11 = 0.0
            r0 = rhs.real
            r1 = rhs.imag
            if i > 0:
                # D -= L X[i-1], r -= L y[i-1] (and W -= L W[i-1]), X[i-1] = inv(D'[i-1])
                # U[i-1] in UB_
                x00 = B[UB_, i - 1, 0, l]
                x01 = B[UB_, i - 1, 1, l]
                x10 = B[UB_, i - 1, 2, l]
                x11 = B[UB_, i - 1, 3, l]
                d00 -= l00 * x00 + l01 * x10
                d01 -= l00 * x01 + l01 * x11
                d10 -= l10 * x00 + l11 * x10
                d11 -= l10 * x01 + l11 * x11
                r0 -= l00 * B[RB_, i - 1, 0, l] + l01 * B[RB_, i - 1, 1, l]
                r1 -= l10 * B[RB_, i - 1, 0, l] + l11 * B[RB_, i - 1, 1, l]
                if ring:
                    x00 = B[WB_, i - 1, 0, l]
                    x01 = B[WB_, i - 1, 1, l]
                    x10 = B[WB_, i - 1, 2, l]
                    x11 = B[WB_, i - 1, 3, l]
                    w00 -= l00 * x00 + l01 * x10
                    w01 -= l00 * x01 + l01 * x11
                    w10 -= l10 * x00 + l11 * x10
                    w11 -= l10 * x01 + l11 * x11
            det = d00 * d11 - d01 * d10
            scale = abs(d00) + abs(d01) + abs(d10) + abs(d11)
            if not (abs(det) > 1e-300 * scale * scale) or not math.isfinite(det):
                M[BAD_, l] = True
            inv = 1.0 / det
            B[RB_, i, 0, l], B[RB_, i, 1, l] = _solve2(d00, d01, d10, d11, r0, r1, inv)
            if i < ne - 1:
                B[UB_, i, 0, l], B[UB_, i, 2, l] = _solve2(d00, d01, d10, d11, u00, u10, inv)
                B[UB_, i, 1, l], B[UB_, i, 3, l] = _solve2(d00, d01, d10, d11, u01, u11, inv)
            if ring:
                B[WB_, i, 0, l], B[WB_, i, 2, l] = _solve2(d00, d01, d10, d11, w00, w10, inv)
                B[WB_, i, 1, l], B[WB_, i, 3, l] = _solve2(d00, d01, d10, d11, w01, w11, inv)
    for i in range(ne - 2, -1, -1):
        for l in range(LANES):
            if M[RUN_, l]:
                x00 = B[UB_, i, 0, l]
                x01 = B[UB_, i, 1, l]
                x10 = B[UB_, i, 2, l]
                x11 = B[UB_, i, 3, l]
                y0 = B[RB_, i + 1, 0, l]
                y1 = B[RB_, i + 1, 1, l]
                B[RB_, i, 0, l] -= x00 * y0 + x01 * y1
                B[RB_, i, 1, l] -= x10 * y0 + x11 * y1
                if ring:
                    for c in range(2):
                        y0 = B[WB_, i + 1, c, l]
                        y1 = B[WB_, i + 1, 2 + c, l]
                        B[WB_, i, c, l] -= x00 * y0 + x01 * y1
                        B[WB_, i, 2 + c, l] -= x10 * y0 + x11 * y1
    if ring:
        for l in range(LANES):
            if not M[RUN_, l]:
                continue
            # last block row: B0 w_0 + L w_{nd-2} + D w_{nd-1} = r, w_j = w'_j - W_j w
            g = C[GD_, last, l]
            m = g * C[H_, last, l]
            d00, d01, d10, d11 = _block(1.0 + g * C[K_, last, l], m, C[E_, last, l])
            rhs = m * R[F_, last, l]
            r0 = 0.0
            r1 = 0.0
            for c in range(2):      # c = 0: the first damper, c = 1: damper nd - 2
                jc = 0 if c == 0 else nd - 2
                g = C[GU_, last if c == 0 else nd - 2, l]
                m = g * C[H_, jc, l]
                b00, b01, b10, b11 = _block(g * C[K_, jc, l], m, C[E_, jc, l])
                rhs += m * R[F_, jc, l]
                d00 -= b00 * B[WB_, jc, 0, l] + b01 * B[WB_, jc, 2, l]
                d01 -= b00 * B[WB_, jc, 1, l] + b01 * B[WB_, jc, 3, l]
                d10 -= b10 * B[WB_, jc, 0, l] + b11 * B[WB_, jc, 2, l]
                d11 -= b10 * B[WB_, jc, 1, l] + b11 * B[WB_, jc, 3, l]
                r0 -= b00 * B[RB_, jc, 0, l] + b01 * B[RB_, jc, 1, l]
                r1 -= b10 * B[RB_, jc, 0, l] + b11 * B[RB_, jc, 1, l]
            r0 += rhs.real
            r1 += rhs.imag
            det = d00 * d11 - d01 * d10
            scale = abs(d00) + abs(d01) + abs(d10) + abs(d11)
            if not (abs(det) > 1e-300 * scale * scale) or not math.isfinite(det):
                M[BAD_, l] = True
            y0, y1 = _solve2(d00, d01, d10, d11, r0, r1, 1.0 / det)
            B[RB_, last, 0, l] = y0
            B[RB_, last, 1, l] = y1
            for i in range(last):
                B[RB_, i, 0, l] -= B[WB_, i, 0, l] * y0 + B[WB_, i, 1, l] * y1
                B[RB_, i, 1, l] -= B[WB_, i, 2, l] * y0 + B[WB_, i, 3, l] * y1
    for l in range(LANES):
        if not M[RUN_, l]:
            continue
        big = 0.0
        for j in range(nd):
            ee = C[E_, j, l]
            R[DX_, j, l] = -R[F_, j, l] - (ee.real * B[RB_, j, 0, l] - ee.imag * B[RB_, j, 1, l])
            big = max(big, abs(R[DX_, j, l]))
        if not math.isfinite(big):
            M[BAD_, l] = True
        elif big > _MAX_STEP:
            sc = _MAX_STEP / big
            for j in range(nd):
                R[DX_, j, l] *= sc


@jit(fastmath=FASTMATH)
def newton_lanes(tol, max_iter, C, R, B, V, M, nd, ring):
    """Damped Newton in ``x = log s`` for the lanes in ``M[NEED_]``, from ``R[X_]``.

    Every lane runs its own iteration (evaluate, accept or halve the step, new step),
    asynchronously; one loop drives all lanes so that the evaluation and the step each
    appear once in the compiled code.

    Parameters
    ----------
    tol, max_iter : float, int
        As :func:`mcfric.core.newton.newton`.
    C, R, B, V, M : ndarray
        Scratch from :func:`workspace`, holding the inputs: ``R[X_]`` the initial
        guesses (nd, LANES), ``M[NEED_]`` the lanes that hold a sample, per damper
        ``R[KC_]`` stiffness (N/m), ``R[CC_]`` ``log(mu0 N0 / kc)``, ``M[ACT_ + j]``
        force-transmitting, ``C[GD_]`` and ``C[GU_]`` the diagonal and super-diagonal of
        ``G = B D11 B^T`` (m/N), ``C[Q0_]`` ``q0`` (m). On return ``R[X_]`` holds the last
        accepted iterates, ``M[OK_]`` converged (``max |f| <= tol / 10``, or a stall
        within ``tol``), ``V[ITS_]`` the Newton steps taken, and ``C[K_]``, ``C[Q_]`` and
        ``R[F_]`` K (N/m), q (m) and the log residual at ``R[X_]``.
    """
    target = _TARGET * tol
    n_pend = 0
    for l in range(LANES):
        V[ITS_, l] = 0.0
        M[OK_, l] = False
        M[RUN_, l] = False          # lanes that need a new Newton step
        M[PEND_, l] = M[NEED_, l]   # lanes with a trial point to evaluate
        V[LAM_, l] = 0.0            # lam = 0 marks the initial point: always accepted
        n_pend += M[NEED_, l]
        for j in range(nd):
            R[XT_, j, l] = R[X_, j, l]
    while n_pend > 0:
        _eval(C, R, V, M, nd, ring)
        n_run = 0
        for l in range(LANES):
            if not M[PEND_, l]:
                continue
            lam = V[LAM_, l]
            first = lam == 0.0
            if first or V[PHIT_, l] <= (1.0 - 2.0 * _ARMIJO * lam) * V[PHI_, l]:
                M[PEND_, l] = False
                if first and not math.isfinite(V[PHIT_, l]):
                    continue        # no finite start: ok stays False
                for j in range(nd):
                    R[X_, j, l] = R[XT_, j, l]
                    C[K_, j, l] = C[KT_, j, l]
                    C[KP_, j, l] = C[KPT_, j, l]
                    C[Q_, j, l] = C[QT_, j, l]
                    R[F_, j, l] = R[FT_, j, l]
                V[PHI_, l] = V[PHIT_, l]
                V[FM_, l] = V[FMT_, l]
                if V[FM_, l] <= target:
                    M[OK_, l] = True
                elif V[ITS_, l] >= max_iter:
                    M[OK_, l] = V[FM_, l] <= tol
                else:
                    M[RUN_, l] = True
                    n_run += 1
            elif lam > 0.5 ** (_MAX_HALVINGS - 1):
                lam *= 0.5
                V[LAM_, l] = lam
                for j in range(nd):
                    R[XT_, j, l] = R[X_, j, l] + lam * R[DX_, j, l]
            else:                   # no acceptable step: a stall at the rounding floor?
                M[PEND_, l] = False
                M[OK_, l] = V[FM_, l] <= tol
        if n_run > 0:
            _step(C, R, B, M, nd, ring)
            for l in range(LANES):
                if not M[RUN_, l]:
                    continue
                M[RUN_, l] = False
                if M[BAD_, l]:
                    M[OK_, l] = V[FM_, l] <= tol
                    continue
                V[ITS_, l] += 1.0
                V[LAM_, l] = 1.0
                M[PEND_, l] = True
                for j in range(nd):
                    R[XT_, j, l] = R[X_, j, l] + R[DX_, j, l]
        n_pend = 0
        for l in range(LANES):
            n_pend += M[PEND_, l]


@jit
def workspace(nd):
    """Scratch arrays ``(C, R, B, V, M)`` for :func:`newton_lanes` (one set per batch)."""
    return (np.zeros((14, nd, LANES), np.complex128), np.zeros((7, nd, LANES)),
            np.zeros((3, nd, 4, LANES)), np.zeros((6, LANES)),
            np.zeros((ACT_ + nd, LANES), np.bool_))
