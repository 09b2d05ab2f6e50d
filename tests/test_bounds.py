"""Validity and tightness of the equivalent-linear bounds.

References are independent of the bounds search: a dense grid of the describing-function
box solved in physical space (naive.py) for one damper, harmonic-balance ensembles, and a
random + scipy multistart search of the box for seven dampers.
"""

import dataclasses

import numba
import numpy as np
import pytest
from scipy import optimize

import mcfric
from mcfric.bounds import compute_bounds, force_limit

from . import naive
from .conftest import naive_beams, naive_pairs
from .test_certified import physical_grid

K_MAX = 15000.0
N0 = 0.5
F_LIM = force_limit(1.0, N0)          # mu0 ~ U(0, 1), N0 = 0.5 N
#: The searched bounds only: the certified ones are tests/test_certified.py's (the
#: certification's time is not spent again here).
SEARCHED = dict(certified=False)


class PhysicalMetric:
    """M(K) = max_b |y_b| at one frequency from the physical-space solve of naive.py."""

    def __init__(self, model, freq_hz):
        self.model, self.freq_hz = model, freq_hz
        self.D, self.Fext, self.index = naive._assemble(2 * np.pi * freq_hz, naive_beams(model),
                                                        model.force, 0, 1, 2)
        self.pairs = naive_pairs(model)

    def __call__(self, K):
        r = naive._solve_physical(self.D, self.Fext, self.index, self.pairs, np.asarray(K),
                                  0, 1)
        return np.max(np.abs(r["y_output"]))


def _dense_box_extremes(metric, n_grid=121, n_edge=4001):
    """Min and max of M over [0, K_MAX]^2 for one damper: a 2-D grid, every edge sampled
    finely (sharp resonance ridges run along Im K = 0), and a Nelder-Mead polish of both."""
    g = np.linspace(0, K_MAX, n_grid)
    pts = [complex(a, b) for a in g for b in g]
    e = np.linspace(0, K_MAX, n_edge)
    pts += [complex(v, 0) for v in e] + [complex(v, K_MAX) for v in e]
    pts += [complex(0, v) for v in e] + [complex(K_MAX, v) for v in e]
    # the grid in batches (the same physical-space equations, (I - D K) Y = D F)
    vals = physical_grid(metric.model, metric.freq_hz, np.array(pts)[:, None])[0]
    out = []
    for sign, pick in ((1.0, np.argmin), (-1.0, np.argmax)):
        z0 = pts[pick(vals)]
        res = optimize.minimize(
            lambda x: sign * metric([complex(*np.clip(x, 0, K_MAX))]), [z0.real, z0.imag],
            method="Nelder-Mead", options=dict(xatol=1e-3, fatol=0, maxiter=2000))
        out.append(min(vals.min(), res.fun) if sign > 0 else max(vals.max(), -res.fun))
    return out


@pytest.mark.parametrize("F0", [0.22, 1.1])
def test_one_damper_equals_dense_grid(F0):
    model = mcfric.two_beam(F0)
    f = np.array([12.0, 17.0, 30.0, 40.0, 55.0, 64.0, 90.0, 112.0, 140.0])
    B = compute_bounds(model, f, K_MAX, **SEARCHED)   # box only: the search is not capped
    for k, fk in enumerate(f):
        lo, hi = _dense_box_extremes(PhysicalMetric(model, fk))
        # valid: no admissible K outside, and tight: within 0.5 % of the grid
        assert B.upper_box[k] >= hi * (1 - 1e-9), (fk, B.upper_box[k], hi)
        assert B.lower[k] <= lo * (1 + 1e-9), (fk, B.lower[k], lo)
        assert B.upper_box[k] <= hi * 1.005, (fk, B.upper_box[k], hi)
        assert B.lower[k] >= lo / 1.005, (fk, B.lower[k], lo)


