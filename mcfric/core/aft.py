"""Alternating frequency-time (AFT) evaluation of a Jenkins friction element.

The Jenkins element is a spring ``kc`` in series with a Coulomb slider that slips at the
force ``fs = mu0 N0``. Given the harmonics of the relative contact displacement::

    q(theta) = Re sum_h Q_h exp(i n_h theta),   theta = omega t,  n_h odd orders,

it returns the same harmonics of the periodic friction force, ``F_h = (1/pi) integral
f(theta) exp(-i n_h theta) dtheta`` over one period, and their exact derivatives with respect
to ``(Re Q_m, Im Q_m)``.

Event-located AFT
-----------------
``n_time`` samples per period only *bracket* the events: the extrema of ``q`` (where a slip
ends and the slider sticks; sign changes of ``q'``, and pairs of extrema between two
samples where ``q''`` changes sign and ``q'`` may dip through zero) and the crossings where
the spring force reaches ``+-fs`` (where a stick ends). Each event is then located by a
safeguarded Newton iteration on the trigonometric polynomial. Between events the force is
either constant (slip) or ``f_a + kc (q - q_a)`` (stick, anchored at the last reversal),
so its Fourier integrals are evaluated in closed form. The result is exact up to the event
tolerance: with one harmonic it reproduces the describing function of
:mod:`mcfric.core.friction` to rounding, where a plain sampled AFT would carry an
``O(n_time^-2)`` error from the kinks of ``f``.

The periodic hysteresis loop needs no settling passes: the walk starts at the global
maximum of ``q``. If ``kc (q_max - q_min) > 2 fs`` the slider slips on the way up to
that maximum in every period, so the force there is exactly ``+fs``; otherwise it never
slips and ``f = kc (q - c)``, whose harmonics do not depend on the offset ``c``. One pass
from there is the periodic state.

With odd orders only, ``q(theta + pi) = -q(theta)``; the extrema, the events and the
periodic force are mirrored the same way, and ``f(theta) exp(-i n theta)`` has period
``pi`` for odd ``n``. So half a period is bracketed (``n_time`` rounded up to even),
located and integrated, from the global maximum to the global minimum, and the
integrals doubled.

Contact-law interface
---------------------
A contact law for the multi-harmonic kernel is a function
``law(Q, orders, kc, fs, n_time, F, dF, work) -> int`` with ``Q`` complex (n_h,),
``orders`` int64 (n_h,), outputs ``F`` complex (n_h,) in N and ``dF`` float64
(2 n_h, 2 n_h) in N/m (row ``2h`` / ``2h+1``: Re / Im of ``F_h``; column ``2m`` /
``2m+1``: Re / Im of ``Q_m``), ``work`` a float64 scratch array of :func:`work_size`, and
a return code (0 success, < 0 failure). :func:`jenkins` is the only law so far.
"""

import math

import numpy as np

from ._jit import inline_jit, jit

_TWO_OVER_PI = 2.0 / math.pi
_FOUR_OVER_PI = 4.0 / math.pi
#: Event location stops when the Newton step is below this, rad.
_THETA_TOL = 1e-13
_EVENT_ITER = 60
#: Where ``q'`` is 0 on a sample, the rest of the step is searched from this fraction of
#: a step away from it.
_EDGE = 1e-7
#: ``work[0:3]`` tags the sample table that follows: this value, ``n_time``, ``n_h``.
_TAG = -0.7853981633974483e-300
_TAG_SIZE = 3


@jit
def work_size(n_h, n_time):
    """Length of the float64 scratch array that :func:`jenkins` needs (orders ``2h+1``)."""
    n_half = (n_time + 1) // 2
    return _TAG_SIZE + (2 * n_h + 5) * n_half + 8 * (4 * n_h - 1) + 8


