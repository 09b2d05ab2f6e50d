"""The second-order moment relaxation (mcfric.bounds.moments): its structure, the validity
of its verified bound whatever the dual, and its bounds against exhaustive grids and
random admissible points solved in physical space (tests/naive.py's solve)."""

import numpy as np
import pytest

import mcfric
from mcfric.bounds import compute_bounds, moments
from mcfric.core.branch_bound import force_bounds

from .test_certified import F_LIM, K_MAX, chain, grid_points, physical_grid, random_admissible
from .test_force_ascent import arrays

pytest.importorskip("clarabel")


def admissible_responses(G, q0, ylin, H, beam, K):
    """``|y_beam|`` (m) at the rows of ``K`` (P, nd; N/m) whose damper forces all meet
    ``F_LIM``, solved in contact space: ``(I + diag(K) G) p = K q0``, ``y = ylin - H p``."""
    n = len(q0)
    p = np.linalg.solve(np.eye(n) + K[:, :, None] * G[None], (K * q0)[..., None])[..., 0]
    return np.abs(ylin[beam] - p @ H[beam])[np.abs(p).max(axis=1) <= F_LIM]


def first_resonance(F0, Kw=None):
    """The eight-beam rig at ``F0`` (N) at 16.17 Hz (its first resonance, frequency 44
    of the 1000 in 10-150 Hz): the contact-space arrays, the box's force limits made
    symmetric (N), and ``M`` (m) at the admissible point ``Kw`` (N/m) solved in physical
    space (asserted admissible; NaN without ``Kw``)."""
    model = mcfric.eight_beam(F0)
    freq = 10 + 140 * 44 / 999
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    limits = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
    limits = np.maximum(limits, limits[::-1])
    M = np.nan
    if Kw is not None:
        Ms, force = physical_grid(model, freq, Kw[None])
        assert force[0] <= 1
        M = Ms[0]
    return (G, q0, ylin, H), limits, M


def test_structure_of_a_seven_damper_chain():
    """Five cliques of three neighbouring dampers: 28 x 28 moment matrices, 7 x 7
    localising ones, 770 moments (those of degree <= 4 within a clique)."""
    st = moments.structure(7)
    assert st["cliques"] == [[0, 1, 2], [1, 2, 3], [2, 3, 4], [3, 4, 5], [4, 5, 6]]
    assert st["n_moments"] == 770
    assert all(len(m) == 28 * 29 // 2 for m in st["moment"])
    assert all(t.shape == (28, 7, 7) for t in st["local"])
    assert st["clique_of"] == [0, 0, 1, 2, 3, 4, 4]


@pytest.mark.parametrize("freq", [18.6, 71.0])
def test_three_dampers_enclose_an_exhaustive_grid(freq):
    """A four-beam chain (three dampers: one clique, the dense second order), F0 = 0.5 N:
    every beam's bound is at least every admissible point of a 7 x 7 grid of every
    rectangle (117,649 points) and of 3000 random ones, and at most Eq. 10."""
    model = chain(4, 0.5)
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    K = grid_points(3, 7)
    M, force = physical_grid(model, freq, K)
    best = max(M[force <= 1.0].max(), random_admissible(model, freq, 3000, 1).max())
    eq10 = np.empty(4)
    force_bounds(ylin, H, F_LIM, eq10)
    bound = max(moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, b)[0] for b in range(4))
    assert best <= bound <= eq10.max() * (1 + 1e-9)


def test_dual_bound_is_valid_for_any_dual():
    """Eight beams at 73 Hz, 0.25 N (where the first-order relaxation is 2.6 times the
    best admissible point): the verified bound from the solver's dual, from that dual
    perturbed (relative 1e-2) and from a zero dual are each above every random
    admissible point; the solver's is the tightest, within 5 % of the certificate's
    witness."""
    import clarabel

    model = mcfric.eight_beam(0.25)
    f = np.array([73.063])
    G, q0, ylin, H = (x[0] for x in arrays(model, f))
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, moments=False)
    best = max(random_admissible(model, f[0], 3000, 2).max(), B.certificate.upper_witness[0])
    values = []
    for beam in (3, 4):
        A, b, q, c0, sizes, sy = moments.problem(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, beam)
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        sol = clarabel.DefaultSolver((A[:0].T @ A[:0]).tocsc(), q, A, b,
                                     [clarabel.PSDTriangleConeT(s) for s in sizes],
                                     settings).solve()
        z = np.asarray(sol.z)
        rng = np.random.default_rng(beam)
        got = [moments.dual_bound(A, b, q, c0, w, sizes) for w in
               (z, z * (1 + 1e-2 * rng.standard_normal(len(z))), np.zeros_like(z))]
        values.append([np.sqrt(max(v, 0) * sy) for v in got])
    values = np.array(values)
    assert np.all(values.max(axis=0) >= best)
    assert np.all(values[:, 0] <= values[:, 1]) and np.all(values[:, 0] <= values[:, 2])
    assert values[:, 0].max() <= 1.05 * B.certificate.upper_witness[0]
    assert B.certificate.upper[0] > 2 * B.certificate.upper_witness[0]


