"""Describing function of Coulomb friction in series with a tangential stiffness.

physics.md section 2 (paper Eq. 2-5). With ``s = mu0 N0 / (kc A)``:

* ``0 < s < 1`` (partial slip):
  ``Re K = kc/pi (arccos(1-2s) - 2(1-2s) sqrt(s(1-s)))``, ``Im K = 4 kc/pi s(1-s)``;
* ``s >= 1`` (stuck): ``K = kc``;
* ``s = 0`` (gross slip, zero friction limit or infinite amplitude): ``K = 0``.

``K`` is continuous at ``s = 1``; ``Re K`` is C1 there, ``Im K`` has a kink. The functions
below work with the normalised ``kappa = K / kc`` so that one evaluation serves any ``kc``.
"""

import math

import numpy as np

from ._jit import inline_jit, jit

_INV_PI = 1.0 / math.pi
# Below this s, Re K comes from a series (u = 4 asin(sqrt s) < 0.57, truncation < 1e-16
# relative); above, the closed form loses at most eps / (4 s) ~ 1e-14 relative.
_SMALL_S = 0.02


@inline_jit
def _re_kappa(s, r):
    """``Re K / kc`` for ``0 < s < 1`` given ``r = sqrt(s (1 - s))``."""
    if s < _SMALL_S:
        # arccos(1-2s) - 2(1-2s)sqrt(s(1-s)) = (u - sin u)/2 with u = 4 asin(sqrt s):
        # the closed form cancels to ~s^1.5 here, so sum the series of u - sin u instead
        u = 4.0 * math.asin(math.sqrt(s))
        u2 = u * u
        series = u * u2 / 6.0 * (1.0 - u2 / 20.0 * (1.0 - u2 / 42.0 * (1.0 - u2 / 72.0 * (
            1.0 - u2 / 110.0 * (1.0 - u2 / 156.0)))))
        return 0.5 * _INV_PI * series
    t = 1.0 - 2.0 * s
    return _INV_PI * (math.acos(t) - 2.0 * t * r)


@inline_jit
def kappa(s):
    """Normalised describing function ``K / kc`` at slip ratio ``s``.

    Parameters
    ----------
    s : float
        Slip ratio ``mu0 N0 / (kc A)``, dimensionless, ``s >= 0`` (``inf`` allowed).

    Returns
    -------
    complex
        ``K / kc``, dimensionless.
    """
    if s >= 1.0:
        return 1.0 + 0.0j
    if s <= 0.0:
        return 0.0j
    r = math.sqrt(s * (1.0 - s))
    return complex(_re_kappa(s, r), 4.0 * _INV_PI * s * (1.0 - s))


@inline_jit
def kappa_dlogs(s):
    """Derivative ``s d(K/kc)/ds`` = derivative of ``K/kc`` with respect to ``log s``.

    Zero in the stuck region ``s > 1``; at ``s = 1`` exactly it is the slip-side (left)
    derivative ``-4i/pi``, so a damper parked at the stick limit can leave it.

    Parameters
    ----------
    s : float
        Slip ratio, dimensionless.

    Returns
    -------
    complex
        ``d(K/kc) / d(log s)``, dimensionless.
    """
    if s > 1.0 or s <= 0.0:
        return 0.0j
    return complex(8.0 * _INV_PI * s * math.sqrt(s * (1.0 - s)),
                   4.0 * _INV_PI * s * (1.0 - 2.0 * s))


@inline_jit
def kappa_slip(s):
    """``K / kc`` and its derivative with respect to ``log s`` in partial slip, sharing a sqrt.

    Parameters
    ----------
    s : float
        Slip ratio, dimensionless, ``0 < s < 1``.

    Returns
    -------
    (complex, complex)
        ``K / kc`` and ``d(K/kc)/d(log s)``, dimensionless.
    """
    r = math.sqrt(s * (1.0 - s))
    return (complex(_re_kappa(s, r), 4.0 * _INV_PI * s * (1.0 - s)),
            complex(8.0 * _INV_PI * s * r, 4.0 * _INV_PI * s * (1.0 - 2.0 * s)))


@inline_jit
def kappa_logs(x):
    """``K / kc`` and its derivative with respect to ``x = log s``, sharing one exp and sqrt.

    Parameters
    ----------
    x : float
        ``log s``; ``x >= 0`` is the stuck region (at ``x = 0`` the derivative is the
        slip-side one, as in :func:`kappa_dlogs`).

    Returns
    -------
    (complex, complex)
        ``K / kc`` and ``d(K/kc)/dx``, dimensionless.
    """
    if x > 0.0:
        return 1.0 + 0.0j, 0.0j
    if x == 0.0:
        return 1.0 + 0.0j, complex(0.0, -4.0 * _INV_PI)
    s = math.exp(x)
    if s <= 0.0:
        return 0.0j, 0.0j
    return kappa_slip(s)


@jit
def describing_function(s, kc):
    """Describing function ``K(s)`` in N/m (complex; Re = stiffness, Im = dissipation).

    Parameters
    ----------
    s : ndarray of float
        Slip ratios ``mu0 N0 / (kc A)``, dimensionless, ``>= 0``.
    kc : float
        Tangential (contact) stiffness, N/m.

    Returns
    -------
    ndarray of complex, same shape as ``s``
        ``K`` in N/m.
    """
    out = np.empty(s.shape, dtype=np.complex128)
    sf = s.ravel()
    of = out.ravel()
    for i in range(sf.size):
        of[i] = kc * kappa(sf[i])
    return out


@jit
def describing_function_derivative(s, kc):
    """``dK/ds`` in N/m: ``kc/pi (8 sqrt(s(1-s)) + 4i (1-2s))`` for ``0 < s <= 1``, else 0.

    Parameters
    ----------
    s : ndarray of float
        Slip ratios, dimensionless.
    kc : float
        Tangential stiffness, N/m.

    Returns
    -------
    ndarray of complex, same shape as ``s``
        ``dK/ds`` in N/m (the slip-side derivative at ``s = 1``).
    """
    out = np.empty(s.shape, dtype=np.complex128)
    sf = s.ravel()
    of = out.ravel()
    for i in range(sf.size):
        si = sf[i]
        of[i] = kc * kappa_dlogs(si) / si if si > 0.0 else complex(0.0, 4.0 * _INV_PI * kc)
    return out
