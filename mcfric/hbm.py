"""Harmonic-balance solves of a model: validate, call the kernel, wrap the result.

This is the Python layer above :mod:`mcfric.core.sweep`: it checks every input once,
so that a user sees a ``ValueError`` naming the argument rather than a numba typing error,
and it owns the output arrays.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numba
import numpy as np

from .core import harmonic_indicator as _indicator
from .core import multi_harmonic as _multi_harmonic
from .core import sweep as _sweep
from .core.aft import harmonic_orders
from .core.aft import work_size as aft_work_size
from .core.multi_harmonic import FROM_ABOVE, FROM_REST
from .core.newton import NOT_CONVERGED
from .core.receptance import D21
from .memory import MemoryRefused, check_fits
from .metric import check_beams, response_metric
from .model import CONTACT_LAWS, Model, check_squarable
from .peaks import Peaks, PeakSettings, refine
from .threads import threads
from .validators import InputError, flag, integer, real_array, residual_tol
from .validators import frequencies as check_frequencies
from .validators import per_damper as check_parameters

#: Default accepted relative residual ``|s kc A - mu0 N0| <= tol mu0 N0``; Newton aims
#: 10x lower and accepts a stall (rounding floor) only within ``tol``.
TOL = 1e-10
MAX_ITER = 50
#: A single-harmonic point whose :attr:`HBMResult.harmonic_indicator` exceeds this is
#: flagged: one harmonic may not be enough there (docs: theory, "When one harmonic is not
#: enough", for the measured quality of this choice).
INDICATOR_THRESHOLD = 0.003


@dataclass
class HBMResult:
    """Responses of ``n_s`` samples at ``n_f`` frequencies.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_f,)
        Frequencies, Hz.
    response : ndarray of complex, shape (n_s, n_f, n_beams)
        Displacement amplitude at the output position of every beam, m
        (``x(t) = Re{X e^{i omega t}}``). NaN where not converged.
    s : ndarray, shape (n_s, n_f, nd)
        Slip ratio ``mu0 N0 / (kc A)`` per damper (>= 1: stuck). NaN where not converged;
        0 for a damper with ``mu0 N0 = 0``, inf for one with ``kc = 0``. With
        ``harmonics > 1``, ``A`` is the fundamental's amplitude ``|Q_j1|``: ``s >= 1`` then
        only suggests a stuck damper (higher harmonics add to the motion).
    status : ndarray of int8, shape (n_s, n_f)
        0 converged, 1 converged after a restart (with ``harmonics > 1`` or ``aft``:
        from the single-harmonic solution, as every first frequency is, having no
        previous solution to continue), 2 by the last-resort solver, -1 not
        converged; with ``harmonics > 1`` or ``aft`` also :data:`FROM_ABOVE`
        (3): converged only from the solution at the next frequency, sweeping back down
        (on an upward grid the branch reached from above, which may differ from the one
        continued from below where there are several); there, 0 also marks a point
        converged after the sweep by continuation in frequency from the point below; and
        4 (:data:`~mcfric.core.multi_harmonic.FROM_REST`) one converged after the sweep
        only by continuation in the drive from rest, at its own frequency (where no
        retry from a neighbour converged; the only way in where no neighbour did).
    iterations : ndarray of int16, shape (n_s, n_f)
    residual : ndarray, shape (n_s, n_f)
        Single harmonic: ``max_j |s_j kc_j A_j / (mu0_j N0_j) - 1|`` of the returned
        point over the sliding dampers; ``inf`` where not finite, and where a point that
        did not converge would show a passing value. With ``harmonics > 1``: the largest
        modulus of the balance equations' residual over the largest ``|Q_j1|`` or
        ``|q0_j|`` (a relative displacement error, -).
    mu0, kc, N0 : ndarray, shape (n_s, nd)
        The parameters solved for (N0 in N, kc in N/m).
    peaks : Peaks or None
        The refined peaks of every member (:mod:`mcfric.peaks`), when asked for.
    harmonics : int
        Highest odd harmonic balanced (1: the single-harmonic describing function).
    response_peak : ndarray, shape (n_s, n_f, n_beams) or None
        With ``harmonics > 1``: the largest ``|x(t)|`` over a period at the output of
        every beam, all harmonics together, m. NaN where not converged.
    harmonic_indicator : ndarray, shape (n_s, n_f) or None
        Single-harmonic solves with ``indicator=True``: an estimate (not a bound) of the
        3rd and 5th harmonics at the output relative to the fundamental (-);
        above :data:`INDICATOR_THRESHOLD`, rerun the point with ``harmonics >= 3``;
        NaN where not converged, inf where the outputs have no fundamental but the
        dampers' harmonics reach them.
    response_harmonics : ndarray of complex, shape (n_s, n_f, n_h, n_beams) or None
        With ``store_harmonics``: the odd harmonics 1, 3, ..., of the output
        displacement, m (``response`` is the first of them).
    """

    freq_hz: np.ndarray
    response: np.ndarray
    s: np.ndarray
    status: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    mu0: np.ndarray
    kc: np.ndarray
    N0: np.ndarray
    peaks: Peaks | None = None
    harmonics: int = 1
    response_peak: np.ndarray | None = None
    response_harmonics: np.ndarray | None = None
    harmonic_indicator: np.ndarray | None = None

    @property
    def converged(self):
        """Boolean mask (n_s, n_f) of converged points."""
        return self.status > NOT_CONVERGED

    @property
    def from_above(self):
        """Boolean mask (n_s, n_f) of points that converged only from the solution at
        the next frequency (multi-harmonic runs; all false otherwise)."""
        return self.status == FROM_ABOVE

    @property
    def from_rest(self):
        """Boolean mask (n_s, n_f) of points that converged only from rest, by raising the
        drive at their own frequency, no neighbour's solution converging there
        (multi-harmonic runs; all false otherwise)."""
        return self.status == FROM_REST

    @property
    def n_not_converged(self):
        """Number of points that did not converge."""
        return int(np.count_nonzero(~self.converged))

    def metric(self, quantity="displacement", beams=None):
        """Response metric ``M`` (docs: theory, "Response metric"), shape (n_s, n_f).

        Parameters
        ----------
        quantity : {"displacement", "velocity", "acceleration"}
            ``M`` in m, m/s or m/s^2 (``omega^k`` times the displacement amplitude).
        beams : sequence of int, optional
            Beams to take the maximum over, 0-based (the configuration counts from 1);
            default all.
        """
        return response_metric(self.response, self.freq_hz, quantity, beams)

    def summary(self):
        """One line: samples x frequencies, the non-converged points, and those converged
        only from the next frequency's solution (where there are any)."""
        n = self.status.size
        bad = self.n_not_converged
        up = int(np.count_nonzero(self.from_above))
        rest = int(np.count_nonzero(self.from_rest))
        return (f"{self.status.shape[0]} samples x {self.status.shape[1]} frequencies = {n} "
                f"points; not converged: {bad} ({100.0 * bad / max(n, 1):.4g} %)"
                + (f"; {up} converged only from the next frequency's solution (from_above)"
                   if up else "")
                + (f"; {rest} only from rest, raising the drive (from_rest)" if rest
                   else ""))