def test_force_limits_bound_every_admissible_force():
    """Eight beams, 0.25 N: the proven force limits are at most F_lim and at least every
    damper force of 3000 random admissible points (physical-space solves); at 12.2 Hz
    (first resonances) they are below a fifth of F_lim."""
    model = mcfric.eight_beam(0.25)
    for freq, seed in ((12.2, 3), (73.0, 4)):
        G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
        limits = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
        rng = np.random.default_rng(seed)
        K = 10.0 ** rng.uniform(-3, 0, (3000, 1)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                     + 1j * rng.uniform(0, K_MAX, (3000, 7)))
        _, p = physical_grid(model, freq, K, forces=True)
        p = p[p.max(axis=1) <= F_LIM]
        assert len(p) > 100
        assert np.all(limits <= F_LIM) and np.all(p <= limits)
        if freq < 20:
            assert limits.max() < 0.2 * F_LIM


def test_part_force_limits_bound_every_admissible_force_of_the_part():
    """Eight beams, 0.25 N, 73.3 Hz (the witness has beam 4's own dampers, 3 and 4
    counted from 0, at ``K = k_max``): over the part with those two dampers' rectangles
    cut to ``[0.99, 1] k_max x [0, 0.01] k_max``, the part's force limits are at most
    the box's, at least a tenth below them for one damper, and at least every damper
    force of 3000 random admissible points of the part (physical-space solves); made
    symmetric, the mirrored part's are exactly these reversed."""
    from mcfric.bounds.moments_branch import part_limits
    from mcfric.core.relaxation_branch import mirror_sign

    model = mcfric.eight_beam(0.25)
    freq = 10 + 140 * 452 / 999
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    s = mirror_sign(G, q0, ylin, H)
    assert s != 0
    box = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
    box = np.maximum(box, box[::-1])
    lo, hi = moments.box(7, K_MAX, K_MAX)
    lo[3:5] = 0.99 * K_MAX
    hi[3:5] = complex(K_MAX, 0.01 * K_MAX)
    lim = part_limits(G, q0, K_MAX, K_MAX, F_LIM, box, (lo, hi))
    assert np.all(lim <= box) and np.any(lim < 0.9 * box)
    rng = np.random.default_rng(9)
    n = 3000
    K = 10.0 ** rng.uniform(-3, 0, (n, 1)) * (rng.uniform(0, K_MAX, (n, 7))
                                              + 1j * rng.uniform(0, K_MAX, (n, 7)))
    K[:, 3:5] = (rng.uniform(0.99, 1, (n, 2)) + 1j * rng.uniform(0, 0.01, (n, 2))) * K_MAX
    _, p = physical_grid(model, freq, K, forces=True)
    p = p[p.max(axis=1) <= F_LIM]
    assert len(p) > 100 and np.all(p <= lim)
    sym = part_limits(G, q0, K_MAX, K_MAX, F_LIM, box, (lo, hi), s)
    rev = part_limits(G, q0, K_MAX, K_MAX, F_LIM, box, (lo[::-1].copy(), hi[::-1].copy()), s)
    assert np.array_equal(rev, sym[::-1]) and np.all(sym >= lim)


