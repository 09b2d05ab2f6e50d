"""Small dense and tridiagonal solves for the Newton kernel.

Every routine works in place and returns an info code instead of raising:
0 = success, k > 0 = zero or non-finite pivot at step k (1-based), as LAPACK does.
"""

import math

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


@inline_jit
def cinv(z):
    """``1/z`` as ``conj(z)/|z|^2``: one real division instead of numba's scaled complex one."""
    r = 1.0 / (z.real * z.real + z.imag * z.imag)
    return complex(z.real * r, -z.imag * r)


@inline_jit
def tridiag_solve(lower, diag, upper, rhs, n):
    """Thomas algorithm (no pivoting) for a tridiagonal complex system, in place.

    Row ``i`` reads ``lower[i] x[i-1] + diag[i] x[i] + upper[i] x[i+1] = rhs[i]``
    (``lower[0]`` and ``upper[n-1]`` are ignored). ``diag`` is overwritten with the
    reciprocals of the eliminated pivots and ``rhs`` with the solution.

    Returns
    -------
    int
        0 on success, ``i + 1`` if pivot ``i`` is zero or not finite (the caller then
        falls back to :func:`lu_factor`, which pivots).
    """
    for i in range(n):
        if i > 0:
            m = lower[i] * diag[i - 1]
            diag[i] -= m * upper[i - 1]
            rhs[i] -= m * rhs[i - 1]
        d = diag[i]
        a2 = d.real * d.real + d.imag * d.imag
        if not (a2 > 0.0 and a2 < math.inf):
            return i + 1
        diag[i] = cinv(d)
    rhs[n - 1] *= diag[n - 1]
    for i in range(n - 2, -1, -1):
        rhs[i] = (rhs[i] - upper[i] * rhs[i + 1]) * diag[i]
    return 0


@inline_jit
def block2_tridiag_solve(L, D, U, r, n):
    """Block-tridiagonal solve with real 2x2 blocks (block Thomas, no block pivoting).

    Block row ``i``: ``L[i] x[i-1] + D[i] x[i] + U[i] x[i+1] = r[i]`` with
    ``L, D, U`` of shape (n, 2, 2) and ``r`` of shape (n, 2); ``D`` and ``r`` are
    overwritten (``r`` becomes the solution).

    Returns
    -------
    int
        0 on success, ``i + 1`` if block pivot ``i`` is singular or not finite.
    """
    for i in range(n):
        if i > 0:
            # D[i] -= L[i] @ X[i-1] with X[i-1] = inv(D[i-1]) U[i-1], stored in U[i-1]
            l00 = L[i, 0, 0]
            l01 = L[i, 0, 1]
            l10 = L[i, 1, 0]
            l11 = L[i, 1, 1]
            x00 = U[i - 1, 0, 0]
            x01 = U[i - 1, 0, 1]
            x10 = U[i - 1, 1, 0]
            x11 = U[i - 1, 1, 1]
            D[i, 0, 0] -= l00 * x00 + l01 * x10
            D[i, 0, 1] -= l00 * x01 + l01 * x11
            D[i, 1, 0] -= l10 * x00 + l11 * x10
            D[i, 1, 1] -= l10 * x01 + l11 * x11
            r[i, 0] -= l00 * r[i - 1, 0] + l01 * r[i - 1, 1]
            r[i, 1] -= l10 * r[i - 1, 0] + l11 * r[i - 1, 1]
        d00 = D[i, 0, 0]
        d01 = D[i, 0, 1]
        d10 = D[i, 1, 0]
        d11 = D[i, 1, 1]
        det = d00 * d11 - d01 * d10
        scale = abs(d00) + abs(d01) + abs(d10) + abs(d11)
        if not (abs(det) > 1e-300 * scale * scale) or not math.isfinite(det):
            return i + 1
        inv = 1.0 / det
        # y[i] = inv(D[i]) r[i]
        y0 = (d11 * r[i, 0] - d01 * r[i, 1]) * inv
        y1 = (d00 * r[i, 1] - d10 * r[i, 0]) * inv
        r[i, 0] = y0
        r[i, 1] = y1
        if i < n - 1:
            u00 = U[i, 0, 0]
            u01 = U[i, 0, 1]
            u10 = U[i, 1, 0]
            u11 = U[i, 1, 1]
            U[i, 0, 0] = (d11 * u00 - d01 * u10) * inv
            U[i, 0, 1] = (d11 * u01 - d01 * u11) * inv
            U[i, 1, 0] = (d00 * u10 - d10 * u00) * inv
            U[i, 1, 1] = (d00 * u11 - d10 * u01) * inv
    for i in range(n - 2, -1, -1):
        r[i, 0] -= U[i, 0, 0] * r[i + 1, 0] + U[i, 0, 1] * r[i + 1, 1]
        r[i, 1] -= U[i, 1, 0] * r[i + 1, 0] + U[i, 1, 1] * r[i + 1, 1]
    return 0
