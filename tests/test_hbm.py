"""The harmonic-balance kernel against the plain physical-space reference in naive.py."""

import dataclasses

import numpy as np
import pytest

import mcfric
from mcfric.model import TABLE_1, Excitation, Model
from mcfric.peaks import PeakSettings

from . import naive
from .conftest import naive_beams, naive_pairs

#: Table 1 with its drive column (position 3) zeroed
ZERO_AT_3 = mcfric.ModalTable(TABLE_1.freq_hz, TABLE_1.zeta,
                              np.array(TABLE_1.shapes) * [1.0, 1.0, 0.0])

N_POINTS = 500          # per F0: 2 x 500 = 1000 random points per array size
N_POINTS_QUICK = 200    # per F0 in the default suite (the 1000 are a slow validation run)
F_BAND = (10.0, 150.0)
KC_MAX = 15000.0
N0 = 0.5


def _random_points(model, n, seed):
    rng = np.random.default_rng(seed)
    nd = model.n_dampers
    return (rng.uniform(*F_BAND, n), rng.uniform(0, 1, (n, nd)),
            rng.uniform(0, KC_MAX, (n, nd)))


def _assert_matches_a_reference_root(model, f, mu0, kc, y, s, rtol=1e-8):
    def err(root):
        ey = np.max(np.abs(root["y_output"] - y)) / np.max(np.abs(root["y_output"]))
        finite = np.isfinite(root["s"]) & (root["s"] < 1e12)
        es = np.max(np.abs(root["s"][finite] - s[finite]) / root["s"][finite], initial=0.0)
        return max(ey, es)

    # the reference's first root, and every root only where that is not ours (the same
    # verdict as the full search at once, in a sixth of the solver runs)
    for first in (True, False):
        roots = naive.solve_point(2 * np.pi * f, naive_beams(model), naive_pairs(model),
                                  model.force, mu0, np.full(len(mu0), N0), kc,
                                  starts=[np.ones(len(mu0))], first=first)
        assert roots, f"reference found no root at f={f}"
        errs = [err(root) for root in roots]
        if min(errs) <= rtol:
            return
    assert min(errs) <= rtol, (f, mu0, kc, min(errs))


@pytest.mark.parametrize("n_points",
                         [N_POINTS_QUICK, pytest.param(N_POINTS, marks=pytest.mark.slow)])
@pytest.mark.parametrize("n_beams", [2, 8])
def test_random_points_match_reference(n_beams, n_points):
    """Random cold-started points (2 x n_points per array size: 400 by default, 1000 with
    -m slow) agree with fsolve on the full equations."""
    worst = 0.0
    for F0, seed in ((0.22, 1), (1.1, 2)):
        model = mcfric.two_beam(F0) if n_beams == 2 else mcfric.eight_beam(F0)
        f, mu0, kc = _random_points(model, n_points, seed + 10 * n_beams)
        for i in range(n_points):
            r = mcfric.solve(model, f[i], mu0[i], kc[i], N0)
            assert r.status[0, 0] >= 0, (f[i], mu0[i], kc[i], r.residual[0, 0])
            assert r.residual[0, 0] <= 1e-10
            _assert_matches_a_reference_root(model, f[i], mu0[i], kc[i],
                                             r.response[0, 0], r.s[0, 0])
            worst = max(worst, r.residual[0, 0])
    assert worst <= 1e-10


@pytest.mark.parametrize("n_beams", [2, 8])
def test_warm_started_sweeps_match_reference(n_beams):
    """Sample i swept over all frequencies, checked at frequency i (the warm-start path)."""
    model = mcfric.two_beam(0.22) if n_beams == 2 else mcfric.eight_beam(0.25)
    n = 60
    f, mu0, kc = _random_points(model, n, 7 + n_beams)
    f = np.sort(f)
    r = mcfric.solve(model, f, mu0, kc, N0)
    assert r.n_not_converged == 0
    for i in range(n):
        _assert_matches_a_reference_root(model, f[i], mu0[i], kc[i], r.response[i, i],
                                         r.s[i, i])


