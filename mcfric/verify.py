"""Time-domain verification of harmonic-balance points (``mcfric verify``).

For one parameter set and a few frequencies, integrate the modal equations with exact
Jenkins return mapping (:mod:`mcfric.core.time_integration`) to a periodic steady state,
project its harmonics, and set them beside the single- and multi-harmonic solutions of the
same point. A response that does not settle is reported as not periodic, never averaged
into a number.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from .core.aft import harmonic_orders
from .core.friction import describing_function
from .core.receptance import contact_space
from .core.time_integration import integrate
from .hbm import MAX_N_TIME, check_harmonics, solve
from .model import Model
from .validators import InputError, flag, fraction, integer, residual_tol
from .validators import frequencies as check_frequencies
from .validators import per_damper as check_parameters

#: Time steps per kernel call of the integration (a few tenths of a second on eight beams,
#: the wait for Ctrl-C), or one period where a period has more (up to ``MAX_STEPS``).
STEPS_PER_CALL = 200_000

#: Defaults: relative change of the harmonics per period that counts as settled, the
#: number of consecutive settled periods, and the period limit.
TOL = 1e-8
SETTLE = 5
MAX_PERIODS = 20000
#: Largest ``max_periods`` and smallest ``tol`` accepted.
MAX_PERIODS_CAP, TOL_MIN = 10 * MAX_PERIODS, 1e-14
#: Largest ``omega dt`` of the fastest mode (RK4 is accurate to ~(omega dt)^4 / 120).
OMEGA_DT = 0.05
#: Most time steps per period (given or from the fastest mode): a period of 1e7 steps
#: stores an 80 MB history per beam, and low frequencies need ever more.
MAX_STEPS = 10**7
STARTS = ("single", "rest")
#: A time-domain harmonic below this fraction of the largest fundamental is not told from
#: zero (the default settling tolerance, ``TOL``): no relative difference is formed with
#: it.
NOISE = TOL


@dataclass
class Verification:
    """One frequency: time integration against harmonic balance.

    Attributes
    ----------
    freq_hz : float
        Drive frequency, Hz.
    orders : ndarray of int, shape (n_h,)
        Harmonic orders projected (odd, 1 first).
    periodic : bool
        The integration settled to a periodic state.
    periods : int
        Periods integrated.
    change : float
        Relative change of the harmonics over the last period.
    time : ndarray, shape (steps,)
        Time over the last period, s.
    history : ndarray, shape (steps, n_beams)
        Output displacement over the last period, m.
    harmonics : ndarray of complex, shape (n_h, n_beams)
        Output harmonics of the time integration, m.
    peak : ndarray, shape (n_beams,)
        Largest ``|y(t)|`` over the last period, m.
    single : ndarray of complex, shape (n_beams,)
        Single-harmonic fundamental at the same point, m (NaN if not converged).
    multi : ndarray of complex, shape (n_h_mhb, n_beams)
        Multi-harmonic output harmonics (orders 1, 3, ...), m (NaN if not converged).
    multi_peak : ndarray, shape (n_beams,)
        Multi-harmonic full-period peak, m.
    even : ndarray, shape (n_beams,)
        The integration's largest even content, the mean or the 2nd harmonic
        (``max(|mean|, |y_2|)``), m: the balance assumes a state that repeats with the
        sign flipped half a period later, which has none.
    """

    freq_hz: float
    orders: np.ndarray
    periodic: bool
    periods: int
    change: float
    time: np.ndarray
    history: np.ndarray
    harmonics: np.ndarray
    peak: np.ndarray
    single: np.ndarray
    multi: np.ndarray
    multi_peak: np.ndarray
    even: np.ndarray

    def differences(self):
        """Relative differences per beam: (single-harmonic, multi-harmonic) fundamental
        amplitude against the integration's, and the multi-harmonic 3rd harmonic against
        the integration's (NaN without a 3rd harmonic, and where the integration's is 0
        or rounding noise, below ``NOISE`` times the largest fundamental: a beam at rest,
        or stuck contacts, have no relative difference; all NaN where the integration is
        not periodic: no steady state to compare with)."""
        if not self.periodic:
            nan = np.full(self.harmonics.shape[1], np.nan)
            return nan, nan.copy(), nan.copy()
        td1 = np.abs(self.harmonics[0])
        d1 = _ratio(np.abs(self.single), td1) - 1.0
        dm = _ratio(np.abs(self.multi[0]), td1) - 1.0
        if self.multi.shape[0] > 1 and len(self.orders) > 1:
            td3 = np.abs(self.harmonics[1])
            td3 = np.where(td3 > NOISE * np.max(td1, initial=0.0), td3, 0.0)
            d3 = _ratio(np.abs(self.multi[1]), td3) - 1.0
        else:
            d3 = np.full_like(d1, np.nan)
        return d1, dm, d3

    def table(self):
        """Text table, one row per beam."""
        head = (f"f = {self.freq_hz:.6g} Hz: " + (
            f"periodic after {self.periods} periods" if self.periodic else
            f"NOT PERIODIC after {self.periods} periods (change {self.change:.2g}); "
            "the time-domain numbers below are the last period's, not a steady state"))
        cols = ("beam", "|y1| time", *(f"|y{n}|/|y1|" for n in self.orders[1:]),
                "even/|y1|", "peak time", "|y1| H=1", "diff H=1", "|y1| MHB", "diff MHB",
                "peak MHB")
        rows = [head, "  ".join(f"{c:>11}" for c in cols)]
        d1, dm, _ = self.differences()
        for bb in range(self.history.shape[1]):
            y1 = abs(self.harmonics[0, bb])
            vals = [f"{bb + 1:>11d}", f"{y1:11.4e}"]
            vals += [_percent(_ratio(abs(self.harmonics[h, bb]), y1), "")
                     for h in range(1, len(self.orders))]
            vals += [_percent(_ratio(self.even[bb], y1), ""), f"{self.peak[bb]:11.4e}",
                     f"{abs(self.single[bb]):11.4e}",
                     _percent(d1[bb], "+"), f"{abs(self.multi[0, bb]):11.4e}",
                     _percent(dm[bb], "+"), f"{self.multi_peak[bb]:11.4e}"]
            rows.append("  ".join(vals))
        return "\n".join(rows)


def _steps(model, omega, kc):
    """Time steps per period: the fastest mode, stiffened by the contacts, at
    ``omega dt <= OMEGA_DT``; a multiple of 64, at least 1024 (a float above
    ``MAX_STEPS``, possibly inf, where a period needs more)."""
    f, _, u = model.modal_arrays()
    w = 2 * np.pi * f
    # a stuck contact adds at most kc (uc_a^2 + uc_b^2) to a mode's stiffness per damper
    extra = 4.0 * float(np.max(kc, initial=0.0)) * float(np.max(u[:, :, 0] ** 2))
    w_max = math.sqrt(float(np.max(w)) ** 2 + extra)
    den = float(omega) * OMEGA_DT         # a float, and 0 only below ~1e-322 Hz
    n = 2 * math.pi * w_max / den if den > 0 else math.inf
    if not n <= MAX_STEPS:
        # too many (below ~1e-303 Hz the ratio overflows to inf): the caller refuses it
        return n
    n = math.ceil(n)
    return max(1024, -(-n // 64) * 64)


def _ratio(num, den):
    """``num / den``, NaN where ``den`` is 0 (a beam at rest), without a warning."""
    num, den = np.broadcast_arrays(np.asarray(num, float), np.asarray(den, float))
    out = np.full(num.shape, np.nan)
    np.divide(num, den, out=out, where=den > 0)
    return out


def _percent(x, sign):
    """A table cell: ``x`` in percent, ``-`` where it is NaN (no relative measure)."""
    return f"{'-':>11}" if np.isnan(x) else f"{float(x):{sign}11.3%}"


def time_steps(model, freq_hz, kc, steps=None):
    """The frequencies (validated) and the time steps per period at each.

    Parameters
    ----------
    model : Model
    freq_hz : float or array_like
        Frequencies, Hz.
    kc : float or array_like
        Contact stiffness of every damper, N/m (the stiffest stuck contact sets the step).
    steps : int, optional
        Given steps per period (64 .. ``MAX_STEPS``); default from the fastest mode.

    Returns
    -------
    f : ndarray
        The frequencies, Hz.
    n : list of int
        Time steps per period at each.

    Raises
    ------
    ValueError
        A frequency that is not finite and positive, or one so low that a period needs
        more than ``MAX_STEPS`` steps; or a ``kc`` so stiff that it does (one line, naming
        which).
    """
    f = check_frequencies(np.atleast_1d(freq_hz))
    if steps is not None and (isinstance(steps, bool) or not isinstance(steps, (int, np.integer))
                              or not 64 <= steps <= MAX_STEPS):
        raise ValueError(f"steps: expected an integer in 64..{MAX_STEPS}, got {steps!r}")
    n = [int(steps) if steps is not None else _steps(model, 2 * np.pi * fk, kc) for fk in f]
    for fk, nk in zip(f, n):
        if nk > MAX_STEPS:
            count = f"{nk:.3g}" if math.isfinite(nk) else "too many"
            if steps is None and _steps(model, 2 * np.pi * fk, 0.0) <= MAX_STEPS:
                # the stiff contacts set the step, not the frequency
                raise InputError("kc", f"{float(np.max(kc)):g} N/m makes a period at {fk:g} Hz "
                                 f"need {count} time steps (at most {MAX_STEPS}); a contact "
                                 f"this stiff is stuck: integrate with a softer kc")
            raise InputError("freq_hz", f"at {fk:g} Hz a period needs {count} time steps (at "
                             f"most {MAX_STEPS}); integrate at higher frequencies")
    return f, n


def _integrate(args, max_periods, outputs, progress=False):
    """The kernel's integration in calls of at most ``STEPS_PER_CALL`` steps.

    Ctrl-C acts between calls (a numba kernel cannot be stopped); the state carries over,
    so the result is bit for bit that of one call. With ``progress``, an integration
    that lasts over a second shows its periods on a bar. Returns the periods integrated
    (negative if not periodic) and the last relative change.
    """
    from tqdm import tqdm

    n_steps = args[15]                    # the kernel's ``steps``
    per_call = max(1, STEPS_PER_CALL // n_steps)
    done, calm = 0, 0
    with tqdm(total=max_periods, unit="period", disable=not progress, leave=False, delay=1.0,
              dynamic_ncols=True, file=sys.stderr, desc="to a periodic state") as bar:
        while True:
            periods, change, calm = integrate(*args, calm, min(per_call, max_periods - done),
                                              *outputs)
            done += abs(periods)
            bar.update(abs(periods))
            if periods > 0:
                return done, change
            if not math.isfinite(change) or done >= max_periods:
                return -done, change


def _single_harmonic_state(model, omega, mu0, kc, N0, s):
    """Modal state at ``t = 0`` and damper forces of the single-harmonic solution."""
    a, b = model.dampers
    rec = model.receptances(np.array([omega]))[0]
    G, q0, _, _ = contact_space(rec, model.force, a, b)
    K = np.array([describing_function(np.array([sj]), kcj)[0] for sj, kcj in zip(s, kc)])
    q = np.linalg.solve(np.eye(len(K)) + G[0] * K[None, :], q0[0])
    F = K * q
    f, z, u = model.modal_arrays()
    w = 2 * np.pi * f
    contact = np.zeros(model.n_beams, complex)
    np.add.at(contact, a, F)
    np.add.at(contact, b, -F)
    load = u[:, :, 2] * model.force[:, None] - u[:, :, 0] * contact[:, None]
    eta = load / (w * w - omega * omega + 2j * z * w * omega)
    fs = mu0 * N0
    return eta.real.copy(), (1j * omega * eta).real.copy(), np.clip(F.real, -fs, fs)


def verify(model, freq_hz, mu0, kc, N0=0.5, *, harmonics=9, start="single", tol=TOL,
           settle=SETTLE, max_periods=MAX_PERIODS, steps=None, progress=False,
           hb_tol=None, hb_max_iter=None, hb_n_time=None):
    """Integrate to a periodic state at each frequency and compare with harmonic balance.

    Parameters
    ----------
    model : Model
        The array.
    freq_hz : float or array_like
        Drive frequencies, Hz.
    mu0, kc, N0 : float or array_like, shape (nd,)
        Friction coefficient (-), tangential stiffness (N/m), normal preload (N).
    harmonics : int
        Highest odd harmonic (>= 3) of the multi-harmonic solution compared (and
        projected); the single-harmonic solution is compared as well.
    start : {"single", "rest"}
        Initial state: the single-harmonic solution, or rest.
    tol : float
        Settled when no harmonic changed by more than ``tol`` (relative to the largest
        fundamental) over ``settle`` consecutive periods.
    settle : int
        Consecutive settled periods needed.
    max_periods : int
        Periods after which the response is reported as not periodic.
    steps : int, optional
        Time steps per period (default from the fastest mode; at least 64).
    progress : bool
        Show a tqdm bar over the frequencies on stderr (an integration takes seconds),
        and one of the periods integrated where a frequency takes over a second.
    hb_tol, hb_max_iter, hb_n_time : float, int, int, optional
        The harmonic-balance solver's residual tolerance, Newton iterations and AFT
        samples per period (default: :func:`mcfric.solve`'s), e.g. a results file's, to
        solve its points as its run did.

    Returns
    -------
    list of Verification
    """
    if not isinstance(model, Model):
        raise ValueError(f"model: expected a mcfric Model, got {type(model).__name__}")
    if model.contact_law != "coulomb":
        # the integrator's contacts are Jenkins elements
        raise ValueError(f"contact_law = {model.contact_law!r}: verify integrates the "
                         f"coulomb law only")
    check_frequencies(np.atleast_1d(freq_hz))
    p = check_parameters(model.n_dampers, mu0=mu0, kc=kc, N0=N0)
    if p["mu0"].shape[0] != 1:
        raise ValueError("mu0, kc, N0: verify takes one parameter set (scalars or per damper)")
    mu0, kc, N0 = (p[k][0] for k in ("mu0", "kc", "N0"))
    harmonics, _ = check_harmonics(harmonics)
    if harmonics < 3:
        # the single-harmonic solution is compared in any case: H = 1 twice would fill
        # the multi-harmonic columns with it
        raise ValueError(f"harmonics: verify balances H >= 3 beside the single-harmonic "
                         f"solution, which it always compares; got {harmonics}")
    if start not in STARTS:
        raise ValueError(f"start: expected one of {STARTS}, got {start!r}")
    # a floor and a cap: a tolerance below rounding never settles, and 1e9 periods would
    # run for days
    if fraction("tol", tol) < TOL_MIN:
        raise InputError("tol", f"expected a number in [{TOL_MIN:g}, 1) (below it rounding "
                                f"never settles), got {tol!r}")
    integer(1)(settle, "settle")
    flag("progress", progress)
    integer(1, MAX_PERIODS_CAP)(max_periods, "max_periods")
    # named here: solve() would blame "tol", which is the integration's
    if hb_tol is not None:
        residual_tol("hb_tol", hb_tol)
    if hb_max_iter is not None:
        integer(1, 10000)(hb_max_iter, "hb_max_iter")
    if hb_n_time is not None:
        integer(4 * harmonics + 4, MAX_N_TIME)(hb_n_time, "hb_n_time")
    f, n_steps_at = time_steps(model, freq_hz, kc, steps)
    orders = harmonic_orders(harmonics)
    # the mean and the 2nd harmonic are projected (and settled) too: a state that breaks
    # the half-period symmetry the balance assumes shows there
    projected = np.concatenate([orders, [0, 2]]).astype(np.int64)
    n_odd = len(orders)
    hb = {k: v for k, v in (("tol", hb_tol), ("max_iter", hb_max_iter)) if v is not None}
    shb = solve(model, f, mu0[None], kc[None], N0[None], **hb)
    mhb = solve(model, f, mu0[None], kc[None], N0[None], harmonics=harmonics,
                n_time=hb_n_time, store_harmonics=True, **hb) if harmonics > 1 else None
    fr, z, u = model.modal_arrays()
    w = 2 * np.pi * fr
    uc, uo, ud = (np.ascontiguousarray(u[:, :, i]) for i in range(3))
    a, b = (x.astype(np.int64) for x in model.dampers)
    force = np.ascontiguousarray(model.force, dtype=np.complex128)
    from tqdm import tqdm

    out = []
    for k, fk in enumerate(tqdm(f, unit="frequency", disable=not progress, leave=False,
                                dynamic_ncols=True, file=sys.stderr)):
        omega = 2 * np.pi * fk
        n_steps = n_steps_at[k]
        if start == "single" and shb.converged[0, k]:
            eta0, vel0, f0 = _single_harmonic_state(model, omega, mu0, kc, N0, shb.s[0, k])
        else:
            eta0 = np.zeros_like(w)
            vel0 = np.zeros_like(w)
            f0 = np.zeros(model.n_dampers)
        y_h = np.zeros((len(projected), model.n_beams), complex)
        q_h = np.zeros((len(projected), model.n_dampers), complex)
        peak = np.zeros(model.n_beams)
        hist = np.zeros((n_steps, model.n_beams))
        periods, change = _integrate(
            (w, np.ascontiguousarray(z), uc, uo, ud, force, omega, a, b, kc, mu0 * N0,
             eta0, vel0, f0, projected, n_steps, float(tol), int(settle)),
            int(max_periods), (y_h, q_h, peak, hist), progress)
        if mhb is not None:
            multi = mhb.response_harmonics[0, k]
            multi_peak = mhb.response_peak[0, k]
        else:
            multi = shb.response[0, k][None]
            multi_peak = np.abs(shb.response[0, k])
        out.append(Verification(
            freq_hz=float(fk), orders=orders, periodic=periods > 0, periods=abs(periods),
            change=float(change), time=np.arange(n_steps) / (n_steps * fk), history=hist,
            harmonics=y_h[:n_odd], peak=peak, single=shb.response[0, k], multi=multi,
            multi_peak=multi_peak,
            # the projection doubles every order: the mean is half of order 0's
            even=np.maximum(0.5 * np.abs(y_h[n_odd]), np.abs(y_h[n_odd + 1]))))
    return out