def solve(model, freq_hz, mu0, kc, N0=0.5, *, modal_freq_hz=None, tol=TOL,
          max_iter=MAX_ITER, n_threads=None, peaks=None, harmonics=1, n_time=None,
          aft=False, store_harmonics=False, indicator=False):
    """Harmonic balance of a friction-coupled array for many parameter sets: single-harmonic
    (the describing function), or multi-harmonic with ``harmonics`` > 1.

    Each sample sweeps the frequencies in the order given (upward for a sorted grid),
    warm-starting every point from the previous ones: like a slow stepped sine, so on a
    branch with several solutions the one continued from below is returned. With
    ``harmonics > 1`` or ``aft``, a point the sweep cannot reach is tried again from the
    converged solution at the next frequency (status :data:`FROM_ABOVE`), directly or by
    continuation in frequency, then by continuation in frequency from the converged one
    before it (status 0), last by continuation in the drive from rest (status
    4, :data:`~mcfric.core.multi_harmonic.FROM_REST`).

    Parameters
    ----------
    model : Model
        The array, its dampers and its excitation.
    freq_hz : array_like, shape (n_f,)
        Excitation frequencies, Hz (> 0, finite).
    mu0, kc, N0 : array_like
        Friction coefficient (-), tangential stiffness (N/m) and normal preload (N) per
        damper: scalar, (nd,), (n_s, 1) or (n_s, nd); all >= 0, ``kc`` at most 1e12 N/m
        (:data:`mcfric.validators.KC_MAX`, a stuck contact). ``N0`` defaults to 0.5 N.
    modal_freq_hz : array_like, shape (n_s, n_beams, n_modes), optional
        Per-sample modal frequencies in Hz (mistuned rigs); default the model's. Friction
        parameters given for one sample apply to all ``n_s``. ``n_modes`` is the largest
        mode count of the model's beams; a beam with fewer modes takes any value > 0 in
        its padding slots (they have zero shapes and add nothing, like the 1 Hz
        :meth:`Model.modal_arrays` puts there).
    tol : float
        Accepted relative residual, 1e-14..0.1, default 1e-10 (iterations aim 10x lower).
    max_iter : int
        Newton iterations per attempt (default 50); a multi-harmonic attempt may add up
        to 10 undamped steps where its line search crawls (docs: harmonics).
    n_threads : int, optional
        numba threads for this call.
    peaks : PeakSettings or int, optional
        Refine the largest peaks of every member after its sweep (an int: that many
        peaks of the displacement metric over all beams, default settings); needs an
        increasing frequency grid. None: no refinement. Single-harmonic only.
    harmonics : int
        Balance the odd harmonics ``1, 3, ..., harmonics`` of the contact motion (docs:
        harmonics, "Multi-harmonic balance"); 1 (default) is the describing-function model.
        Each point of a multi-harmonic solve starts from the single-harmonic solution,
        which is computed first.
    n_time : int, optional
        AFT samples per period that bracket the stick-slip events; default
        ``max(32, 8 harmonics)``; at least ``4 harmonics + 4``.
    aft : bool
        Solve ``harmonics = 1`` through the multi-harmonic (AFT) kernel as well, to check
        one kernel against the other.
    store_harmonics : bool
        Keep every output harmonic in ``response_harmonics`` (multi-harmonic solves).
    indicator : bool
        Compute ``harmonic_indicator`` (single-harmonic solves; about a tenth of the kernel time).

    Returns
    -------
    HBMResult

    Raises
    ------
    ValueError
        An input it cannot use, one line naming it: a value out of range, shapes that do
        not match, ``peaks`` or ``indicator`` with ``harmonics > 1`` or ``aft``,
        ``store_harmonics`` with the closed-form kernel, or results larger than the memory
        available.
    """
    if not isinstance(model, Model):
        raise ValueError(f"model: expected a mcfric Model, got {type(model).__name__}")
    f = check_frequencies(freq_hz)
    nd = model.n_dampers
    p = check_parameters(nd, mu0=mu0, kc=kc, N0=N0)
    n_s = p["mu0"].shape[0]
    residual_tol("tol", tol)
    for name, value in (("indicator", indicator), ("aft", aft),
                        ("store_harmonics", store_harmonics)):
        flag(name, value)
    max_iter = integer(1, 10000)(max_iter, "max_iter")
    omega = 2 * np.pi * f
    if modal_freq_hz is not None:
        mf = np.array(real_array("modal_freq_hz", modal_freq_hz), dtype=float)
        if n_s == 1 and mf.ndim == 3 and mf.shape[0] > 1:
            # scalar friction parameters apply to every mistuned sample
            n_s = mf.shape[0]
            p = {k: np.ascontiguousarray(np.broadcast_to(v, (n_s, nd))) for k, v in p.items()}
        expect = (n_s, model.n_beams, max(t.n_modes for t in model.beams))
        if mf.shape != expect:
            raise ValueError(f"modal_freq_hz: expected shape {expect}, got {mf.shape}")
        check_squarable("modal_freq_hz", mf)
        modal_freq_hz = mf
    if isinstance(peaks, (int, np.integer)) and not isinstance(peaks, bool):
        peaks = PeakSettings(count=int(peaks))
    if peaks is not None and not isinstance(peaks, PeakSettings):
        raise ValueError(f"peaks: expected a PeakSettings or a count, got {peaks!r}")
    if peaks is not None and peaks.beams is not None:
        check_beams(peaks.beams, model.n_beams, "peaks.beams")
    if peaks is not None and np.any(np.diff(f) <= 0):
        raise ValueError("peaks: refinement needs increasing frequencies")
    harmonics, n_time = check_harmonics(harmonics, n_time)
    if model.contact_law != "coulomb" and (harmonics > 1 or aft or indicator):
        # the AFT and the indicator evaluate the Jenkins (Coulomb) element only
        raise ValueError(f"contact_law = {model.contact_law!r}: harmonics > 1, aft and "
                         f"indicator are for the coulomb law only")
    if peaks is not None and (harmonics > 1 or aft):
        raise ValueError("peaks: refinement is single-harmonic only (harmonics = 1)")
    if indicator and (harmonics > 1 or aft):
        # it estimates what a single-harmonic solve leaves out; here nothing is left out
        raise InputError("indicator", "for single-harmonic solves (harmonics = 1, aft = "
                         "False); a multi-harmonic solve balances those harmonics itself")
    if store_harmonics and harmonics == 1 and not aft:
        raise InputError("store_harmonics", "for multi-harmonic solves (harmonics >= 3); "
                         "with harmonics = 1 the response is the only harmonic")
    with threads(n_threads):
        if harmonics > 1 or aft:
            # inside: the Newton workspaces are per thread, so the need depends on it
            check_harmonic_memory(model, harmonics, n_time, len(f),
                                  1 if modal_freq_hz is None else n_s)
        check_output_memory(model, n_s, len(f), harmonics, store_harmonics,
                            1 if modal_freq_hz is None else n_s)
        rec = model.receptances(omega, modal_freq_hz)
        out = allocate(n_s, len(f), model.n_beams, nd, numba.get_num_threads())
        args = run_kernel(model, rec, omega, p["mu0"], p["N0"], p["kc"], tol, max_iter, *out)
        result = HBMResult(f, *out, mu0=p["mu0"], kc=p["kc"], N0=p["N0"])
        if indicator and harmonics == 1 and not aft:
            result.harmonic_indicator = harmonic_indicator(model, result, omega,
                                                           modal_freq_hz, args)
        if harmonics > 1 or aft:
            multi_harmonic(model, result, omega, modal_freq_hz, harmonics, n_time, tol,
                           max_iter, args, store_harmonics)
        if peaks is not None:
            mf = model.modal_arrays()[0][None] if modal_freq_hz is None else modal_freq_hz
            result.peaks = refine(model, result, omega, mf, peaks, *args, tol, max_iter)
    return result


