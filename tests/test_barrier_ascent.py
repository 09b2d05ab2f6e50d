"""The joint ascent of the upper witness (mcfric.core.barrier_ascent), checked by
physical-space solves written independently of the contact-space code."""

import numpy as np
import pytest

import mcfric
from mcfric.core.barrier_ascent import ascend_frequencies
from mcfric.core.receptance import contact_space

from .test_certified import F_LIM, K_MAX, edge_points, grid_points, physical_grid


def arrays(model, f):
    a, b = model.dampers
    return [np.ascontiguousarray(x) for x in
            contact_space(model.receptances(2 * np.pi * f)[0], model.force, a, b)]


def test_ascent_is_admissible_and_never_loses():
    """Eight beams, 20 random admissible starts at each of 4 frequencies: every result
    lies in the box and within the force limit, attains its value, and is no lower than
    its start."""
    model = mcfric.eight_beam(0.25)
    f = np.array([20.5, 45.0, 90.0, 130.0])
    args = arrays(model, f)
    nd = model.n_dampers
    rng = np.random.default_rng(2)
    for k, fk in enumerate(f):
        s = 10.0 ** rng.uniform(-3, -1, (60, 1))
        K0 = s * (rng.uniform(0, K_MAX, (60, nd)) + 1j * rng.uniform(0, K_MAX, (60, nd)))
        M0, force = physical_grid(model, fk, K0)
        K0, M0 = K0[force <= 0.99][:20], M0[force <= 0.99][:20]
        assert len(K0) >= 10
        for K_start, M_start in zip(K0, M0):
            starts = np.full((len(f), 1, nd), np.nan + 0j)
            starts[k, 0] = K_start
            K = np.zeros((len(f), nd), complex)
            M = np.full(len(f), -np.inf)
            ascend_frequencies(*args, K_MAX, K_MAX, F_LIM, starts, np.array([k]), K, M)
            W = K[k]
            assert np.all((W.real >= 0) & (W.real <= K_MAX) & (W.imag >= 0) & (W.imag <= K_MAX))
            Mw, fw = physical_grid(model, fk, W[None, :])
            assert fw[0] <= 1.0 and Mw[0] == pytest.approx(M[k], rel=1e-9)
            assert M[k] >= M_start * (1 - 1e-12)


@pytest.mark.parametrize("freq", [14.0, 25.0, 60.0])
def test_one_damper_ascent_reaches_the_grid_maximum(freq):
    """One damper, the box and the force limit: the best of five starts comes within 1 %
    of a dense physical-space grid's admissible maximum."""
    model = mcfric.two_beam(1.1)
    args = arrays(model, np.array([freq]))
    K = np.concatenate([grid_points(1, 301), edge_points(20001)])
    M, force = physical_grid(model, freq, K)
    grid_max = M[force <= 1.0].max()
    rng = np.random.default_rng(0)
    starts = (rng.uniform(0, K_MAX, (1, 5, 1)) + 1j * rng.uniform(0, K_MAX, (1, 5, 1))) * 1e-2
    Kb = np.zeros((1, 1), complex)
    Mb = np.full(1, -np.inf)
    ascend_frequencies(*args, K_MAX, K_MAX, F_LIM, starts, np.array([0]), Kb, Mb)
    Mw, fw = physical_grid(model, freq, Kb)
    assert fw[0] <= 1.0 and Mw[0] == pytest.approx(Mb[0], rel=1e-9)
    assert Mb[0] == pytest.approx(grid_max, rel=0.01)