def test_upper_bound_is_the_largest_beam_bound_of_box_and_eq_10():
    """One damper (exact search): upper = max over beams of min(box max, Eq. 10 bound)."""
    model = mcfric.two_beam(1.1)
    f = np.linspace(10, 150, 29)
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, **SEARCHED)
    box_beam = np.array([compute_bounds(model, f, K_MAX, beams=[b], **SEARCHED).upper_box
                         for b in range(model.n_beams)]).T
    force_beam = np.array([naive.force_bound(2 * np.pi * fk, naive_beams(model),
                                             naive_pairs(model), model.force, F_LIM)
                           for fk in f])
    np.testing.assert_allclose(B.upper_force, force_beam.max(axis=1), rtol=1e-12)
    np.testing.assert_allclose(B.upper, np.minimum(box_beam, force_beam).max(axis=1),
                               rtol=1e-9)
    assert np.any(B.limited_by == 1) and np.any(B.limited_by == 0)


@pytest.mark.parametrize("F0", [0.22, 1.1])
def test_upper_bound_never_above_the_papers(F0):
    """Never above min(box maximum of M, force bound of M) (paper Section 3.2, step 4)."""
    model = mcfric.eight_beam(F0)
    f = np.linspace(10, 150, 57)
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, **SEARCHED)
    box = compute_bounds(model, f, K_MAX, **SEARCHED)
    force = [naive.force_bound(2 * np.pi * fk, naive_beams(model), naive_pairs(model),
                               model.force, F_LIM).max() for fk in f]
    np.testing.assert_allclose(B.upper_force, force, rtol=1e-12)
    assert np.all(B.upper <= np.minimum(box.upper_box, B.upper_force) * (1 + 1e-9))


def _ensemble_check(model, n_members, freq, seed):
    rng = np.random.default_rng(seed)
    nd = model.n_dampers
    r = mcfric.solve(model, freq, rng.uniform(0, 1, (n_members, nd)),
                     rng.uniform(0, K_MAX, (n_members, nd)), N0)
    B = compute_bounds(model, freq, K_MAX, F_lim=F_LIM, **SEARCHED)
    M = r.metric()
    ok = r.converged
    inside = B.contains(M, rtol=1e-9)
    assert B.n_failed == 0
    assert np.all(inside[ok]), (
        f"{np.count_nonzero(~inside & ok)} member points outside; worst above "
        f"{np.nanmax(M / B.upper):.6g}, worst below {np.nanmin(M / B.lower):.6g}")
    return B, M


@pytest.mark.parametrize("F0", [0.22, 1.1])
@pytest.mark.parametrize("preset", ["two-beam", "eight-beam"])
def test_every_ensemble_member_lies_within_the_bounds(preset, F0):
    model = mcfric.preset(preset, F0)
    _ensemble_check(model, 500, np.linspace(10, 150, 281), seed=3)


@pytest.mark.slow
@pytest.mark.parametrize("F0", [0.22, 0.25, 1.1])
@pytest.mark.parametrize("preset", ["two-beam", "eight-beam"])
def test_every_member_of_large_ensembles_lies_within_the_bounds(preset, F0):
    model = mcfric.preset(preset, F0)
    _ensemble_check(model, 4000, np.linspace(10, 150, 1000), seed=4)


@pytest.mark.parametrize("F0", [0.22, 1.1])
def test_seven_dampers_random_and_multistart_search_stay_inside(F0):
    """Random points of the box, random corners, and scipy polishes from the best of them,
    all in physical space, find nothing above the box maximum or below the box minimum
    (bounds computed, as a user would, on a fine frequency grid; checked at ten of its
    frequencies)."""
    model = mcfric.eight_beam(F0)
    grid = np.linspace(10, 150, 281)
    B = compute_bounds(model, grid, K_MAX, **SEARCHED)   # the box alone: what the search must cover
    rng = np.random.default_rng(7)
    nd = model.n_dampers
    for k in np.linspace(4, 276, 10).astype(int):
        metric = PhysicalMetric(model, grid[k])
        K = K_MAX * (rng.uniform(0, 1, (1500, nd)) + 1j * rng.uniform(0, 1, (1500, nd)))
        corners = K_MAX * np.array([0, 1, 1 + 1j, 1j])[rng.integers(0, 4, (500, nd))]
        cand = np.concatenate([K, corners])
        vals = np.array([metric(z) for z in cand])
        for sign, order in ((-1.0, np.argsort(-vals)), (1.0, np.argsort(vals))):
            for z in cand[order[:3]]:
                res = optimize.minimize(
                    lambda x: sign * metric(x[:nd] + 1j * x[nd:]),
                    np.concatenate([z.real, z.imag]), method="L-BFGS-B",
                    bounds=[(0, K_MAX)] * (2 * nd), options=dict(maxiter=300))
                vals = np.append(vals, sign * res.fun)
        assert vals.max() <= B.upper_box[k] * (1 + 1e-9), (grid[k], vals.max(), B.upper_box[k])
        assert vals.min() >= B.lower[k] * (1 - 1e-9), (grid[k], vals.min(), B.lower[k])


