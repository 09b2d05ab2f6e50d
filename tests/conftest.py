import numpy as np
import pytest

import mcfric

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
