"""Equivalent-linear response bounds (paper Section 3): the admissible region and the bounds.

The friction law is not specified: each damper's describing function ``K_j`` may be any
complex number in the admissible region

* box: ``0 <= Re K_j <= k_max_re`` (stiffness), ``0 <= Im K_j <= k_max_im`` (dissipation);
* force saturation: ``|K_j| A_j <= F_lim`` with ``F_lim = (4/pi) mu_max N0_max``, the
  first-harmonic amplitude of a saturated Coulomb force.

At each frequency the bounds on the metric ``M = max_b |y_b|`` are

* upper: each beam's response is bounded by the smaller of its maximum over the box and
  its force bound (Eq. 10: every damper at the force limit with the worst phase); M by the
  largest of these. This is never above the paper's min(box maximum of M, force bound of
  M) and equally valid. ``limited_by`` records whether the force limit or the box sets
  it. Where a beam reaches its force bound the box search for it stops (the box can no
  longer matter), which also saves most of the work at high forcing;
* lower: the minimum of M over the box (the force constraint only removes points, so the
  box minimum stays a valid lower bound).

Every Coulomb damper with ``kc <= k_max``, ``mu0 <= mu_max`` and ``N0 <= N0_max`` is
admissible (``Re K <= kc``, ``Im K <= kc / pi``, ``|K| A <= (4/pi) mu0 N0``), so every
converged ensemble member lies between the bounds.

The box search is the jitted coordinate search of :mod:`mcfric.core.coordinate_search`
(exact per damper: the response is a Moebius function of each ``K_j``), run from many
starts per frequency and in parallel over frequencies (:mod:`.search`); the minimum
ends with the Gauss-Newton minimax search of :mod:`mcfric.core.minimax` (all beams are
equal there). The docs' bounds page describes the algorithm and its checks.
It replaces the paper's ``fmincon``/SQP: a generic local optimiser, measured here, stopped
up to 30 % short of the true maximum on the eight-beam rig.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.receptance import contact_space
from ..metric import QUANTITIES, check_beams, check_quantity
from ..model import Model
from ..threads import threads
from ..validators import KC_MAX, InputError, flag, integer, is_bool, real
from ..validators import frequencies as check_frequencies
from .certified import (
    Certificate,
    certify,
    check_moments_choice,
    resolve_moments,
    subset_of_ring,
    turns,
    within,
)
from .search import box_extreme, starts

#: Largest k_max (and k_max_im) the bounds accept, N/m: far stiffer than any contact
#: (a stuck damper); beyond it the search's arithmetic overflows. The solvers' limit.
K_MAX_LIMIT = KC_MAX
#: Largest product of the box's largest describing function |K| and the contacts'
#: receptance at resonance that the bounds take: near 1e16 the ``1 + G K`` of the
#: searches' Moebius maps keeps none of the 1 in rounding and a search divides by zero.
SCALE_MAX = 1e15

#: ``limited_by`` codes: which constraint sets the upper bound.
LIMITED_BY = ("box", "force")
N_STARTS = 3
#: The most starts per frequency (as the configuration's ``bounds.n_starts``).
N_STARTS_MAX = 10000
#: Starts over the whole frequency grid at least: the continuation along frequency shares
#: what the starts find, so a coarse grid gets more starts per frequency (the total effort
#: stays about that of a 1000-point grid).
MIN_TOTAL_STARTS = 3000
MAX_SWEEPS = 20
#: The maximum's exploring searches stop after half as many sweeps: on a resonance ridge
#: a coordinate search crawls, and the continuation's repeated searches and the tight
#: final search take over (measured: the docs' performance page).
MAX_SWEEPS_FRACTION_MAX = 0.5


#: Relative slack of the admissibility checks: ``"auto"`` limits are these very products.
ADMIT_SLACK = 1.0 + 1e-12


def past_limits(mu0, kc, N0, k_max_re, k_max_im, F_lim):
    """Where a Jenkins damper leaves the bounds' admissible region, per constraint.

    A damper of stiffness ``kc`` and slip force ``mu0 N0`` has ``0 <= Re K <= kc``, ``0
    <= Im K <= kc / pi`` (at ``fs / (kc A) = 1/2``) and ``|K| A <= 4 / pi mu0 N0`` at any
    amplitude ``A``: the bounds hold for it if ``kc <= k_max_re``, ``kc / pi <=
    k_max_im`` and ``4 / pi mu0 N0 <= F_lim`` (each with :data:`ADMIT_SLACK`).

    Parameters
    ----------
    mu0, kc, N0 : float or ndarray
        Friction coefficient (1), contact stiffness (N/m), preload (N).
    k_max_re, k_max_im, F_lim : float
        The limits, N/m, N/m, N.

    Returns
    -------
    tuple of three bool (or bool arrays)
        ``kc`` past ``k_max_re``, ``kc / pi`` past ``k_max_im``, ``4 / pi mu0 N0`` past
        ``F_lim``.
    """
    return (kc > k_max_re * ADMIT_SLACK, kc / np.pi > k_max_im * ADMIT_SLACK,
            4.0 / np.pi * mu0 * N0 > F_lim * ADMIT_SLACK)


@dataclass
class Bounds:
    """Bounds on the metric over frequency: the paper's, found by a search, and (in
    ``certificate``) the certified ones.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_f,)
        Drive frequencies, Hz.
    upper, lower : ndarray, shape (n_f,)
        The searched bounds on ``M`` in the metric's unit (m, m/s or m/s^2): extremes a
        search found, not certified (the certified ones are ``certificate.upper`` and
        ``certificate.lower``). NaN where the search failed (a singular linear system:
        counted in :meth:`summary`).
    upper_box : ndarray, shape (n_f,)
        Largest box value found over the beams, in the metric's unit. Where a beam
        reached its force bound the search stopped there, so it is then only known to be
        at least that.
    upper_force : ndarray, shape (n_f,)
        Force bound of M (Eq. 10, largest over the beams), in the metric's unit.
    limited_by : ndarray of int8, shape (n_f,)
        0 where the box sets the upper bound, 1 where the force saturation does.
    K_upper, K_lower : ndarray of complex, shape (n_f, nd)
        Describing functions (N/m) at which the box maximum and minimum are reached.
    k_max_re, k_max_im, F_lim : float
        The constraints used (N/m, N/m, N; ``inf`` = no force constraint).
    quantity : str
        What M measures: "displacement" (m), "velocity" (m/s) or "acceleration"
        (m/s^2).
    beams : tuple of int
        0-based beams the metric takes the maximum over.
    certificate : Certificate or None
        The certified bounds over the admissible set and their witnesses
        (:mod:`.certified`); None where certification was skipped.
    """

    freq_hz: np.ndarray
    upper: np.ndarray
    lower: np.ndarray
    upper_box: np.ndarray
    upper_force: np.ndarray
    limited_by: np.ndarray
    K_upper: np.ndarray
    K_lower: np.ndarray
    k_max_re: float
    k_max_im: float
    F_lim: float
    quantity: str = "displacement"
    beams: tuple = field(default_factory=tuple)
    certificate: Certificate | None = None

    @property
    def n_failed(self):
        """Frequencies where the search failed (NaN bounds)."""
        return int(np.count_nonzero(~np.isfinite(self.upper) | ~np.isfinite(self.lower)))

    def summary(self):
        """What sets the upper bound where, the failures, and the certificate's gaps."""
        # a failed search (either bound: n_failed) has no constraint to name
        ok = np.isfinite(self.upper) & np.isfinite(self.lower)
        force = np.count_nonzero(ok & (self.limited_by == 1))
        box = np.count_nonzero(ok & (self.limited_by != 1))
        text = (f"searched bounds at {len(self.freq_hz)} frequencies: upper set by the force "
                f"limit at {force}, by the box at {box}; failed: {self.n_failed}")
        if self.certificate is not None:
            C = self.certificate
            # admissible witnesses past the searched bounds: the search missed them
            with np.errstate(invalid="ignore", divide="ignore"):
                above = C.upper_witness / self.upper - 1.0
                below = 1.0 - C.lower_witness / self.lower
            up = np.isfinite(above) & (above > 1e-9)
            lo = np.isfinite(below) & (below > 1e-9)
            if up.any() or lo.any():
                parts = ([f"upper at {np.count_nonzero(up)} (up to {100 * above[up].max():.3g} "
                          f"% above)"] if up.any() else []) + \
                        ([f"lower at {np.count_nonzero(lo)} (up to {100 * below[lo].max():.3g} "
                          f"% below)"] if lo.any() else [])
                text += ("\nthe certificate's admissible witnesses lie past the searched "
                         f"bounds, {' and '.join(parts)} of the frequencies: the search "
                         "missed them there (the certified bounds hold)")
            text += "\n" + C.summary(self.freq_hz)
        return text

    def admits(self, mu0, kc, N0):
        """Boolean mask of the members whose friction lies inside the bounds' constraints.

        The bounds hold for a member whose every damper is inside their constraints
        (:func:`past_limits`), and need not for others.

        Parameters
        ----------
        mu0, kc, N0 : array_like, shape (..., nd)
            Friction coefficient (1), contact stiffness (N/m), preload (N) per damper.

        Returns
        -------
        ndarray of bool, shape (...)

        Raises
        ------
        ValueError
            A parameter without one value per damper last, or with values not finite or
            below 0.
        """
        nd = self.K_upper.shape[-1]
        checked = []
        for name, x in (("mu0", mu0), ("kc", kc), ("N0", N0)):
            try:
                a = np.asarray(x, float)
            except (TypeError, ValueError):
                raise ValueError(f"{name}: expected numbers, got {x!r}") from None
            if a.ndim == 0 or a.shape[-1] != nd:
                raise InputError(name, f"expected shape (..., {nd}) (a value per damper "
                                 f"last), got {a.shape}")
            if not np.all(np.isfinite(a) & (a >= 0)):
                raise ValueError(f"{name}: expected finite values >= 0")
            checked.append(a)
        re, im, force = past_limits(*checked, self.k_max_re, self.k_max_im, self.F_lim)
        return ~(re | im | force).any(axis=-1)

    def contains(self, metric, rtol=1e-9):
        """Boolean mask ``lower (1 - rtol) <= metric <= upper (1 + rtol)`` (NaN -> False).

        Parameters
        ----------
        metric : array_like, shape (..., n_f)
            Real values of the metric in the bounds' unit, frequencies last (as
            ``HBMResult.metric()`` returns them).
        rtol : float
            Relative slack, in [0, 0.5).

        Returns
        -------
        ndarray of bool, shape (..., n_f)
        """
        m = np.asarray(metric)
        if not (np.issubdtype(m.dtype, np.floating) or np.issubdtype(m.dtype, np.integer)) \
                or m.dtype == bool:
            raise ValueError(f"metric: expected real numbers, got dtype {m.dtype}")
        if m.ndim == 0 or m.shape[-1] != len(self.freq_hz):
            raise InputError("metric", f"expected shape (..., {len(self.freq_hz)}) (the "
                             f"bounds' frequencies last), got {m.shape}")
        rtol = real("rtol", rtol, lo=0)
        if not rtol < 0.5:
            raise ValueError(f"rtol: expected a number in [0, 0.5), got {rtol!r}")
        return within(m, self.lower, self.upper, rtol)


