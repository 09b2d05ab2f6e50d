"""The paper's rigs (docs: theory, "The rig" and "Excitation").

* ``two-beam``: beams 5 and 6 of the rig as an isolated pair, one damper, the first beam
  driven (``F = [F0, 0]``), F0 = 0.22 N (Fig. 7a).
* ``eight-beam``: the full linear rig, seven dampers, driven in the pattern of the third
  free-chain first-passband mode (``m = 2``, "approximately engine order 2"),
  F0 = 1.1 N (Fig. 9b).
* ``disk-24``: a tuned bladed disk, 24 Table-1 blades in a ring (24 dampers), driven by
  an engine-order 3 travelling wave, F0 = 1.1 N on every blade.
* ``disk-72``: the same with 72 blades and engine order 8.

All use Table 1 for every beam, contact at position 1, output at 2, drive at 3. The disks
are the paper's blades joined into rings, not a rig of the paper: their passband is the
eight-beam rig's (16-73 Hz with the default contact stiffness), and an engine order E
excites the ring's E-nodal-diameter wave.
"""

from .model import TABLE_1, Excitation, Model
from .validators import InputError

PRESETS = ("two-beam", "eight-beam", "disk-24", "disk-72")


def two_beam(F0=0.22):
    """The two-beam sub-assembly (one damper, beam 1 driven).

    Parameters
    ----------
    F0 : float
        Force amplitude at beam 1's drive point, N (the paper's Fig. 7: 0.22 N).

    Returns
    -------
    Model
    """
    return Model.identical(TABLE_1, 2, excitation=Excitation("single", F0, beam=1),
                           topology="linear", name="two-beam")


def eight_beam(F0=1.1):
    """The eight-beam rig (seven dampers, free-chain mode m = 2 drive pattern).

    Parameters
    ----------
    F0 : float
        Amplitude of the drive pattern, N (the paper's: 0.25 and 1.1 N).

    Returns
    -------
    Model
    """
    return Model.identical(TABLE_1, 8, excitation=Excitation("mode", F0, mode=2),
                           topology="linear", name="eight-beam")


def disk(n_blades=24, engine_order=3, F0=1.1):
    """A tuned bladed disk: ``n_blades`` Table-1 blades in a ring, engine-order wave.

    Parameters
    ----------
    n_blades : int
        Blades (beams) in the ring, at least 3; as many dampers, one between each pair of
        neighbours.
    engine_order : int
        Nodal diameters of the travelling wave, 0 .. n_blades - 1.
    F0 : float
        Force amplitude at every blade's drive point, N.

    Returns
    -------
    Model
    """
    return Model.identical(TABLE_1, n_blades,
                           excitation=Excitation("travelling", F0, engine_order=engine_order),
                           topology="circular", name=f"disk-{n_blades}")


def disk_24(F0=1.1):
    """24 blades in a ring, engine order 3.

    Parameters
    ----------
    F0 : float
        Amplitude of the travelling-wave excitation, N.

    Returns
    -------
    Model
    """
    return disk(24, 3, F0)


def disk_72(F0=1.1):
    """72 blades in a ring, engine order 8.

    Parameters
    ----------
    F0 : float
        Amplitude of the travelling-wave excitation, N.

    Returns
    -------
    Model
    """
    return disk(72, 8, F0)


def preset(name, F0=None):
    """A preset model by name.

    Parameters
    ----------
    name : str
        One of ``PRESETS``: ``"two-beam"``, ``"eight-beam"``, ``"disk-24"``, ``"disk-72"``.
    F0 : float, optional
        Force amplitude, N; default the preset's.

    Returns
    -------
    Model

    Raises
    ------
    ValueError
        An unknown name.
    """
    makers = {"two-beam": two_beam, "eight-beam": eight_beam, "disk-24": disk_24,
              "disk-72": disk_72}
    if not isinstance(name, str) or name not in makers:
        raise InputError("preset", f"expected one of {PRESETS}, got {name!r}")
    return makers[name]() if F0 is None else makers[name](F0)