def test_second_order_in_proven_force_scales_is_tight_at_the_first_resonance():
    """Eight beams, 0.25 N, 12.2 Hz: the first-order relaxation stays 10 % above the
    witness whatever the splitting. In the variables ``p / F_lim`` the second order is
    as loose (the forces that matter are a tenth of F_lim and the solver stops short);
    in ``p / limits`` (the proven force limits) it is within 1 % of the witness, whose
    ``M`` is recomputed in physical space, and above 3000 random admissible points
    (beams 4-7 from their mirror beams' duals)."""
    from mcfric.core.relaxation_branch import mirror_sign

    model = mcfric.eight_beam(0.25)
    f = np.array([12.2])
    G, q0, ylin, H = (x[0] for x in arrays(model, f))
    C = compute_bounds(model, f, K_MAX, F_lim=F_LIM, moments=False).certificate
    M, force = physical_grid(model, f[0], C.K_upper[:1])
    assert force[0] <= 1 + 1e-9
    best = max(M[0], random_admissible(model, f[0], 3000, 6).max())
    limits = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
    limits = np.maximum(limits, limits[::-1])
    plain = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3)[0]
    s = mirror_sign(G, q0, ylin, H)
    scaled = -np.inf
    for b in range(4):
        v, _, z = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, b, limits)
        scaled = max(scaled, v, moments.mirrored_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM,
                                                       7 - b, limits, z, s))
    assert plain > 1.05 * M[0]
    assert best <= scaled <= 1.01 * M[0]


def test_mirrored_dual_proves_the_mirror_beam_bound():
    """Eight beams, 1.1 N, 104.9 Hz (a chain that is its own mirror image, drive
    antisymmetric): beam 1's dual, reversed and signed, proves beam 6's bound within 1e-4
    of beam 6's own solve (the solver's precision) and above 3000 random admissible
    points of beam 6; with the wrong sign the verified bound is five times looser (the
    map must matter)."""
    from mcfric.core.relaxation_branch import mirror_sign

    model = mcfric.eight_beam(1.1)
    freq = 104.9
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    s = mirror_sign(G, q0, ylin, H)
    assert s == -1
    limits = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
    limits = np.maximum(limits, limits[::-1])
    _, _, z = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 1, limits)
    own = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 6, limits)[0]
    mirrored = moments.mirrored_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 6, limits, z, s)
    wrong = moments.mirrored_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 6, limits, z, -s)
    rng = np.random.default_rng(7)
    K = 10.0 ** rng.uniform(-3, 0, (3000, 1)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                 + 1j * rng.uniform(0, K_MAX, (3000, 7)))
    best = admissible_responses(G, q0, ylin, H, 6, K).max()
    assert best <= mirrored
    assert abs(mirrored / own - 1) < 1e-4
    assert wrong > 5 * own


def test_splitting_the_own_dampers_closes_the_gap_at_105_hz():
    """Eight beams, 1.1 N, 105.0 Hz: the second order over the whole box is 2.4 % above
    an admissible point (describing functions that scipy SLSQP from 150 starts did not
    better, ``M`` recomputed in physical space). One split of beam 3's own dampers at
    that point (16 parts) takes at least 40 % of the excess off; the bound stays above
    that point and 3000 random admissible points of beam 3; the parts the first order
    proves below the goal (no second-order solve) hold 1000 random admissible points of
    their own below their bounds, and the first order proves beam 4's reversed part to
    1e-6 of the same; the leaves, mirrored, prove beam 4's bound to 1e-6 of beam 3's."""
    from mcfric.bounds import moments_branch
    from mcfric.core.relaxation_branch import mirror_sign

    model = mcfric.eight_beam(1.1)
    freq = 10 + 140 * 678 / 999
    G, q0, ylin, H = (x[0] for x in arrays(model, np.array([freq])))
    Kw = np.array([1j, 1j, 0, 0.0101j, 0.0132j, 0.1196j, 0.3773j]) * K_MAX
    M, force = physical_grid(model, freq, Kw[None])
    assert force[0] <= 1
    limits = moments.force_limits(G, q0, K_MAX, K_MAX, F_LIM)
    limits = np.maximum(limits, limits[::-1])
    value, _, z = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3, limits)
    bound, used, leaves, _, failed = moments_branch.branch_bound(
        G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3, limits, value, z, Kw, 1.005 * M[0], 16)
    first = [leaf for leaf in leaves if leaf[1] is moments_branch.FIRST_ORDER]
    assert len(leaves) == 16 and used == 16 - len(first) and 0 < len(first) < 16
    assert failed == 0
    assert value > 1.02 * M[0]
    assert M[0] <= bound < M[0] + 0.6 * (value - M[0])
    rng = np.random.default_rng(8)
    K = 10.0 ** rng.uniform(-3, 0, (3000, 1)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                 + 1j * rng.uniform(0, K_MAX, (3000, 7)))
    assert admissible_responses(G, q0, ylin, H, 3, K).max() <= bound
    for (lo, hi), _, leaf_bound, _ in first:
        assert leaf_bound <= 1.005 * M[0]
        u = rng.uniform(0, 1, (1000, 7)) + 1j * rng.uniform(0, 1, (1000, 7))
        Kp = lo.real + u.real * (hi - lo).real + 1j * (lo.imag + u.imag * (hi - lo).imag)
        Kp[:, [0, 1, 4, 5, 6]] *= 10.0 ** rng.uniform(-3, 0, (1000, 1))
        yp = admissible_responses(G, q0, ylin, H, 3, Kp)
        assert len(yp) and yp.max() <= leaf_bound
        # the mirror beam's reversed part: the same first-order problem, mirrored
        full = moments.first_order_bound(G, q0, ylin, H, F_LIM, 3, (lo, hi))
        mirror = moments.first_order_bound(G, q0, ylin, H, F_LIM, 4,
                                           (lo[::-1].copy(), hi[::-1].copy()))
        assert full <= leaf_bound and abs(mirror / full - 1) < 1e-6
    mirrored, verified = moments_branch.mirrored_branch(
        G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 4, limits, leaves, mirror_sign(G, q0, ylin, H))
    assert abs(mirrored / bound - 1) < 1e-6
    assert verified == len({id(leaf[1]) for leaf in leaves if leaf[1] is not
                            moments_branch.FIRST_ORDER})


