"""The branch and bound over relaxations of parts of the box
(mcfric.core.relaxation_branch): each part's relaxation against random admissible
points of that part, the branch and bound against an exhaustive grid and random
admissible points (all solved in physical space, tests/naive.py's equations), and what
it closes on eight beams."""

import numpy as np
import pytest

import mcfric
from mcfric.bounds import compute_bounds
from mcfric.core.relaxation import buffers, relaxed_bound
from mcfric.core.relaxation_branch import branch

from .test_certified import F_LIM, K_MAX, chain, grid_points, physical_grid
from .test_force_ascent import arrays


def _buffers(nd, nb, lower):
    """The kernels' buffers with a force limit, and a ``stats`` counter."""
    return (*buffers(nd, nb, True, lower), np.zeros(3, np.int64))


def _in_part(lo, hi, n, rng):
    """``n`` random points of the part ``[lo, hi]`` (each damper's rectangle), with a
    quarter of them on its sides."""
    u = rng.uniform(0, 1, (n, len(lo)))
    v = rng.uniform(0, 1, (n, len(lo)))
    u[: n // 4] = np.round(u[: n // 4])
    return lo.real + u * (hi.real - lo.real) + 1j * (lo.imag + v * (hi.imag - lo.imag))


@pytest.mark.parametrize("freq", [23.7, 121.8])
def test_each_part_encloses_its_admissible_points(freq):
    """Eight beams, 0.25 N: the relaxation of random parts of the box (not touching 0)
    bounds every beam's response from above, and the largest from below, at 2000 random
    admissible points of the part."""
    model = mcfric.eight_beam(0.25)
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    rng = np.random.default_rng(7)
    nd, nb = 7, 8
    checked = 0
    for trial in range(4):
        a = rng.uniform(0, 0.6, (2, nd)) * K_MAX
        w = rng.uniform(0.1, 0.4, (2, nd)) * K_MAX
        lo = a[0] + 1j * a[1]
        hi = lo + w[0] + 1j * w[1]
        K = _in_part(lo, hi, 2000, rng)
        M, force = physical_grid(model, freq, K)
        ok = force <= 1.0
        if not ok.any():
            continue
        checked += 1
        buf = _buffers(nd, nb, False)
        upper = max(relaxed_bound(G, q0, ylin, H, lo, hi, F_LIM, b, 0.0, *buf)
                    for b in range(nb))
        buf = _buffers(nd, nb, True)
        lower = relaxed_bound(G, q0, ylin, H, lo, hi, F_LIM, -1, np.inf, *buf)
        assert np.isfinite(upper) and np.isfinite(lower)
        assert lower <= M[ok].min() and M[ok].max() <= upper
    assert checked >= 2


@pytest.mark.parametrize("freq", [18.6, 71.0])
def test_three_dampers_enclose_an_exhaustive_grid(freq):
    """A four-beam chain (three dampers), F0 = 0.5 N, a budget of 120 relaxations and a
    goal nothing reaches (it spends the budget): the bounds enclose every admissible
    point of a 7 x 7 grid of every rectangle (117,649 points), and are no looser than
    the whole box's relaxation."""
    model = chain(4, 0.5)
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    M, force = physical_grid(model, freq, grid_points(3, 7))
    ok = force <= 1.0
    nd, nb = 3, 4
    lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
    uppers = []
    for b in range(nb):
        buf = _buffers(nd, nb, False)
        whole = relaxed_bound(G, q0, ylin, H, lo, hi, F_LIM, b, 0.0, *buf)
        bound, used = branch(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, b, whole, 0.0, 120, *buf)
        assert used <= 120 and bound <= whole
        uppers.append(bound)
    assert M[ok].max() <= max(uppers)
    buf = _buffers(nd, nb, True)
    whole = relaxed_bound(G, q0, ylin, H, lo, hi, F_LIM, -1, np.inf, *buf)
    lower, used = branch(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, -1, whole, np.inf, 120, *buf)
    assert used <= 120 and whole <= lower <= M[ok].min()


def test_splitting_closes_eight_beam_gaps_and_stays_sound():
    """Eight beams, 0.25 N, 5 frequencies where the relaxation of the whole box leaves a
    lower or upper gap: with the default budget the certificate is never looser, the
    lower bound within 1 % of its witness at 4 or more (at most 1 without), and both
    enclose 3000 random admissible points per frequency."""
    model = mcfric.eight_beam(0.25)
    f = np.array([104.6, 120.15, 121.83, 132.62, 136.83])
    kw = dict(F_lim=F_LIM)
    C0 = compute_bounds(model, f, K_MAX, split=0, **kw).certificate
    C = compute_bounds(model, f, K_MAX, **kw).certificate
    assert np.all(C.upper <= C0.upper) and np.all(C.lower >= C0.lower)
    assert np.count_nonzero(C0.lower_gap <= 0.01) <= 1
    assert np.count_nonzero(C.lower_gap <= 0.01) >= 4
    assert C.split_used[1] > 0
    rng = np.random.default_rng(3)
    for k, freq in enumerate(f):
        K = 10.0 ** rng.uniform(-3, 0, (3000, 1)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                    + 1j * rng.uniform(0, K_MAX, (3000, 7)))
        M, force = physical_grid(model, freq, K)
        M = M[force <= 1.0]
        assert C.lower[k] <= M.min() and M.max() <= C.upper[k]