def force_limit(mu_max, N0_max):
    """``F_lim = (4/pi) mu_max N0_max``: first harmonic of a saturated Coulomb force, N.

    Parameters
    ----------
    mu_max : float
        Largest friction coefficient (-), finite and > 0.
    N0_max : float
        Largest normal preload, N, finite and > 0 (0 would leave every damper free, a
        limit :func:`compute_bounds` does not take: ``F_lim > 0``).

    Returns
    -------
    float
        ``F_lim``, N.
    """
    mu = real("mu_max", mu_max, lo=0, lo_open=True)
    n0 = real("N0_max", N0_max, lo=0, lo_open=True)
    F = 4.0 / np.pi * mu * n0
    if not 0 < F < np.inf:      # inf would mean "no force limit", 0 is refused later
        raise InputError("mu_max", f"4/pi x {mu:g} x {n0:g} = {F:g} N overflows or "
                                   f"underflows: give limits whose product is a force")
    return F


def upper_bound(G, q0, ylin, H, kr, ki, F_lim, starts_max, max_sweeps):
    """The upper bound per frequency, in displacement (m), from contact-space arrays.

    Each beam is bounded by the smaller of its maximum over the box and its force bound
    (paper Eq. 10: every damper at the force limit with the worst phases); ``M`` by the
    largest of these, never above the paper's min(box max of M, force bound of M).

    Returns
    -------
    upper, upper_box, upper_force : ndarray, shape (n_f,)
    limited_by : ndarray of int8, shape (n_f,)
    K_upper : ndarray of complex, shape (n_f, nd)
    """
    force_beam = np.abs(ylin) + F_lim * np.abs(H).sum(axis=2)          # (n_f, nb)
    box_beam, K_beam = box_extreme(G, q0, ylin, H, kr, ki, starts_max, True, cap=force_beam,
                                   max_sweeps=max_sweeps)
    per_beam = np.fmin(box_beam.T, force_beam)                          # (n_f, nb)
    failed = np.isnan(box_beam).all(axis=0)
    b_star = np.argmax(np.where(np.isnan(per_beam), -np.inf, per_beam), axis=1)
    idx = np.arange(G.shape[0])
    upper = np.where(failed, np.nan, per_beam[idx, b_star])
    upper_box = np.where(failed, np.nan, np.nanmax(np.where(np.isnan(box_beam), -np.inf,
                                                            box_beam), axis=0))
    upper_force = force_beam.max(axis=1)
    limited_by = (force_beam[idx, b_star] <= box_beam[b_star, idx]).astype(np.int8)
    return upper, upper_box, upper_force, limited_by, K_beam[b_star, idx]


