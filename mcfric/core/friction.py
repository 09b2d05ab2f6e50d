"""Describing function of Coulomb friction in series with a tangential stiffness.

Paper Eq. 2-5; the docs' theory page, section "Describing function". With ``s = mu0 N0 / (kc A)``:

* ``0 < s < 1`` (partial slip):
  ``Re K = kc/pi (arccos(1-2s) - 2(1-2s) sqrt(s(1-s)))``, ``Im K = 4 kc/pi s(1-s)``;
* ``s >= 1`` (stuck): ``K = kc``;
* ``s = 0`` (gross slip, zero friction limit or infinite amplitude): ``K = 0``.

``K`` is continuous at ``s = 1``; ``Re K`` is C1 there, ``Im K`` has a kink. The functions
below work with the normalised ``kappa = K / kc`` so that one evaluation serves any ``kc``.
"""

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.core.extending import intrinsic

from ._jit import inline_jit, jit

_INV_PI = 1.0 / math.pi
# Below this s, Re K comes from a series (u = 4 asin(sqrt s) < 0.57, truncation < 1e-16
# relative); above, the closed form loses at most eps / (4 s) ~ 1e-14 relative.
_SMALL_S = 0.02


# asin(x) = x + x R(x^2) for |x| <= 0.5, R a rational function (fdlibm's e_asin.c, < 1 ulp)
_PS0 = 1.66666666666666657415e-01
_PS1 = -3.25565818622400915405e-01
_PS2 = 2.01212532134862925881e-01
_PS3 = -4.00555345006794114027e-02
_PS4 = 7.91534994289814532176e-04
_PS5 = 3.47933107596021167570e-05
_QS1 = -2.40339491173441421878e+00
_QS2 = 2.02094576023350569471e+00
_QS3 = -6.88283971605453293030e-01
_QS4 = 7.70381505559019352791e-02
_PIO2_HI = 1.57079632679489655800e+00
_PIO2_LO = 6.12323399573676603587e-17
_PI = 3.14159265358979311600e+00


@inline_jit
def _asin_r(z):
    """``R(z)`` of ``asin(x) = x + x R(x^2)``, for ``0 <= z <= 1/4``."""
    p = z * (_PS0 + z * (_PS1 + z * (_PS2 + z * (_PS3 + z * (_PS4 + z * _PS5)))))
    q = 1.0 + z * (_QS1 + z * (_QS2 + z * (_QS3 + z * _QS4)))
    return p / q


@inline_jit
def _acos_1m2s(s):
    """``arccos(1 - 2 s)`` for ``0 <= s <= 1``, inline (no libm call; a few ulp).

    Each branch evaluates the asin kernel on ``[0, 1/4]`` from a quantity known exactly:
    ``2 asin(sqrt s)``, ``pi/2 - asin(1 - 2s)`` and ``pi - 2 asin(sqrt(1 - s))``.
    """
    if s < 0.25:
        w = math.sqrt(s)
        return 2.0 * (w + w * _asin_r(s))
    if s <= 0.75:
        t = 1.0 - 2.0 * s
        return _PIO2_HI - (t - (_PIO2_LO - t * _asin_r(t * t)))
    z = 1.0 - s
    w = math.sqrt(z)
    return _PI - 2.0 * (w + (w * _asin_r(z) - _PIO2_LO))


@inline_jit
def _re_kappa(s, r):
    """``Re K / kc`` for ``0 < s < 1`` given ``r = sqrt(s (1 - s))``."""
    a = _acos_1m2s(s)               # once: each copy is inlined wherever K is (compile time)
    if s < _SMALL_S:
        # arccos(1-2s) - 2(1-2s)sqrt(s(1-s)) = (u - sin u)/2 with u = 4 asin(sqrt s):
        # the closed form cancels to ~s^1.5 here, so sum the series of u - sin u instead
        u = 2.0 * a
        u2 = u * u
        series = u * u2 / 6.0 * (1.0 - u2 / 20.0 * (1.0 - u2 / 42.0 * (1.0 - u2 / 72.0 * (
            1.0 - u2 / 110.0 * (1.0 - u2 / 156.0)))))
        return 0.5 * _INV_PI * series
    t = 1.0 - 2.0 * s
    return _INV_PI * (a - 2.0 * t * r)


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


#: Contact laws of the dense solvers: Coulomb friction in series with a stiffness (the
#: paper's, and the only one of the fast kernels), and a stiffening spring used to test
#: the detection of multiple steady states.
LAW_COULOMB = 0
LAW_CUBIC = 1


@inline_jit
def kappa_law_logs(x, law):
    """``K / kc`` and ``d(K/kc)/d(log s)`` of the contact law ``law``.

    ``LAW_COULOMB``: :func:`kappa_logs`. ``LAW_CUBIC``: the describing function of a
    spring ``f = kc (z + z^3 / (0.75 a^2))``, ``K = kc (1 + (A / a)^2)`` with
    ``a = mu0 N0 / kc`` (so ``A / a = 1 / s``): real, stiffening, no dissipation.
    """
    if law == LAW_COULOMB:
        return kappa_logs(x)
    e = math.exp(-2.0 * x)
    return complex(1.0 + e, 0.0), complex(-2.0 * e, 0.0)