def test_circular_mistuned_array_matches_reference():
    """A ring (the bordered chain kernel) with per-beam modal data, travelling-wave drive."""
    rng = np.random.default_rng(3)
    beams = tuple(TABLE_1.with_frequency(1, 16.2 * (1 + 0.02 * rng.standard_normal()))
                  .with_frequency(2, 105.8 * (1 + 0.02 * rng.standard_normal()))
                  for _ in range(6))
    model = Model(beams, Excitation("travelling", 0.8, engine_order=1), topology="circular")
    assert model.n_dampers == 6
    f, mu0, kc = _random_points(model, 80, 4)
    for i in range(80):
        r = mcfric.solve(model, f[i], mu0[i], kc[i], N0)
        assert r.status[0, 0] >= 0
        _assert_matches_a_reference_root(model, f[i], mu0[i], kc[i], r.response[0, 0],
                                         r.s[0, 0])


def test_per_sample_modal_frequencies_match_reference(eight_beam):
    rng = np.random.default_rng(5)
    n = 20
    f, mu0, kc = _random_points(eight_beam, n, 6)
    fm, _, _ = eight_beam.modal_arrays()
    modal = fm[None] * (1 + 0.03 * rng.standard_normal((n,) + fm.shape))
    r = mcfric.solve(eight_beam, np.sort(f), mu0, kc, N0, modal_freq_hz=modal)
    for i in range(n):
        beams = tuple(TABLE_1.with_frequency(1, modal[i, b, 0]).with_frequency(2, modal[i, b, 1])
                      for b in range(8))
        m_i = dataclasses.replace(eight_beam, beams=beams)
        _assert_matches_a_reference_root(m_i, np.sort(f)[i], mu0[i], kc[i], r.response[i, i],
                                         r.s[i, i])


@pytest.mark.parametrize("maker", [mcfric.two_beam, mcfric.eight_beam])
def test_stuck_limit_is_the_linear_system_with_K_equal_kc(maker):
    model = maker(1.1)
    f = np.linspace(10, 150, 141)
    kc = np.linspace(1000, 14000, model.n_dampers)
    r = mcfric.solve(model, f, mu0=1e9, kc=kc, N0=N0)
    assert r.n_not_converged == 0
    assert np.all(r.s >= 1)
    for k in range(0, len(f), 7):
        ref = naive.linear_stuck_response(2 * np.pi * f[k], naive_beams(model),
                                          naive_pairs(model), model.force, kc)
        np.testing.assert_allclose(r.response[0, k], ref, rtol=1e-11,
                                   atol=1e-11 * np.abs(ref).max())


@pytest.mark.parametrize("maker", [mcfric.two_beam, mcfric.eight_beam])
@pytest.mark.parametrize("free", ["mu0", "kc"])
def test_free_limit_is_the_uncoupled_beams(maker, free):
    model = maker(0.22)
    f = np.linspace(10, 150, 141)
    params = dict(mu0=0.7, kc=9000.0, N0=N0)
    params[free] = 0.0
    r = mcfric.solve(model, f, **params)
    assert r.n_not_converged == 0
    ref = np.array([naive.uncoupled_response(2 * np.pi * fk, naive_beams(model), model.force)
                    for fk in f])
    np.testing.assert_allclose(r.response[0], ref, rtol=1e-13, atol=1e-16)
    expected_s = 0.0 if free == "mu0" else np.inf
    assert np.all(r.s == expected_s)


def test_ensemble_convergence_eight_beam(eight_beam):
    """2000 samples x 1000 frequencies, paper's distributions: >= 99.99 % converged."""
    rng = np.random.default_rng(2024)
    n_s, nd = 2000, eight_beam.n_dampers
    f = np.linspace(*F_BAND, 1000)
    r = mcfric.solve(eight_beam, f, rng.uniform(0, 1, (n_s, nd)),
                     rng.uniform(0, KC_MAX, (n_s, nd)), N0)
    ok = r.converged
    n_bad = r.n_not_converged
    print(f"\neight-beam 2000 x 1000: not converged {n_bad} of {ok.size}; "
          f"status counts {np.unique(r.status, return_counts=True)}; "
          f"max residual of converged {r.residual[ok].max():.3g}")
    assert n_bad <= 1e-4 * ok.size
    assert np.all(r.residual[ok] <= 1e-10)
    # flagged points carry no numbers
    assert np.all(np.isnan(r.response[~ok])) and np.all(np.isnan(r.s[~ok]))


