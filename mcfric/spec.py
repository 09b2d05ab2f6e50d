"""The run specification: a validated configuration resolved once into plain objects.

A :class:`RunSpec` holds everything a run needs and nothing it must look up again: the
model, the frequency grid, the sampler, the metric, the solver and bounds settings, the
output layout and how to execute. :meth:`mcfric.config.Config.spec` builds it; the
ensemble, the bounds and the command line take it as it is. It knows nothing of TOML
or of the command line.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .model import Model
from .peaks import PeakSettings
from .sampling import Sampler


@dataclass(frozen=True)
class MetricSpec:
    """What ``M`` is: ``max_b omega^k |y_b|`` over ``beams``.

    Attributes
    ----------
    quantity : {"displacement", "velocity", "acceleration"}
    beams : tuple of int or None
        0-based beams the maximum runs over; None: all.
    """

    quantity: str = "displacement"
    beams: tuple | None = None

    @property
    def beams_label(self):
        """``"all"`` or the 1-based beam numbers, as a configuration writes them."""
        return "all" if self.beams is None else [b + 1 for b in self.beams]


@dataclass(frozen=True)
class SolverSpec:
    """Harmonic-balance solver settings.

    Attributes
    ----------
    tol : float
        Accepted relative friction-force residual (-).
    max_iter : int
        Newton iterations per attempt.
    harmonics : int
        Highest odd harmonic balanced (1: single-harmonic).
    n_time : int or None
        AFT samples per period (None: the default for ``harmonics``).
    """

    tol: float
    max_iter: int
    harmonics: int = 1
    n_time: int | None = None


@dataclass(frozen=True)
class BoundsSpec:
    """The admissible region and search effort of the response bounds.

    Attributes
    ----------
    k_max_re, k_max_im : float
        Largest ``Re K`` and ``Im K`` of a damper, N/m.
    F_lim : float
        Friction force limit of the first harmonic, N (``inf``: no force constraint).
    n_starts : int
        Starts of the box search per frequency.
    certify : bool
        Whether the bounds are also certified (branch and bound).
    budget : int or None
        Enclosures per frequency and bound of the certification; None: 4000 for one
        damper, 400 for more, 50 from six dampers where a relaxation follows
        (:func:`mcfric.bounds.certified.default_budget`).
    split : int or None
        Relaxations of parts of the box per frequency where the relaxation of the whole
        box leaves the upper bound loose, the lower bound at most 800 of them (0: none);
        None: the default, 3200.
    moments : bool or "auto"
        Whether the certified upper bound is tightened by the second-order moment
        relaxation where the first order leaves it loose; ``"auto"``: where it applies
        (chains of 2-7 dampers with a force limit).
    """

    k_max_re: float
    k_max_im: float
    F_lim: float
    n_starts: int
    certify: bool = True
    budget: int | None = None
    split: int | None = None
    moments: bool | str = "auto"


@dataclass(frozen=True)
class ExecutionSpec:
    """How to compute; never changes a result.

    Attributes
    ----------
    threads : int or None
        numba threads (None: all).
    chunk : int
        Samples per chunk (0: automatic).
    checkpoint_s : float
        Minimum seconds between crash-safe checkpoints (0: after every chunk).
    scheduler : str
        ``""``: solve in this process; ``"local:N"`` or ``"tcp://host:port"``: solve the
        chunks on a Dask cluster (:mod:`mcfric.distributed`).
    """

    threads: int | None = None
    chunk: int = 0
    checkpoint_s: float = 0.0
    scheduler: str = ""


@dataclass(frozen=True)
class RunSpec:
    """Everything a run needs, resolved.

    Attributes
    ----------
    model : Model
        The nominal rig.
    freq_hz : ndarray, shape (n_f,)
        Frequency grid, Hz, increasing (read-only).
    sampler : Sampler
        Draws sample i's friction parameters (and mistuning) from its own seed.
    samples : int
        Ensemble size.
    metric : MetricSpec
    solver : SolverSpec
    peaks : PeakSettings or None
        Resolved peaks of every member (of the metric), or None.
    bounds : BoundsSpec or None
        None when the bounds are not computed with the run.
    keep_response : bool
        Store the complex response per beam (False: the metric only).
    keep_harmonics : bool
        With ``solver.harmonics > 1``: store every odd harmonic of the response.
    response_format : {"complex", "amplitude"}
        With ``keep_response``: the complex response per beam (``response``, complex128),
        or its amplitude (``amplitude``, float32, four times smaller).
    execution : ExecutionSpec
    config_toml, config_json : str
        The complete configuration, as recorded in a results file.
    identity : dict
        The part of the configuration that determines the results (compared on resume).
    """

    model: Model
    freq_hz: np.ndarray
    sampler: Sampler
    samples: int
    metric: MetricSpec
    solver: SolverSpec
    peaks: PeakSettings | None
    bounds: BoundsSpec | None
    keep_response: bool
    execution: ExecutionSpec
    config_toml: str
    config_json: str
    identity: dict
    keep_harmonics: bool = False
    response_format: str = "complex"

    @property
    def seed(self):
        """Root seed of the sampler."""
        return self.sampler.seed

    @property
    def mistuned(self):
        """True when the members' modal frequencies are drawn (mistuning > 0)."""
        return self.sampler.mistuning > 0

    def matches(self, other):
        """True if ``other`` is the same run in every field, arrays compared by value."""
        return _same(self, other)


def _same(x, y):
    """Structural equality of specs: dataclasses field by field, arrays by value (a
    dataclass's own ``==`` fails on array fields), NaN equal to NaN."""
    if type(x) is not type(y):
        return False
    if dataclasses.is_dataclass(x):
        return all(_same(getattr(x, f.name), getattr(y, f.name))
                   for f in dataclasses.fields(x))
    if isinstance(x, np.ndarray):
        return x.shape == y.shape and bool(np.all((x == y) | ((x != x) & (y != y))))
    if isinstance(x, (tuple, list)):
        return len(x) == len(y) and all(_same(a, b) for a, b in zip(x, y))
    if isinstance(x, dict):
        return x.keys() == y.keys() and all(_same(x[k], y[k]) for k in x)
    if isinstance(x, float) and x != x:
        return y != y
    return bool(x == y)
