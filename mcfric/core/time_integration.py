"""Time integration of the modal equations with Jenkins contacts, to a periodic state.

An independent check of harmonic balance: no describing function, no AFT. Every beam
``b`` and mode ``k`` obeys::

    eta'' + 2 zeta w eta' + w^2 eta = u_drive Re(F_b e^{i Omega t}) - u_contact (B^T f)_b

with ``f_j`` the force of damper ``j``, a Jenkins element on the relative contact
displacement ``q_j = y_a - y_b``, advanced by the exact return mapping
``f = clip(f_n + kc (q - q_n), -fs, fs)`` from the state at the start of the step.
The step is classic Runge-Kutta 4 with the force evaluated at each stage by that mapping;
the slider state is committed at the end of a step.

After every period the harmonics of the output and contact displacements are projected
(rectangle rule over the period's steps, exact for trigonometric polynomials of degree
below the step count). The run stops when no harmonic amplitude changed by more than
``tol`` (relative to the largest fundamental) over ``settle`` consecutive periods, or
reports "not periodic" after ``max_periods``.
"""

import math

import numpy as np

from ._jit import jit


@jit
def _contact_forces(eta, uc, a, b, kc, fs, f_n, q_n, f, q):
    """Contact displacements ``q`` and the return-mapped forces ``f`` at state ``eta``."""
    nd = a.shape[0]
    for j in range(nd):
        ya = 0.0
        yb = 0.0
        for k in range(eta.shape[1]):
            ya += uc[a[j], k] * eta[a[j], k]
            yb += uc[b[j], k] * eta[b[j], k]
        q[j] = ya - yb
        t = f_n[j] + kc[j] * (q[j] - q_n[j])
        f[j] = min(max(t, -fs[j]), fs[j])


@jit
def _rhs(t, eta, vel, w, zeta, uc, ud, force, omega, a, b, kc, fs, f_n, q_n, f, q, acc):
    """Modal accelerations at time ``t``."""
    _contact_forces(eta, uc, a, b, kc, fs, f_n, q_n, f, q)
    n_beams, n_modes = eta.shape
    c = math.cos(omega * t)
    s = math.sin(omega * t)
    for bb in range(n_beams):
        drive = force[bb].real * c - force[bb].imag * s
        contact = 0.0
        for j in range(a.shape[0]):
            if a[j] == bb:
                contact += f[j]
            if b[j] == bb:
                contact -= f[j]
        for k in range(n_modes):
            wk = w[bb, k]
            acc[bb, k] = (ud[bb, k] * drive - uc[bb, k] * contact
                          - 2.0 * zeta[bb, k] * wk * vel[bb, k] - wk * wk * eta[bb, k])


@jit
def _axpy(out, x, alpha, y):
    """``out = x + alpha y`` elementwise (no temporaries)."""
    for i in range(x.shape[0]):
        for k in range(x.shape[1]):
            out[i, k] = x[i, k] + alpha * y[i, k]


@jit
def _sum_abs(z):
    """Sum of the moduli of a 2-D complex array (NaN or inf if any entry is)."""
    s = 0.0
    for i in range(z.shape[0]):
        for j in range(z.shape[1]):
            s += abs(z[i, j])
    return s