@pytest.mark.parametrize("n_beams, mu0, kc", [(2, 0.3, 8000.0), (8, 0.3, 8000.0),
                                             (2, 0.0, 0.0), (8, 0.5, 0.0)])
def test_non_converged_points_are_flagged_never_numbers(n_beams, mu0, kc):
    """An undamped mode hit exactly has no finite solution: flagged, NaN, counted; also
    with the contacts free (kc = 0 or mu0 = 0), where the kernel's residual passed at a
    NaN response (status 0 before)."""
    table = dataclasses.replace(TABLE_1, zeta=[0.0, 0.0071])
    model = Model.identical(table, n_beams, excitation=Excitation("mode", 0.5, mode=1))
    f = np.array([12.0, 16.0, 16.2, 16.4, 30.0])
    r = mcfric.solve(model, f, mu0=mu0, kc=kc, N0=N0)
    bad = ~r.converged
    assert bad[0].tolist() == [False, False, True, False, False]
    assert np.all(np.isnan(r.response[bad])) and np.all(np.isnan(r.s[bad]))
    assert np.all(r.status[bad] == -1)
    assert np.all(np.isfinite(r.response[~bad]))
    assert r.n_not_converged == 1
    assert "not converged: 1 " in r.summary()


@pytest.mark.parametrize("maker", [mcfric.two_beam, mcfric.eight_beam])
def test_bitwise_identical_with_one_and_two_threads(maker):
    model = maker(0.22)
    rng = np.random.default_rng(11)
    nd = model.n_dampers
    args = (np.linspace(10, 150, 300), rng.uniform(0, 1, (64, nd)),
            rng.uniform(0, KC_MAX, (64, nd)), N0)
    r1 = mcfric.solve(model, *args, n_threads=1)
    r2 = mcfric.solve(model, *args, n_threads=2)
    for name in ("response", "s", "status", "iterations", "residual"):
        a, b = getattr(r1, name), getattr(r2, name)
        assert a.tobytes() == b.tobytes(), name
    # and a sample's result does not depend on the other samples of the call
    r_one = mcfric.solve(model, args[0], args[1][17:18], args[2][17:18], N0)
    assert r_one.response.tobytes() == r1.response[17:18].tobytes()


BAD = [
    (dict(freq_hz=[10.0, np.nan]), "freq_hz"),
    (dict(freq_hz=[10.0, -5.0]), "freq_hz"),
    (dict(freq_hz=[0.0, 5.0]), "freq_hz"),
    (dict(freq_hz=[[10.0]]), "freq_hz"),
    (dict(freq_hz="abc"), "freq_hz"),
    (dict(kc=-1.0), "kc"),
    (dict(mu0=-0.1), "mu0"),
    (dict(N0=-0.5), "N0"),
    (dict(mu0=np.inf), "mu0"),
    (dict(kc=np.nan), "kc"),
    (dict(mu0=np.ones(3)), "mu0"),                       # 7 dampers expected
    (dict(mu0=np.ones((4, 7)), kc=np.ones((5, 7))), "kc"),
    (dict(mu0=np.ones((2, 3, 7))), "mu0"),
    (dict(tol=0.0), "tol"),
    (dict(max_iter=0), "max_iter"),
    (dict(modal_freq_hz=np.ones((1, 8, 3))), "modal_freq_hz"),
    (dict(modal_freq_hz=np.full((1, 8, 2), np.nan)), "modal_freq_hz"),
    (dict(n_threads=99), "threads"),
    (dict(peaks=PeakSettings(beams=(8,))), "peaks.beams"),   # read out of bounds before
    (dict(freq_hz=[20.0, 1e160]), "at most 1e\\+06 Hz"),     # zeros marked converged
    (dict(tol=None), "tol"),                                 # numpy's TypeError before
    (dict(n_threads=1.5), "threads"),                        # truncated to 1 before
    (dict(indicator="no"), "indicator"),                     # truthy: computed before
    (dict(max_iter=True), "max_iter"),                       # one iteration before
    (dict(modal_freq_hz=np.full((1, 8, 2), 20.0 + 1j)), "modal_freq_hz"),  # imag dropped
    # every response 0 and "converged" before (the receptance's squares overflowed)
    (dict(modal_freq_hz=np.full((1, 8, 2), 1e160)), "modal_freq_hz: .*at most 1e\\+100 Hz"),
]


