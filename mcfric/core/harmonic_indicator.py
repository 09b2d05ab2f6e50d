"""A-posteriori indicator of the higher-harmonic content of single-harmonic points.

For a converged single-harmonic point, each slipping damper's force has 3rd and 5th
harmonics (closed form: :func:`mcfric.core.friction.higher_harmonics`), which drive the
beams at ``3 omega`` and ``5 omega``. Without their phases (only the slip ratios are kept)
the output harmonics they cause, to first order, are bounded by the triangle inequality::

    |y_3b| <= |D21_b(3 omega)| sum_{j at beam b} |F_3j|,   |F_nj| = kc_j A_j |F_n / (kc A)|(s_j)

with ``A_j = mu0_j N0_j / (kc_j s_j)``. The indicator of a point is
``max_b (|y_3b| + |y_5b|) / max_b |y_1b|``: the higher harmonics at the output relative
to the largest fundamental. The triangle inequality takes the worst phases, but the
feedback of the harmonics on the fundamental is ignored: an estimate, not a bound (it
can lie below the harmonics a time integration finds). The docs (harmonics, "When one
harmonic is not enough") give its measured quality against multi-harmonic solutions.
"""

import math

import numpy as np
from numba import prange

from ._jit import jit
from .friction import higher_harmonics


@jit(parallel=True, nogil=True)
def harmonic_indicator(h3, h5, a, b, mu0, N0, kc, s, y, out):
    """Indicator of every point.

    Parameters
    ----------
    h3, h5 : ndarray, shape (n_r, n_f, n_beams)
        ``|D21(3 omega)|`` and ``|D21(5 omega)|`` per beam (output to contact), m/N;
        ``n_r`` is 1 or n_s.
    a, b : ndarray of int64, shape (nd,)
        Beams of each damper.
    mu0, N0, kc : ndarray, shape (n_s, nd)
        Damper parameters.
    s : ndarray, shape (n_s, n_f, nd)
        Slip ratios of the solution (NaN where not converged).
    y : ndarray of complex, shape (n_s, n_f, n_beams)
        Output displacement (fundamental), m.
    out : ndarray, shape (n_s, n_f)
        Out: the indicator (-), NaN where the point did not converge, inf where the
        outputs have higher harmonics but no fundamental.
    """
    n_s, n_f, nd = s.shape
    n_beams = y.shape[2]
    for i in prange(n_s):
        r = 0
        if h3.shape[0] > 1:        # per-sample receptances (mistuned rigs)
            r = np.int64(i)
        f3 = np.zeros(n_beams)
        f5 = np.zeros(n_beams)
        for k in range(n_f):
            for bb in range(n_beams):
                f3[bb] = 0.0
                f5[bb] = 0.0
            bad = False
            for j in range(nd):
                sj = s[i, k, j]
                if math.isnan(sj):
                    bad = True
                    break
                if not 0.0 < sj < 1.0:
                    continue
                g3, g5 = higher_harmonics(sj)
                scale = mu0[i, j] * N0[i, j] / sj       # kc A = mu0 N0 / s
                m3 = scale * math.sqrt(g3.real * g3.real + g3.imag * g3.imag)
                m5 = scale * math.sqrt(g5.real * g5.real + g5.imag * g5.imag)
                f3[a[j]] += m3
                f3[b[j]] += m3
                f5[a[j]] += m5
                f5[b[j]] += m5
            big = 0.0
            high = 0.0
            for bb in range(n_beams):
                v = y[i, k, bb]
                a2 = v.real * v.real + v.imag * v.imag
                bad = bad or math.isnan(a2)     # max() would drop a NaN
                big = max(big, a2)
                high = max(high, h3[r, k, bb] * f3[bb] + h5[r, k, bb] * f5[bb])
            big = math.sqrt(big)
            if bad:
                out[i, k] = math.nan
            elif big > 0.0:
                out[i, k] = high / big
            else:
                # no fundamental at any output: harmonics there are infinitely many
                # times it (0 said there were none)
                out[i, k] = math.inf if high > 0.0 else 0.0
