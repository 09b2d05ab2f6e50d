"""The admissible set and a beam's response as quadratic forms in the damper forces.

With every damper force ``p`` as the variable, ``q = q0 - G p`` and ``y_b = ylin_b -
H_b p`` are affine, and ``K_j = p_j / q_j`` lies in damper ``j``'s rectangle ``[Re lo_j,
Re hi_j] x [Im lo_j, Im hi_j]`` (the box ``[0, kr] x [0, ki]``, or a part of it) and in
the rectangle's circumscribed disc (centre ``m``, radius ``rho``), with ``|p_j| <=
s_j``, if and only if (for ``q_j != 0``)

    Re(p_j conj q_j) - Re lo_j |q_j|^2 >= 0,   Re hi_j |q_j|^2 - Re(p_j conj q_j) >= 0,
    Im(p_j conj q_j) - Im lo_j |q_j|^2 >= 0,   Im hi_j |q_j|^2 - Im(p_j conj q_j) >= 0,
    rho^2 |q_j|^2 - |p_j - m q_j|^2 >= 0,      s_j^2 - |p_j|^2 >= 0.

(The disc is implied by the box; it is kept because relaxations are tighter with it.)
``s_j`` is damper ``j``'s force limit: ``F_lim``, or a smaller proven bound of ``|p_j|``
over the admissible set. In the real coordinates ``x_j = (Re p_j, Im p_j) / s_j`` (each in
[-1, 1] under the force limit) each is ``z^T M z`` with ``z = (x, 1)``.
"""

import numpy as np

from ._jit import jit

#: Forms per damper: the four box sides, the disc and the force limit.
PER_DAMPER = 6


@jit
def admissible_forms(G, q0, lo, hi, scale, Mc):
    """Fill ``Mc`` (``PER_DAMPER`` nd, 2 nd + 1, 2 nd + 1) with the forms of every damper
    (in the order of the module docstring), each scaled to a largest entry of 1;
    ``lo``, ``hi`` (nd,; complex, N/m) are the corners of each damper's rectangle and
    ``scale`` (nd,; N) holds the force limits ``s_j``."""
    nd = q0.shape[0]
    n = 2 * nd + 1
    al = np.zeros(n, np.complex128)
    be = np.zeros(n, np.complex128)
    Mc[:] = 0.0
    for j in range(nd):
        lr, li, hr, hi_ = lo[j].real, lo[j].imag, hi[j].real, hi[j].imag
        m = 0.5 * (lo[j] + hi[j])
        rho2 = 0.25 * ((hr - lr) * (hr - lr) + (hi_ - li) * (hi_ - li))
        # p_j = al . z and q_j = be . z
        al[:] = 0.0
        al[j] = scale[j]
        al[nd + j] = 1j * scale[j]
        for k in range(nd):
            be[k] = -G[j, k] * scale[k]
            be[nd + k] = -1j * G[j, k] * scale[k]
        be[n - 1] = q0[j]
        c = PER_DAMPER * j
        for a in range(n):
            for b in range(n):
                # p conj(q), |q|^2 and |p - m q|^2, each symmetrised
                pq = 0.5 * (al[a] * be[b].conjugate() + al[b] * be[a].conjugate())
                qq = be[a].real * be[b].real + be[a].imag * be[b].imag
                da = al[a] - m * be[a]
                db = al[b] - m * be[b]
                Mc[c, a, b] = pq.real - lr * qq
                Mc[c + 1, a, b] = hr * qq - pq.real
                Mc[c + 2, a, b] = pq.imag - li * qq
                Mc[c + 3, a, b] = hi_ * qq - pq.imag
                Mc[c + 4, a, b] = rho2 * qq - (da.real * db.real + da.imag * db.imag)
        Mc[c + 5, n - 1, n - 1] = 1.0
        Mc[c + 5, j, j] = -1.0
        Mc[c + 5, nd + j, nd + j] = -1.0
        for i in range(5):
            s = np.abs(Mc[c + i]).max()
            if s > 0.0:
                Mc[c + i] /= s


@jit
def response_form(ylin, H, scale, beam, My):
    """Fill ``My`` (2 nd + 1, 2 nd + 1) with ``|y_b|^2`` (m^2) of beam ``beam`` in the
    coordinates of ``scale`` (nd,; N)."""
    nd = H.shape[1]
    n = 2 * nd + 1
    ga = np.zeros(n, np.complex128)
    for j in range(nd):
        ga[j] = -H[beam, j] * scale[j]
        ga[nd + j] = -1j * H[beam, j] * scale[j]
    ga[n - 1] = ylin[beam]
    for a in range(n):
        for b in range(n):
            My[a, b] = ga[a].real * ga[b].real + ga[a].imag * ga[b].imag