#: Largest number of odd harmonics and of AFT samples accepted (beyond them the dense
#: Newton system and the event brackets cost more than any use justifies).
MAX_HARMONICS = 99
MAX_N_TIME = 65536
#: Memory the multi-harmonic receptances may take, bytes.
MAX_HARMONIC_BYTES = 8 * 2**30


def check_harmonics(harmonics, n_time=None):
    """Validate ``harmonics`` (odd, 1..99) and ``n_time``; return both (default n_time)."""
    if (isinstance(harmonics, bool) or not isinstance(harmonics, (int, np.integer))
            or not 1 <= harmonics <= MAX_HARMONICS or harmonics % 2 == 0):
        raise ValueError(f"harmonics: expected an odd integer in 1..{MAX_HARMONICS} (the odd "
                         f"harmonics 1, 3, ..., H are balanced), got {harmonics!r}")
    harmonics = int(harmonics)
    if n_time is None:
        n_time = max(32, 8 * harmonics)
    lo = 4 * harmonics + 4
    if (isinstance(n_time, bool) or not isinstance(n_time, (int, np.integer))
            or not lo <= n_time <= MAX_N_TIME):
        raise ValueError(f"n_time: expected an integer in {lo}..{MAX_N_TIME} (at least "
                         f"4 H + 4 samples per period for H = {harmonics}), got {n_time!r}")
    return harmonics, int(n_time)


