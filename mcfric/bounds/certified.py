"""Certified bounds: an enclosure of the metric's extremes over the admissible set.

The searched bounds (:mod:`.equivalent_linear`) are the extremes a search found. Here a
branch and bound (:mod:`mcfric.core.branch_bound`) proves, at every frequency, a value
``upper_certified >=`` the largest ``M`` over the admissible set (every damper in its box
*and* at or below the force limit) and ``lower_certified <=`` the smallest, each beside a
witness: an admissible set of describing functions that attains it. Rounding cannot
break the guarantee (the argument: :mod:`mcfric.core.enclosure`, and the docs' bounds
page). Where the budget of enclosures runs out first the certified values are still
valid, only looser; the upper one is never above the force bound (paper Eq. 10, itself a
proof; rounded outward by ``_FORCE_MARGIN``, so up to 1e-12 relative above the stored
``upper_force``) and the lower one never below 0.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..core import force_ascent, force_newton
from ..core.box_relaxation import relax_frequencies
from ..core.branch_bound import certify_frequencies
from ..core.joint_ascent import values, witnesses
from ..core.joint_descent import lowest
from ..core.partly_tied_relaxation import NEAR
from ..core.relaxation_branch import branch_frequencies, mirror_sign
from ..threads import in_threads
from ..validators import is_bool
from .search import _chunks

#: Enclosures per frequency and bound at most (the branch and bound's budget) ...
BUDGET = 400
#: ... and with one damper, where each enclosure is cheap and the branch and bound closes
#: the gap everywhere given enough of them (measured: the docs' bounds page).
BUDGET_ONE_DAMPER = 4000
#: ... and with six or more dampers where the relaxation follows, which then proves all the
#: branch and bound did (seven dampers: the same bounds and witnesses at 50 as at 400, 0.6 s
#: less per 1000 frequencies; five dampers: 20 instead of 400 left 5 % fewer lower bounds
#: tight, so fewer dampers keep ``BUDGET``).
BUDGET_RELAXED = 50
RELAXED_FROM = 6
#: Stop where the best open bound is within this of the witness (relative; two or more
#: dampers: the tightness asked of the certificate; half of it costs much more time for
#: the same count within it, docs/bounds.md) ...
RTOL = 1e-2
#: ... with one damper, where the enclosures are cheap ...
RTOL_ONE_DAMPER = 5e-3
#: ... or, for the minimum, within this fraction of the certified upper bound (absolute).
ATOL_FRACTION = 1e-3
#: Above this many dampers the branch and bound proves nothing beyond the force bound and
#: 0 within any practical budget (measured: the docs' bounds page), so it is not run: the
#: certificate is then Eq. 10 and 0, with the witnesses ...
MAX_DAMPERS = 7
#: ... but on a tuned ring under a travelling wave of up to this many dampers the
#: relaxation of the whole box tightens them (one relaxation per frequency and bound; its
#: time grows about with the cube of the dampers: the docs' performance page).
MAX_TURNED = 24
#: ... and of up to this many the relaxations with the multipliers tied across dampers
#: (the lower bound's all, the upper bound's but near the beam: Fourier barriers, cheap;
#: the checks of every beam's turned multipliers, O(nd^3) each, and the climbs and
#: descents to the witnesses cost more, about as the searches do; where the tied lower
#: relaxation fails the full one runs, whose dense workspace grows with nd^2 and its
#: steps with nd^3). The largest ring measured (the docs' performance page).
MAX_TIED = 144
#: The ascent to the upper witness over the admissible set, per frequency: random points
#: of the box tried (besides no damper and the search's box optimum) ...
WITNESS_POOL = 200
#: ... of which this many admissible ones, those of largest M, are climbed ...
WITNESS_STARTS = 6
#: ... each for this many beams (those of the largest force bound) ...
WITNESS_BEAMS = 2
#: ... with at most this many sweeps over the dampers, stopping when one gains less than
#: this (relative), and this many samples per force circle and edge of a damper's
#: rectangle in each step.
WITNESS_SWEEPS = 20
WITNESS_GAIN = 1e-4
WITNESS_SAMPLES = 12
#: Upper witnesses where the bound is loose are climbed again from the witnesses of the
#: frequencies this many places either side, and again while that improves any (at most
#: ``NEIGHBOUR_PASSES`` times): the maximiser moves smoothly with frequency.
NEIGHBOUR_REACH = 2
NEIGHBOUR_PASSES = 8
#: Whether the semidefinite relaxation of the whole box tightens the branch and bound's
#: bounds where they are not yet within the tolerance (two or more dampers, a force limit).
RELAX = True
#: Relaxations of parts of the box per frequency at most for the upper bound, where the
#: relaxation of the whole box leaves it loose (:mod:`mcfric.core.relaxation_branch`).
SPLIT_BUDGET = 3200
#: The lower bound's at most (more closes few lower bounds: docs/bounds.md).
LOWER_SPLIT_BUDGET = 800
#: Open parts of least lower bound whose relaxations are rounded, where splitting leaves
#: the lower bound loose, as starts for the lower witness's descent.
ROUNDED_PARTS = 4
#: Newton steps, barrier rounds, relaxations and failed relaxations of the last call,
#: upper and lower (for the docs' measurements); the split's also the mirrored parts
#: verified.
LAST_RELAXATION = np.zeros((2, 4), np.int64)
LAST_SPLIT = np.zeros((2, 5), np.int64)
#: Second-order bounds of the last call taken from the mirror beam's duals, relaxations
#: of parts (:mod:`.moments_branch`; also counted as solved), and of those the geometric
#: branch's.
LAST_MOMENTS = np.zeros(3, np.int64)
#: A mirrored second-order dual is kept where its bound is within this of the mirror
#: beam's (on a chain that is its mirror image they agree to about 1e-12).
MIRROR_RTOL = 1e-6
#: The second order's parts are relaxed where its bound is above the witness's
#: tolerance but within this of the witness (farther above, splitting the own dampers
#: was not seen to help), at most ``MOMENTS_SPLIT`` relaxations per frequency.
MOMENTS_SPLIT_GAP = 0.03
MOMENTS_SPLIT = 64
#: Where the own dampers' parts do not reach the witness's tolerance, or the bound is
#: above ``MOMENTS_SPLIT_GAP`` but within this of the witness, every damper's rectangle
#: is split, one at a time (:func:`.moments_branch.branch_bound`'s ``geometric``; the
#: same budget).
GEOMETRIC_GAP = 0.05
#: Where the upper bound is still loose after the second order, at most this many
#: frequencies (the loosest) have their witnesses polished beam by beam by SLSQP
#: (:mod:`.witness_polish`): a bounded cost where many stay loose and the looseness is
#: the bound's, not the witness's (docs/bounds.md).
POLISH_MAX = 16
#: Frequencies polished in the last call, and of those where the witness rose.
LAST_POLISH = np.zeros(2, np.int64)
#: Relative margin on the force bound (a sum of non-negative products: (nd + 2) u).
_FORCE_MARGIN = 1e-12


@dataclass
class Certificate:
    """Certified bounds over frequency, in the metric's unit, and their witnesses.

    Attributes
    ----------
    upper, lower : ndarray, shape (n_f,)
        ``upper >= max M`` and ``lower <= min M`` over the admissible set.
    upper_witness, lower_witness : ndarray, shape (n_f,)
        ``M`` at the witnesses: admissible points, so the true extremes lie between
        witness and certified value.
    K_upper, K_lower : ndarray of complex, shape (n_f, nd)
        The witnesses' describing functions, N/m.
    converged : ndarray of bool, shape (2, n_f)
        Whether the upper (row 0) and lower (row 1) bound met the tolerance (by the
        branch and bound within its budget, or after the relaxation).
    evaluations : ndarray of int, shape (2, n_f)
        Enclosures evaluated.
    budget : int
    relaxed : bool
        Whether the semidefinite relaxation ran: after the branch and bound (two to seven
        dampers), or alone (tuned rings of 8 to ``MAX_TURNED`` blades; up to
        ``MAX_TIED`` with the multipliers tied across dampers).
    second_order : ndarray of int, shape (2,)
        Second-order moment relaxations (:mod:`.moments`) of the upper bound solved, and
        of those failed (solver or verification; the first-order bound kept there).
    first_order : ndarray of int, shape (2,)
        First-order relaxations (:mod:`mcfric.core.relaxation`) of the whole box and of
        its parts, upper and lower bound together, and of those failed (nothing
        verified: the bound before them kept, valid and looser).
    split : int
        Relaxations of parts of the box per frequency and bound at most
        (:mod:`mcfric.core.relaxation_branch`; 0: none).
    split_used : ndarray of int, shape (2,)
        Relaxations of parts of the box made for the upper and the lower bound.
    moments : bool
        Whether the second-order relaxation was on (it runs where the first order
        leaves the upper bound loose).
    rtol : float
        The tolerance the certification aimed for (relative, above the upper witness and
        below the lower; ``converged`` says where it was met).
    """

    upper: np.ndarray
    lower: np.ndarray
    upper_witness: np.ndarray
    lower_witness: np.ndarray
    K_upper: np.ndarray
    K_lower: np.ndarray
    converged: np.ndarray
    evaluations: np.ndarray
    budget: int
    relaxed: bool = False
    second_order: np.ndarray = field(default_factory=lambda: np.zeros(2, np.int64))
    split: int = 0
    split_used: np.ndarray = field(default_factory=lambda: np.zeros(2, np.int64))
    moments: bool = False
    rtol: float = RTOL_ONE_DAMPER
    first_order: np.ndarray = field(default_factory=lambda: np.zeros(2, np.int64))

    @property
    def upper_gap(self):
        """``upper / upper_witness - 1`` per frequency (inf where not certified)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.upper / self.upper_witness - 1.0

    @property
    def lower_gap(self):
        """``1 - lower / lower_witness`` per frequency (1 where only 0 is proved)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.lower_witness > 0, 1.0 - self.lower / self.lower_witness, 0.0)

    def contains(self, metric, rtol=1e-9):
        """Boolean mask ``lower (1 - rtol) <= metric <= upper (1 + rtol)`` (NaN -> False)."""
        return within(metric, self.lower, self.upper, rtol)

    @property
    def lower_tight(self):
        """Where the lower bound is within 1 % of its witness or within ``ATOL_FRACTION``
        of the certified upper bound (absolute: deep valleys of the minimum)."""
        with np.errstate(invalid="ignore"):
            return ((self.lower_gap <= 0.01)
                    | (np.isfinite(self.upper)
                       & (self.lower_witness - self.lower <= ATOL_FRACTION * self.upper)))

    def summary(self, freq_hz):
        """Which order certified, where the certificate is within 1 % of its witness, the
        largest gaps and where they are, and where the tolerance was not met
        (``freq_hz``: the frequencies, Hz)."""
        f = np.asarray(freq_hz)
        n = len(self.upper)
        up = self.upper_gap
        loose = ~self.lower_tight
        k_up = int(np.argmax(np.where(np.isnan(up), -np.inf, up)))
        lo_gap = np.where(loose, self.lower_gap, -np.inf)
        k_lo = int(np.argmax(lo_gap))
        if not self.moments:
            order = "first order"
        else:
            solved, failed = (int(x) for x in self.second_order)
            order = (f"second order: {solved} relaxations" + (f", {failed} failed (first-"
                     f"order bound kept there)" if failed else "") if solved
                     else "second order: none needed")
        relaxed, failed = (int(x) for x in self.first_order)
        if failed:
            order += (f"; {failed} of {relaxed} first-order relaxations failed (the bound "
                      f"before each kept)")
        text = (f"certified ({order}; stopping {100 * self.rtol:.3g} % from the witnesses): "
                f"upper within 1 % "
                f"of its witness at {np.count_nonzero(up <= 0.01)} of {n} frequencies "
                f"(largest gap {_pct(up[k_up])} at {f[k_up]:.4g} Hz); lower within 1 % or "
                f"{ATOL_FRACTION:g} x upper at {n - np.count_nonzero(loose)}")
        if loose.any():
            text += f" (largest gap elsewhere {_pct(lo_gap[k_lo])} at {f[k_lo]:.4g} Hz)"
        # above MAX_DAMPERS no branch and bound runs: say so, not that a budget ran out
        why = ("within the budget" if self.K_upper.shape[1] <= MAX_DAMPERS else
               f"(a relaxation only, no branch and bound above {MAX_DAMPERS} dampers)"
               if self.relaxed else f"(no branch and bound above {MAX_DAMPERS} dampers)")
        for row, name in enumerate(("upper", "lower")):
            out = ~self.converged[row]
            if out.any():
                text += (f"; {name}: tolerance not met {why} at "
                         f"{np.count_nonzero(out)} frequencies in {f[out].min():.4g}-"
                         f"{f[out].max():.4g} Hz (valid there, looser)")
        return text


def within(metric, lower, upper, rtol):
    """Boolean mask ``lower (1 - rtol) <= metric <= upper (1 + rtol)`` (NaN -> False): the
    containment test of searched and certified bounds alike."""
    metric = np.asarray(metric)
    with np.errstate(invalid="ignore"):
        return (metric >= lower * (1 - rtol)) & (metric <= upper * (1 + rtol))


def default_rtol(n_dampers):
    """The certificate's default relative tolerance: ``RTOL_ONE_DAMPER`` for one damper,
    else ``RTOL``."""
    return RTOL_ONE_DAMPER if n_dampers == 1 else RTOL


def default_budget(n_dampers, relaxed=False):
    """The branch and bound's default budget: ``BUDGET_ONE_DAMPER`` for one damper,
    ``BUDGET_RELAXED`` for ``RELAXED_FROM`` dampers or more where the relaxation follows
    (``relaxed``), else ``BUDGET``."""
    if n_dampers == 1:
        return BUDGET_ONE_DAMPER
    return BUDGET_RELAXED if relaxed and n_dampers >= RELAXED_FROM else BUDGET


def joint_witnesses(args, kr, ki, F_lim, given, stop, freqs=None, pool=None, climb=None,
                    seed=0):
    """Admissible points of large ``M`` (N/m, shape (n_f, nd)) and their ``M`` (m): the
    best that :func:`mcfric.core.joint_ascent.witnesses` climbs to per frequency, from
    the rows of ``given`` (n_f, n_g, nd; pulled inside the force limit) and ``pool``
    random points (default ``WITNESS_POOL``; ``climb``: how many of the best are climbed,
    default ``WITNESS_STARTS``), until one comes within 1e-4 of ``stop`` (n_f,) m.
    ``args``: the contact-space arrays (contiguous); ``freqs``: the frequencies to treat
    (default all; elsewhere ``M = -inf``)."""
    n_f, n_g, nd = given.shape
    freqs = np.arange(n_f) if freqs is None else np.asarray(freqs)
    pool = WITNESS_POOL if pool is None else pool
    climb = WITNESS_STARTS if climb is None else climb
    given = np.ascontiguousarray(given)
    stop = np.ascontiguousarray(stop, dtype=float)
    K = np.zeros((n_f, nd), complex)
    M = np.full(n_f, -np.inf)
    if len(freqs):
        in_threads(lambda fs: witnesses(*args, kr, ki, F_lim, given, pool, climb,
                                        WITNESS_BEAMS, WITNESS_SWEEPS, WITNESS_GAIN,
                                        WITNESS_SAMPLES, seed, stop,
                                        np.asarray(fs, np.int64), K, M),
                   [freqs[c] for c in _chunks(len(freqs))])
    return K, M


def moments_apply(chain, n_dampers, F_lim):
    """Whether the second-order relaxation applies: a chain (``chain``) of 2 to
    ``MAX_DAMPERS`` dampers with a finite force limit (N)."""
    return bool(chain and 2 <= n_dampers <= MAX_DAMPERS and np.isfinite(F_lim))


def check_moments_choice(moments):
    """Raise a one-line ValueError unless ``moments`` is ``"auto"``, True or False."""
    if not (is_bool(moments) or (isinstance(moments, str) and moments == "auto")):
        raise ValueError(f'moments: expected "auto", True or False, got {moments!r}')


def resolve_moments(moments, chain, n_dampers, F_lim):
    """The second order on or off: ``"auto"`` (the default) where it applies
    (:func:`moments_apply`), ``True`` everywhere (a one-line ValueError where it cannot
    run), ``False`` nowhere."""
    check_moments_choice(moments)
    if isinstance(moments, str):
        moments = moments_apply(chain, n_dampers, F_lim)
    if moments:
        check_moments(chain, n_dampers, F_lim)
    return bool(moments)


def check_moments(chain, n_dampers, F_lim):
    """Raise a one-line ValueError unless the second-order relaxation can run: Clarabel
    installed, a chain (``chain``) of 2 to ``MAX_DAMPERS`` dampers, a finite force limit
    (N)."""
    from .moments import available

    if not available():
        raise ValueError('moments: needs Clarabel, a dependency of mcfric: pip install '
                         '"clarabel>=0.9"')
    if not moments_apply(chain, n_dampers, F_lim):
        raise ValueError(f"moments: only for a chain of 2 to {MAX_DAMPERS} dampers with a "
                         f"force limit (this one: {n_dampers} damper"
                         f"{'s' if n_dampers != 1 else ''}, {'a chain' if chain else 'not a chain'}"
                         f", F_lim = {F_lim:g} N)")


def turns(n_dampers, F_lim):
    """Whether :func:`certify` relaxes a tuned ring of ``n_dampers`` blades with every
    blade in the metric (``turned``): above ``MAX_DAMPERS`` and up to ``MAX_TIED``, with
    a finite force limit (N)."""
    return bool(RELAX and np.isfinite(F_lim) and MAX_DAMPERS < n_dampers <= MAX_TIED)


def subset_of_ring(sub, whole, G, q0, ylin, H, beams, F_lim, scale):
    """A tuned ring's certificate for some of its blades, with the upper bound and its
    witness of the whole ring's.

    Every blade's response is at most the largest over all blades, so ``whole.upper``
    bounds the subset's maximum too. Turning the ring maps the admissible set onto
    itself and one blade's response onto another's, so a turn of the whole ring's upper
    witness puts its largest blade on the subset's first: both ways of turning are
    tried, and the better admissible result (its value and forces recomputed here)
    replaces ``sub``'s witness where it is higher. The lower bound stays ``sub``'s (the
    minimum over a subset has no such symmetry).

    Parameters
    ----------
    sub, whole : Certificate
        Of the subset (``turned`` off) and of every blade (``turned`` on), same grid.
    G, q0, ylin, H : ndarray
        The contact-space arrays of every blade (:func:`mcfric.core.receptance.
        contact_space`; ``ylin`` and ``H`` in m before ``scale``).
    beams : list of int
        The subset, 0-based.
    F_lim : float
        Force limit, N.
    scale : ndarray, shape (n_f,)
        The metric's factor (``omega ** k`` for the quantity).
    """
    n_f, nd = q0.shape
    eye = np.eye(nd)
    target = beams[0]            # by the symmetry every blade of the subset does as well
    value = np.empty((n_f, 2))
    force = np.empty((n_f, 2, nd))
    cand = np.empty((n_f, 2, nd), complex)
    for lo in range(0, n_f, 64):                 # (64, 2, nd, nd) systems at a time
        f = slice(lo, lo + 64)

        def responses(K, f=f):
            """Every blade's response (m) and damper force (N) at the candidates ``K``
            (n, c, nd): ``q = (I + G diag(K))^-1 q0``, as the kernels solve it."""
            T = eye + G[f, None] * K[:, :, None, :]
            q = np.linalg.solve(T, np.broadcast_to(q0[f, None, :, None],
                                                   K.shape + (1,)))[..., 0]
            p = K * q
            return ylin[f, None] - np.einsum("fbj,fcj->fcb", H[f], p), np.abs(p)

        Kw = whole.K_upper[f]
        with np.errstate(all="ignore"):
            y, _ = responses(Kw[:, None])
            top = np.argmax(np.nan_to_num(np.abs(y[:, 0]), nan=-1.0), axis=1)
            # turn the largest blade onto the target, one way or the other round
            s = np.stack([(target - top) % nd, (top - target) % nd], axis=1)
            idx = (np.arange(nd)[None, None, :] - s[:, :, None]) % nd
            cand[f] = np.take_along_axis(np.broadcast_to(Kw[:, None, :], idx.shape), idx,
                                         axis=2)
            y, force[f] = responses(cand[f])
            value[f] = np.abs(y[..., beams]).max(axis=2) * scale[f, None]
    ok = np.isfinite(value) & np.all(force <= F_lim, axis=2)
    value = np.where(ok, value, -np.inf)
    best = np.argmax(value, axis=1)
    found = value[np.arange(n_f), best]
    better = found > sub.upper_witness
    wit = np.where(better, found, sub.upper_witness)
    K = np.where(better[:, None], cand[np.arange(n_f), best], sub.K_upper)
    upper = np.maximum(np.fmin(sub.upper, whole.upper), wit)
    converged = sub.converged.copy()
    converged[0] |= _met(True, upper, wit, sub.rtol, 0.0)
    return replace(sub, upper=upper, upper_witness=wit, K_upper=K, converged=converged,
                   relaxed=sub.relaxed or whole.relaxed,
                   first_order=sub.first_order + whole.first_order)


def _met(want_max, cert, wit, rtol, atol):
    """Where a certified bound is within the tolerance of its witness: ``rtol``
    relative, or for the minimum also ``atol`` absolute (m)."""
    if want_max:
        return cert <= wit * (1 + rtol)
    return (cert >= wit * (1 - rtol)) | (wit - cert <= atol)


def _target(want_max, wit, rtol, atol):
    """What a certified bound must reach to meet the tolerance of :func:`_met` (m)."""
    return wit * (1 + rtol) if want_max else np.maximum(wit * (1 - rtol), wit - atol)


def _force_ascent(args, kr, ki, F_lim, starts, stop, wit, K, newton=True):
    """Witnesses improved in the damper forces from ``starts`` (n_f, n_s, nd) where
    ``wit`` is below ``stop`` (m), stopping there: first by
    :func:`mcfric.core.force_ascent.ascend_frequencies` (each beam's own dampers' forces),
    then (``newton``), where still below, by
    :func:`mcfric.core.force_newton.climb_frequencies` (all forces at once). ``K`` is
    updated in place, the new witness values returned."""
    starts = np.ascontiguousarray(starts)
    stop = np.ascontiguousarray(stop, dtype=float)
    kernels = (force_ascent.ascend_frequencies, force_newton.climb_frequencies)
    for kernel in kernels if newton else kernels[:1]:
        todo = np.flatnonzero(wit < stop)
        if not len(todo):
            break
        floor = np.ascontiguousarray(wit, dtype=float)
        Kb = np.zeros_like(K)
        Mb = np.full(len(wit), -np.inf)
        in_threads(lambda fs, kernel=kernel, floor=floor, Kb=Kb, Mb=Mb: kernel(
            *args, kr, ki, F_lim, starts, floor, stop, np.asarray(fs, np.int64), Kb, Mb),
            [todo[c] for c in _chunks(len(todo))])
        better = Mb > wit
        K[better] = Kb[better]
        wit = np.where(better, Mb, wit)
    return wit


def _neighbours(K):
    """Starts from the witnesses ``K`` (n_f, nd; N/m) of the ``NEIGHBOUR_REACH`` rows
    either side of each row (clipped at the ends): (n_f, 2 NEIGHBOUR_REACH, nd)."""
    n_f = len(K)
    rows = np.arange(n_f)
    return np.stack([K[np.clip(rows + d, 0, n_f - 1)]
                     for r in range(1, NEIGHBOUR_REACH + 1) for d in (-r, r)], axis=1)


def _from_neighbours(args, kr, ki, F_lim, want_max, cert, wit, K, stop, rtol, atol):
    """Witnesses improved where ``cert`` is loose by climbing (upper) or descending
    (lower) from the witnesses of the neighbouring frequencies (:func:`_neighbours`; the
    rows are taken as neighbours in frequency), repeated while any improves: a search
    that stopped on a lower peak than at the neighbouring frequencies (every other
    frequency at 117-123 Hz, 0.25 N, with upper bounds 25-45 % above them) starts from
    theirs. ``stop`` (m): where the upper climbs stop. ``K`` and ``wit`` are updated in
    place; returns ``wit``."""
    for _ in range(NEIGHBOUR_PASSES):
        loose = ~_met(want_max, cert, wit, rtol, atol)
        if want_max:
            loose &= wit < stop
        todo = np.flatnonzero(loose)
        if not len(todo) or len(K) < 2:
            break
        given = _neighbours(K)
        before = wit.copy()
        if want_max:
            Kw, Mw = joint_witnesses(args, kr, ki, F_lim, given, stop, todo, pool=0,
                                     climb=given.shape[1])
            better = Mw > wit
            K[better] = Kw[better]
            wit[better] = Mw[better]
            # and in the forces (near a resonance the response is a sharp ridge in K)
            wit[:] = _force_ascent(args, kr, ki, F_lim, given, stop, wit, K)
            gained = wit > before * (1 + 1e-9)
        else:
            _descend(args, kr, ki, F_lim, given, cert, wit, K, rtol, atol)
            gained = wit < before * (1 - 1e-9)
        if not gained.any():
            break
    return wit


def _relaxed(args, kr, ki, F_lim, want_max, cert, wit, rtol, atol, turn=False, near=0):
    """``cert`` improved by the semidefinite relaxation of the whole box
    (:mod:`mcfric.core.relaxation`) where it is not yet within the tolerance of its
    witness (``turn``: a tuned ring's arrays, :func:`certify`'s ``turned``; ``near > 0``:
    the upper bound's multipliers tied but at the ``2 near`` dampers next to the beam,
    :mod:`mcfric.core.partly_tied_relaxation`); the
    relaxation's rounded points (n_f, 2, nd; N/m, NaN where none:
    :func:`mcfric.core.relaxation.rounded`), each beam's proven bound (n_f, nb; m,
    ``inf`` where not relaxed; the upper bound's only), and the numbers of relaxations
    made and failed (2,)."""
    n_f, nd = args[1].shape
    loose = np.flatnonzero(~_met(want_max, cert, wit, rtol, atol))
    target = _target(want_max, wit, rtol, atol)
    K_round = np.full((n_f, 2, nd), np.nan + 0j)
    beam_bounds = np.full((n_f, args[2].shape[1]), np.inf)
    if not len(loose):
        return cert, K_round, beam_bounds, np.zeros(2, np.int64)
    got = np.full(n_f, np.inf if want_max else 0.0)
    floor = np.ascontiguousarray(wit)
    target = np.ascontiguousarray(target)
    stats = np.zeros((len(loose), 4), np.int64)
    # a frequency per task: Ctrl-C waits for one frequency's kernel, not a batch's
    in_threads(lambda item: relax_frequencies(*args, kr, ki, F_lim, want_max, floor,
                                              target, item[1], got, K_round, beam_bounds,
                                              stats[item[0]], bool(turn), np.int64(near)),
               enumerate(np.split(loose.astype(np.int64), len(loose))))
    total = stats.sum(axis=0)
    LAST_RELAXATION[int(not want_max)] = total
    cert = np.fmin(cert, got) if want_max else np.fmax(cert, got)
    return cert, K_round, beam_bounds, total[2:4]


def _split(args, kr, ki, F_lim, want_max, cert, wit, rtol, atol, beam_bounds, budget,
           progress=None):
    """``cert`` tightened, where it is not yet within the tolerance of ``wit``, by the
    branch and bound over relaxations of parts of the box
    (:mod:`mcfric.core.relaxation_branch`), ``budget`` relaxations per frequency at most;
    ``beam_bounds`` (the upper bound's) is updated in place. Returns the new ``cert``,
    the number of relaxations, for the lower bound the rounded points of the
    :data:`ROUNDED_PARTS` open parts of least bound where it stays loose (n_f,
    2 ROUNDED_PARTS, nd; N/m, NaN where none), and the numbers of relaxations made
    (the lower bound's roundings included) and failed (2,). ``progress`` as for
    :func:`certify`."""
    n_f, nd = args[1].shape
    K_round = np.full((n_f, 0 if want_max else 2 * ROUNDED_PARTS, nd), np.nan + 0j)
    loose = np.flatnonzero(~_met(want_max, cert, wit, rtol, atol) & np.isfinite(cert))
    if not len(loose) or budget <= 0:
        return cert, 0, K_round, np.zeros(2, np.int64)
    target = _target(want_max, wit, rtol, atol)
    from tqdm import tqdm

    got = cert.copy()
    stats = np.zeros((len(loose), 5), np.int64)
    args_ = (*args, kr, ki, F_lim, want_max, np.ascontiguousarray(cert),
             np.ascontiguousarray(target), int(budget))
    # up to a second per frequency: a bar on stderr
    with tqdm(total=len(loose), unit="frequency", disable=_disable(progress), leave=False,
              desc=f"splitting the box ({'upper' if want_max else 'lower'})") as bar:
        def step(item):
            branch_frequencies(*args_, item[1], beam_bounds, got, stats[item[0]], K_round)
            bar.update(len(item[1]))

        # a frequency per task (up to seconds each): Ctrl-C waits for one, not a batch
        in_threads(step, enumerate(np.split(loose.astype(np.int64), len(loose))))
    total = stats.sum(axis=0)
    LAST_SPLIT[int(not want_max)] = total
    return ((np.fmin(cert, got) if want_max else np.fmax(cert, got)),
            int(total[2]), K_round, total[2:4])


def _climb(args, kr, ki, F_lim, starts, stop, wit, K, climb):
    """``wit`` improved (returned; ``K`` in place) by climbs from ``starts`` (n_f, n_s,
    nd; N/m, frequencies whose first row is NaN skipped), ``climb`` of them per
    frequency and no random pool, where the witness is below ``stop`` (n_f,; m):
    :func:`joint_witnesses`."""
    todo = np.flatnonzero(~np.isnan(starts[:, 0, 0]) & (wit < stop))
    Kw, Mw = joint_witnesses(args, kr, ki, F_lim, starts, stop, todo, pool=0, climb=climb)
    better = Mw > wit
    K[better] = Kw[better]
    return np.where(better, Mw, wit)


def _descend(args, kr, ki, F_lim, starts, cert, wit, K, rtol, atol):
    """Lower witnesses improved, where the lower bound is loose, by descents from
    ``starts`` (n_f, n_s, nd; N/m, NaN rows skipped:
    :func:`mcfric.core.joint_descent.lowest`); ``wit`` and ``K`` in place."""
    todo = np.flatnonzero(~np.isnan(starts[:, :, 0]).all(axis=1) &
                          ~_met(False, cert, wit, rtol, atol))
    if len(todo):
        in_threads(lambda fs: lowest(*args, kr, ki, F_lim, starts,
                                     np.asarray(fs, np.int64), K, wit),
                   [todo[c] for c in _chunks(len(todo))])


def _witness_for_beams(G, q0, ylin, H, K):
    """Per beam (nb, nd; N/m) where to cut its own dampers (:mod:`.moments_branch`): the
    witness's describing functions ``K``, reversed for the mirror of the beam where it
    is largest."""
    nd, nb = q0.shape[0], ylin.shape[0]
    K = np.nan_to_num(K)
    p = np.linalg.solve(np.eye(nd) + K[:, None] * G, K * q0)
    top = int(np.argmax(np.abs(ylin - H @ p)))
    out = np.repeat(K[None], nb, axis=0)
    if nb - 1 - top != top:
        out[nb - 1 - top] = K[::-1]
    return out


def _second_order(args, kr, ki, F_lim, cert, wit, K, beam_bounds, rtol, progress=None):
    """The upper ``cert`` improved by the second-order moment relaxation
    (:mod:`.moments`) where it is not yet within ``rtol`` of ``wit``: per frequency the
    beams in decreasing order of ``beam_bounds`` until the next is proven no higher than
    the bounds found (or the witness's tolerance); where a beam's bound is a little above
    the witness (``MOMENTS_SPLIT_GAP``), over parts of its own dampers' rectangles cut at
    the witness's ``K`` (n_f, nd; N/m; :mod:`.moments_branch`), and where that is not
    enough or the bound is farther above (``GEOMETRIC_GAP``), over parts of every
    damper's, one at a time, cut at the whole box's relaxation's describing functions
    (:func:`.moments_branch.geometric_cuts`). Returns the new ``cert``, the
    relaxation's first moments of the beam of largest bound as describing functions
    (n_f, 1, nd; N/m, clipped to the box; NaN where none: starts for the witness) and the
    number of relaxations solved and failed. ``progress`` as for :func:`certify`."""
    from tqdm import tqdm

    from . import moments, moments_branch

    G, q0, ylin, H = args
    n_f, nd = q0.shape
    todo = np.flatnonzero(~_met(True, cert, wit, rtol, 0.0) & np.isfinite(cert))
    counts = np.zeros((len(todo), 5), np.int64)
    new = cert.copy()
    K_first = np.full((n_f, 1, nd), np.nan + 0j)

    def one(i):
        k = todo[i]
        if not np.isfinite(beam_bounds[k]).any():
            return
        order = np.argsort(-beam_bounds[k])
        done = -np.inf
        rest = -np.inf
        # the forces' proven sizes scale the variables (a tenth of F_lim near the first
        # resonances at small drives, where p / F_lim leaves the solver short)
        limits = moments.force_limits(G[k], q0[k], kr, ki, F_lim)
        sign = mirror_sign(G[k], q0[k], ylin[k], H[k])
        if sign:
            # a larger bound is still one; mirrored duals need the same on both sides
            limits = np.maximum(limits, limits[::-1])
        nb = ylin.shape[1]
        goal = wit[k] * (1 + rtol)
        cut = _witness_for_beams(G[k], q0[k], ylin[k], H[k], K[k])
        budget = MOMENTS_SPLIT
        solved = {}
        for b in order:
            if beam_bounds[k, b] <= max(done, goal):
                rest = beam_bounds[k, b]
                break
            m = nb - 1 - b
            solve = m not in solved
            if not solve:
                # the mirror beam's duals, reversed: verified here in a tenth of a second
                # each (solved instead where the chain is not its mirror image after all)
                pm, leaves, vm = solved[m]
                value, verified = moments_branch.mirrored_branch(
                    G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, b, limits, leaves, sign)
                p = sign * pm[::-1]
                counts[i, 2] += verified
                solve = not value <= max(vm * (1 + MIRROR_RTOL), done)
            if solve:
                value, p, z = moments.beam_bound(G[k], q0[k], ylin[k], H[k], kr, ki, F_lim,
                                                 b, limits)
                counts[i, 0] += 1
                counts[i, 1] += not np.isfinite(value)
                leaves = [(moments.box(nd, kr, ki), z, value, limits)]
                box_value = value
                # parts only where the bound stays above the goal after the first-order
                # cap (both are bounds): a little above the witness, the beam's own
                # dampers; where that is not enough or the bound is farther above, every
                # damper one at a time, closing in on nearly open ones
                for geometric, gap in ((False, MOMENTS_SPLIT_GAP), (True, GEOMETRIC_GAP)):
                    if not (goal < min(value, beam_bounds[k, b]) <= wit[k] * (1 + gap)
                            and budget > 0):
                        continue
                    at = (moments_branch.geometric_cuts(cut[b], p, G[k], q0[k], kr, ki)
                          if geometric else cut[b])
                    v, used, lv, stalled, failed = moments_branch.branch_bound(
                        G[k], q0[k], ylin[k], H[k], kr, ki, F_lim, b, limits, box_value,
                        z, at, max(goal, done), budget, sign, geometric)
                    if v < value:
                        value, leaves = v, lv
                    budget -= used
                    counts[i, 0] += used
                    counts[i, 1] += failed
                    counts[i, 3] += used
                    counts[i, 4] += used if geometric else 0
                # splitting that stalls (or runs out) on one beam keeps the frequency loose
                if value > max(goal, done) and min(value, beam_bounds[k, b]) <= wit[k] * (
                        1 + GEOMETRIC_GAP):
                    budget = 0
                # the duals' own (uncapped) bound: the mirror beam's reference
                if sign and np.isfinite(value) and all(leaf[1] is not None for leaf in leaves):
                    solved[b] = (p, leaves, value)
            if min(beam_bounds[k, b], value) > done and not np.isnan(p[0]):
                K_first[k, 0] = moments.describing_functions(p, G[k], q0[k], kr, ki)
            done = max(done, min(beam_bounds[k, b], value))
        new[k] = min(cert[k], max(done, rest, wit[k]))

    # about a second per relaxation: a bar on stderr
    with tqdm(total=len(todo), unit="frequency", desc="second-order relaxations",
              disable=_disable(progress), leave=False) as bar:
        def step(i):
            one(i)
            bar.update()

        # Clarabel releases the GIL: one frequency per thread
        in_threads(step, range(len(todo)))
    total = counts.sum(axis=0)
    LAST_MOMENTS[:] = total[2:5]
    return new, K_first, total[:2]


def _polish(args, kr, ki, F_lim, cert, wit, K, beam_bounds, rtol):
    """Upper witnesses improved where ``cert`` (m; capped by the force bound) is still
    not within ``rtol`` of ``wit``, at the ``POLISH_MAX`` loosest frequencies: each beam
    whose proven bound (``beam_bounds``, m) is above the witness's tolerance is maximised
    on its own (:func:`.witness_polish.polish`; on a chain that is its own mirror image
    one beam of each mirror pair, the one of larger bound). ``K`` is updated in place;
    returns the new ``wit``."""
    from .witness_polish import polish

    before, wit = wit, wit.copy()
    loose = np.flatnonzero(~_met(True, cert, wit, rtol, 0.0) & np.isfinite(cert))
    loose = loose[np.argsort(wit[loose] / cert[loose], kind="stable")][:POLISH_MAX]
    beams = []
    for k in loose:
        over = ~(beam_bounds[k] <= wit[k] * (1 + rtol))
        if mirror_sign(*(a[k] for a in args)):
            nb = len(over)
            for b in range(nb // 2):
                m = nb - 1 - b
                if over[b] and over[m]:
                    over[b if beam_bounds[k, b] < beam_bounds[k, m] else m] = False
        beams.append(np.flatnonzero(over).tolist())
    polish(args, kr, ki, F_lim, K, wit, loose, beams)
    LAST_POLISH[:] = len(loose), np.count_nonzero(wit > before)
    return wit


def _disable(progress):
    """The tqdm ``disable`` of ``progress``: None shows the bar on a terminal only."""
    return None if progress is None else not progress


def _pct(x):
    return "unbounded" if not np.isfinite(x) else f"{100 * x:.3g} %"


def certify(G, q0, ylin, H, kr, ki, F_lim, K_upper, K_lower, scale, budget=None,
            rtol=None, split=None, moments=False, turned=False, progress=None, lower=True):
    """Certified bounds from contact-space arrays (all beams of the metric).

    Parameters
    ----------
    G, q0, ylin, H : ndarray of complex
        Contact-space arrays over frequency (:func:`mcfric.core.receptance.contact_space`),
        ``ylin`` and ``H`` restricted to the beams of the metric.
    kr, ki, F_lim : float
        The admissible region (N/m, N/m, N; ``F_lim = inf``: box only).
    K_upper, K_lower : ndarray of complex, shape (n_f, nd)
        A search's optima, N/m: candidate witnesses (used where admissible).
    scale : ndarray, shape (n_f,)
        ``omega ** k`` from displacement to the metric's quantity.
    budget : int, optional
        Enclosures per frequency and bound; default :func:`default_budget` (0 above
        ``MAX_DAMPERS`` dampers: the certificate is then Eq. 10 and 0, with the
        witnesses, or, with ``turned`` and a force limit, the relaxations of the whole
        box, up to ``MAX_TIED`` dampers).
    rtol : float, optional
        Relative tolerance of the branch and bound and the relaxations (their goal above
        the upper witness, below the lower); default :func:`default_rtol`.
    split : int, optional
        Relaxations of parts of the box per frequency for the upper bound where the
        relaxation of the whole box leaves it loose (:mod:`mcfric.core.relaxation_branch`;
        the beams after the first a quarter more), the lower bound at most
        ``LOWER_SPLIT_BUDGET`` of them; default ``SPLIT_BUDGET``, 0: none.
    moments : bool or "auto"
        Also tighten the upper bound by the second-order moment relaxation
        (:mod:`.moments`; chains of 2 to ``MAX_DAMPERS`` dampers with a force limit,
        :func:`resolve_moments`; ``"auto"``: where it applies): about a second per
        relaxation, a few per frequency where the first-order one is loose. Default
        False here; :func:`mcfric.bounds.compute_bounds` defaults to ``"auto"``.
    turned : bool
        The model is a tuned ring under a travelling wave, every beam of it in the
        metric (:func:`mcfric.bounds.rotation_invariant`): above ``MAX_DAMPERS`` and up
        to ``MAX_TURNED`` dampers, with a force limit, the relaxation of the whole box
        then tightens Eq. 10 and 0 (one relaxation per frequency and bound: the other
        beams take its multipliers turned, verified on their own forms); up to
        ``MAX_TIED`` dampers the relaxations with the multipliers tied across dampers
        (the upper bound's but near the beam) tighten them.
    progress : bool or None
        Progress bars on stderr for the stages that take long (the splitting of the box,
        the second-order relaxations): None (default) on a terminal only, False never,
        True always.
    lower : bool
        Certify the lower bound too (default). False: the upper bound only, for a caller
        that uses nothing else (:func:`subset_of_ring`'s whole ring); the lower bound is
        then the trivial ``0``, not met, with a NaN witness.

    Returns
    -------
    Certificate
    """
    n_f, nd = q0.shape
    # the relaxation needs the force limit (its multiplier makes the start definite)
    relax = RELAX and np.isfinite(F_lim) and 2 <= nd <= MAX_DAMPERS
    # rings above MAX_DAMPERS: the relaxation of the whole box alone
    turn = bool(turned) and ylin.shape[1] == nd
    whole = turn and turns(nd, F_lim) and nd <= MAX_TURNED
    # larger tuned rings: tied multipliers (the full relaxation takes seconds per
    # frequency there)
    tied = turn and turns(nd, F_lim) and nd > MAX_TURNED
    from .moments import is_chain
    moments = resolve_moments(moments, is_chain(G), nd, F_lim)
    second_order = np.zeros(2, np.int64)
    first_order = np.zeros(2, np.int64)
    # the diagnostics of this call only (a stage that has nothing to do leaves zeros)
    for last in (LAST_RELAXATION, LAST_SPLIT, LAST_MOMENTS, LAST_POLISH):
        last[...] = 0
    split_used = np.zeros(2, np.int64)
    if budget is None:
        budget = default_budget(nd, relax)
    rtol = default_rtol(nd) if rtol is None else float(rtol)
    split = SPLIT_BUDGET if split is None else int(split)
    if nd > MAX_DAMPERS:
        budget = 0
    uniform = np.array([0.0, kr, kr + 1j * ki, 1j * ki, 0.5 * (kr + 1j * ki)])
    corners = np.broadcast_to(uniform[None, :, None], (n_f, len(uniform), nd))
    init_up = np.ascontiguousarray(np.concatenate([K_upper[:, None], corners], axis=1))
    init_lo = np.ascontiguousarray(np.concatenate([K_lower[:, None], corners], axis=1))
    args = [np.ascontiguousarray(a) for a in (G, q0, ylin, H)]
    # M at the box search's maximum: no admissible point is above it, as far as the box
    # search is right, so the witnesses' climbs stop there
    box_max = np.empty(n_f)
    values(*args, np.ascontiguousarray(K_upper), box_max)
    if np.isfinite(F_lim) and nd <= MAX_DAMPERS:
        # the box search ignores the force limit: climb to admissible witnesses as well
        given = np.stack([K_upper, np.zeros_like(K_upper)], axis=1)
        climbed, _ = joint_witnesses(args, kr, ki, F_lim, given, box_max)
        init_up = np.concatenate([init_up, climbed[:, None]], axis=1)
    out = {}
    force = (np.abs(ylin) + (F_lim * np.abs(H).sum(axis=2) if np.isfinite(F_lim) else np.inf)
             ).max(axis=1) * (1 + _FORCE_MARGIN)
    passes = ((True, init_up, np.zeros(n_f)), (False, init_lo, None))
    for want_max, init, atol in passes[:2 if lower else 1]:
        if atol is None:
            atol = ATOL_FRACTION * out[True][0]
            atol = np.where(np.isfinite(atol), atol, 0.0)
        cert = np.empty(n_f)
        wit = np.empty(n_f)
        K = np.zeros((n_f, nd), complex)
        ev = np.zeros(n_f, np.int64)
        ok = np.zeros(n_f, np.bool_)
        in_threads(lambda freqs, w=want_max, i=init, a=atol, c=cert, x=wit, k=K, e=ev, o=ok:
                   certify_frequencies(*args, kr, ki, F_lim, w, i, int(budget), rtol, a,
                                       np.asarray(freqs, np.int64), c, x, k, e, o),
                   _chunks(n_f))
        if relax:
            cert, K_round, beam_bounds, n = _relaxed(args, kr, ki, F_lim, want_max, cert,
                                                     wit, rtol, atol, turn)
            first_order += n
            if want_max:
                # where the relaxation is (nearly) tight its primal point is (nearly) the
                # maximiser: climb from it to a better witness
                stop = np.fmin(cert / (1 + rtol), box_max)
                wit = _climb(args, kr, ki, F_lim, K_round[:, :1], stop, wit, K, 1)
                # then in each beam's own dampers' forces (no ridge there near a
                # resonance), from the witness and both rounded points
                wit = _force_ascent(args, kr, ki, F_lim,
                                    np.concatenate([K[:, None], K_round], axis=1), stop,
                                    wit, K)
                # a frequency whose search stopped on a lower peak than its neighbours'
                # starts from theirs (the split's goal and stall rule rest on the witness)
                wit = _from_neighbours(args, kr, ki, F_lim, True, cert, wit, K, stop, rtol,
                                       atol)
            if not want_max:
                # the box search's minimum may break the force limit, and the corners
                # lie far above the joint minimum: descend from the relaxation's rounded
                # points and the witness where the bound is loose
                _descend(args, kr, ki, F_lim, K_round, cert, wit, K, rtol, atol)
                # and from the neighbouring frequencies' lower witnesses
                _from_neighbours(args, kr, ki, F_lim, False, cert, wit, K, None, rtol, atol)
            cert, used, K_parts, n = _split(args, kr, ki, F_lim, want_max, cert, wit, rtol,
                                            atol, beam_bounds,
                                            split if want_max else min(split,
                                                                       LOWER_SPLIT_BUDGET),
                                            progress)
            first_order += n
            split_used[int(not want_max)] = used
            if not want_max:
                # the parts' relaxations are tighter, and a part holds one of a mirror
                # pair of minima that the whole box's rounding mixes into the symmetric
                # point: descend from them too
                _descend(args, kr, ki, F_lim, K_parts, cert, wit, K, rtol, atol)
            elif moments:
                cert, K_first, second_order = _second_order(args, kr, ki, F_lim, cert, wit,
                                                            K, beam_bounds, rtol, progress)
                # its first moments start one more climb in the forces
                wit = _force_ascent(args, kr, ki, F_lim, K_first,
                                    np.fmin(cert / (1 + rtol), box_max), wit, K)
                # where it is still loose, each beam on its own by a gradient method
                wit = _polish(args, kr, ki, F_lim, np.fmin(cert, force), wit, K,
                              beam_bounds, rtol)
        elif whole or tied:
            cert, K_round, _, n = _relaxed(args, kr, ki, F_lim, want_max, cert, wit, rtol,
                                           atol, turn, NEAR if tied else 0)
            first_order += n
            # a ring's witnesses are six solves: climb, or descend, from the relaxation's
            # rounded points (where it is nearly tight they are nearly the optimisers)
            if want_max:
                stop = np.fmin(cert / (1 + rtol), box_max)
                wit = _climb(args, kr, ki, F_lim, K_round, stop, wit, K, 2)
                # then in each beam's own dampers' forces, from the witness and both
                # rounded points (disk-72, 200 frequencies: within 1 % at 152 instead of
                # 72 for 4 % more time; the Newton climb in all forces at once after it
                # gained 3 more for 15 %)
                wit = _force_ascent(args, kr, ki, F_lim,
                                    np.concatenate([K[:, None], K_round], axis=1), stop,
                                    wit, K, newton=False)
            else:
                _descend(args, kr, ki, F_lim, K_round, cert, wit, K, rtol, atol)
        if want_max:
            cert = np.maximum(np.fmin(cert, force), wit)
        else:
            cert = np.clip(cert, 0.0, wit)
        ok = ok | _met(want_max, cert, wit, rtol, atol)
        out[want_max] = (cert, wit, K, ev, ok)
    if not lower:       # 0 bounds the response from below; nothing attains it
        out[False] = (np.zeros(n_f), np.full(n_f, np.nan), np.full((n_f, nd), np.nan + 0j),
                      np.zeros(n_f, np.int64), np.zeros(n_f, np.bool_))
    (up, wu, Ku, eu, ou), (lo, wl, Kl, el, ol) = out[True], out[False]
    return Certificate(up * scale, lo * scale, wu * scale, wl * scale, Ku, Kl,
                       np.stack([ou, ol]), np.stack([eu, el]), int(budget),
                       bool(relax or whole or tied),
                       second_order, split if relax else 0, split_used, bool(moments), rtol,
                       first_order)