@pytest.mark.parametrize("change, name", BAD)
def test_bad_input_names_the_argument(eight_beam, change, name):
    args = dict(freq_hz=[20.0, 30.0], mu0=0.5, kc=5000.0, N0=N0)
    args.update(change)
    with pytest.raises(ValueError, match=name):
        mcfric.solve(eight_beam, **args)


@pytest.mark.parametrize("build, name", [
    (lambda: mcfric.ModalTable([16.2, np.nan], [0.01, 0.01], [[1, 2, 3], [1, 2, 3]]), "freq_hz"),
    (lambda: mcfric.ModalTable([16.2, 100.0], [0.01, 0.01], [[1, np.inf, 3], [1, 2, 3]]),
     "shapes"),
    (lambda: mcfric.ModalTable([16.2, 100.0], [0.01], [[1, 2, 3], [1, 2, 3]]), "zeta"),
    (lambda: mcfric.ModalTable([-16.2], [0.01], [[1, 2, 3]]), "freq_hz"),
    (lambda: mcfric.ModalTable([16.2], [-0.01], [[1, 2, 3]]), "zeta"),
    # squares overflowed or underflowed: a response of 0 reported as converged
    (lambda: mcfric.ModalTable([16.2, 1e300], [0.01, 0.01], [[1, 2, 3], [1, 2, 3]]),
     "freq_hz: 1e.300 Hz is beyond"),
    (lambda: mcfric.ModalTable([16.2], [0.01], [[1e-300, 2e-300, 0]]),
     r"shapes: the largest entry, 2e-300 kg\^-1/2 \(mode 1, column 2\)"),
    (lambda: mcfric.ModalTable([16.2], [0.01], [[1, 2, 1e200]]), r"1e\+200 kg\^-1/2 \(mode 1, c"),
    (lambda: TABLE_1.column(1.5), "position: expected an integer"),   # column 1 before
    (lambda: Model.identical(TABLE_1, 1), "n_beams"),
    (lambda: Model.identical(TABLE_1, 2, topology="circular"), "topology"),
    (lambda: Model.identical(TABLE_1, 3, topology="ring"), "topology"),
    (lambda: Model.identical(TABLE_1, 3, contact=7), "position 7"),
    (lambda: Excitation("single", -1.0), "F0"),
    (lambda: Excitation("wave", 1.0), "pattern"),
    (lambda: Model.identical(TABLE_1, 3, excitation=Excitation("single", 1.0, beam=5)), "beam"),
    (lambda: Excitation("single", 1.0, beam=1.5), "beam"),
    (lambda: Excitation("travelling", 1.0, engine_order=1.5), "engine_order"),
    (lambda: Model.identical(TABLE_1, 2.7), "n_beams"),          # not truncated to 2
    (lambda: Model.identical(TABLE_1, 8, excitation=Excitation("mode", 1.0, mode=8)),
     "mode: expected a chain mode in 0..7"),                      # drives no beam
    (lambda: TABLE_1.with_frequency(0, 99.0), "mode"),            # not mode 2 silently
    (lambda: TABLE_1.with_frequency(3, 99.0), "mode"),
    (lambda: mcfric.ModalTable([16.2], [0.01], [[1, 2, 3]], positions=(1.5, 2, 3)),
     "positions"),                                                # truncated to 1 before
    (lambda: mcfric.ModalTable([16.2], [0.01], [[1, 2, 3]], positions="123"), "positions"),
    # a set has no order: {30, 1, 2} labelled the columns 1, 2, 30
    (lambda: mcfric.ModalTable([16.2], [0.01], [[1, 2, 3]], positions={30, 1, 2}),
     "positions: expected a sequence"),
    (lambda: Model.identical(TABLE_1, 2, contact=1.9), "contact"),   # used position 1
    # as the configuration's model.name: a newline broke one-line outputs and files
    *[(lambda v=v: Model.identical(TABLE_1, 2, name=v), "name: expected")
      for v in (None, 5, "a\nb", "  ")],
    # three forces for 2.5 beams, none for -1, a TypeError for "2"
    *[(lambda v=v: Excitation("mode", 1.0).force(v), "n_beams: expected an integer")
      for v in (2.5, -1, "2")],
    # legal once, but every response zero: a wrong label or column, most likely
    (lambda: Model.identical(ZERO_AT_3, 3), "drive: every mode shape of the driven beams"),
    (lambda: Model.identical(ZERO_AT_3, 3, output=3, drive=2), "output: every mode shape"),
    (lambda: Model(beams=(TABLE_1, ZERO_AT_3, TABLE_1),
                   excitation=Excitation("single", 1.0, beam=2)), "drive: every"),
])
def test_bad_model_names_the_argument(build, name):
    # ZERO_AT_3 alone, or not driven, is a legal part of a model
    Model(beams=(TABLE_1, ZERO_AT_3, TABLE_1), excitation=Excitation("single", 1.0, beam=1))
    with pytest.raises(ValueError, match=name):
        build()


