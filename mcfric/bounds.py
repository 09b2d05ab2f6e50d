"""Equivalent-linear response bounds (paper Section 3, physics.md section 7).

The friction law is not specified: each damper's describing function ``K_j`` may be any
complex number in the admissible region

* box: ``0 <= Re K_j <= k_max_re`` (stiffness), ``0 <= Im K_j <= k_max_im`` (dissipation);
* force saturation: ``|K_j| A_j <= F_lim`` with ``F_lim = (4/pi) mu_max N0_max``, the
  first-harmonic amplitude of a saturated Coulomb force.

At each frequency the bounds on the metric ``M = max_b |y_b|`` are

* upper = min(maximum of M over the box, force bound of Eq. 10), and ``limited_by``
  records which of the two is smaller;
* lower = minimum of M over the box (the force constraint only removes points, so the box
  minimum stays a valid lower bound).

Every Coulomb damper with ``kc <= k_max``, ``mu0 <= mu_max`` and ``N0 <= N0_max`` is
admissible (``Re K <= kc``, ``Im K <= kc / pi``, ``|K| A <= (4/pi) mu0 N0``), so every
converged ensemble member lies between the bounds.

The box search is the jitted coordinate search of :mod:`mcfric.core.equivalent_linear`
(exact per damper: the response is a Moebius function of each ``K_j``), run from many
starts per frequency and in parallel over frequencies. It replaces the paper's
``fmincon``/SQP: a generic local optimiser, measured here, stopped up to 30 % short of the
true maximum on the eight-beam rig.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .core.equivalent_linear import box_extreme
from .core.receptance import contact_space
from .hbm import QUANTITIES, check_frequencies, threads
from .model import Model

#: ``limited_by`` codes: which constraint sets the upper bound.
LIMITED_BY = ("box", "force")
N_STARTS = 8
MAX_SWEEPS = 20


@dataclass
class Bounds:
    """Bounds on the metric over frequency.

    Attributes
    ----------
    freq_hz : ndarray, shape (n_f,)
    upper, lower : ndarray, shape (n_f,)
        Bounds on ``M`` in the metric's unit (m, m/s or m/s^2). NaN where the search
        failed (a singular linear system: counted in :meth:`summary`).
    upper_box, upper_force : ndarray, shape (n_f,)
        The two candidates of the upper bound.
    limited_by : ndarray of int8, shape (n_f,)
        0 where the box sets the upper bound, 1 where the force saturation does.
    K_upper, K_lower : ndarray of complex, shape (n_f, nd)
        Describing functions (N/m) at which the box maximum and minimum are reached.
    k_max_re, k_max_im, F_lim : float
        The constraints used (N/m, N/m, N; ``inf`` = no force constraint).
    quantity : str
    beams : tuple of int
        0-based beams the metric takes the maximum over.
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

    @property
    def n_failed(self):
        return int(np.count_nonzero(~np.isfinite(self.upper) | ~np.isfinite(self.lower)))

    def summary(self):
        force = np.count_nonzero(self.limited_by == 1)
        return (f"bounds at {len(self.freq_hz)} frequencies: upper set by the force limit at "
                f"{force}, by the box at {len(self.freq_hz) - force}; failed: {self.n_failed}")

    def contains(self, metric, rtol=1e-9):
        """Boolean mask ``lower (1 - rtol) <= metric <= upper (1 + rtol)`` (NaN -> False)."""
        metric = np.asarray(metric)
        with np.errstate(invalid="ignore"):
            return (metric >= self.lower * (1 - rtol)) & (metric <= self.upper * (1 + rtol))


def force_limit(mu_max, N0_max):
    """``F_lim = (4/pi) mu_max N0_max``: first harmonic of a saturated Coulomb force, N."""
    return 4.0 / np.pi * float(mu_max) * float(N0_max)