def multi_harmonic_scratch(nd, n_h, n_f, n_time):
    """Bytes each thread of the multi-harmonic kernel holds (``core.multi_harmonic``'s
    ``_sample``) for ``nd`` dampers, ``n_h`` harmonics, ``n_f`` frequencies and
    ``n_time`` AFT samples per period: the receptance matrices (three of ``n_h nd^2``
    complex: the point's, a neighbour's and the continuation's), every frequency's
    solution (for the pass back down), the Newton step's blocks (a ring's: three of ``2
    n_h`` rows per damper; a chain holds two), the dampers' Jacobians and states, and the
    AFT's and the peak's samples."""
    n = 2 * nd * n_h
    n_time = int(n_time)
    return (48.0 * n_h * nd * nd + 16.0 * n_f * nd * n_h
            + 8.0 * (3 * n + 2 * n_h) * 2 * n_h + 8.0 * nd * (2 * n_h) ** 2
            + 16.0 * (10 * nd * n_h + 4 * nd) + 8.0 * (3 * n + 8 * nd)
            + 8.0 * aft_work_size(n_h, n_time) + 8.0 * 4 * n_time * (2 * n_h + 1))


def check_harmonic_memory(model, harmonics, n_time, n_f, n_r, per="call"):
    """Refuse a multi-harmonic solve whose receptances would not fit in memory
    (``per``: what the message asks for fewer samples of, a ``"call"`` or a run's
    ``"chunk"``)."""
    n_h = (harmonics + 1) // 2
    need = 16.0 * n_r * n_h * n_f * 4 * model.n_beams
    n_time = check_harmonics(harmonics, n_time)[1]          # None: the default for H
    need += multi_harmonic_scratch(model.n_dampers, n_h, n_f, n_time) * numba.get_num_threads()
    if need > MAX_HARMONIC_BYTES:
        raise MemoryRefused(f"harmonics: H = {harmonics} needs {need / 2**30:.3g} GiB for "
                            f"this model and grid (limit {MAX_HARMONIC_BYTES / 2**30:.0f} "
                            f"GiB); use fewer harmonics, frequencies or samples per {per}")