def rotation_invariant(model):
    """True for a tuned ring under a travelling wave: every blade has the same bounds.

    Turning such a ring by one blade maps the admissible set onto itself (every damper has
    the same box and force limit) and multiplies the drive by one phase factor, so the
    response of blade ``b + 1`` under the turned ``K`` is that of blade ``b`` under ``K``
    times that factor: the largest and the smallest amplitude over the admissible set are
    the same for every blade.
    """
    if model.topology != "circular" or model.excitation.pattern != "travelling":
        return False
    t0 = model.beams[0]
    return all(t is t0 or (np.array_equal(t.freq_hz, t0.freq_hz)
                           and np.array_equal(t.zeta, t0.zeta)
                           and np.array_equal(t.shapes, t0.shapes)
                           and tuple(t.positions) == tuple(t0.positions))
               for t in model.beams)


def check_scales(model, k_max, k_max_im, key="model"):
    """Refuse a box whose stiffest describing function dwarfs the beams at the contacts.

    Parameters
    ----------
    model : Model
        The array; every mode damped (zeta > 0).
    k_max, k_max_im : float
        The box's largest ``Re K`` and ``Im K``, N/m.
    key : str
        The input blamed in the error (``model``; ``model.table`` from a configuration).

    Raises
    ------
    InputError
        Where ``2 max_b sum_k u_ck^2 / (2 zeta_k w_k^2)`` (an upper estimate of a damper's
        receptance at resonance, m/N) times ``|k_max + i k_max_im|`` is above
        :data:`SCALE_MAX`: a table in wrong units (shapes not mass-normalised, zeta
        near 0), for which the searches would lose the response in rounding.
    """
    f, z, u = model.modal_arrays()
    w = 2 * np.pi * f
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        peak = float(np.max((u[:, :, 0] ** 2 / (2 * z * w * w)).sum(axis=1)))
        ratio = 2 * peak * float(np.hypot(k_max, k_max_im))
    if not ratio <= SCALE_MAX:
        raise InputError(key, f"the contacts' receptance at resonance (u^2 / (2 zeta w^2) "
                              f"summed over the modes: {peak:.3g} m/N) times the largest "
                              f"describing function modulus ({np.hypot(k_max, k_max_im):.3g} N/m) "
                              f"is {ratio:.3g}, beyond the {SCALE_MAX:g} the bounds resolve "
                              f"in rounding: check the table's units (shapes mass-normalised, "
                              f"kg^-1/2; zeta a ratio)")