def _check_positive(name, value, allow_inf=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not (v > 0) or (np.isinf(v) and not allow_inf) or np.isnan(v):
        allowed = "a positive number (inf allowed)" if allow_inf else "a positive finite number"
        raise ValueError(f"{name}: expected {allowed}, got {value!r}")
    return v


def compute_bounds(model, freq_hz, k_max, *, k_max_im=None, F_lim=None, quantity="displacement",
                   beams=None, n_starts=N_STARTS, max_sweeps=MAX_SWEEPS, seed=0, n_threads=None):
    """Equivalent-linear bounds on the response metric of ``model``.

    Parameters
    ----------
    model : Model
    freq_hz : array_like, shape (n_f,)
        Frequencies, Hz.
    k_max : float
        Largest stiffness ``Re K`` of a damper, N/m (the paper: 15 kN/m).
    k_max_im : float, optional
        Largest dissipation ``Im K``, N/m; default ``k_max``.
    F_lim : float, optional
        Friction force limit of the first harmonic, N: ``force_limit(mu_max, N0_max)``.
        Default ``inf`` (no force constraint: the upper bound is the box maximum).
    quantity : {"displacement", "velocity", "acceleration"}
    beams : sequence of int, optional
        0-based beams of the metric; default all.
    n_starts : int
        Starts of each search (max and min) per frequency.
    max_sweeps : int
        Coordinate sweeps per start.
    seed : int
        Seed of the random starts (the bounds are deterministic for a given seed).
    n_threads : int, optional

    Returns
    -------
    Bounds
    """
    if not isinstance(model, Model):
        raise ValueError(f"model: expected a mcfric Model, got {type(model).__name__}")
    f = check_frequencies(freq_hz)
    kr = _check_positive("k_max", k_max)
    ki = kr if k_max_im is None else _check_positive("k_max_im", k_max_im)
    F_lim = np.inf if F_lim is None else _check_positive("F_lim", F_lim, allow_inf=True)
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity: expected one of {QUANTITIES}, got {quantity!r}")
    beams = tuple(range(model.n_beams)) if beams is None else tuple(int(b) for b in beams)
    if not beams or any(not 0 <= b < model.n_beams for b in beams):
        raise ValueError(f"beams: expected 0-based beam indices in 0..{model.n_beams - 1}")
    if not (isinstance(n_starts, (int, np.integer)) and n_starts >= 1):
        raise ValueError(f"n_starts: expected an integer >= 1, got {n_starts!r}")

    omega = 2 * np.pi * f
    rec = model.receptances(omega)[0]
    a, b = model.dampers
    G, q0, ylin, H = contact_space(rec, model.force, a, b)
    sel = list(beams)
    ylin = np.ascontiguousarray(ylin[:, sel])
    H = np.ascontiguousarray(H[:, sel, :])
    starts_max, starts_min = _starts(model.n_dampers, n_starts, seed)
    G = np.ascontiguousarray(G)
    q0 = np.ascontiguousarray(q0)
    with threads(n_threads):
        upper_box, K_upper = box_extreme(G, q0, ylin, H, kr, ki, starts_max, True,
                                         int(max_sweeps))
        lower, K_lower = box_extreme(G, q0, ylin, H, kr, ki, starts_min, False,
                                     int(max_sweeps))
    # Eq. 10 on the output: every damper at the force limit with the worst phase
    upper_force = (np.abs(ylin) + F_lim * np.abs(H).sum(axis=2)).max(axis=1)
    limited_by = (upper_force < upper_box).astype(np.int8)
    upper = np.minimum(upper_box, upper_force)
    upper = np.where(np.isnan(upper_box), np.nan, upper)
    scale = omega ** QUANTITIES.index(quantity)
    return Bounds(f, upper * scale, lower * scale, upper_box * scale, upper_force * scale,
                  limited_by, K_upper, K_lower, kr, ki, F_lim, quantity, beams)


def _starts(nd, n_starts, seed):
    """Starting points in normalised box coordinates, the same at every frequency.

    Max: the four uniform corners, then random corners (the box maximum lies on the
    perimeter of every damper's rectangle). Min: the uniform corners and the centre,
    then random interior points and random corners.
    """
    rng = np.random.default_rng(seed)
    corners = np.array([0, 1, 1 + 1j, 1j])
    uniform = np.repeat(corners[:, None], nd, axis=1)
    n_rand = max(n_starts - 4, 0)
    rand_corners = corners[rng.integers(0, 4, size=(n_rand, nd))]
    starts_max = np.concatenate([uniform, rand_corners])[:n_starts]
    centre = np.full((1, nd), 0.5 + 0.5j)
    n_int = n_rand // 2
    interior = rng.uniform(0, 1, (n_int, nd)) + 1j * rng.uniform(0, 1, (n_int, nd))
    starts_min = np.concatenate([uniform, centre, interior,
                                 corners[rng.integers(0, 4, size=(n_rand - n_int, nd))]])
    return (np.ascontiguousarray(starts_max, dtype=complex),
            np.ascontiguousarray(starts_min[:n_starts], dtype=complex))