@inline_jit
def _q_derivs(Q, orders, n_h, th):
    """``q``, ``q'`` and ``q''`` at ``th`` (orders 1, 3, 5, ...: one sin/cos, then powers)."""
    e = complex(math.cos(th), math.sin(th))
    e2 = e * e
    p = e
    q = 0.0
    d1 = 0.0
    d2 = 0.0
    for h in range(n_h):
        n = orders[h]
        c = p.real
        s = p.imag
        re = Q[h].real
        im = Q[h].imag
        v = re * c - im * s
        q += v
        d1 += -n * (re * s + im * c)
        d2 += -n * n * v
        p *= e2
    return q, d1, d2


@jit
def _root(Q, orders, n_h, lo, hi, flo, fhi, level, deriv):
    """Root in ``[lo, hi]`` of ``g - level`` (``g = q'`` if ``deriv`` else ``q``), which
    changes sign on the bracket (``flo``, ``fhi``: its values at the ends): Newton from
    the secant point, kept inside the bracket, bisection when it would leave it."""
    th = lo + (hi - lo) * flo / (flo - fhi)
    if not (lo < th < hi):
        th = 0.5 * (lo + hi)
    for _ in range(_EVENT_ITER):
        q, d1, d2 = _q_derivs(Q, orders, n_h, th)
        g = (d1 if deriv else q) - level
        dg = d2 if deriv else d1
        if g == 0.0:
            return th
        if (g > 0.0) == (flo > 0.0):
            lo = th
        else:
            hi = th
        if dg != 0.0:
            step = g / dg
            new = th - step
            if lo <= new <= hi:
                if abs(step) < _THETA_TOL:
                    return new
                th = new
                continue
        th = 0.5 * (lo + hi)
        if hi - lo < _THETA_TOL:
            return th
    return th


@jit
def _zeros_between(Q, orders, n_h, lo, hi, g0, g1, d0, d1):
    """Zeros of ``q'`` inside ``(lo, hi)`` from its values ``g0``, ``g1`` (nonzero) and
    ``q''``'s ``d0``, ``d1`` at the ends: one where ``q'`` changes sign; where it keeps
    its sign but turns between them, the pair of :func:`_close_pair` if it may dip
    through zero. Returns ``(th1, th2, count)``."""
    if g0 == 0.0 or g1 == 0.0:
        return lo, hi, 0                    # a double zero: a loop of zero size
    if (g0 > 0.0) != (g1 > 0.0):
        return _root(Q, orders, n_h, lo, hi, g0, g1, 0.0, np.bool_(True)), hi, 1
    if (d0 > 0.0) != (d1 > 0.0):
        # its value at the turn, with q'' linear over the step, decides whether to look
        # (the estimate errs by O(step^3): looked at below half of the ends' values too)
        est = g0 + 0.5 * d0 * (hi - lo) * d0 / (d0 - d1)
        if (est > 0.0) != (g0 > 0.0) or abs(est) < 0.5 * min(abs(g0), abs(g1)):
            return _close_pair(Q, orders, n_h, lo, hi, g0, g1, d0, d1)
    return lo, hi, 0


@jit
def _close_pair(Q, orders, n_h, lo, hi, g0, g1, d_lo, d_hi):
    """Zeros of ``q'`` in ``[lo, hi]``, where it has the sign of ``g0`` at both ends and
    turns between them (``q''``: ``d_lo``, ``d_hi`` at the ends, changes sign): if it
    changes sign near the turn, a pair of extrema closer than the samples. Returns
    ``(th1, th2, count)``, count 0 or 2."""
    # the turn of q' by regula falsi on q'' (Illinois), stopping as soon as a point
    # with q' of the other sign splits the step in two brackets
    a = lo
    b = hi
    fa = d_lo
    fb = d_hi
    side = 0
    m_prev = lo
    for _ in range(_EVENT_ITER):
        m = (a * fb - b * fa) / (fb - fa)
        if not (a < m < b):
            m = 0.5 * (a + b)
        _, gm, dm = _q_derivs(Q, orders, n_h, m)
        if gm != 0.0 and (gm > 0.0) != (g0 > 0.0):
            return (_root(Q, orders, n_h, lo, m, g0, gm, 0.0, np.bool_(True)),
                    _root(Q, orders, n_h, m, hi, gm, g1, 0.0, np.bool_(True)), 2)
        if dm == 0.0 or abs(m - m_prev) < _THETA_TOL:
            break
        m_prev = m
        if (dm > 0.0) == (fa > 0.0):
            a = m
            fa = dm
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b = m
            fb = dm
            if side == 1:
                fa *= 0.5
            side = 1
    return lo, hi, 0            # q' keeps its sign through the turn (a touch: no loop)