def compute_bounds(model, freq_hz, k_max, *, k_max_im=None, F_lim=None, quantity="displacement",
                   beams=None, n_starts=N_STARTS, max_sweeps=MAX_SWEEPS, seed=0, n_threads=None,
                   certified=True, budget=None, split=None, moments="auto", progress=None):
    """Equivalent-linear bounds on the response metric of ``model``.

    Parameters
    ----------
    model : Model
    freq_hz : array_like, shape (n_f,)
        Frequencies, Hz.
    k_max : float
        Largest stiffness ``Re K`` of a damper, N/m (the paper: 15 kN/m; at most
        ``K_MAX_LIMIT`` = 1e12 N/m).
    k_max_im : float, optional
        Largest dissipation ``Im K``, N/m; default ``k_max`` (at most 1e12 N/m).
    F_lim : float, optional
        Friction force limit of the first harmonic, N: ``force_limit(mu_max, N0_max)``.
        Default ``inf`` (no force constraint: the upper bound is the box maximum).
    quantity : {"displacement", "velocity", "acceleration"}
    beams : sequence of int, optional
        0-based beams of the metric (a set: order and repeats change nothing; kept as
        given in the result); default all.
    n_starts : int
        Starts of the search for the minimum per frequency, 1..10000 (at least
        ``MIN_TOTAL_STARTS / n_f``; the default 3 on a 1000-point grid: the centre and
        the uniform corners K = 0 and K = k_max); the maximum, sought beam by beam, uses
        half as many per beam, at least the four uniform corners.
    max_sweeps : int
        Coordinate sweeps per start of the minimum (the maximum's: half as many,
        ``MAX_SWEEPS_FRACTION_MAX``); the maximum's final tight search takes five times
        as many, the minimum's one tight sweep before its minimax search.
    seed : int
        Seed of the random starts (the bounds are deterministic for a given seed).
    n_threads : int, optional
    certified : bool
        Also certify the bounds over the admissible set (:mod:`.certified`, the
        ``certificate`` attribute); False for a quick look.
    budget : int, optional
        Enclosures per frequency and bound of the certification; default 4000 for one
        damper, 400 for more (50 from six dampers, where the relaxation follows:
        :func:`.certified.default_budget`).
    split : int, optional
        Relaxations of parts of the box per frequency where the relaxation of the whole
        box leaves the upper bound loose, the lower bound at most 800 of them (0: none;
        default :data:`.certified.SPLIT_BUDGET`, 3200:
        :mod:`mcfric.core.relaxation_branch`; two to seven dampers only).
    moments : bool or "auto"
        Also tighten the certified upper bound by the second-order moment relaxation
        where the first-order one leaves it loose (:mod:`.moments`; chains of 2-7
        dampers with a force limit). ``"auto"`` (default): where it applies; False: the
        first order alone (about a third of the time on eight beams, the upper bound
        within 1 % of its witness at 84-93 % of the frequencies instead of 99.9-100 %:
        docs/bounds.md); True: an error where it cannot run.
    progress : bool or None
        Progress bars of the certification on stderr: None (default) on a terminal only,
        False never, True always.

    Returns
    -------
    Bounds
    """
    if not isinstance(model, Model):
        raise ValueError(f"model: expected a mcfric Model, got {type(model).__name__}")
    f = check_frequencies(freq_hz)
    kr = real("k_max", k_max, lo=0, lo_open=True)
    ki = kr if k_max_im is None else real("k_max_im", k_max_im, lo=0, lo_open=True)
    for name, k in (("k_max", kr), ("k_max_im", ki)):
        if k > K_MAX_LIMIT:
            raise ValueError(f"{name}: expected at most {K_MAX_LIMIT:g} N/m (a stuck "
                             f"damper), got {k:g}")
    F_lim = (np.inf if F_lim is None
             else real("F_lim", F_lim, lo=0, lo_open=True, allow_inf=True))
    check_quantity(quantity, "quantity")
    beams = (tuple(range(model.n_beams)) if beams is None
             else check_beams(beams, model.n_beams))
    # n_starts as the configuration's bounds.n_starts: 10**12 asked numpy for 10.9 TiB
    integer(1, N_STARTS_MAX)(n_starts, "n_starts")
    for name, v, lo in (("max_sweeps", max_sweeps, 1), ("seed", seed, 0)):
        integer(lo)(v, name)
    for name, v, lo in (("budget", budget, 1), ("split", split, 0)):
        if v is not None:       # None: the certificate's default
            integer(lo)(v, name)
    flag("certified", certified)
    check_moments_choice(moments)    # without certification too: "yes" was ignored there
    if progress is not None and not is_bool(progress):
        raise ValueError(f"progress: expected True, False or None, got {progress!r}")
    for i, t in enumerate(model.beams):
        if np.any(t.zeta == 0):
            # the box holds free dampers (K = 0): the bounds would be infinite at that
            # mode's resonance, and the search divides by the damping
            raise InputError("model", f"beam {i + 1} has a mode without damping (zeta = 0); "
                             f"the bounds need every mode damped (zeta > 0): an undamped "
                             f"mode has an unbounded resonance")
    check_scales(model, kr, ki)
    if model.contact_law != "coulomb":
        # the box of describing functions and the force limit are Coulomb friction's
        raise ValueError(f"model: the bounds are for Coulomb friction contacts, got "
                         f"contact_law = {model.contact_law!r}")
    if certified:
        moments = resolve_moments(moments, model.topology == "linear", model.n_dampers,
                                  F_lim)

    omega = 2 * np.pi * f
    rec = model.receptances(omega)[0]
    a, b = model.dampers
    G, q0, ylin, H = contact_space(rec, model.force, a, b)
    # the metric is the largest over a set of beams: order and repeats change nothing,
    # and the ring's turns and a chain's mirror pairs read the beams in their order
    sel = sorted(set(beams))
    ylin_all, H_all = ylin, H
    ylin = np.ascontiguousarray(ylin[:, sel])
    H = np.ascontiguousarray(H[:, sel, :])
    # the maximum is sought beam by beam; on a tuned ring under a travelling wave every
    # blade has the same one (rotation_invariant), so one blade's search serves all
    invariant = rotation_invariant(model)
    n_up = 1 if invariant else len(sel)
    n_starts = max(int(n_starts), -(-MIN_TOTAL_STARTS // len(f)))
    # the maximum runs once per beam (each a smoother problem): half the starts each
    starts_max, _ = starts(len(f), model.n_dampers, max(4, n_starts // 2), seed)
    _, starts_min = starts(len(f), model.n_dampers, n_starts, seed + 1)
    G = np.ascontiguousarray(G)
    q0 = np.ascontiguousarray(q0)
    with threads(n_threads):
        upper, upper_box, upper_force, limited_by, K_upper = upper_bound(
            G, q0, np.ascontiguousarray(ylin[:, :n_up]), np.ascontiguousarray(H[:, :n_up]),
            kr, ki, F_lim, starts_max,
            max(1, round(MAX_SWEEPS_FRACTION_MAX * int(max_sweeps))))
        # tuned rings: the gradient stage of the minimum's searches never changed the
        # lower bound (measured: the performance page), and it costs a third of the time
        lower, K_lower = box_extreme(G, q0, ylin, H, kr, ki, starts_min, False,
                                     max_sweeps=int(max_sweeps), gradient=not invariant)
        lower, K_lower = lower[0], K_lower[0]
        scale = omega ** QUANTITIES.index(quantity)
        every = sel == list(range(model.n_beams))
        cert = (certify(G, q0, ylin, H, kr, ki, F_lim, K_upper, K_lower, scale, budget,
                        split=split, moments=moments, turned=invariant and every,
                        progress=progress)
                if certified else None)
        if certified and invariant and not every and turns(model.n_dampers, F_lim):
            # a tuned ring's relaxations need every blade in the metric; the largest
            # response over all blades bounds any subset's (docs/bounds.md, tuned rings)
            whole = certify(G, q0, np.ascontiguousarray(ylin_all),
                            np.ascontiguousarray(H_all), kr, ki, F_lim, K_upper, K_lower,
                            scale, budget, split=split, moments=moments, turned=True,
                            progress=progress, lower=False)
            cert = subset_of_ring(cert, whole, G, q0, ylin_all, H_all, sel, F_lim, scale)
    return Bounds(f, upper * scale, lower * scale, upper_box * scale, upper_force * scale,
                  limited_by, K_upper, K_lower, kr, ki, F_lim, quantity, beams, cert)


def from_spec(spec, n_threads=None, progress=None):
    """Bounds of a :class:`~mcfric.spec.RunSpec` (its nominal model, frequency grid,
    metric and bounds settings); ``n_threads`` defaults to the spec's execution threads,
    ``progress`` as for :func:`compute_bounds`.

    The model is the nominal one: mistuned members come from other linear rigs and need
    not lie inside (the paper's bounds cover friction only).
    """
    b = spec.bounds
    return compute_bounds(spec.model, spec.freq_hz, b.k_max_re, k_max_im=b.k_max_im,
                          F_lim=None if np.isinf(b.F_lim) else b.F_lim,
                          quantity=spec.metric.quantity, beams=spec.metric.beams,
                          n_starts=b.n_starts, certified=b.certify, budget=b.budget,
                          split=b.split, moments=b.moments, progress=progress,
                          n_threads=spec.execution.threads if n_threads is None else n_threads)
