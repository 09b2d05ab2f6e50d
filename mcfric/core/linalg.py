"""Small dense, tridiagonal (chain) and cyclic tridiagonal (ring) linear solves for the
Newton kernels and the bounds searches.

Every routine works in place and raises nothing: a factorisation returns an info code
(0 = success, k > 0 = zero or non-finite pivot at step k, 1-based, as LAPACK does), or,
for the guarded unpivoted eliminations (:func:`tri_factor`, :func:`cyclic_factor_stable`),
False where a pivot is too small and pivoting must take over.
"""

import math

import numpy as np

from ._jit import inline_jit, jit


@jit
def lu_factor(A, piv, n):
    """LU factorisation with partial pivoting of the leading ``n x n`` block of ``A``.

    Parameters
    ----------
    A : ndarray, shape (>= n, >= n), float64 or complex128
        Overwritten with L (unit lower, below the diagonal) and U.
    piv : ndarray of int, shape (>= n,)
        Row interchanges: row ``k`` was swapped with row ``piv[k]``.
    n : int
        Size of the system.

    Returns
    -------
    int
        0 on success, ``k + 1`` if the pivot of column ``k`` is zero or not finite.
    """
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            v = abs(A[i, k])
            if v > big:
                big = v
                p = i
        piv[k] = p
        if not (big > 0.0) or not math.isfinite(big):
            return k + 1
        if p != k:
            for j in range(n):
                t = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = t
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
            lik = A[i, k]
            if lik != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= lik * A[k, j]
    return 0