@inline_jit
def _powers(th, p_max, zr, zi, o):
    """``exp(i p th)`` for ``p = 0..p_max`` into ``zr[o + p] + i zi[o + p]``."""
    c = math.cos(th)
    s = math.sin(th)
    zr[o] = 1.0
    zi[o] = 0.0
    for p in range(1, p_max + 1):
        # recurrence on the unit circle; p_max is a few tens, so rounding stays ~1e-15
        zr[o + p] = zr[o + p - 1] * c - zi[o + p - 1] * s
        zi[o + p] = zr[o + p - 1] * s + zi[o + p - 1] * c


@inline_jit
def _integral(p, a, b, zr, zi, oa, ob):
    """``integral_a^b exp(i p theta) dtheta`` from the powers at both ends (offsets
    ``oa``, ``ob`` in ``zr``, ``zi``; ``p`` may be negative: the conjugate powers)."""
    if p == 0:
        return complex(b - a, 0.0)
    m = abs(p)
    sgn = 1.0 if p > 0 else -1.0
    dr = zr[ob + m] - zr[oa + m]
    di = sgn * (zi[ob + m] - zi[oa + m])
    # (dr + i di) / (i p) = (di - i dr) / p
    inv = 1.0 / p
    return complex(di * inv, -dr * inv)