def test_geometric_parts_cover_the_part_and_close_in_on_zero():
    """One damper's rectangle in four: the parts tile it (areas add up, corners inside);
    from an interval at 0 with the witness's value below a tenth of it, the cut is at
    three times that value (at least 1e-4 of the box's side), elsewhere at the value
    (kept a tenth inside)."""
    from mcfric.bounds import moments_branch

    lo, hi = moments.box(3, K_MAX, K_MAX)
    K_cut = np.array([0.0, 0.9j, 0.5 * K_MAX + 0.99j * K_MAX])
    for d, near in ((0, (1e-4 * K_MAX, 1e-4 * K_MAX)), (1, (1e-4 * K_MAX, 2.7)),
                    (2, (0.5 * K_MAX, 0.9 * K_MAX))):
        kids = list(moments_branch.geometric_children((lo, hi), d, K_cut, K_MAX, K_MAX))
        assert len(kids) == 4
        first = kids[0][1][d]
        assert np.isclose(first.real, near[0]) and np.isclose(first.imag, near[1])
        area = sum((h[d] - l_[d]).real * (h[d] - l_[d]).imag for l_, h in kids)
        assert np.isclose(area, K_MAX * K_MAX, rtol=1e-12)
        for l_, h in kids:
            assert np.all(l_.real >= lo.real) and np.all(h.imag <= hi.imag)
            others = [j for j in range(3) if j != d]
            assert np.array_equal(l_[others], lo[others]) and np.array_equal(h[others], hi[others])
    # a part away from 0: the ordinary cut
    part = (np.full(3, 10.0 + 10.0j), np.full(3, complex(K_MAX, K_MAX)))
    kids = list(moments_branch.geometric_children(part, 1, K_cut, K_MAX, K_MAX))
    assert np.isclose(kids[0][1][1].real, 10 + 0.1 * (K_MAX - 10))


def test_geometric_branch_closes_in_on_nearly_open_dampers():
    """Eight beams, 1.1 N, 16.17 Hz (the first resonance): an admissible point (the
    certification's witness, ``M`` recomputed in physical space; 400,000 random
    admissible points and 31 SLSQP climbs found nothing higher) leaves dampers 0-4
    within 20 N/m of zero. The second order over the box is 3 % above it, and the own
    dampers' parts, cut at a tenth of the side or more, cannot isolate such values. The
    geometric branch takes at least half the excess off within 24 relaxations; its
    leaves tile the box (their volumes add up to the box's) and its bound stays above
    the point and 3000 random admissible points drawn log-uniformly near zero."""
    from mcfric.bounds import moments_branch
    from mcfric.core.relaxation_branch import mirror_sign

    Kw = np.array([19.1904580j, 6.81232550j, 1.20051594j, 0.887184372j, 0,
                   K_MAX + 2035.43571j, 5729.49017j])
    (G, q0, ylin, H), limits, M = first_resonance(1.1, Kw)
    value, _, z = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 4, limits)
    assert value > 1.025 * M
    bound, used, leaves, _, failed = moments_branch.branch_bound(
        G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 4, limits, value, z, Kw, 1.01 * M, 24,
        mirror_sign(G, q0, ylin, H), geometric=True)
    assert used <= 24 and failed == 0
    assert M <= bound <= M + 0.5 * (value - M)
    volume = sum(np.prod((hi - lo).real * (hi - lo).imag) for (lo, hi), *_ in leaves)
    assert np.isclose(volume, K_MAX ** 14, rtol=1e-9)
    rng = np.random.default_rng(9)
    K = 10.0 ** rng.uniform(-5, 0, (3000, 7)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                 + 1j * rng.uniform(0, K_MAX, (3000, 7)))
    assert admissible_responses(G, q0, ylin, H, 4, K).max() <= bound