@pytest.mark.parametrize("F0", [0.22, 1.1])
def test_scipy_slsqp_from_the_minimum_finds_nothing_lower(F0):
    """The lower bound is a local minimum for an independent minimax solver: scipy's SLSQP
    on ``min t`` subject to ``|y_b|^2 <= t`` and the box, in physical space, started from
    the describing functions of the lower bound, finds nothing below it. Checked in the
    first passband's valley (41-62 Hz, every beam nearly at rest at the minimum and all
    of them equal there), where coordinate and smoothed-gradient searches stall: before
    the minimax search SLSQP went lower at 11 and 13 of these 15 frequencies, by up to 0.8 %
    and 3.4 %; after it, measured, by at most 5e-9."""
    model = mcfric.eight_beam(F0)
    grid = np.linspace(10, 150, 281)
    B = compute_bounds(model, grid, K_MAX, F_lim=F_LIM, **SEARCHED)
    nd = model.n_dampers
    gaps = []
    for k in np.flatnonzero((grid >= 41) & (grid <= 62))[::3]:
        metric = PhysicalMetric(model, grid[k])

        def outputs(x):
            K = K_MAX * (np.clip(x[:nd], 0, 1) + 1j * np.clip(x[nd:2 * nd], 0, 1))
            return naive._solve_physical(metric.D, metric.Fext, metric.index, metric.pairs, K,
                                         0, 1)["y_output"]

        K0 = B.K_lower[k] / K_MAX
        scale = np.max(np.abs(outputs(np.concatenate([K0.real, K0.imag]))))
        res = optimize.minimize(
            lambda x: x[-1], np.concatenate([K0.real, K0.imag, [1.0]]), method="SLSQP",
            bounds=[(0, 1)] * (2 * nd) + [(0, None)],
            constraints=[dict(type="ineq",
                              fun=lambda x: x[-1] - np.abs(outputs(x) / scale) ** 2)],
            options=dict(maxiter=300, ftol=1e-14))
        found = np.max(np.abs(outputs(res.x)))
        gaps.append(B.lower[k] / found - 1)
        assert found >= B.lower[k] * (1 - 1e-7), (grid[k], found, B.lower[k])
    assert len(gaps) >= 10