@inline_jit
def higher_harmonics(s):
    """3rd and 5th harmonics of the force of a sinusoidally driven Jenkins element.

    For ``q = A cos(theta)`` and slip ratio ``s = mu0 N0 / (kc A)``, the periodic force's
    harmonics ``F_n = (1/pi) integral f e^{-i n theta}`` divided by ``kc A``. Closed form
    of the stick-slip loop (stick from the maximum of ``q`` until
    ``cos theta* = 1 - 2 s``, then slip): with ``I_p = integral_0^theta* e^{-i p theta}``,
    ``F_n / (kc A) = (2/pi) ((2 s - 1) I_n + (I_{n-1} + I_{n+1}) / 2 - 2 s / (i n))``.
    The powers of ``e^{-i theta*} = 1 - 2 s - 2 i sqrt(s (1 - s))`` need no trig call.
    For ``q = A cos(theta + phi)`` multiply by ``e^{i n phi}``.

    Parameters
    ----------
    s : float
        Slip ratio, dimensionless (>= 1 or <= 0: no higher harmonics).

    Returns
    -------
    (complex, complex)
        ``F_3 / (kc A)`` and ``F_5 / (kc A)``, dimensionless.
    """
    if s >= 1.0 or s <= 0.0:
        return 0.0j, 0.0j
    e1 = complex(1.0 - 2.0 * s, -2.0 * math.sqrt(s * (1.0 - s)))
    e2 = e1 * e1
    e3 = e2 * e1
    e4 = e2 * e2
    e5 = e4 * e1
    e6 = e3 * e3
    # I_p = (1 - e^{-i p theta*}) / (i p) = -i (1 - e^{-i p theta*}) / p (no complex division)
    mi = -1.0j
    i2 = mi * (1.0 - e2) * 0.5
    i3 = mi * (1.0 - e3) * (1.0 / 3.0)
    i4 = mi * (1.0 - e4) * 0.25
    i5 = mi * (1.0 - e5) * 0.2
    i6 = mi * (1.0 - e6) * (1.0 / 6.0)
    c = 2.0 * _INV_PI
    t = 2.0 * s - 1.0
    f3 = c * (t * i3 + 0.5 * (i2 + i4) + complex(0.0, 2.0 * s / 3.0))
    f5 = c * (t * i5 + 0.5 * (i4 + i6) + complex(0.0, 2.0 * s / 5.0))
    return f3, f5


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


# --- a branch-free natural logarithm, for loops over lanes that LLVM vectorises ---

@intrinsic
def _bits(typingctx, x):
    """The IEEE-754 bits of a float64 as an int64 (no conversion)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))
    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, n):
    """The float64 whose IEEE-754 bits are the int64 ``n``."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())
    return types.float64(types.int64), codegen


# log(1 + f) = 2 s + s R(s^2), s = f / (2 + f), for 1 + f in [sqrt(2)/2, sqrt(2)):
# fdlibm's e_log.c (< 1 ulp)
_LN2_HI = 6.93147180369123816490e-01
_LN2_LO = 1.90821492927058770002e-10
_LG1 = 6.666666666666735130e-01
_LG2 = 3.999999999940941908e-01
_LG3 = 2.857142874366239149e-01
_LG4 = 2.222219843214978396e-01
_LG5 = 1.818357216161805012e-01
_LG6 = 1.531383769920937332e-01
_LG7 = 1.479819860511658591e-01
#: Smallest positive normal float64: :func:`log_normal` needs ``MIN_NORMAL <= x < inf``.
MIN_NORMAL = 2.2250738585072014e-308


@inline_jit
def log_normal(x):
    """``log(x)`` without branches or calls, for normal finite ``x > 0`` only.

    fdlibm's algorithm (within 1 ulp of the C library's ``log``, tested on dense grids)
    with the exponent split off by integer operations on the bits, so that a loop over
    lanes compiles to SIMD code; the C library's ``log`` is a call per element. Any other
    ``x`` (0, subnormal, inf, NaN, negative) gives a meaningless number: callers test
    ``MIN_NORMAL <= x < inf`` themselves.

    Parameters
    ----------
    x : float
        Argument, ``MIN_NORMAL <= x < inf``.

    Returns
    -------
    float
        ``log(x)``.
    """
    hx = _bits(x)
    m = hx & 0x000fffffffffffff
    # a mantissa above sqrt(2) is halved and its exponent raised: 1 + f in [0.707, 1.414)
    i = (m + 0x95f6400000000) & 0x10000000000000
    # the exponent as a float without int -> float conversion (none in AVX2): 2^52 + e
    # has the bits 0x4330000000000000 | e
    dk = (_from_bits(((hx >> 52) + (i >> 52)) | 0x4330000000000000) - 4503599627370496.0
          - 1023.0)
    f = _from_bits(m | (i ^ 0x3ff0000000000000)) - 1.0
    s = f / (2.0 + f)
    z = s * s
    w = z * z
    t1 = w * (_LG2 + w * (_LG4 + w * _LG6))
    t2 = z * (_LG1 + w * (_LG3 + w * (_LG5 + w * _LG7)))
    r = t2 + t1
    hfsq = 0.5 * f * f
    return dk * _LN2_HI - ((hfsq - (s * (hfsq + r) + dk * _LN2_LO)) - f)