def test_geometric_cuts_at_the_relaxation_close_the_first_resonance_at_022_n():
    """Eight beams, 0.22 N, 16.17 Hz: the certification's witness there leaves beam 4 free
    (dampers 0 and 3-6 at ``K = 0``; ``M`` recomputed in physical space). Cut at it, the
    geometric branch of beam 3 stalls 1.2 % above it; cut at the whole box's relaxation's
    describing functions (:func:`geometric_cuts`: a few N/m where the witness has 0) it
    comes within 1 % in at most 24 relaxations, and the bound stays above 3000 random
    admissible points drawn log-uniformly near zero."""
    from mcfric.bounds import moments_branch
    from mcfric.core.relaxation_branch import mirror_sign

    Kw = np.array([0, 15000j, 2573.59313 + 15000j, 0, 0, 0, 0])
    (G, q0, ylin, H), limits, M = first_resonance(0.22, Kw)
    value, p, z = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3, limits)
    assert value > 1.02 * M
    at = moments_branch.geometric_cuts(Kw[::-1], p, G, q0, K_MAX, K_MAX)
    assert np.all((at.real >= 0) & (at.real <= K_MAX) & (at.imag >= 0) & (at.imag <= K_MAX))
    # where the relaxation has no first moments, the witness's values
    nan = np.full(7, np.nan + 0j)
    assert np.array_equal(moments_branch.geometric_cuts(Kw, nan, G, q0, K_MAX, K_MAX), Kw)
    bound, used, _, _, failed = moments_branch.branch_bound(
        G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3, limits, value, z, at, 1.01 * M, 24,
        mirror_sign(G, q0, ylin, H), geometric=True)
    assert used <= 24 and failed == 0
    assert M <= bound <= 1.01 * M
    rng = np.random.default_rng(5)
    K = 10.0 ** rng.uniform(-5, 0, (3000, 7)) * (rng.uniform(0, K_MAX, (3000, 7))
                                                 + 1j * rng.uniform(0, K_MAX, (3000, 7)))
    assert admissible_responses(G, q0, ylin, H, 3, K).max() <= bound


def test_thin_part_is_solved_and_tight_at_the_first_resonance():
    """Eight beams, 0.22 N, 16.17 Hz, beam 3: a part of the box that the geometric branch
    reaches (damper 2 within 1.5 N/m of ``K = 0``, damper 3 nearly real, the rest the
    box), on which Clarabel at its default regularization stopped short (1.3 % above the
    beam's free response ``|ylin_3|``, the witness there, after the second solve). Its
    bound is now a solved relaxation's (finite first moments), within 1.25 % of
    ``|ylin_3|``, and above 3000 random admissible points of the part drawn
    log-uniformly."""
    from mcfric.bounds import moments_branch
    from mcfric.core.relaxation_branch import mirror_sign

    (G, q0, ylin, H), limits, _ = first_resonance(0.22)
    lo, hi = moments.box(7, K_MAX, K_MAX)
    hi[2] = 1.5 + 1.5j
    lo[3], hi[3] = 1.5, K_MAX + 1.5j
    part = (lo, hi)
    lim = moments_branch.part_limits(G, q0, K_MAX, K_MAX, F_LIM, limits, part,
                                     mirror_sign(G, q0, ylin, H))
    value, p, _ = moments.beam_bound(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, 3, lim, part)
    assert np.all(np.isfinite(p))
    assert value <= 1.0125 * abs(ylin[3])
    rng = np.random.default_rng(4)
    u = rng.uniform(0, 1, (2, 3000, 7))
    # each axis log-uniform over its interval (from 1e-5 of the side where it starts at 0)
    a = np.maximum(lo.real, 1e-5 * (hi - lo).real)
    b = np.maximum(lo.imag, 1e-5 * (hi - lo).imag)
    K = a * (hi.real / a) ** u[0] + 1j * b * (hi.imag / b) ** u[1]
    assert admissible_responses(G, q0, ylin, H, 3, K).max() <= value