#: Bytes per damper pair of the dense fallback's scratch that each batch of the
#: single-harmonic kernels holds (``core.newton.workspace``: 16 + 8, and G: 16).
DENSE_SCRATCH_BYTES = 40


def scratch_per_thread(nd, harmonics, n_f, n_time=None):
    """Bytes of scratch each thread of a solve holds at most, for ``nd`` dampers: the
    single-harmonic kernels' dense fallback, or with ``harmonics > 1`` the multi-harmonic
    kernel's (:func:`multi_harmonic_scratch`), whichever is larger (they run one after
    the other)."""
    scratch = DENSE_SCRATCH_BYTES * nd * nd
    if harmonics > 1:
        n_time = check_harmonics(harmonics, n_time)[1]
        scratch = max(scratch, multi_harmonic_scratch(nd, (harmonics + 1) // 2, n_f, n_time))
    return scratch


def check_output_memory(model, n_s, n_f, harmonics, store_harmonics, n_r):
    """Refuse a solve whose results (with the receptances and each thread's scratch of the
    dense fallback) would not fit in the memory available: numpy's allocation error
    names no argument, and a request just below the machine's memory would end in the
    system killing the process.

    Parameters
    ----------
    model : Model
    n_s, n_f : int
        Samples and frequencies of the solve.
    harmonics : int
        Highest odd harmonic balanced (1: single-harmonic).
    store_harmonics : bool
        Every output harmonic kept.
    n_r : int
        Receptance sets (1, or ``n_s`` for per-sample modal frequencies).

    Raises
    ------
    ValueError
        The estimate, in bytes, exceeds the memory available (one line).
    """
    nb, nd = model.n_beams, model.n_dampers
    n_h = (harmonics + 1) // 2
    per_point = 16 * nb + 8 * nd + 1 + 2 + 8 + 8          # outputs, the indicator
    if harmonics > 1:
        per_point += 8 * nb + 8 * nd + 16 * nb * (n_h if store_harmonics else 1)
    need = float(n_s) * n_f * per_point + 16.0 * n_r * n_f * 4 * nb
    # each batch in flight holds the dense fallback's scratch, at most one per thread
    # and per sample: 5 GB for two threads on an 8000-blade ring
    scratch = min(numba.get_num_threads(), n_s) * DENSE_SCRATCH_BYTES * nd * nd
    check_fits(need + scratch, f"the solve of {n_s:,} samples x {n_f:,} frequencies",
               "solve fewer samples or frequencies per call"
               + (", or on fewer threads" if scratch > need else ""))


def harmonic_indicator(model, result, omega, modal_freq_hz, params):
    """The indicator of :mod:`mcfric.core.harmonic_indicator` for a single-harmonic result,
    shape (n_s, n_f); NaN where not converged."""
    mu0, N0, kc = params
    h3, h5 = (np.ascontiguousarray(np.abs(model.receptances(n * omega, modal_freq_hz)[:, :, D21]))
              for n in (3, 5))
    a, b = (x.astype(np.int64) for x in model.dampers)
    out = np.empty(result.status.shape)
    _indicator.harmonic_indicator(h3, h5, a, b, mu0, N0, kc, result.s, result.response, out)
    return out


def multi_harmonic(model, result, omega, modal_freq_hz, harmonics, n_time, tol, max_iter,
                   params, store_harmonics=False):
    """Replace a single-harmonic ``result`` in place by the multi-harmonic solution.

    The single-harmonic slip ratios are the starting points; a point converged there but
    not here is reported as not converged (status -1), never as the single-harmonic value.
    """
    mu0, N0, kc = params
    orders = harmonic_orders(harmonics)
    n_h = len(orders)
    recs = [model.receptances(n * omega, modal_freq_hz) for n in orders]
    n_r = recs[0].shape[0]
    rech = np.empty((n_r * n_h,) + recs[0].shape[1:], dtype=np.complex128)
    for h, r in enumerate(recs):
        rech[h::n_h] = r
    a, b = (x.astype(np.int64) for x in model.dampers)
    force = np.ascontiguousarray(model.force, dtype=np.complex128)
    s1 = np.ascontiguousarray(result.s)
    n_s, n_f, n_beams = result.response.shape
    y = np.empty((n_s, n_f, n_h if store_harmonics else 1, n_beams), np.complex128)
    y_peak = np.empty((n_s, n_f, n_beams))
    s = np.empty_like(result.s)
    status = np.empty_like(result.status)
    iterations = np.empty_like(result.iterations)
    residual = np.empty_like(result.residual)
    _multi_harmonic.sweep_multi_harmonic(
        rech, force, a, b, orders, np.ascontiguousarray(omega), mu0, N0, kc, int(n_time), s1,
        float(tol), int(max_iter), y, y_peak, s, status, iterations, residual)
    _not_finite_not_converged(status, y, y_peak, s)
    result.response = np.ascontiguousarray(y[:, :, 0, :])
    result.response_harmonics = y if store_harmonics else None
    result.s, result.status = s, status
    result.iterations, result.residual = iterations, residual
    result.harmonics = harmonics
    result.response_peak = y_peak
    return result


#: Bytes per memory page, for touching fresh output arrays (a multiple of the real size
#: would do as well: any byte faults its whole page in).
_PAGE = 4096


def allocate(n_s, n_f, n_beams, nd, n_threads=1):
    """Output arrays of the kernel: response, s, status, iterations, residual.

    Every page is touched (one byte written) here, before the kernel runs, by
    ``n_threads`` threads (numpy releases the GIL for the strided writes): first touch
    of fresh pages inside the kernel's threads cost about three times this pass (the
    docs' performance page); the kernel then overwrites every element.
    """
    out = (np.empty((n_s, n_f, n_beams), np.complex128), np.empty((n_s, n_f, nd)),
           np.empty((n_s, n_f), np.int8), np.empty((n_s, n_f), np.int16),
           np.empty((n_s, n_f)))
    pages = [a.reshape(-1).view(np.uint8)[::_PAGE] for a in out]

    def touch(t):
        for p in pages:
            p[p.shape[0] * t // n_threads:p.shape[0] * (t + 1) // n_threads] = 0

    workers = [threading.Thread(target=touch, args=(t,)) for t in range(1, n_threads)]
    for w in workers:
        w.start()
    touch(0)
    for w in workers:
        w.join()
    return out


def run_kernel(model, rec, omega, mu0, N0, kc, tol, max_iter, y, s, status, iterations,
               residual):
    """Dispatch to the kernel for this model (validated, contiguous inputs); returns the
    parameters as the kernel saw them (fresh writable copies: mu0, N0, kc)."""
    a, b = model.dampers
    a = a.astype(np.int64)
    b = b.astype(np.int64)
    force = np.ascontiguousarray(model.force, dtype=np.complex128)
    # fresh writable copies: numba compiles a separate specialisation for read-only
    # arrays (broadcast views are read-only), and a call may then reuse whichever one
    # was compiled first, whose rounding differs in the last bit; one signature keeps
    # every result independent of how the parameters were given and of compile history
    mu0, N0, kc = (np.array(x, dtype=np.float64, order="C") for x in (mu0, N0, kc))
    args = (np.ascontiguousarray(rec), force, a, b, np.ascontiguousarray(omega), mu0, N0, kc)
    law = CONTACT_LAWS.index(model.contact_law)
    outs = (float(tol), int(max_iter), y, s, status, iterations, residual)
    if law != 0:
        _sweep.sweep_dense(*args, *outs, np.int64(law))
    elif model.n_dampers == 1:
        _sweep.sweep_one_damper(*args, *outs)
    else:
        _sweep.sweep_chain(*args, *outs)
    _not_finite_not_converged(status, y, None, s)
    return mu0, N0, kc


def _not_finite_not_converged(status, y, y_peak, s):
    """Flag as not converged (outputs NaN) every point marked converged whose response
    ``y`` (every harmonic) or full-period peak ``y_peak`` (None: none) is not finite:
    such a value (an undamped resonance with the contacts free) is no solution, whatever
    the residual said. In place; arrays indexed (sample, frequency, ...)."""
    fine = np.isfinite(y).reshape(status.shape + (-1,)).all(axis=-1)
    if y_peak is not None:
        fine &= np.isfinite(y_peak).reshape(status.shape + (-1,)).all(axis=-1)
    bad = (status >= 0) & ~fine
    if bad.any():
        status[bad] = NOT_CONVERGED
        y[bad] = complex(np.nan, np.nan)
        s[bad] = np.nan
        if y_peak is not None:
            y_peak[bad] = np.nan