@pytest.mark.parametrize("name,law", [("two-beam", "coulomb"), ("eight-beam", "coulomb"),
                                      ("two-beam", "cubic")])
def test_a_point_that_fails_never_reports_a_passing_residual(name, law):
    """A frequency whose receptances are NaN (the kernels given them directly, past the
    input checks) fails for every sample: its NaN iterates once made the residual read
    0.0 (``max(0.0, nan)``); it must read ``inf``, never a value below ``tol``, in the
    one-damper, chain and dense kernels, while the other frequencies converge."""
    from mcfric.hbm import allocate, run_kernel

    model = getattr(mcfric.presets, name.replace("-", "_"))()
    if law != "coulomb":
        model = dataclasses.replace(model, contact_law=law)
    nd, f = model.n_dampers, np.linspace(10.0, 150.0, 20)
    omega = 2 * np.pi * f
    rec = model.receptances(omega).copy()
    rec[:, 5] = np.nan
    mu0, N0, kc = np.full((3, nd), 0.3), np.full((3, nd), 0.5), np.full((3, nd), 1.5e4)
    out = allocate(3, len(f), model.n_beams, nd)
    run_kernel(model, rec, omega, mu0, N0, kc, 1e-10, 50, *out)
    status, residual = out[2], out[4]
    failed = np.zeros(status.shape, bool)
    failed[:, 5] = True
    assert np.all(status[failed] == -1) and np.all(status[~failed] >= 0)
    assert np.all(residual[failed] == np.inf)
    assert np.all(residual[~failed] <= 1e-10)


def test_scalar_friction_parameters_apply_to_every_mistuned_sample():
    """modal_freq_hz for 3 samples with scalar mu0, kc, N0: 3 samples, each as if the
    parameters had been given per sample (it was refused: shape (1, 2, 2) expected)."""
    model = mcfric.two_beam()
    mf = np.tile([16.2, 105.8], (3, 2, 1)) * np.array([1.0, 1.01, 1.02])[:, None, None]
    a = mcfric.solve(model, [20.0, 30.0], 0.5, 5e3, modal_freq_hz=mf)
    b = mcfric.solve(model, [20.0, 30.0], np.full((3, 1), 0.5), np.full((3, 1), 5e3),
                     np.full((3, 1), 0.5), modal_freq_hz=mf)
    assert a.response.shape == (3, 2, 2) and a.converged.all()
    assert a.response.tobytes() == b.response.tobytes()
    assert len(set(np.abs(a.response[:, 0, 0]))) == 3        # the mistuning shows


