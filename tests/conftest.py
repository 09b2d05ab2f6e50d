import numpy as np
import pytest

import mcfric
from mcfric.model import TABLE_1, Excitation, Model

from . import naive  # noqa: F401  (tests import it as tests.naive)


def naive_beams(model):
    """A model's beams as tests/naive.py takes them (positions contact, output, drive)."""
    out = []
    for t in model.beams:
        cols = [t.positions.index(p) for p in (model.contact, model.output, model.drive)]
        out.append(dict(freq_hz=np.array(t.freq_hz), zeta=np.array(t.zeta),
                        u=np.array(t.shapes)[:, cols]))
    return out


def naive_pairs(model):
    a, b = model.dampers
    return list(zip(a.tolist(), b.tolist()))


@pytest.fixture(scope="session")
def two_beam():
    return mcfric.two_beam(0.22)


@pytest.fixture(scope="session")
def eight_beam():
    return mcfric.eight_beam(1.1)


def ring(n, mistuned, engine_order=1, F0=0.8):
    """A ring of ``n`` blades (Table 1 beams, 2 % mistuned in the first two modes if
    ``mistuned``) under a travelling wave of ``engine_order``, ``F0`` N."""
    rng = np.random.default_rng(100 + n)
    if mistuned:
        beams = tuple(TABLE_1.with_frequency(1, 16.2 * (1 + 0.02 * rng.standard_normal()))
                      .with_frequency(2, 105.8 * (1 + 0.02 * rng.standard_normal()))
                      for _ in range(n))
    else:
        beams = (TABLE_1,) * n
    return Model(beams, Excitation("travelling", F0, engine_order=engine_order),
                 topology="circular")