def test_exact_coordinate_minimum_equals_a_dense_search_of_the_rectangle():
    """One coordinate of the search: min over the rectangle of max_b |y_b| for Moebius
    functions y_b = (alpha_b + beta_b z) / (d0 + d1 z) (edges exact, interior by the
    weighted 1-centre), against a 301 x 301 grid polished by Nelder-Mead."""
    from mcfric.core.rectangle import best_on_rectangle

    rng = np.random.default_rng(1)
    E = np.zeros((6, 8))
    n_inside = 0
    for trial in range(150):
        nb = int(rng.integers(2, 9))
        alpha = rng.normal(size=nb) + 1j * rng.normal(size=nb)
        beta = (rng.normal(size=nb) + 1j * rng.normal(size=nb)) * rng.choice([0.1, 1, 3])
        d0 = 1.0 + 0.3j
        d1 = complex(rng.uniform(0, 0.3), rng.uniform(0, 0.3)) if trial % 5 else 0j
        kr, ki = 1.0, float(rng.choice([0.3, 1.0]))

        def M(z):
            return np.max(np.abs(alpha[:, None] + beta[:, None] * np.ravel(z)), axis=0) / \
                np.abs(d0 + d1 * np.ravel(z))

        X, Y = np.meshgrid(np.linspace(0, kr, 301), np.linspace(0, ki, 301))
        vals = M(X + 1j * Y)
        i = np.argmin(vals)
        res = optimize.minimize(lambda x: M(complex(*x))[0], [X.flat[i], Y.flat[i]],
                                method="Nelder-Mead", bounds=[(0, kr), (0, ki)],
                                options=dict(xatol=1e-12, fatol=1e-15, maxiter=5000))
        ref = min(vals[i], res.fun)
        v, z = best_on_rectangle(alpha, beta, d0, d1, kr, ki, False, 0.5 * complex(kr, ki),
                                 0, nb, True, E)
        assert v <= ref * (1 + 1e-9), (trial, v, ref)
        assert abs(M(z)[0] - v) <= 1e-12 * v            # the value is that of the point
        n_inside += 0 < z.real < kr and 0 < z.imag < ki
    assert n_inside >= 10                                # the interior case is exercised



def test_pruned_edges_of_many_beams_find_the_edge_minimum_of_a_dense_sampling():
    """Above ``PRUNE_BEAMS`` beams the minimum's edges make candidates only where every
    beam is below the best value, and only of beams that can be the largest there: the
    perimeter minimum is still found, at most a dense sampling of the edges (50,001
    points each), with near-tied beams (a tuned ring's) among the cases."""
    from mcfric.core.rectangle import PRUNE_BEAMS, best_on_rectangle

    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 1.0, 50_001)
    for trial in range(40):
        nb = int(rng.integers(PRUNE_BEAMS + 1, 4 * PRUNE_BEAMS))
        spread = [1.0, 0.05, 1e-3][trial % 3]      # random, near-tied, almost equal
        alpha = (1 + 0.5j) + spread * (rng.normal(size=nb) + 1j * rng.normal(size=nb))
        beta = (-0.8 + 0.2j) + spread * (rng.normal(size=nb) + 1j * rng.normal(size=nb))
        d0 = 1.0 + 0.3j
        d1 = complex(rng.uniform(0, 0.3), rng.uniform(0, 0.3))
        kr, ki = 1.0, float(rng.choice([0.3, 1.0]))
        corners = [0j, complex(kr, 0), complex(kr, ki), complex(0, ki)]
        ref = np.inf
        for c in range(4):
            z = corners[c] + t * (corners[(c + 1) % 4] - corners[c])
            m = np.max(np.abs(alpha[:, None] + beta[:, None] * z), axis=0) / np.abs(d0 + d1 * z)
            ref = min(ref, m.min())
        E = np.zeros((6, nb))
        v, z = best_on_rectangle(alpha, beta, d0, d1, kr, ki, False, 0j, 0, nb, False, E)
        assert v <= ref * (1 + 1e-12), (trial, v, ref)
        assert np.max(np.abs(alpha + beta * z)) / abs(d0 + d1 * z) == pytest.approx(v, rel=1e-12)