def test_log_and_reciprocal_of_a_response_that_died_out():
    """|q|^2 of a response that decayed along a long array is subnormal or 0: 1 / |q|^2
    overflowed and log |q|^2 was -inf. Against Python's own complex arithmetic (scaled)."""
    import math

    from mcfric.core.newton import log_abs, reciprocal

    for scale in (1.0, 1e-100, 1e-150, 1e-155, 1e-160, 1e-170, 1e-250):
        for q in (complex(3.0, -4.0) * scale, complex(0.0, 2.0) * scale,
                  complex(-1.0, 1e-3) * scale):
            q2 = q.real * q.real + q.imag * q.imag
            assert log_abs(q, q2) == pytest.approx(math.log(abs(q)), rel=1e-14)
            assert abs(reciprocal(q, q2) - 1 / q) <= 1e-14 * abs(1 / q)
    assert log_abs(0j, 0.0) == -math.inf and reciprocal(0j, 0.0) == 0j


def test_a_long_chain_whose_response_dies_out_converges():
    """Two-beam rig grown to 300 beams, one driven: the response falls by orders of
    magnitude per beam until |q|^2 underflows far down the chain. Member 2 of the seed-0
    draw at 65.7-67.8 Hz failed at 5 of 7 points (NaN Newton steps, then minutes of dense
    fallbacks on 299 dampers). Now all converge and agree with the plain solver on the
    first 16 beams (the rest of the chain holds nothing that reaches back)."""
    from mcfric import config

    cfg = (config.load("two-beam").replace("model.n_beams", 300)
           .replace("sampling.samples", 4).replace("frequency.n", 200))
    spec = cfg.spec
    d = spec.sampler.draw(np.arange(4))
    f = spec.freq_hz[78:85]
    res = mcfric.solve(spec.model, f, d.mu0[2:3], d.kc[2:3], d.N0[2:3], n_threads=2)
    assert res.converged.all(), res.status
    # far down the chain the dampers stick with slip ratios near 1e160, not inf
    assert np.isfinite(res.s).all() and res.s.max() > 1e100
    short = config.load("two-beam").replace("model.n_beams", 16).spec.model
    roots = naive.solve_point(2 * np.pi * f[3], naive_beams(short), naive_pairs(short),
                              short.force, d.mu0[2, :15], d.N0[2, :15], d.kc[2, :15])
    y = res.response[0, 3, :10]
    assert len(roots) == 1
    assert np.max(np.abs(roots[0]["y_output"][:10] - y)) <= 1e-6 * np.abs(y).max()


def test_a_restart_from_the_stick_limit_stays_on_the_fast_path():
    """Where the warm-started Newton fails (member 0 of the 300-beam chain above at
    17.0 Hz: the cubic prediction throws far stuck dampers into slip), the restart from
    s = 1 runs on the O(nd) chain Newton before the dense fallback (O(nd^3) a step:
    seconds here). Status 1 as before; the answer solves the equations, checked plainly:
    the physical-space response of the array at the returned describing functions, and
    every slipping damper's force at mu0 N0."""
    from mcfric import config
    from mcfric.core.newton import CONVERGED_RESTART

    spec = (config.load("two-beam").replace("model.n_beams", 300)
            .replace("sampling.samples", 4).replace("frequency.n", 200)).spec
    d = spec.sampler.draw(np.arange(4))
    res = mcfric.solve(spec.model, spec.freq_hz[:20], d.mu0[:1], d.kc[:1], d.N0[:1],
                       n_threads=1)
    assert res.converged.all() and res.status[0, 10] == CONVERGED_RESTART, res.status
    s, kc, fs = res.s[0, 10], d.kc[0], d.mu0[0] * d.N0[0]
    K = np.array([naive.describing_function(sj, kj) for sj, kj in zip(s, kc)])
    model = spec.model
    ref = naive.beam_space_response(2 * np.pi * spec.freq_hz[10], naive_beams(model),
                                    naive_pairs(model), model.force, K)
    y = res.response[0, 10]
    assert np.max(np.abs(ref["y_output"] - y)) <= 1e-9 * np.abs(y).max()
    slip = s < 1.0
    assert slip.any()
    np.testing.assert_allclose((s * kc * np.abs(ref["q"]))[slip], fs[slip], rtol=1e-8)
