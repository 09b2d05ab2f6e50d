"""The paper's rigs (docs: theory, "The rig" and "Excitation").

* ``two-beam``: beams 5 and 6 of the rig as an isolated pair, one damper, the first beam
  driven (``F = [F0, 0]``), F0 = 0.22 N (Fig. 7a).
* ``eight-beam``: the full linear rig, seven dampers, driven in the pattern of the third
  free-chain first-passband mode (``m = 2``, "approximately engine order 2"),
  F0 = 1.1 N (Fig. 9b).

Both use Table 1 for every beam, contact at position 1, output at 2, drive at 3.
"""

from .model import TABLE_1, Excitation, Model

PRESETS = ("two-beam", "eight-beam")


def two_beam(F0=0.22):
    """The two-beam sub-assembly (one damper, beam 1 driven)."""
    return Model.identical(TABLE_1, 2, excitation=Excitation("single", F0, beam=1),
                           topology="linear", name="two-beam")


def eight_beam(F0=1.1):
    """The eight-beam rig (seven dampers, free-chain mode m = 2 drive pattern)."""
    return Model.identical(TABLE_1, 8, excitation=Excitation("mode", F0, mode=2),
                           topology="linear", name="eight-beam")


def preset(name, F0=None):
    """A preset model by name (``two-beam`` or ``eight-beam``), optionally with its F0 in N."""
    makers = {"two-beam": two_beam, "eight-beam": eight_beam}
    if name not in makers:
        raise ValueError(f"preset: expected one of {PRESETS}, got {name!r}")
    return makers[name]() if F0 is None else makers[name](F0)