@jit
def _segment(Q, orders, n_h, a, b, stick, f_a, q_a, kc, fs_sign, F, dF, zr, zi, oa, ob,
             p_max, tr, ti):
    """Add twice one segment ``[a, b]`` of the half period to ``F`` and ``dF`` (the
    powers of ``exp(i a)``, ``exp(i b)`` at offsets ``oa``, ``ob``).

    Slip: ``f = fs_sign`` (the signed slip force). Stick: ``f = f_a + kc (q - q_a)``,
    anchored at ``a``, an extremum of ``q`` (so ``q'(a) = 0``: moving the anchor
    changes nothing to first order).
    """
    if b <= a:
        return
    if not stick:
        for h in range(n_h):
            F[h] += _TWO_OVER_PI * fs_sign * _integral(-orders[h], a, b, zr, zi, oa, ob)
        return
    # the integrals of exp(i p theta) for the even p = nm - n and -nm - n, once each
    # (index (p + p_max) / 2) instead of twice per pair of orders
    for t in range(p_max // 2 + n_h):
        v = _integral(2 * t - p_max, a, b, zr, zi, oa, ob)
        tr[t] = v.real
        ti[t] = v.imag
    for h in range(n_h):
        n = orders[h]
        e_n = _integral(-n, a, b, zr, zi, oa, ob)
        acc = (f_a - kc * q_a) * e_n
        for m in range(n_h):
            nm = orders[m]
            t1 = (nm - n + p_max) // 2
            t2 = (p_max - nm - n) // 2
            i1 = complex(tr[t1], ti[t1])
            i2 = complex(tr[t2], ti[t2])
            c_mn = 0.5 * (i1 + i2)                      # integral cos(nm th) e^{-i n th}
            d = i1 - i2
            s_mn = complex(0.5 * d.imag, -0.5 * d.real)  # integral sin(nm th) e^{-i n th}
            acc += kc * (Q[m].real * c_mn - Q[m].imag * s_mn)
            # exp(i nm a): the anchor's powers
            d_re = kc * _TWO_OVER_PI * (c_mn - zr[oa + nm] * e_n)
            d_im = kc * _TWO_OVER_PI * (-s_mn + zi[oa + nm] * e_n)
            dF[2 * h, 2 * m] += d_re.real
            dF[2 * h + 1, 2 * m] += d_re.imag
            dF[2 * h, 2 * m + 1] += d_im.real
            dF[2 * h + 1, 2 * m + 1] += d_im.imag
        F[h] += _TWO_OVER_PI * acc


@jit
def jenkins(Q, orders, kc, fs, n_time, F, dF, work):
    """Harmonics of a Jenkins element's force and their Jacobian, by event-located AFT.

    Parameters
    ----------
    Q : ndarray of complex128, shape (n_h,)
        Harmonics of the relative contact displacement, m.
    orders : ndarray of int64, shape (n_h,)
        Harmonic orders: exactly ``1, 3, ..., 2 n_h - 1`` (:func:`harmonic_orders`).
    kc : float
        Spring stiffness, N/m (>= 0).
    fs : float
        Slip force ``mu0 N0``, N (>= 0).
    n_time : int
        Samples per period that bracket the events (>= 4 max(orders)).
    F : ndarray of complex128, shape (n_h,)
        Out: force harmonics, N.
    dF : ndarray of float64, shape (2 n_h, 2 n_h)
        Out: derivatives of (Re F_h, Im F_h) with respect to (Re Q_m, Im Q_m), N/m.
    work : ndarray of float64, shape (work_size(n_h, n_time),)
        Scratch. Its head caches a table of the samples' cos and sin between calls,
        tagged with ``n_time`` and ``n_h`` and rebuilt when the tag does not match
        (any initial content is fine).

    Returns
    -------
    int
        Number of events on the loop (0: stuck throughout, or no force), or -1 if the
        extrema of ``q`` could not be bracketed (``n_time`` too small), ``work`` is too
        short, or a harmonic came out above ``4 fs / pi``, which no force bounded by
        ``fs`` has (a loop walked wrongly: a failure, not a number).
    """
    n_h = orders.shape[0]
    for h in range(n_h):
        F[h] = 0.0j
        for m in range(2 * n_h):
            dF[2 * h, m] = 0.0
            dF[2 * h + 1, m] = 0.0
    if work.shape[0] < work_size(n_h, n_time) or n_time < 4:
        return -1
    if not (kc > 0.0) or not (fs > 0.0):
        return 0
    # the range of q is at most 2 sum |Q_h|: stuck throughout if even that cannot slip
    bound = 0.0
    for h in range(n_h):
        bound += abs(Q[h])
    if kc * bound <= fs:
        for h in range(n_h):
            F[h] = kc * Q[h]
            dF[2 * h, 2 * h] = kc
            dF[2 * h + 1, 2 * h + 1] = kc
        return 0
    # odd orders only: q(th + pi) = -q(th), and so are the extrema, the events and the
    # periodic force; half a period is sampled, located and integrated, the rest mirrored
    n_half = (n_time + 1) // 2
    p_max = 2 * orders[n_h - 1]
    o = _TAG_SIZE + 2 * n_h * n_half
    ext = work[o:o + n_half]                # extrema angles in [0, pi)
    qe = work[o + n_half:o + 2 * n_half]    # q there
    dq = work[o + 2 * n_half:o + 3 * n_half]
    qs = work[o + 3 * n_half:o + 4 * n_half]
    d2q = work[o + 4 * n_half:o + 5 * n_half]
    o += 5 * n_half
    pw = p_max + 1
    zr = work[o:o + 3 * pw]                 # powers at three angles
    zi = work[o + 3 * pw:o + 6 * pw]
    tr = work[o + 6 * pw:o + 7 * pw]
    ti = work[o + 7 * pw:o + 8 * pw]
    # brackets of the extrema: sign changes of q' on the samples (and q there, for the
    # crossings). cos and sin of n_h theta_i are a table kept at the head of ``work``
    # (built when its tag does not match), so that the sums over the samples run in SIMD
    # lanes
    step = math.pi / n_half
    tab = work[_TAG_SIZE:_TAG_SIZE + 2 * n_h * n_half]
    if work[0] != _TAG or work[1] != n_time or work[2] != n_h:
        for h in range(n_h):
            for i in range(n_half):
                th = orders[h] * step * i
                tab[2 * h * n_half + i] = math.cos(th)
                tab[(2 * h + 1) * n_half + i] = math.sin(th)
        work[0] = _TAG
        work[1] = n_time
        work[2] = n_h
    for i in range(n_half):
        dq[i] = 0.0
        qs[i] = 0.0
        d2q[i] = 0.0
    for h in range(n_h):
        re = Q[h].real
        im = Q[h].imag
        a_c = -orders[h] * im
        a_s = -orders[h] * re
        n2 = -float(orders[h] * orders[h])
        c = tab[2 * h * n_half:(2 * h + 1) * n_half]
        sn = tab[(2 * h + 1) * n_half:(2 * h + 2) * n_half]
        for i in range(n_half):
            dq[i] += a_c * c[i] + a_s * sn[i]
            v = re * c[i] - im * sn[i]
            qs[i] += v
            d2q[i] += n2 * v
    m_ext = 0
    q_max = -math.inf
    i_max = -1
    for i in range(n_half):
        g0 = dq[i]
        g1 = dq[i + 1] if i + 1 < n_half else -dq[0]
        if g0 != 0.0 and g1 != 0.0 and (g0 > 0.0) != (g1 > 0.0):
            # the usual case: one extremum between the samples
            if m_ext >= n_half:
                return -1
            th = _root(Q, orders, n_h, step * i, step * (i + 1), g0, g1, 0.0,
                       np.bool_(True))
            ext[m_ext] = th
            qe[m_ext] = _q_derivs(Q, orders, n_h, th)[0]
            m_ext += 1
            continue
        d0 = d2q[i]
        d1 = d2q[i + 1] if i + 1 < n_half else -d2q[0]
        if g0 != 0.0 and g1 != 0.0 and (d0 > 0.0) == (d1 > 0.0):
            # q' and q'' keep their signs: no extremum seen (q'' changing sign twice
            # between the samples could hide a pair: the docs' harmonics page)
            continue
        lo = step * i
        hi = lo + step
        if g0 == 0.0:
            # an extremum on the sample itself: recorded, and the rest of the step looked
            # at from just after it (one on the upper sample is the next step's)
            if m_ext >= n_half:
                return -1
            ext[m_ext] = lo
            qe[m_ext] = _q_derivs(Q, orders, n_h, lo)[0]
            m_ext += 1
            lo += _EDGE * step
            _, g0, d0 = _q_derivs(Q, orders, n_h, lo)
        if g1 == 0.0:
            hi -= _EDGE * step
            _, g1, d1 = _q_derivs(Q, orders, n_h, hi)
        th, th2, n_r = _zeros_between(Q, orders, n_h, lo, hi, g0, g1, d0, d1)
        for r in range(n_r):
            if m_ext >= n_half:
                return -1
            ext[m_ext] = th if r == 0 else th2
            qe[m_ext] = _q_derivs(Q, orders, n_h, ext[m_ext])[0]
            m_ext += 1
    # the global maximum over the period: q at an extremum or -q half a period on
    for m in range(m_ext):
        q = qe[m]
        if q > q_max:
            q_max = q
            i_max = m
        if -q > q_max:
            q_max = -q
            i_max = m + n_half
    if m_ext == 0:
        # q constant (all Q zero): the element sticks, f = kc (q - c)
        for h in range(n_h):
            F[h] = kc * Q[h]
            dF[2 * h, 2 * h] = kc
            dF[2 * h + 1, 2 * h + 1] = kc
        for h in range(n_h):
            if Q[h] != 0.0:
                return -1
        return 0
    if kc * q_max <= fs:
        for h in range(n_h):
            F[h] = kc * Q[h]
            dF[2 * h, 2 * h] = kc
            dF[2 * h + 1, 2 * h + 1] = kc
        return 0
    # walk half a period from the global maximum to the global minimum, piece by monotone
    # piece; a stick phase keeps its anchor across reversals, so it is integrated as one
    # segment from the end of the last slip to the start of the next. Extremum k of the
    # period (k = i + m_ext j) is ext[i] + j pi with q = (-1)^j qe[i].
    k0 = i_max if i_max < n_half else i_max - n_half + m_ext
    th0 = ext[k0 % m_ext] + math.pi * (k0 // m_ext)
    q_a = q_max
    f_a = fs
    n_events = 0
    a = th0
    q_s = q_max
    stick_from = th0
    o_f = np.int64(0)                       # powers at stick_from, at th_s, at b
    o_s = pw
    o_b = 2 * pw
    _powers(th0, p_max, zr, zi, o_f)
    for p in range(1, m_ext + 1):
        k = k0 + p
        j = k // m_ext
        b = th0 + math.pi if p == m_ext else ext[k - m_ext * j] + math.pi * j
        q_b = -q_max if p == m_ext else (qe[k - m_ext * j] if j % 2 == 0
                                         else -qe[k - m_ext * j])
        up = q_b > q_s
        level = q_a + ((fs - f_a) / kc if up else -(fs + f_a) / kc)
        if (up and q_b > level) or (not up and q_b < level):
            # q is monotone on the piece: narrow the bracket to the samples around the
            # crossing (sample k at k step, q = (-1)^(k // n_half) qs[k % n_half])
            lo = a
            hi = b
            flo = q_s - level
            fhi = q_b - level
            if (flo < 0.0) if up else (flo > 0.0):
                ks = int(math.floor(a / step)) + 1
                while ks * step < b:
                    js = ks // n_half
                    v = qs[ks - js * n_half]
                    v = (v if js % 2 == 0 else -v) - level
                    if (v > 0.0) != (flo > 0.0):
                        hi = ks * step
                        fhi = v
                        break
                    lo = ks * step
                    flo = v
                    ks += 1
                th_s = _root(Q, orders, n_h, lo, hi, flo, fhi, level, np.bool_(False))
            else:
                # the slip distance 2 fs / kc is below the rounding of q: the crossing
                # is the extremum itself (a bracket of no sign change gave a long stick
                # phase, a force of about kc Q instead of at most fs)
                th_s = a
            _powers(th_s, p_max, zr, zi, o_s)
            _powers(b, p_max, zr, zi, o_b)
            _segment(Q, orders, n_h, stick_from, th_s, np.bool_(True), f_a, q_a, kc, 0.0, F, dF,
                     zr, zi, o_f, o_s, p_max, tr, ti)
            sgn = fs if up else -fs
            _segment(Q, orders, n_h, th_s, b, np.bool_(False), 0.0, 0.0, kc, sgn, F, dF,
                     zr, zi, o_s, o_b, p_max, tr, ti)
            q_a = q_b
            f_a = sgn
            stick_from = b
            o_f, o_b = o_b, o_f
            n_events += 2
        a = b
        q_s = q_b
    if stick_from < th0 + math.pi:
        # not reached when the loop slips into the global minimum (it does, unless
        # rounding hides the last crossing)
        _powers(th0 + math.pi, p_max, zr, zi, o_b)
        _segment(Q, orders, n_h, stick_from, th0 + math.pi, np.bool_(True), f_a, q_a, kc,
                 0.0, F, dF, zr, zi, o_f, o_b, p_max, tr, ti)
    # |f| <= fs at every instant bounds every harmonic by 4 fs / pi (a square wave's):
    # a loop that breaks it was walked wrongly, and fails rather than gives a number.
    # The stick phases' integrals carry rounding of about kc q_max eps, whatever fs.
    cap = _FOUR_OVER_PI * fs * (1.0 + 1e-9) + 1e-12 * kc * q_max
    for h in range(n_h):
        if not abs(F[h]) <= cap:
            return -1
    return 2 * n_events


def harmonic_orders(harmonics):
    """The odd orders ``1, 3, ..., harmonics`` as int64."""
    return np.arange(1, int(harmonics) + 1, 2, dtype=np.int64)