def test_banded_elimination_of_the_smoothed_maximum_equals_dense_lu():
    """The smoothed maximum and its gradient by the O(nd) eliminations (chain, and the
    bordered one of a ring) equal those of the dense LU path."""
    from mcfric.bounds.search import sparsity
    from mcfric.core.coordinate_search import workspace
    from mcfric.core.linalg import banded
    from mcfric.core.projected_gradient import smooth_max
    from mcfric.core.receptance import contact_space

    chain = mcfric.eight_beam(0.25)
    f = np.linspace(10, 150, 12)
    rng = np.random.default_rng(2)
    for model, code in ((chain, 1), (dataclasses.replace(chain, topology="circular"), 2)):
        rec = model.receptances(2 * np.pi * f)[0]
        G, q0, ylin, H = contact_space(rec, model.force, *model.dampers)
        nd, nb = G.shape[1], ylin.shape[1]
        hr, gr = sparsity(G, H)
        w_band = workspace(nd, nb, hr, gr)
        w_dense = workspace(nd, nb, np.tile([0, nd], (nb, 1)), np.tile([0, nd], (nd, 1)))
        for k in range(len(f)):
            Gk = np.ascontiguousarray(G[k])
            assert banded(Gk, gr, nd) == code
            w_band[14][0] = code
            w_dense[14][0] = 0
            for _ in range(10):
                K = K_MAX * (rng.uniform(size=nd) + 1j * rng.uniform(size=nd))
                g1, g2 = np.zeros(nd, complex), np.zeros(nd, complex)
                v1, _ = smooth_max(Gk, q0[k], ylin[k], H[k], K, 0.01, 0, nb, g1, w_band)
                v2, _ = smooth_max(Gk, q0[k], ylin[k], H[k], K, 0.01, 0, nb, g2, w_dense)
                assert abs(v1 - v2) <= 1e-10 * abs(v2)
                assert np.max(np.abs(g1 - g2)) <= 1e-9 * np.max(np.abs(g2))


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs 2 threads")
def test_bounds_do_not_depend_on_the_thread_count():
    # the searches run as tasks on Python threads that write disjoint parts of the output
    model = mcfric.eight_beam(0.25)
    f = np.linspace(30, 140, 40)
    one, two = (compute_bounds(model, f, K_MAX, F_lim=F_LIM, n_threads=n, **SEARCHED)
                for n in (1, 2))
    for name in ("upper", "lower", "limited_by", "K_upper", "K_lower"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    assert np.all(np.isfinite(one.upper)) and np.all(one.lower < one.upper)


def test_bounds_scale_with_the_metric_quantity():
    model = mcfric.two_beam(0.22)
    f = np.linspace(20, 120, 6)
    d = compute_bounds(model, f, K_MAX, F_lim=F_LIM, n_starts=2, **SEARCHED)
    a = compute_bounds(model, f, K_MAX, F_lim=F_LIM, n_starts=2, quantity="acceleration",
                       **SEARCHED)
    np.testing.assert_allclose(a.upper, d.upper * (2 * np.pi * f) ** 2, rtol=1e-12)
    np.testing.assert_allclose(a.lower, d.lower * (2 * np.pi * f) ** 2, rtol=1e-12)


@pytest.mark.parametrize("kwargs, name", [
    (dict(k_max=0.0), "k_max"),
    (dict(k_max=np.nan), "k_max"),
    (dict(k_max=K_MAX, k_max_im=-1.0), "k_max_im"),
    (dict(k_max=K_MAX, F_lim=0.0), "F_lim"),
    (dict(k_max=K_MAX, beams=[9]), "beams"),
    (dict(k_max=K_MAX, beams=[0.9]), "beams"),          # not truncated to beam 0
    (dict(k_max=K_MAX, beams="01"), "beams"),
    (dict(k_max=1e20), "k_max: expected at most"),       # the search overflowed
    (dict(k_max=K_MAX, k_max_im=1e300), "k_max_im: expected at most"),
    (dict(k_max=K_MAX, quantity="jerk"), "quantity"),
    (dict(k_max=K_MAX, n_starts=0), "n_starts"),
    (dict(k_max=K_MAX, n_starts=10**12), "n_starts"),    # numpy's MemoryError (10.9 TiB)
    (dict(k_max=K_MAX, beams="all"), "beams: .*got 'all'"),   # it said "got 'a'"
    (dict(k_max=K_MAX, max_sweeps=0), "max_sweeps"),
    (dict(k_max=K_MAX, seed=1.5), "seed"),
    (dict(k_max=K_MAX, certified="no"), "certified"),    # a truthy string ran it
    (dict(k_max=K_MAX, budget=True), "budget"),           # ran with a budget of 1
    (dict(k_max=K_MAX, split=False), "split"),            # ran with split 0
    (dict(k_max=K_MAX, certified=False, moments="yes"), "moments"),   # ignored silently
    (dict(k_max=K_MAX, model=dataclasses.replace(mcfric.two_beam(), contact_law="cubic")),
     "Coulomb"),
    (dict(k_max=K_MAX, freq_hz=[1e160]), "at most"),     # receptances overflowed to 0
])
def test_bad_input_names_the_argument(kwargs, name):
    args = dict(model=mcfric.two_beam(), freq_hz=[20.0, 30.0])
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        compute_bounds(args.pop("model"), args.pop("freq_hz"), **args)


def _scaled_two_beam(zeta1=None, shape=None):
    t = mcfric.two_beam().beams[0]
    z = t.zeta.copy() if zeta1 is None else np.array([zeta1, t.zeta[1]])
    u = t.shapes.copy()
    if shape is not None:
        u[0, 0] = shape
    table = mcfric.ModalTable(t.freq_hz, z, u, t.positions)
    m = mcfric.two_beam()
    return dataclasses.replace(m, beams=(table,) * m.n_beams)


@pytest.mark.parametrize("zeta1, shape", [(1e-30, None), (1e-300, None), (None, 1e7)])
def test_a_table_out_of_scale_is_refused_not_divided_by_zero(zeta1, shape):
    """A damping of 1e-30 or a shape of 1e7 kg^-1/2 (a table in wrong units) made the
    box search's Moebius maps lose their 1 and divide by complex zero: a 38-line
    ZeroDivisionError from the kernel. Refused up front, naming the scale."""
    model = _scaled_two_beam(zeta1, shape)
    with pytest.raises(ValueError, match=r"beyond the 1e\+15 the bounds resolve"):
        compute_bounds(model, np.linspace(10.0, 150.0, 8), 15000.0, certified=False)


@pytest.mark.parametrize("name", ["two-beam", "eight-beam", "disk-24", "disk-72"])
def test_every_preset_is_in_scale_up_to_the_stiffest_box(name):
    """The scale check leaves every preset its whole range of k_max (up to a stuck
    damper, 1e12 N/m) with two decades to spare."""
    from mcfric.bounds.equivalent_linear import K_MAX_LIMIT, SCALE_MAX, check_scales

    model = mcfric.preset(name)
    check_scales(model, 100 * K_MAX_LIMIT, 100 * K_MAX_LIMIT)
    with pytest.raises(ValueError):
        check_scales(model, 1e4 * SCALE_MAX, 1e4 * SCALE_MAX)


def test_a_failed_frequency_is_not_counted_as_set_by_the_box():
    """The summary counted a frequency whose search failed (NaN bound, limited_by 0)
    as set by the box."""
    B = compute_bounds(mcfric.two_beam(0.22), np.linspace(10.0, 150.0, 20), 15000.0,
                       certified=False)
    up = B.upper.copy()
    up[3] = np.nan
    text = dataclasses.replace(B, upper=up).summary()
    force = int(np.count_nonzero(B.limited_by == 1))
    assert (f"upper set by the force limit at {force}, by the box at {19 - force}; "
            f"failed: 1") in text, text


def test_the_summary_says_where_a_witness_lies_past_the_searched_bounds():
    """An admissible witness above the searched upper bound (or below the lower) shows
    the search missed it: on eight beams at 15.5 Hz (17 frequencies) by 8.7 %, which
    the summary did not say. Here the searched bounds are moved inward by hand."""
    B = compute_bounds(mcfric.two_beam(0.22), np.linspace(10.0, 150.0, 12), 15000.0,
                       F_lim=force_limit(1.0, 0.5))
    assert "lie past the searched bounds" not in B.summary()
    C = B.certificate
    up, lo = B.upper.copy(), B.lower.copy()
    up[2] = C.upper_witness[2] / 1.05
    lo[5] = C.lower_witness[5] / 0.98
    text = dataclasses.replace(B, upper=up, lower=lo).summary()
    assert ("witnesses lie past the searched bounds, upper at 1 (up to 5 % above) and lower "
            "at 1 (up to 2 % below) of the frequencies: the search missed them") in text, text


def test_admits_names_the_constraints_and_refuses_what_it_cannot_check():
    """``Bounds.admits``: a member inside ``kc <= k_max``, ``kc / pi <= k_max_im``, ``4 /
    pi mu0 N0 <= F_lim`` is admitted, one past any of them not; a member of another
    damper count or with NaN or negative friction is refused (it returned True)."""
    model = mcfric.eight_beam()
    B = compute_bounds(model, np.array([20.0, 40.0]), 15000.0, F_lim=force_limit(1.0, 0.5),
                       certified=False)
    nd = model.n_dampers
    mu0, kc, N0 = np.full(nd, 0.5), np.full(nd, 1e3), np.full(nd, 0.5)
    assert B.admits(mu0, kc, N0)
    kc_out = kc.copy()
    kc_out[3] = 15001.0
    mu_out = mu0.copy()
    mu_out[0] = 1.01
    assert list(B.admits(np.stack([mu0, mu0, mu_out]), np.stack([kc, kc_out, kc]),
                         N0)) == [True, False, False]
    for args, message in (((mu0[:3], kc[:3], N0[:3]), r"mu0: expected shape \(\.\.\., 7\)"),
                          ((0.5, kc, N0), r"mu0: expected shape"),
                          ((-mu0, kc, N0), "mu0: expected finite values >= 0"),
                          ((mu0, kc, np.full(nd, np.nan)), "N0: expected finite")):
        with pytest.raises(ValueError, match=message):
            B.admits(*args)


def test_a_bounds_file_is_written_for_its_configurations_grid_only(tmp_path):
    """Bounds computed on another grid than the configuration's were written under its
    record, which then described another grid (info and plot refuse such a file)."""
    from mcfric import config
    from mcfric.bounds import write_bounds_file

    cfg = config.load("two-beam", {"frequency.n": (6, "--n-freq")})
    model = cfg.spec.model
    other = np.linspace(20.0, 40.0, 5)
    B = compute_bounds(model, other, 15000.0, F_lim=force_limit(1.0, 0.5), certified=False)
    with pytest.raises(ValueError, match="bounds on 5 frequencies, not on the configuration"):
        write_bounds_file(tmp_path / "b.h5", cfg, B)
    assert list(tmp_path.iterdir()) == []


def test_check_members_counts_a_point_pushed_past_the_bounds(tmp_path):
    """``check_members`` from Python, as ``mcfric run`` prints it: every converged point
    checked and none outside; one point set to twice the upper bound (with h5py, the
    bounds read from the file by hand) is counted outside both bounds."""
    import h5py

    from mcfric import config, ensemble
    from mcfric.bounds import check_members

    cfg = config.load("two-beam").replace("sampling.samples", 6).replace("frequency.n", 12)
    path = ensemble.run(cfg, tmp_path / "r.h5", progress=False).path
    with h5py.File(path, "r") as h5:
        converged = h5["converged"][...]
        upper = h5["bounds/upper"][...]
    check = check_members(path)
    assert check.total == np.count_nonzero(converged) > 0
    assert (check.outside, check.outside_certified, check.left_out) == (0, 0, 0)
    i, k = np.argwhere(converged)[0]
    with h5py.File(path, "r+") as h5:
        h5["metric"][i, k] = 2 * upper[k]
    check = check_members(path)
    assert (check.outside, check.outside_certified) == (1, 1)
    # a NaN stored at a converged point is no point outside the bounds: counted apart
    with h5py.File(path, "r+") as h5:
        h5["metric"][i, k] = np.nan
    check = check_members(path)
    assert (check.outside, check.outside_certified, check.non_finite) == (0, 0, 1)
    assert check.total == np.count_nonzero(converged) - 1
    # a damaged file: one line naming the dataset, not a KeyError
    with h5py.File(path, "r+") as h5:
        del h5["bounds/upper"]
    with pytest.raises(Exception, match="bounds/upper is missing") as e:
        check_members(path)
    assert len(str(e.value).splitlines()) == 1 and not isinstance(e.value, KeyError)