def test_certify_with_moments_tightens_and_stays_sound():
    """Eight beams, 1.1 N, two frequencies where the first-order relaxation is loose:
    with the second-order relaxation (on by default on a chain) the certified upper
    bounds are never looser, at least one is tighter, and all stay above the witness and
    3000 random admissible points."""
    model = mcfric.eight_beam(1.1)
    f = np.array([73.06, 118.47])
    B0 = compute_bounds(model, f, K_MAX, F_lim=F_LIM, moments=False)
    B1 = compute_bounds(model, f, K_MAX, F_lim=F_LIM)   # the default: "auto"
    C0, C1 = B0.certificate, B1.certificate
    assert C1.moments and not C0.moments and C0.second_order[0] == 0
    assert C1.second_order[0] >= 1
    assert C1.summary(f).startswith(f"certified (second order: {C1.second_order[0]} "
                                    f"relaxations; stopping 1 % from the witnesses)")
    assert np.all(C1.upper <= C0.upper * (1 + 1e-12))
    assert np.any(C1.upper < C0.upper * 0.99)
    assert np.all(C1.upper >= C1.upper_witness)
    for k, fk in enumerate(f):
        assert random_admissible(model, fk, 3000, k).max() <= C1.upper[k]


def test_the_second_order_is_on_by_default_where_it_applies(tmp_path):
    """``"auto"`` (the default of the API and the configuration): on for a chain of 2-7
    dampers with a force limit, off for a ring, one damper or no force limit (no error);
    ``--first-order`` turns it off; anything but "auto", true or false is one line."""
    from mcfric import config
    from mcfric.bounds.certified import resolve_moments
    from mcfric.config import ConfigError

    assert resolve_moments("auto", True, 7, 0.6) is True
    assert resolve_moments("auto", True, 1, 0.6) is False
    assert resolve_moments("auto", False, 24, 0.6) is False
    assert resolve_moments("auto", True, 7, np.inf) is False
    assert resolve_moments(False, True, 7, 0.6) is False
    with pytest.raises(ValueError, match="moments: expected"):
        resolve_moments("yes", True, 7, 0.6)
    on = {name: config.load(name).spec.bounds.moments
          for name in ("eight-beam", "two-beam", "disk-24")}
    assert on == {"eight-beam": True, "two-beam": False, "disk-24": False}
    assert config.load("eight-beam", {"bounds.F_lim": ("none", "--F-lim")}
                       ).spec.bounds.moments is False
    assert config.load("eight-beam", {"bounds.certify_moments": (False, "--first-order")}
                       ).spec.bounds.moments is False
    with pytest.raises(ConfigError, match="only for a chain"):
        config.load("two-beam", {"bounds.certify_moments": (True, "--moments")}).spec
    p = tmp_path / "c.toml"
    p.write_text('model.preset = "eight-beam"\n[bounds]\ncertify_moments = "yes"\n')
    with pytest.raises(ConfigError, match="certify_moments"):
        config.load(p)


def test_moments_refuse_rings_single_dampers_and_no_force_limit(tmp_path):
    """One line, before anything runs: a ring, one damper, or no force limit; from the
    command line exit 2 and nothing written."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    for model in (mcfric.preset("disk-24", 1.0), mcfric.two_beam(0.22)):
        with pytest.raises(ValueError, match="moments: only for a chain"):
            compute_bounds(model, np.array([50.0]), K_MAX, F_lim=F_LIM, moments=True)
    with pytest.raises(ValueError, match="moments: only for a chain"):
        compute_bounds(mcfric.eight_beam(0.25), np.array([50.0]), K_MAX, moments=True)
    r = subprocess.run([sys.executable, "-m", "mcfric", "bounds", "disk-24", "--moments",
                        "-o", "b.h5"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300,
                       env=dict(os.environ, PYTHONPATH=str(Path(__file__).parents[1])))
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert r.stderr.startswith("mcfric: error: --moments: only for a chain")
    assert list(tmp_path.iterdir()) == []
