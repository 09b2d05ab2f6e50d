"""The friction-coupled beam array: modal tables, dampers and excitation.

The conventions (positions, signs, excitation patterns) are those of the theory page of
the docs, sections "The rig", "Conventions" and "Excitation".

Everything here is validated once, at construction, so that the kernels downstream never
see a bad value. Units are SI: Hz for modal frequencies, kg^-1/2 for mass-normalised mode
shapes, N for forces.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from .core.receptance import beam_receptances
from .validators import F0_RANGE, InputError, choice, finite_array, integer, number, real, string

TOPOLOGIES = ("linear", "circular")
#: Contact laws: Coulomb friction in series with a stiffness (the paper's), and a
#: stiffening spring that exists to test the detection of multiple steady states.
CONTACT_LAWS = ("coulomb", "cubic")
PATTERNS = ("single", "mode", "travelling")
#: Largest natural frequency (Hz) and mode-shape magnitude a modal table may hold, and the
#: inverse of the smallest largest magnitude: the receptance's squares stay normal numbers.
SQUARABLE = 1e100


def check_squarable(name, freq_hz):
    """Refuse natural frequencies (Hz) that are not finite, not > 0 or above
    :data:`SQUARABLE`, past which the receptance's squares overflow to responses of 0
    reported as converged (an InputError naming ``name``)."""
    f = np.asarray(freq_hz)
    if f.size == 0 or not (np.all(np.isfinite(f)) and np.all(f > 0) and f.max() <= SQUARABLE):
        raise InputError(name, f"values must be finite, > 0 and at most {SQUARABLE:g} Hz "
                               f"(which double precision squares safely)")


@dataclass(frozen=True)
class ModalTable:
    """Modes of one beam (paper Table 1 layout).

    Parameters
    ----------
    freq_hz : array_like, shape (n_modes,)
        Natural frequencies, Hz (> 0).
    zeta : array_like, shape (n_modes,)
        Modal damping ratios (>= 0).
    shapes : array_like, shape (n_modes, n_positions)
        Mass-normalised mode shapes at the measurement positions, kg^-1/2.
    positions : tuple of int
        Label of each column of ``shapes`` (the paper's positions 1, 2, 3, or UFF node
        numbers).
    """

    freq_hz: np.ndarray
    zeta: np.ndarray
    shapes: np.ndarray
    positions: tuple = (1, 2, 3)

    def __post_init__(self):
        f = finite_array("freq_hz", self.freq_hz, 1, positive=True)
        z = finite_array("zeta", self.zeta, 1, nonnegative=True)
        if np.any(z > 1):
            # overdamped: no resonance; more often a damping in percent (2 for 0.02)
            raise ValueError(f"zeta: expected damping ratios in [0, 1] (0.02 for 2 %), "
                             f"got {z.max():g}")
        u = finite_array("shapes", self.shapes, 2)
        if len(f) == 0:
            raise ValueError("freq_hz: a modal table needs at least one mode")
        if z.shape != f.shape:
            raise ValueError(f"zeta: expected {len(f)} values (one per mode), got {len(z)}")
        if u.shape[0] != len(f):
            raise ValueError(f"shapes: expected {len(f)} rows (one per mode), got {u.shape[0]}")
        if not np.any(u != 0):
            raise ValueError("shapes: all zero: the beam could not move (a modal table with "
                             "no deflection anywhere)")
        # the receptance squares both: a table past these scales overflowed or underflowed
        # to responses of 0 reported as converged (single tiny entries, e.g. a clamped
        # node's noise, underflow towards their true value and are kept)
        if f.max() > SQUARABLE:
            raise ValueError(f"freq_hz: {f.max():g} Hz is beyond {SQUARABLE:g} Hz, which "
                             f"double precision squares safely")
        a = np.abs(u)
        if a.max() > SQUARABLE or a.max() < 1 / SQUARABLE:
            m, c = np.unravel_index(int(np.argmax(a)), a.shape)
            raise ValueError(f"shapes: the largest entry, {a.max():g} kg^-1/2 (mode {m + 1}, "
                             f"column {c + 1}), is outside {1 / SQUARABLE:g}..{SQUARABLE:g}, "
                             f"which double precision squares safely")
        # a set has no order: its labels would name the shape columns in another order
        if (isinstance(self.positions, (str, set, frozenset, dict))
                or not hasattr(self.positions, "__len__")):
            raise ValueError(f"positions: expected a sequence of integer labels, one per "
                             f"shape column in order, got {self.positions!r}")
        pos = tuple(integer()(p, "positions") for p in self.positions)    # 1.5 is no label
        if len(pos) != u.shape[1]:
            raise ValueError(f"positions: expected {u.shape[1]} labels (one per shape column), "
                             f"got {len(pos)}")
        if len(set(pos)) != len(pos):
            raise ValueError(f"positions: labels must be distinct, got {pos}")
        object.__setattr__(self, "freq_hz", f)
        object.__setattr__(self, "zeta", z)
        object.__setattr__(self, "shapes", u)
        object.__setattr__(self, "positions", pos)

    @property
    def n_modes(self):
        """Number of modes in the table."""
        return len(self.freq_hz)

    def column(self, position):
        """Mode shapes at a position label.

        Parameters
        ----------
        position : int
            Position label, one of ``positions``.

        Returns
        -------
        ndarray, shape (n_modes,)
            Mass-normalised mode shapes at that position, kg^-1/2.
        """
        label = integer()(position, "position")        # 1.5 is no label (it gave 1)
        try:
            return self.shapes[:, self.positions.index(label)]
        except ValueError:
            raise ValueError(f"position {position} is not in the modal table "
                             f"(positions: {list(self.positions)})") from None

    def with_frequency(self, mode, freq_hz):
        """A copy with one mode moved to another natural frequency.

        Parameters
        ----------
        mode : int
            The mode, 1-based.
        freq_hz : float
            Its new natural frequency, Hz (> 0; e.g. Fig. 10b's 108 Hz for mode 2).

        Returns
        -------
        ModalTable
            The copy; shapes, damping and positions unchanged.
        """
        f = np.array(self.freq_hz)
        integer(1, len(f))(mode, "mode")
        f[mode - 1] = real("freq_hz", freq_hz, lo=0, lo_open=True)   # not "108" or [108]
        return dataclasses.replace(self, freq_hz=f)


#: The paper's Table 1 (beam 6): two bending modes, positions 1 (top, contact),
#: 2 (mid-point, output), 3 (drive).
TABLE_1 = ModalTable(freq_hz=[16.20, 105.8], zeta=[0.0017, 0.0071],
                     shapes=[[2.55, 0.99, 0.48], [-1.84, 2.18, 1.42]], positions=(1, 2, 3))


@dataclass(frozen=True)
class Excitation:
    """Harmonic force at the drive position of each beam (docs: theory, "Excitation").

    Parameters
    ----------
    pattern : {"single", "mode", "travelling"}
        ``single``: only beam ``beam`` is driven, ``F = F0`` there.
        ``mode``: free-chain mode ``m``, ``F_b = F0 cos(m pi (b - 1/2) / n)``, b = 1..n.
        ``travelling``: engine-order ``E`` wave, ``F_b = F0 exp(-2 pi i E (b-1) / n)``.
    F0 : float
        Force amplitude, N (1e-12 to 1e6: :data:`mcfric.validators.F0_RANGE`).
    beam : int
        Driven beam for ``single`` (1-based).
    mode : int
        ``m`` for ``mode`` (>= 0).
    engine_order : int
        ``E`` for ``travelling``.
    """

    pattern: str = "single"
    F0: float = 1.0
    beam: int = 1
    mode: int = 2
    engine_order: int = 2

    def __post_init__(self):
        choice(*PATTERNS)(self.pattern, "pattern")
        object.__setattr__(self, "F0", number(*F0_RANGE)(self.F0, "F0"))
        integer(0)(self.mode, "mode")
        integer(1)(self.beam, "beam")
        integer()(self.engine_order, "engine_order")

    def force(self, n_beams):
        """Complex force amplitudes at the drive position of each beam.

        Parameters
        ----------
        n_beams : int
            Number of beams in the array.

        Returns
        -------
        ndarray of complex, shape (n_beams,)
            Force amplitudes, N.
        """
        integer(1)(n_beams, "n_beams")       # 2.5 gave three forces, -1 none
        b = np.arange(1, n_beams + 1)
        if self.pattern == "single":
            if not 1 <= self.beam <= n_beams:
                raise ValueError(f"beam: expected 1..{n_beams}, got {self.beam}")
            F = np.zeros(n_beams, dtype=complex)
            F[self.beam - 1] = self.F0
            return F
        if self.pattern == "mode":
            return (self.F0 * np.cos(self.mode * np.pi * (b - 0.5) / n_beams)).astype(complex)
        return self.F0 * np.exp(-2j * np.pi * self.engine_order * (b - 1) / n_beams)


@dataclass(frozen=True)
class Model:
    """A friction-coupled beam array.

    Parameters
    ----------
    beams : tuple of ModalTable
        One modal table per beam (may differ: mistuning, measured tables).
    excitation : Excitation
        Drive pattern and amplitude.
    topology : {"linear", "circular"}
        ``linear``: dampers between neighbours (the rig, ``n - 1`` dampers);
        ``circular``: also between the last and the first beam (a bladed disk).
    contact, output, drive : int
        Position labels of the friction contact, the response output and the drive.
    name : str
        Free text used in plots and files.
    contact_law : {"coulomb", "cubic"}
        ``coulomb`` (default): the paper's friction damper. ``cubic``: a stiffening spring
        ``K = kc (1 + (A kc / (mu0 N0))^2)``, no friction, solved by the dense kernel
        only; it has multiple steady states when driven hard and is there to test their
        detection (the bounds assume Coulomb friction).
    """

    beams: tuple
    excitation: Excitation = field(default_factory=Excitation)
    topology: str = "linear"
    contact: int = 1
    output: int = 2
    drive: int = 3
    name: str = "custom"
    contact_law: str = "coulomb"

    def __post_init__(self):
        if isinstance(self.beams, (ModalTable, str, bytes)) or not hasattr(self.beams,
                                                                            "__iter__"):
            raise InputError("beams", f"expected a sequence of ModalTable objects (one per "
                             f"beam), got {type(self.beams).__name__}")
        beams = tuple(self.beams)
        if len(beams) < 2:
            raise ValueError(f"n_beams: expected at least 2 beams, got {len(beams)}")
        if not all(isinstance(t, ModalTable) for t in beams):
            raise InputError("beams", "expected ModalTable objects")
        if self.topology not in TOPOLOGIES:
            raise ValueError(f"topology: expected one of {TOPOLOGIES}, got {self.topology!r}")
        if self.topology == "circular" and len(beams) < 3:
            raise ValueError("topology: a circular array needs at least 3 beams")
        choice(*CONTACT_LAWS)(self.contact_law, "contact_law")
        string(nonblank=True)(self.name, "name")      # as model.name: it goes into files
        if not isinstance(self.excitation, Excitation):
            raise ValueError("excitation: expected an Excitation")
        for name in ("contact", "output", "drive"):
            integer()(getattr(self, name), name)          # 1.9 would be position 1
        for t in beams:
            for name in ("contact", "output", "drive"):
                try:
                    t.column(getattr(self, name))
                except ValueError as e:
                    raise ValueError(f"{name}: {e}") from None
        object.__setattr__(self, "beams", beams)
        force = self.excitation.force(len(beams))  # validates the driven beam index
        ex = self.excitation
        if ex.pattern == "mode" and not ex.mode < len(beams):
            # m = n drives no beam, m and 2n - m the same pattern: one name for each
            raise ValueError(f"mode: expected a chain mode in 0..{len(beams) - 1} "
                             f"(n_beams - 1), got {ex.mode}")
        if ex.pattern == "travelling" and not 0 <= ex.engine_order < len(beams):
            # E and E + n drive the same wave: one name for each
            raise ValueError(f"engine_order: expected 0..{len(beams) - 1} (n_beams - 1), "
                             f"got {ex.engine_order}")
        driven = np.abs(force) > 0
        if not any(np.any(t.column(self.drive)) for t, d in zip(beams, driven) if d):
            # a legal model whose every response is zero: most likely a wrong label
            raise ValueError(f"drive: every mode shape of the driven beams is zero at the "
                             f"drive position {self.drive}: nothing would be excited")
        if not any(np.any(t.column(self.output)) for t in beams):
            raise ValueError(f"output: every mode shape is zero at the output position "
                             f"{self.output}: every response would read zero")

    @classmethod
    def identical(cls, table, n_beams, **kwargs):
        """An array of identical beams.

        Parameters
        ----------
        table : ModalTable
            The modal table of every beam.
        n_beams : int
            Number of beams (>= 2).
        **kwargs
            The other fields of :class:`Model` (``excitation``, ``topology``, ``contact``,
            ``output``, ``drive``, ...).

        Returns
        -------
        Model
        """
        return cls(beams=(table,) * integer(2)(n_beams, "n_beams"), **kwargs)

    @property
    def n_beams(self):
        """Number of beams."""
        return len(self.beams)

    @property
    def n_dampers(self):
        """Number of dampers: ``n_beams - 1`` (linear) or ``n_beams`` (circular)."""
        return self.n_beams - 1 if self.topology == "linear" else self.n_beams

    @property
    def dampers(self):
        """Beams coupled by each damper, 0-based: ``(a, b)`` int arrays, shape (nd,)."""
        a = np.arange(self.n_dampers)
        return a, (a + 1) % self.n_beams

    @property
    def force(self):
        """Complex force amplitudes at the drive positions (n_beams,), N."""
        return self.excitation.force(self.n_beams)

    def with_F0(self, F0):
        """The same model with another drive amplitude.

        Parameters
        ----------
        F0 : float
            Excitation amplitude, N, of the same pattern.

        Returns
        -------
        Model
        """
        return dataclasses.replace(self, excitation=dataclasses.replace(self.excitation, F0=F0))

    def modal_arrays(self):
        """Modal data as arrays, padded to the largest mode count.

        Returns
        -------
        freq_hz, zeta : ndarray, shape (n_beams, n_modes)
            Natural frequencies, Hz, and modal damping ratios (-). Padding modes read 1.
        u : ndarray, shape (n_beams, n_modes, 3)
            Shapes at the contact, output and drive positions, kg^-1/2. Padding modes
            have zero shape and contribute nothing.
        """
        n_modes = max(t.n_modes for t in self.beams)
        f = np.ones((self.n_beams, n_modes))
        z = np.ones((self.n_beams, n_modes))
        u = np.zeros((self.n_beams, n_modes, 3))
        for i, t in enumerate(self.beams):
            m = t.n_modes
            f[i, :m] = t.freq_hz
            z[i, :m] = t.zeta
            for p, label in enumerate((self.contact, self.output, self.drive)):
                u[i, :m, p] = t.column(label)
        return f, z, u

    def receptances(self, omega, modal_freq_hz=None):
        """Per-beam receptances for the kernel, shape (n_r, n_f, 4, n_beams), m/N.

        Parameters
        ----------
        omega : ndarray, shape (n_f,)
            Angular frequencies, rad/s.
        modal_freq_hz : ndarray, shape (n_r, n_beams, n_modes), optional
            Per-sample natural frequencies, Hz (mistuning); default the model's own
            (n_r = 1).

        Returns
        -------
        ndarray of complex, shape (n_r, n_f, 4, n_beams)
            The receptances the kernel reads, m/N.
        """
        f, z, u = self.modal_arrays()
        if modal_freq_hz is None:
            modal_freq_hz = f[None]
        zeta = np.broadcast_to(z, np.shape(modal_freq_hz))
        return beam_receptances(omega, modal_freq_hz, zeta, u)
