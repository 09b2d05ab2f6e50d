"""Random friction parameters (and mistuning) for Monte Carlo ensembles.

The theory page of the docs explains the choices (section "Monte Carlo ensembles").

Reproducibility contract
------------------------
Sample ``i`` of a run with seed ``seed`` draws from its own stream,
``Generator(PCG64(SeedSequence(seed, spawn_key=(i,))))`` (the ``i``-th child of
``SeedSequence(seed).spawn(...)``), and from it one block of uniforms, in this order:

    ``mu0`` (nd), ``kc`` (nd), ``N0`` (nd), mistuning (n_beams * n_modes, row-major)

The whole block is always drawn, whatever the distributions, so changing one distribution
never shifts the numbers another one sees. Each uniform ``u = rng.random()`` (a multiple of
2^-53 in [0, 1)) is moved to the open interval, ``u + 2^-54``, and mapped through the
distribution's inverse CDF. So a sample's parameters depend on (seed, i, config) only: never
on the chunk it was computed in, the thread count, the ensemble size or a resume.

Distributions (all values in the parameter's own unit: mu0 -, kc N/m, N0 N)
---------------------------------------------------------------------------
``fixed(value)``, ``uniform(low, high)``, ``normal(mean, std)``,
``truncnormal(mean, std, low, high)``, ``lognormal(median, sigma)``; see the classes.
Every parameter must be >= 0, and the distributions are validated so that no draw can be
negative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from .model import check_squarable
from .validators import InputError, finite_array, integer, real, real_array

#: Half the spacing of ``Generator.random``: maps its [0, 1) grid onto (0, 1).
_HALF_ULP = 2.0 ** -54
#: Largest relative standard deviation of mistuning: with |z| <= 8.3 (the extreme normal
#: quantile reachable from the uniform grid) every mistuned frequency stays > 0.17 f.
MISTUNING_MAX = 0.1
MISTUNING_PER = ("beam", "mode")
#: ``normal`` is conditioned on >= 0; allowed only while that removes <= 0.135 % of it.
NORMAL_MIN_MEAN_OVER_STD = 3.0


@dataclass(frozen=True)
class Fixed:
    """Always the same value.

    Parameters
    ----------
    value : float
        The value (>= 0), in the unit of the parameter drawn (-, N/m or N).
    """

    value: float
    dist = "fixed"

    def __post_init__(self):
        object.__setattr__(self, "value", real("value", self.value, lo=0))

    def ppf(self, u):
        """Inverse CDF.

        Parameters
        ----------
        u : array_like
            Uniforms in (0, 1).

        Returns
        -------
        ndarray
            The quantiles, shaped as ``u``, in the parameter's unit.
        """
        return np.full(np.shape(_unit(u)), self.value)


@dataclass(frozen=True)
class Uniform:
    """Uniform on [low, high].

    Parameters
    ----------
    low, high : float
        The limits, ``0 <= low <= high``, in the unit of the parameter drawn (-, N/m or N).
    """

    low: float
    high: float
    dist = "uniform"

    def __post_init__(self):
        low = real("low", self.low, lo=0)
        high = real("high", self.high, lo=0)
        if high < low:
            raise ValueError(f"high: expected a number >= low ({low:g}), got {self.high!r}")
        object.__setattr__(self, "low", low)
        object.__setattr__(self, "high", high)

    def ppf(self, u):
        """Inverse CDF.

        Parameters
        ----------
        u : array_like
            Uniforms in (0, 1).

        Returns
        -------
        ndarray
            The quantiles, shaped as ``u``, in the parameter's unit.
        """
        return self.low + (self.high - self.low) * _unit(u)


@dataclass(frozen=True)
class Normal:
    """Normal(mean, std) conditioned on >= 0 (a parameter cannot be negative).

    Requires ``mean >= 3 std``, so that the conditioning removes at most 0.135 % of the
    probability; for wider spreads use :class:`TruncNormal` and state the limits.

    Parameters
    ----------
    mean, std : float
        Mean (>= 0) and standard deviation (<= mean / 3), in the unit of the parameter
        drawn (-, N/m or N).
    """

    mean: float
    std: float
    dist = "normal"

    def __post_init__(self):
        mean = real("mean", self.mean, lo=0)
        std = real("std", self.std, lo=0)
        if mean < NORMAL_MIN_MEAN_OVER_STD * std * (1 - 1e-12):   # 0.3 vs 3 * 0.1 is equal
            raise ValueError(f"std: expected <= mean/3 ({mean / 3:g}) so that negative values "
                             f"are negligible, got {self.std!r}; for a wider spread use "
                             f'dist = "truncnormal" with low = 0')
        object.__setattr__(self, "mean", mean)
        object.__setattr__(self, "std", std)

    def ppf(self, u):
        """Inverse CDF.

        Parameters
        ----------
        u : array_like
            Uniforms in (0, 1).

        Returns
        -------
        ndarray
            The quantiles, shaped as ``u``, in the parameter's unit.
        """
        u = _unit(u)
        if self.std == 0:
            return np.full(np.shape(u), self.mean)
        return _truncnorm_ppf(u, self.mean, self.std, 0.0, math.inf)


@dataclass(frozen=True)
class TruncNormal:
    """Normal(mean, std) restricted to [low, high].

    Parameters
    ----------
    mean, std : float
        Mean and standard deviation (> 0) of the normal before the restriction, in the
        unit of the parameter drawn (-, N/m or N).
    low, high : float
        The limits, ``0 <= low < high`` (``high`` may be inf), in the same unit.
    """

    mean: float
    std: float
    low: float
    high: float
    dist = "truncnormal"

    def __post_init__(self):
        mean = real("mean", self.mean)
        std = real("std", self.std, lo=0, lo_open=True)
        low = real("low", self.low, lo=0)
        high = real("high", self.high, lo=0, allow_inf=True)
        if not high > low:
            raise ValueError(f"high: expected a number > low ({low:g}), got {self.high!r}")
        # the inverse CDF loses all precision once both limits are > ~37 std on one side
        if min(abs(low - mean), abs(high - mean)) > 30 * std and (low - mean) * (high - mean) > 0:
            raise ValueError(f"low: [low, high] lies more than 30 std from the mean "
                             f"({mean:g}); the distribution is degenerate there")
        for k, v in (("mean", mean), ("std", std), ("low", low), ("high", high)):
            object.__setattr__(self, k, v)

    def ppf(self, u):
        """Inverse CDF.

        Parameters
        ----------
        u : array_like
            Uniforms in (0, 1).

        Returns
        -------
        ndarray
            The quantiles, shaped as ``u``, in the parameter's unit.
        """
        return _truncnorm_ppf(_unit(u), self.mean, self.std, self.low, self.high)


@dataclass(frozen=True)
class LogNormal:
    """``median * exp(sigma Z)``, Z standard normal.

    Parameters
    ----------
    median : float
        The median (> 0), in the unit of the parameter drawn (-, N/m or N).
    sigma : float
        Standard deviation of ``ln(value)`` (>= 0, dimensionless), e.g. 0.3.
    """

    median: float
    sigma: float
    dist = "lognormal"

    def __post_init__(self):
        object.__setattr__(self, "median", real("median", self.median, lo=0, lo_open=True))
        object.__setattr__(self, "sigma", real("sigma", self.sigma, lo=0))
        # the draws reach ndtri(2^-53) ~ 8.2 standard deviations: they must stay finite
        if math.log(self.median) + 8.2 * self.sigma > math.log(np.finfo(float).max):
            raise InputError("sigma", f"median x exp(8.2 sigma) overflows (median "
                             f"{self.median:g}, sigma {self.sigma:g}): sigma is the standard "
                             f"deviation of ln(value), e.g. 0.3")

    def ppf(self, u):
        """Inverse CDF.

        Parameters
        ----------
        u : array_like
            Uniforms in (0, 1).

        Returns
        -------
        ndarray
            The quantiles, shaped as ``u``, in the parameter's unit.
        """
        return self.median * np.exp(self.sigma * special.ndtri(_unit(u)))


def _unit(u):
    """``u`` as a float array of values in (0, 1), or an InputError (a uniform outside
    it gave values outside the distribution: 2.0 on Uniform(0, 1) drew 2)."""
    u = real_array("u", u)
    if not np.all((u > 0) & (u < 1)):
        raise InputError("u", "expected uniforms in (0, 1)")
    return u


def _sample_numbers(index):
    """``index`` as a 1-d int64 array of sample numbers >= 0, or an InputError (1.7 was
    sample 1, 2**64 - 1 wrapped to -1, and a 2-d array was flattened)."""
    given = np.asarray(index)
    if given.ndim > 1:
        raise InputError("index", f"expected a sequence of sample numbers, got shape "
                                  f"{given.shape}")
    if given.size and (given.dtype.kind not in "iu" or given.dtype == np.bool_):
        raise InputError("index", f"expected integer sample numbers, got dtype {given.dtype}")
    lo, hi = (given.min(), given.max()) if given.size else (0, 0)
    if lo < 0 or hi > np.iinfo(np.int64).max:
        raise InputError("index", f"sample numbers must be in 0..2**63 - 1, got "
                                  f"{lo if lo < 0 else hi}")
    return given.astype(np.int64).reshape(-1)


def _truncnorm_ppf(u, mean, std, low, high):
    from scipy.stats import truncnorm  # scipy.stats costs ~0.3 s to import: only when used

    a = (low - mean) / std
    b = (high - mean) / std
    return np.clip(truncnorm.ppf(np.asarray(u), a, b, loc=mean, scale=std), low, high)


#: dist name -> (class, parameter names in order)
DISTRIBUTIONS = {cls.dist: (cls, tuple(cls.__dataclass_fields__))
                 for cls in (Fixed, Uniform, Normal, TruncNormal, LogNormal)}


def distribution(dist, **params):
    """Build a distribution by name, e.g. ``distribution("uniform", low=0, high=1)``.

    Parameters
    ----------
    dist : str
        ``"fixed"`` (``value``), ``"uniform"`` (``low``, ``high``), ``"normal"``
        (``mean``, ``std``), ``"truncnormal"`` (``mean``, ``std``, ``low``, ``high``) or
        ``"lognormal"`` (``median``, ``sigma``).
    **params : float
        Exactly the parameters of ``dist``, in the unit of the quantity drawn (mu0: -,
        kc: N/m, N0: N); docs: configuration, "Distributions".

    Returns
    -------
    Fixed, Uniform, Normal, TruncNormal or LogNormal

    Raises
    ------
    ValueError
        Unknown ``dist``, a missing or unknown parameter, or a value out of range; the
        message starts with the offending name.
    """
    if dist not in DISTRIBUTIONS:
        raise ValueError(f"dist: expected one of {', '.join(DISTRIBUTIONS)}, got {dist!r}")
    cls, names = DISTRIBUTIONS[dist]
    for k in params:
        if k not in names:
            raise ValueError(f'{k}: not a parameter of dist "{dist}" '
                             f"(allowed: {', '.join(names)})")
    for k in names:
        if k not in params:
            raise ValueError(f'{k}: missing; dist "{dist}" needs {", ".join(names)}')
    return cls(**params)


def as_dict(d):
    """``{"dist": ..., <parameters>}`` of a distribution (the TOML table form)."""
    return {"dist": d.dist, **{k: getattr(d, k) for k in DISTRIBUTIONS[d.dist][1]}}


#: The paper's ensemble: mu0 ~ U(0, 1), kc ~ U(0, 15 kN/m), N0 = 0.5 N.
PAPER = {"mu0": Uniform(0.0, 1.0), "kc": Uniform(0.0, 15000.0), "N0": Fixed(0.5)}


@dataclass(frozen=True)
class Draw:
    """Parameters of a block of samples.

    Attributes
    ----------
    index : ndarray of int64, shape (n,)
        Sample numbers.
    mu0, kc, N0 : ndarray, shape (n, nd)
        Friction coefficient (-), tangential stiffness (N/m), normal preload (N).
    modal_freq_hz : ndarray, shape (n, n_beams, n_modes), or None
        Mistuned modal frequencies, Hz; None without mistuning.
    """

    index: np.ndarray
    mu0: np.ndarray
    kc: np.ndarray
    N0: np.ndarray
    modal_freq_hz: np.ndarray | None


@dataclass(frozen=True)
class Sampler:
    """Draws the parameters of sample ``i`` from its own ``SeedSequence`` child.

    Parameters
    ----------
    seed : int
        Root seed (>= 0).
    n_dampers : int
        Dampers per sample (independent draws).
    mu0, kc, N0 : distribution
        One of :class:`Fixed`, :class:`Uniform`, :class:`Normal`, :class:`TruncNormal`,
        :class:`LogNormal`, of the friction coefficient (-), the tangential stiffness (N/m)
        and the normal preload (N); every damper of every sample draws independently.
    modal_freq_hz : ndarray, shape (n_beams, n_modes), optional
        Nominal modal frequencies, Hz (needed for mistuning).
    mistuning : float
        Relative standard deviation of the modal frequencies, 0 <= mistuning <= 0.1:
        ``f = f_nominal (1 + mistuning z)``, z standard normal. 0: no mistuning.
    mistuning_per : {"beam", "mode"}
        ``beam``: one z per beam scales all its modes (stiffness-like blade mistuning);
        ``mode``: an independent z per beam and mode.
    """

    seed: int
    n_dampers: int
    mu0: object = PAPER["mu0"]
    kc: object = PAPER["kc"]
    N0: object = PAPER["N0"]
    modal_freq_hz: np.ndarray | None = None
    mistuning: float = 0.0
    mistuning_per: str = "beam"

    def __post_init__(self):
        integer(0)(self.seed, "seed")
        integer(1)(self.n_dampers, "n_dampers")
        for name in ("mu0", "kc", "N0"):
            d = getattr(self, name)
            if getattr(d, "dist", None) not in DISTRIBUTIONS:
                raise ValueError(f"{name}: expected a distribution, got {d!r}")
        m = real("mistuning", self.mistuning, lo=0)
        if m > MISTUNING_MAX:
            raise ValueError(f"mistuning: expected 0..{MISTUNING_MAX:g}, got {self.mistuning!r}")
        if self.mistuning_per not in MISTUNING_PER:
            raise ValueError(f"mistuning_per: expected one of {MISTUNING_PER}, "
                             f"got {self.mistuning_per!r}")
        f = None
        if self.modal_freq_hz is not None:
            f = np.array(finite_array("modal_freq_hz", self.modal_freq_hz, 2))
            check_squarable("modal_freq_hz", f)
            f.setflags(write=False)
        elif m > 0:
            raise ValueError("modal_freq_hz: needed for mistuning")
        object.__setattr__(self, "mistuning", m)
        object.__setattr__(self, "modal_freq_hz", f)

    @property
    def n_uniforms(self):
        """Uniforms drawn per sample (the block layout in the module docstring)."""
        n_modal = 0 if self.modal_freq_hz is None else self.modal_freq_hz.size
        return 3 * self.n_dampers + n_modal

    def uniforms(self, index):
        """The per-sample uniform blocks.

        Parameters
        ----------
        index : array_like of int
            Sample numbers (>= 0).

        Returns
        -------
        ndarray, shape (len(index), n_uniforms)
            Uniforms in (0, 1), one row per sample, each from the sample's own seed.
        """
        index = _sample_numbers(index)
        u = np.empty((len(index), self.n_uniforms))
        n = self.n_uniforms
        for row, i in enumerate(index.tolist()):
            ss = np.random.SeedSequence(self.seed, spawn_key=(i,))
            u[row] = np.random.Generator(np.random.PCG64(ss)).random(n)
        return u + _HALF_ULP

    def draw(self, index):
        """The parameters of some samples.

        Parameters
        ----------
        index : array_like of int
            Sample numbers (>= 0), in any order, any subset.

        Returns
        -------
        Draw
            Their friction coefficients, tangential stiffnesses (N/m), preloads (N) and,
            with mistuning, modal frequencies (Hz), one row per sample.
        """
        index = _sample_numbers(index)
        u = self.uniforms(index)
        nd = self.n_dampers
        mu0 = self.mu0.ppf(u[:, :nd])
        kc = self.kc.ppf(u[:, nd:2 * nd])
        N0 = self.N0.ppf(u[:, 2 * nd:3 * nd])
        mf = None
        if self.mistuning > 0:
            nb, nm = self.modal_freq_hz.shape
            z = special.ndtri(u[:, 3 * nd:]).reshape(len(index), nb, nm)
            if self.mistuning_per == "beam":
                z = np.repeat(z[:, :, :1], nm, axis=2)
            mf = self.modal_freq_hz[None] * (1.0 + self.mistuning * z)
        return Draw(index, mu0, kc, N0, mf)