@jit
def lu_solve(A, piv, b, n):
    """Solve ``A x = b`` in place (``b`` becomes ``x``) with factors from :func:`lu_factor`."""
    for k in range(n):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= A[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[i, j] * b[j]
        b[i] = acc / A[i, i]


@jit
def lm_step(A, g, lam, N, piv, d, m, n):
    """Levenberg-Marquardt step: ``(A^T A + lam (I + diag(A^T A))) d = -g``.

    ``A`` (m, n) is the Jacobian of the residuals, ``g = A^T r`` the gradient; ``N`` (n, n)
    and ``piv`` are scratch. Returns the info code of :func:`lu_factor`.
    """
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(m):
                acc += A[k, i] * A[k, j]
            N[i, j] = acc
    return lm_solve(N, g, lam, piv, d, n)


@inline_jit
def lm_solve(N, g, lam, piv, d, n):
    """Solve ``(N + lam (I + diag(N))) d = -g`` for the normal matrix ``N = A^T A``,
    which is damped and factorised in place (a caller trying several ``lam`` forms N
    once and copies it). Returns the info code of :func:`lu_factor`."""
    for i in range(n):
        N[i, i] += lam * (1.0 + N[i, i])
        d[i] = -g[i]
    info = lu_factor(N, piv, n)
    if info == 0:
        lu_solve(N, piv, d, n)
    return info


@inline_jit
def contact_solve(G, K, q0, T, piv, q, nd):
    """``q = (I + G diag(K))^-1 q0`` by LU with partial pivoting (any damper graph).

    ``T`` keeps the LU factors and ``piv`` the interchanges. Returns the info code of
    :func:`lu_factor` (``q`` is valid only for 0).
    """
    for i in range(nd):
        for j in range(nd):
            T[i, j] = G[i, j] * K[j]
        T[i, i] += 1.0
        q[i] = q0[i]
    info = lu_factor(T, piv, nd)
    if info == 0:
        lu_solve(T, piv, q, nd)
    return info


@inline_jit
def cinv(z):
    """``1/z`` as ``conj(z)/|z|^2``: one real division instead of numba's scaled complex one."""
    r = 1.0 / (z.real * z.real + z.imag * z.imag)
    return complex(z.real * r, -z.imag * r)


#: Samples solved in lockstep by the batched kernels (:mod:`mcfric.core.chain_newton`):
#: their O(nd) eliminations are latency-bound chains, and interleaving independent systems
#: fills the pipeline (timings per lane count: the docs' performance page).
LANES = 4


@jit
def factor_inverse(G, K, Tinv, T, piv, nd):
    """``Tinv = (I + G diag(K))^-1``. Returns False if singular."""
    for i in range(nd):
        for j in range(nd):
            T[i, j] = G[i, j] * K[j]
        T[i, i] += 1.0
    if lu_factor(T, piv, nd) != 0:
        return False
    col = np.zeros(nd, dtype=np.complex128)
    for j in range(nd):
        for i in range(nd):
            col[i] = 0.0j
        col[j] = 1.0
        lu_solve(T, piv, col, nd)
        for i in range(nd):
            Tinv[i, j] = col[i]
    return True


@inline_jit
def tri_factor(G, K, T, nd):
    """LU factors of ``I + G diag(K)`` for a tridiagonal G, without pivoting, in rows
    0-2 of ``T`` (1 / pivots, the eliminated super-diagonal, the sub-diagonal). Returns
    False (use pivoting instead) at a pivot small against its row."""
    cp = 0.0j
    for i in range(nd):
        a = 1.0 + G[i, i] * K[i]
        if i > 0:
            lo = G[i, i - 1] * K[i - 1]
            a -= lo * cp
            T[2, i - 1] = lo
        if not (abs(a) > 1e-10 * (1.0 + abs(G[i, i] * K[i]))):
            return False
        inv = 1.0 / a
        cp = G[i, i + 1] * K[i + 1] * inv if i < nd - 1 else 0.0j
        T[0, i] = inv
        T[1, i] = cp
    return True


@inline_jit
def tri_solve(T, x, nd):
    """Solve ``(I + G diag(K)) x = b`` in place (``x`` holds b) with the factors of
    :func:`tri_factor`."""
    x[0] *= T[0, 0]
    for i in range(1, nd):
        x[i] = (x[i] - T[2, i - 1] * x[i - 1]) * T[0, i]
    for i in range(nd - 2, -1, -1):
        x[i] -= T[1, i] * x[i + 1]


@inline_jit
def tri_solve_transposed(T, b, nd):
    """Solve ``(I + G diag(K))^T x = b`` in place with the factors of
    :func:`tri_factor` (``A = L U``, U unit upper: ``U^T`` forward, ``L^T`` back)."""
    for i in range(1, nd):
        b[i] -= T[1, i - 1] * b[i - 1]
    b[nd - 1] *= T[0, nd - 1]
    for i in range(nd - 2, -1, -1):
        b[i] = (b[i] - T[2, i] * b[i + 1]) * T[0, i]


@jit
def lu_solve_transposed(A, piv, b, n):
    """Solve ``A^T x = b`` in place with the factors of :func:`lu_factor` (P A = L U)."""
    # A^T = U^T L^T P: solve U^T z = b, L^T v = z, then x = P^T v
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= A[j, i] * b[j]
        b[i] = acc / A[i, i]
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= A[j, i] * b[j]
        b[i] = acc
    for k in range(n - 1, -1, -1):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t


@jit
def is_tridiagonal(gr, nd):
    """G is tridiagonal (a chain of dampers) and large enough for the row storage of
    :func:`tri_factor`."""
    if nd < 3:
        return False
    for j in range(nd):
        if gr[j, 0] < j - 1 or gr[j, 1] > j + 2:
            return False
    return True


@jit
def is_cyclic(G, nd):
    """G is cyclic tridiagonal with a nonzero corner (a ring of dampers), ``nd >= 5``:
    ``I + G diag(K)`` then factors by :func:`cyclic_factor` in O(nd)."""
    if nd < 5 or (G[0, nd - 1] == 0.0 and G[nd - 1, 0] == 0.0):
        return False
    for i in range(nd):
        for j in range(nd):
            d = abs(i - j)
            if d > 1 and d != nd - 1 and G[i, j] != 0.0:
                return False
    return True


@inline_jit
def _t(G, K, i, j):
    """Entry (i, j) of ``I + G diag(K)``."""
    v = G[i, j] * K[j]
    return v + 1.0 if i == j else v


@jit
def cyclic_factor(G, K, F, nd):
    """Unpivoted factorisation of ``T = I + G diag(K)`` for a cyclic tridiagonal ``G``,
    bordered by the last row and column: the tridiagonal block ``A`` (rows and columns
    0..nd-2) by elimination, ``w = A^-1 u`` for the last column ``u`` and the Schur
    complement ``s``. ``F`` (4, nd) complex keeps pivots, multipliers, ``w`` and ``s``.

    Unpivoted like the chain's elimination: the searches use it, the values they report
    are recomputed by LU with partial pivoting. Returns 0, or ``k + 1`` for a zero or
    non-finite pivot at step ``k``.
    """
    m = nd - 1
    F[0, 0] = _t(G, K, 0, 0)
    for i in range(1, m):
        p = F[0, i - 1]
        if not (abs(p) > 0.0) or not math.isfinite(abs(p)):
            return i
        li = _t(G, K, i, i - 1) / p
        F[1, i] = li
        F[0, i] = _t(G, K, i, i) - li * _t(G, K, i - 1, i)
    p = F[0, m - 1]
    if not (abs(p) > 0.0) or not math.isfinite(abs(p)):
        return m
    w = F[2]
    for i in range(m):
        w[i] = 0.0
    w[0] = _t(G, K, 0, m)
    w[m - 1] += _t(G, K, m - 1, m)
    _tri_apply(G, K, F, w, m)
    s = _t(G, K, m, m) - _t(G, K, m, 0) * w[0] - _t(G, K, m, m - 1) * w[m - 1]
    if not (abs(s) > 0.0) or not math.isfinite(abs(s)):
        return nd
    F[3, 0] = s
    return 0


@inline_jit
def _tri_apply(G, K, F, x, m):
    """``x = A^-1 x`` in place for the first ``m`` rows, with :func:`cyclic_factor`'s
    factors of the tridiagonal block."""
    for i in range(1, m):
        x[i] -= F[1, i] * x[i - 1]
    x[m - 1] /= F[0, m - 1]
    for i in range(m - 2, -1, -1):
        x[i] = (x[i] - _t(G, K, i, i + 1) * x[i + 1]) / F[0, i]


@jit
def cyclic_solve(G, K, F, x, nd):
    """Solve ``(I + G diag(K)) x = b`` in place (``x`` holds ``b``) with the factors of
    :func:`cyclic_factor`."""
    m = nd - 1
    _tri_apply(G, K, F, x, m)
    xl = (x[m] - _t(G, K, m, 0) * x[0] - _t(G, K, m, m - 1) * x[m - 1]) / F[3, 0]
    x[m] = xl
    for i in range(m):
        x[i] -= F[2, i] * xl


@jit
def cyclic_solve_transposed(G, K, F, b, nd):
    """Solve ``(I + G diag(K))^T x = b`` in place with the factors of
    :func:`cyclic_factor`: the last unknown from the transposed Schur complement (the
    same ``s``), then ``A^T = U^T L^T`` forward and back."""
    m = nd - 1
    acc = b[m]
    for i in range(m):
        acc -= F[2, i] * b[i]
    xl = acc / F[3, 0]
    b[m] = xl
    b[0] -= _t(G, K, m, 0) * xl
    b[m - 1] -= _t(G, K, m, m - 1) * xl
    b[0] /= F[0, 0]
    for i in range(1, m):
        b[i] = (b[i] - _t(G, K, i - 1, i) * b[i - 1]) / F[0, i]
    for i in range(m - 2, -1, -1):
        b[i] -= F[1, i + 1] * b[i + 1]


@jit
def cyclic_factor_stable(G, K, F, nd):
    """:func:`cyclic_factor` with the chain's guard (:func:`tri_factor`): False (use
    pivoting instead) also at a pivot small against its row."""
    if cyclic_factor(G, K, F, nd) != 0:
        return False
    for i in range(nd - 1):
        if not (abs(F[0, i]) > 1e-10 * (1.0 + abs(G[i, i] * K[i]))):
            return False
    return abs(F[3, 0]) > 1e-10 * (1.0 + abs(G[nd - 1, nd - 1] * K[nd - 1]))


@jit
def banded(G, gr, nd):
    """How the searches solve with ``I + G diag(K)``: 1 a chain (:func:`tri_factor`),
    2 a ring (:func:`cyclic_factor`), 0 neither (dense LU)."""
    if is_tridiagonal(gr, nd):
        return 1
    return 2 if is_cyclic(G, nd) else 0


@jit
def ridge_solve(A, L, b, x, m, first, growth, attempts):
    """``x = (A + ridge I)^-1 b`` for real symmetric ``A`` (m, m) by Cholesky into ``L``,
    with the smallest ``ridge`` of ``0, first max|A_jj|, growth`` times that, ... (at most
    ``attempts`` tries) that makes the matrix positive definite; ``b`` is overwritten.
    Returns False if none does."""
    scale = 0.0
    for j in range(m):
        scale = max(scale, abs(A[j, j]))
    ridge = 0.0
    ok = False
    for attempt in range(attempts):
        ok = True
        for j in range(m):
            d = A[j, j] + ridge
            for k in range(j):
                d -= L[j, k] ** 2
            if not d > 0.0:
                ok = False
                break
            d = math.sqrt(d)
            L[j, j] = d
            for i in range(j + 1, m):
                acc = A[i, j]
                for k in range(j):
                    acc -= L[i, k] * L[j, k]
                L[i, j] = acc / d
        if ok:
            break
        ridge = first * scale if ridge == 0.0 else growth * ridge
    if not ok:
        return False
    for i in range(m):
        acc = b[i]
        for k in range(i):
            acc -= L[i, k] * b[k]
        b[i] = acc / L[i, i]
    for i in range(m - 1, -1, -1):
        acc = b[i]
        for k in range(i + 1, m):
            acc -= L[k, i] * x[k]
        x[i] = acc / L[i, i]
    return True