@jit
def integrate(w, zeta, uc, uo, ud, force, omega, a, b, kc, fs, eta, vel, f_n, orders,
              steps, tol, settle, calm, max_periods, y_h, q_h, y_peak, history):
    """Integrate period by period until the harmonics settle.

    The state (``eta``, ``vel``, ``f_n``, ``y_h``, ``q_h`` and ``calm``) goes in and comes
    out, so that a long integration can run as several calls, bit for bit the same as one.

    Parameters
    ----------
    w, zeta : ndarray, shape (n_beams, n_modes)
        Natural angular frequencies (rad/s) and damping ratios (-).
    uc, uo, ud : ndarray, shape (n_beams, n_modes)
        Mode shapes at the contact, output and drive positions, kg^-1/2.
    force : ndarray of complex, shape (n_beams,)
        Drive amplitudes, N.
    omega : float
        Drive frequency, rad/s.
    a, b : ndarray of int64, shape (nd,)
        Beams of each damper.
    kc, fs : ndarray, shape (nd,)
        Spring stiffness (N/m) and slip force ``mu0 N0`` (N) per damper.
    eta, vel : ndarray, shape (n_beams, n_modes)
        In and out: modal displacements and velocities at the start of a period
        (kg^1/2 m and kg^1/2 m/s).
    f_n : ndarray, shape (nd,)
        In and out: the committed damper forces, N (``|f_n| <= fs``).
    orders : ndarray of int64, shape (n_h,)
        Harmonic orders to project (1 first).
    steps : int
        Time steps per period.
    tol : float
        Settling tolerance on the change of harmonics per period, relative.
    settle : int
        Consecutive periods within ``tol`` needed.
    calm : int
        Consecutive periods within ``tol`` before this call (0 at the start).
    max_periods : int
        Periods to integrate at most in this call.
    y_h : ndarray of complex, shape (n_h, n_beams)
        In and out: output-displacement harmonics of the last period, m (zeros at the
        start).
    q_h : ndarray of complex, shape (n_h, nd)
        In and out: contact-displacement harmonics of the last period, m (zeros at the
        start).
    y_peak : ndarray, shape (n_beams,)
        Out: largest ``|y(t)|`` over the last period, m.
    history : ndarray, shape (steps, n_beams)
        Out: the output displacement over the last period, m.

    Returns
    -------
    (int, float, int)
        Periods integrated in this call (negative if the state did not settle in them),
        the last relative change of the harmonics (NaN where the state blew up) and
        ``calm`` after the last period.
    """
    n_beams, n_modes = eta.shape
    nd = a.shape[0]
    n_h = orders.shape[0]
    dt = 2.0 * math.pi / omega / steps
    q_n = np.zeros(nd)
    f = np.zeros(nd)
    q = np.zeros(nd)
    # the committed contact displacement of the state: a function of eta alone
    _contact_forces(eta, uc, a, b, kc, fs, f_n, q_n, f, q)
    for j in range(nd):
        q_n[j] = q[j]
    k1e = np.empty_like(eta)
    k1v = np.empty_like(eta)
    k2e = np.empty_like(eta)
    k2v = np.empty_like(eta)
    k3e = np.empty_like(eta)
    k3v = np.empty_like(eta)
    k4v = np.empty_like(eta)
    te = np.empty_like(eta)
    tv = np.empty_like(eta)
    prev_y = y_h.copy()
    prev_q = q_h.copy()
    cur_y = np.zeros((n_h, n_beams), dtype=np.complex128)
    cur_q = np.zeros((n_h, nd), dtype=np.complex128)
    change = math.inf
    # e^{-i n theta} on the step grid, once
    ph = np.empty((steps, n_h), dtype=np.complex128)
    for step in range(steps):
        for h in range(n_h):
            th = orders[h] * 2.0 * math.pi * step / steps
            ph[step, h] = complex(math.cos(th), -math.sin(th))
    for period in range(1, max_periods + 1):
        for h in range(n_h):
            for bb in range(n_beams):
                cur_y[h, bb] = 0.0j
            for j in range(nd):
                cur_q[h, j] = 0.0j
        for bb in range(n_beams):
            y_peak[bb] = 0.0
        for step in range(steps):
            t = step * dt      # time within the period: the drive is periodic
            # sample the state at the start of the step for the projections
            for bb in range(n_beams):
                y = 0.0
                for k in range(n_modes):
                    y += uo[bb, k] * eta[bb, k]
                history[step, bb] = y
                y_peak[bb] = max(y_peak[bb], abs(y))
                for h in range(n_h):
                    cur_y[h, bb] += y * ph[step, h]
            _contact_forces(eta, uc, a, b, kc, fs, f_n, q_n, f, q)
            for j in range(nd):
                for h in range(n_h):
                    cur_q[h, j] += q[j] * ph[step, h]
            # RK4 with the return mapping from the committed slider state at every stage
            _rhs(t, eta, vel, w, zeta, uc, ud, force, omega, a, b, kc, fs, f_n, q_n, f, q,
                 k1v)
            _axpy(te, eta, 0.5 * dt, vel)
            _axpy(tv, vel, 0.5 * dt, k1v)
            k1e[:, :] = vel
            _rhs(t + 0.5 * dt, te, tv, w, zeta, uc, ud, force, omega, a, b, kc, fs, f_n,
                 q_n, f, q, k2v)
            k2e[:, :] = tv
            _axpy(te, eta, 0.5 * dt, k2e)
            _axpy(tv, vel, 0.5 * dt, k2v)
            _rhs(t + 0.5 * dt, te, tv, w, zeta, uc, ud, force, omega, a, b, kc, fs, f_n,
                 q_n, f, q, k3v)
            k3e[:, :] = tv
            _axpy(te, eta, dt, k3e)
            _axpy(tv, vel, dt, k3v)
            _rhs(t + dt, te, tv, w, zeta, uc, ud, force, omega, a, b, kc, fs, f_n, q_n, f,
                 q, k4v)
            for bb in range(n_beams):
                for k in range(n_modes):
                    eta[bb, k] += dt / 6.0 * (k1e[bb, k] + 2.0 * k2e[bb, k]
                                              + 2.0 * k3e[bb, k] + tv[bb, k])
                    vel[bb, k] += dt / 6.0 * (k1v[bb, k] + 2.0 * k2v[bb, k]
                                              + 2.0 * k3v[bb, k] + k4v[bb, k])
            # commit the slider state at the end of the step
            _contact_forces(eta, uc, a, b, kc, fs, f_n, q_n, f, q)
            for j in range(nd):
                f_n[j] = f[j]
                q_n[j] = q[j]
        scale = 0.0
        for h in range(n_h):
            for bb in range(n_beams):
                cur_y[h, bb] *= 2.0 / steps
            for j in range(nd):
                cur_q[h, j] *= 2.0 / steps
        for bb in range(n_beams):
            scale = max(scale, abs(cur_y[0, bb]))
        for j in range(nd):
            scale = max(scale, abs(cur_q[0, j]))
        change = 0.0
        for h in range(n_h):
            for bb in range(n_beams):
                change = max(change, abs(cur_y[h, bb] - prev_y[h, bb]))
                prev_y[h, bb] = cur_y[h, bb]
            for j in range(nd):
                change = max(change, abs(cur_q[h, j] - prev_q[h, j]))
                prev_q[h, j] = cur_q[h, j]
        change = change / scale if scale > 0.0 else 0.0
        # max() drops a NaN: a state that blew up must not read as settled
        if not (math.isfinite(change) and math.isfinite(_sum_abs(cur_y) + _sum_abs(cur_q))):
            change = math.nan
            break
        calm = calm + 1 if change <= tol else 0
        if calm >= settle:
            y_h[:, :] = cur_y
            q_h[:, :] = cur_q
            return period, change, calm
    y_h[:, :] = cur_y
    q_h[:, :] = cur_q
    # the periods actually integrated: fewer than max_periods where the state blew up
    return -period, change, calm
