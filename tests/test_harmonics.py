"""Multi-harmonic balance: the AFT against plain references, the solver against the closed
form and against time integration, which is itself checked against exact linear limits."""

import numpy as np
import pytest

import mcfric
from mcfric import cli, hbm
from mcfric.core import aft
from mcfric.core.multi_harmonic import FROM_ABOVE, FROM_REST
from mcfric.verify import verify

from . import naive
from .conftest import naive_beams, naive_pairs, ring


def sampled_jenkins(Q, orders, kc, fs, n=200_000):
    """Plain reference: the Jenkins loop on a dense time grid, two passes, then the
    rectangle-rule Fourier projection."""
    th = 2 * np.pi * np.arange(n) / n
    q = np.real(np.exp(1j * np.outer(th, orders)) @ Q)
    dq = np.diff(q, prepend=q[-1])
    f = np.empty(n)
    fc = 0.0
    for _ in range(2):
        # plain loop in chunks: clip of a running sum is not vectorisable
        for i in range(n):
            fc = min(max(fc + kc * dq[i], -fs), fs)
            f[i] = fc
    return np.array([2 * np.mean(f * np.exp(-1j * k * th)) for k in orders])


def test_aft_one_harmonic_is_the_describing_function():
    orders = aft.harmonic_orders(1)
    F = np.zeros(1, complex)
    dF = np.zeros((2, 2))
    w = np.zeros(aft.work_size(1, 32))
    rng = np.random.default_rng(3)
    for _ in range(300):
        A, kc, fs = 10 ** rng.uniform(-6, -3), 10 ** rng.uniform(2, 5), 10 ** rng.uniform(-3, 1)
        Q = np.array([A * np.exp(2j * np.pi * rng.uniform())])
        aft.jenkins(Q, orders, kc, fs, 32, F, dF, w)
        K = naive.describing_function(fs / (kc * A), kc)
        assert abs(F[0] - K * Q[0]) <= 1e-11 * abs(kc * Q[0])


def test_aft_multi_harmonic_against_a_dense_time_loop_and_finite_differences():
    orders = aft.harmonic_orders(7)
    nh = len(orders)
    F = np.zeros(nh, complex)
    dF = np.zeros((2 * nh, 2 * nh))
    w = np.zeros(aft.work_size(nh, 64))
    rng = np.random.default_rng(4)
    kc, fs = 1e5, 3.0
    for _ in range(3):
        Q = (rng.normal(size=nh) + 1j * rng.normal(size=nh)) * 1e-4 * np.array([1, .5, .3, .2])
        assert aft.jenkins(Q, orders, kc, fs, 64, F, dF, w) > 0
        ref = sampled_jenkins(Q, orders, kc, fs)
        # the dense loop carries an O(n^-2) kink error, ~1e-9 of the force here
        assert np.max(abs(F - ref)) <= 1e-7 * fs
        x = np.column_stack([Q.real, Q.imag]).ravel()
        h = 1e-10
        for m in range(2 * nh):
            Fp, Fm, d = np.zeros(nh, complex), np.zeros(nh, complex), np.zeros_like(dF)
            xp, xm = x.copy(), x.copy()
            xp[m] += h
            xm[m] -= h
            aft.jenkins(xp[0::2] + 1j * xp[1::2], orders, kc, fs, 64, Fp, d, w)
            aft.jenkins(xm[0::2] + 1j * xm[1::2], orders, kc, fs, 64, Fm, d, w)
            col = (Fp - Fm) / (2 * h)
            assert np.allclose(dF[0::2, m], col.real, rtol=0, atol=1e-5 * kc)
            assert np.allclose(dF[1::2, m], col.imag, rtol=0, atol=1e-5 * kc)


@pytest.mark.parametrize("fs", [1e-16, 1e-18, 1e-22, 0.0])
def test_aft_a_slip_distance_below_rounding_is_coulomb_friction(fs):
    """With 2 fs / kc below the rounding of q the element slips but for instants: the
    force is fs sign(q'), every harmonic below 4 fs / pi. The crossing search found no
    sign change there and walked a long stick phase: |F_1| = 0.10 N at fs = 1e-18 N."""
    orders = aft.harmonic_orders(5)
    F = np.zeros(3, complex)
    dF = np.zeros((6, 6))
    w = np.zeros(aft.work_size(3, 40))
    Q = np.array([1e-5 + 2e-6j, 3e-7 - 1e-7j, 1e-8])
    assert aft.jenkins(Q, orders, 6000.0, fs, 40, F, dF, w) >= 0
    # the dense loop places the reversals to within its step (1e-4 of fs); the stick
    # phases' integrals round to about kc |Q| eps (6e-18 N here), whatever fs
    rounding = 1e-4 * fs + 1e-13 * 6000.0 * abs(Q[0])
    assert np.all(abs(F) <= 4 / np.pi * fs + rounding)
    assert np.max(abs(F - sampled_jenkins(Q, orders, 6000.0, fs))) <= rounding


@pytest.mark.parametrize("c, phi", [(-0.114, 0.1486), (-0.114, 0.1731), (-0.115, 0.181),
                                    (-0.117, np.pi / 16)])
def test_aft_tells_apart_extrema_closer_than_the_samples(c, phi):
    """Near an inflection of q (a 3rd harmonic of about -1/9 of the fundamental), q has
    two extrema within one sample step of the default 32 samples (the last case: one of
    them on a sample); the small hysteresis loop between them was lost (errors of 2e-5
    to 1e-3 of fs before)."""
    orders = aft.harmonic_orders(3)
    F = np.zeros(2, complex)
    dF = np.zeros((4, 4))
    w = np.zeros(aft.work_size(2, 32))
    Q = np.array([np.exp(-1j * phi), c * np.exp(-3j * phi)])
    assert aft.jenkins(Q, orders, 1.0, 0.5, 32, F, dF, w) > 0
    # the dense loop's own kink error is ~1e-10 of fs here
    assert np.max(abs(F - sampled_jenkins(Q, orders, 1.0, 0.5))) <= 1e-8 * 0.5


@pytest.mark.parametrize("name", ["two-beam", "eight-beam"])
def test_aft_path_with_one_harmonic_equals_closed_form_kernel(name):
    """1000 random points per preset: the AFT kernel at H = 1 against the closed form."""
    model = mcfric.preset(name)
    rng = np.random.default_rng(5)
    f = np.sort(rng.uniform(10, 150, 50))
    mu0, kc = rng.uniform(0, 1, (20, 1)), rng.uniform(0, 15000, (20, 1))
    closed = hbm.solve(model, f, mu0, kc, 0.5)
    via_aft = hbm.solve(model, f, mu0, kc, 0.5, aft=True)
    ok = closed.converged & via_aft.converged
    assert ok.sum() >= 990
    scale = np.abs(closed.response).max(axis=-1, keepdims=True)
    err = np.abs(via_aft.response - closed.response) / scale
    assert np.max(err[ok]) <= 1e-9


def _linear_case(model, mu0, kc):
    beams, pairs = naive_beams(model), naive_pairs(model)
    return lambda w: (naive.linear_stuck_response(w, beams, pairs, model.force, [kc] * len(pairs))
                      if mu0 > 0 else naive.uncoupled_response(w, beams, model.force))


@pytest.mark.parametrize("mu0", [1e6, 0.0], ids=["stuck", "free"])
def test_time_integration_reaches_the_linear_limits(mu0, two_beam, eight_beam):
    for model in (two_beam, eight_beam):
        ref = _linear_case(model, mu0, 6000.0)
        cases = [(14.0, "single"), (37.5, "single")]
        if model is two_beam:
            # from rest the light modal damping (0.17 %) needs ~5000 periods to settle:
            # one such start per case keeps the test short
            cases.append((60.0, "rest"))
        for f, start in cases:
            v, = verify(model, f, mu0, 6000.0, 0.5, harmonics=3, start=start)
            assert v.periodic
            y = ref(2 * np.pi * f)
            tol = 1e-5 if start == "single" else 1e-3
            assert np.max(abs(v.harmonics[0] - y)) <= tol * np.max(abs(y))
            assert np.max(abs(v.harmonics[1])) <= 1e-6 * np.max(abs(y))


def test_a_beam_at_rest_has_no_relative_differences(two_beam):
    """Without contact stiffness the undriven beam of two-beam stays at rest: its
    harmonics relative to the fundamental and its differences are NaN (``-`` in the
    table), with no warning, and the driven beam's are numbers."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        v, = verify(two_beam, 50.0, 0.5, 0.0, 0.5, harmonics=3)
        d1, dm, d3 = v.differences()
        text = v.table()
    assert np.all(v.harmonics[:, 1] == 0) and np.isnan([d1[1], dm[1], d3[1]]).all()
    assert np.isfinite([d1[0], dm[0]]).all() and abs(d1[0]) < 1e-6
    assert "nan" not in text and text.splitlines()[-1].split()[2] == "-"


def test_an_unsettled_integration_has_no_differences(two_beam, tmp_path, capsys):
    """Stopped before it settles, the integration's last period is no steady state: the
    differences to the balances are NaN (``-`` in the table, empty in the CSV), its own
    columns stay, marked periodic = 0; they were numbers like -0.28 before."""
    v, = verify(two_beam, 17.0, 0.03, 15000.0, 0.5, start="rest", max_periods=6)
    assert not v.periodic
    assert all(np.isnan(d).all() for d in v.differences())
    out = tmp_path / "v.csv"
    assert cli.main(["verify", "two-beam", "--f", "17", "--mu0", "0.03", "--kc", "15000",
                     "--start", "rest", "--max-periods", "6", "-o", str(out),
                     "--no-figure"]) == 0
    t = np.genfromtxt(out, delimiter=",", names=True)
    assert (t["periodic"] == 0).all() and np.isfinite(t["time_harmonic1_m"]).all()
    assert all(np.isnan(t[c]).all() for c in ("diff_h1", "diff_mhb", "diff_mhb_harmonic3"))


@pytest.mark.parametrize("kwargs", [dict(harmonics=3), dict(aft=True),
                                    dict(indicator=True)])
def test_the_aft_paths_refuse_a_law_they_do_not_evaluate(two_beam, kwargs):
    """The AFT, the indicator and the integrator know the Jenkins element only: a cubic
    contact gave Coulomb answers with status 0 before."""
    import dataclasses

    cubic = dataclasses.replace(two_beam, contact_law="cubic")
    with pytest.raises(ValueError, match="coulomb law only"):
        hbm.solve(cubic, [30.0], 0.5, 6000.0, **kwargs)
    with pytest.raises(ValueError, match="coulomb law only"):
        verify(cubic, 30.0, 0.5, 6000.0)
    hbm.solve(cubic, [30.0], 0.5, 6000.0)          # the single-harmonic dense kernel


def test_stuck_contacts_give_no_third_harmonic_difference(two_beam):
    """Stuck at 20 Hz (two-beam, mu0 = 0.5): the integration's 3rd harmonic is rounding
    noise and the balance's exactly 0; their relative difference would read -100 %."""
    v, = verify(two_beam, 20.0, 0.5, 6000.0, 0.5, harmonics=3, max_periods=10)
    assert v.periodic
    d1, dm, d3 = v.differences()
    assert np.all(np.abs(v.harmonics[1]) < 1e-9 * np.abs(v.harmonics[0]))
    assert np.isnan(d3).all() and np.isfinite(dm).all()


@pytest.mark.parametrize("kwargs, starts", [
    (dict(hb_tol=0.0), "hb_tol: expected a number in 1e-14..0.1"),  # solve() blamed "tol"
    (dict(hb_tol="1e-8"), "hb_tol"),
    (dict(hb_max_iter=True), "hb_max_iter"),
])
def test_verify_names_its_harmonic_balance_settings(two_beam, kwargs, starts):
    with pytest.raises(ValueError) as e:
        verify(two_beam, 50.0, 0.5, 6000.0, 0.5, harmonics=3, **kwargs)
    assert str(e.value).startswith(starts)


# points where the contacts slip (stuck contacts are linear and would pass trivially),
# 17-106 Hz, with the 5:1 (21.16 Hz) and 3:1 (35.3 Hz) resonances of two-beam
POINTS = [("two-beam", 0.03, 15000.0, [17.0, 21.16, 35.3, 60.0]),
          ("eight-beam", 0.5, 6000.0, [17.5, 21.0, 37.5, 106.0])]
#: Where the integration settles with a static offset that depends on its start (docs:
#: harmonics, "Why odd harmonics only"): the even content is not checked there.
STATIC_OFFSET = {("eight-beam", 21.0)}


@pytest.mark.parametrize("name, mu0, kc, freqs", POINTS, ids=[p[0] for p in POINTS])
def test_multi_harmonic_agrees_with_time_integration(name, mu0, kc, freqs):
    model = mcfric.preset(name)
    single = hbm.solve(model, freqs, mu0, kc, 0.5)
    assert single.converged.all() and np.all(single.s.min(axis=2) < 1.0)   # slipping
    vs = verify(model, freqs, mu0, kc, 0.5, harmonics=9)
    for v in vs:
        assert v.periodic, v.table()
        td1, td3 = v.harmonics[0], v.harmonics[1]
        m1, m3 = v.multi[0], v.multi[1]
        a1 = abs(td1)
        # every beam's fundamental within 0.5 % of its own
        assert np.all(abs(m1 - td1) <= 5e-3 * a1), v.table()
        # the 3rd harmonic within 2 %, relative to itself where it is at least 1 % of the
        # beam's fundamental (below that, 2 % of 1 % of the fundamental)
        assert np.all(abs(m3 - td3) <= 0.02 * np.maximum(abs(td3), 0.01 * a1)), v.table()
        if (name, v.freq_hz) not in STATIC_OFFSET:
            # no mean and no 2nd harmonic: the half-period symmetry the balance assumes
            assert np.all(v.even <= 1e-8 * a1), v.table()


def test_newton_passes_a_kink_of_the_friction_force():
    """A member of eight beams at 17.04 Hz, H = 5: between the start and the solution one
    damper's loop gains a second slip phase, the residual has a kink there, and the
    halving line search crawled (steps of 1/64) until it ran out of iterations. The
    watchdog's undamped steps pass it; the point agrees with time integration."""
    model = mcfric.preset("eight-beam")
    rng = np.random.default_rng(1)
    mu0 = rng.uniform(0, 1, (40, model.n_dampers))[6]
    kc = rng.uniform(0, 15000.0, (40, model.n_dampers))[6]
    f = np.linspace(10.0, 150.0, 200)[:11]           # the sweep up to 17.035 Hz
    res = hbm.solve(model, f, mu0[None], kc[None], 0.5, harmonics=5)
    assert res.converged.all(), res.status
    v = verify(model, f[-1], mu0, kc, 0.5, harmonics=5)[0]
    assert v.periodic
    a1 = abs(v.harmonics[0])
    assert np.all(abs(res.response[0, -1] - v.harmonics[0]) <= 2e-3 * a1.max())


def test_a_point_the_upward_sweep_misses_converges_from_the_one_above():
    """Member 52 of the default run's draw (eight beams) at 11.40 Hz, H = 7: a
    superharmonic resonance below the first mode, where Newton fails from the previous
    frequency, from the single-harmonic start and by continuation. The sweep's second
    pass starts it from the converged solution at the next frequency, labels it
    ``FROM_ABOVE``, and it agrees with time integration as its converged neighbours do
    at this order (0.2 % here; 0.05 and 0.3 % at the two above)."""
    model = mcfric.preset("eight-beam")
    mu0 = np.array([0.2526385, 0.70972409, 0.13397817, 0.93157952, 0.37374907, 0.93139735,
                    0.02406183])
    kc = np.array([14785.65064518, 9612.99783187, 7898.58202803, 5085.55754201,
                   8793.39196153, 2905.19872606, 7599.92877579])
    f = np.linspace(10.0, 150.0, 1000)[10:13]         # 11.40 Hz and the two above
    res = hbm.solve(model, f, mu0[None], kc[None], 0.5, harmonics=7, n_threads=1)
    assert res.converged.all(), res.status
    assert res.status[0, 0] == FROM_ABOVE and not res.from_above[0, 1:].any(), res.status
    assert res.summary().endswith("; 1 converged only from the next frequency's solution "
                                  "(from_above)")
    # alone, no start of the sweep reaches it: only the drive raised from rest, after
    # the sweep, on the same solution
    alone = hbm.solve(model, f[:1], mu0[None], kc[None], 0.5, harmonics=7, n_threads=1)
    assert alone.status[0, 0] == FROM_REST, alone.status
    assert alone.from_rest[0, 0] and not alone.from_above[0, 0]
    assert "1 only from rest, raising the drive (from_rest)" in alone.summary()
    assert np.all(abs(alone.response[0, 0] - res.response[0, 0])
                  <= 1e-9 * abs(res.response[0, 0]).max())
    v = verify(model, f[0], mu0, kc, 0.5, harmonics=7)[0]
    assert v.periodic
    a1 = abs(v.harmonics[0])
    assert np.all(abs(res.response[0, 0] - v.harmonics[0]) <= 1e-2 * a1.max()), v.table()


def test_continuation_in_frequency_reaches_a_point_from_either_neighbour():
    """Member 844 of the default run's draw (eight beams) at 11.26 Hz, H = 7: Newton
    fails there from the converged solution at 11.12 Hz below, and from the one at
    11.40 Hz above, directly or predicted. Continuation in frequency from either (the
    receptances and the drive moved to the point's in steps) converges: from above
    ``FROM_ABOVE``, from below status 0, on the same solution, which agrees with time
    integration (0.02 % measured)."""
    model = mcfric.preset("eight-beam")
    mu0 = np.array([0.2972219690310291, 0.02962459286608704, 0.03977779430767442,
                    0.4118309103573741, 0.9192818081849625, 0.5752096324630525,
                    0.3344677780869753])
    kc = np.array([10820.915392186218, 2784.076133845652, 7613.44366073981,
                   10210.378358454422, 1349.433469863822, 108.35887345990142,
                   14031.836100690965])
    f = np.linspace(10.0, 150.0, 1000)[8:11]          # 11.12, 11.26 and 11.40 Hz
    down = hbm.solve(model, f[1:], mu0[None], kc[None], 0.5, harmonics=7, n_threads=1)
    up = hbm.solve(model, f[:2], mu0[None], kc[None], 0.5, harmonics=7, n_threads=1)
    assert down.status.tolist() == [[FROM_ABOVE, 1]], down.status
    assert up.status.tolist() == [[1, 0]], up.status
    a = abs(down.response[0, 0]).max()
    assert np.all(abs(down.response[0, 0] - up.response[0, 1]) <= 1e-9 * a)
    v = verify(model, f[1], mu0, kc, 0.5, harmonics=7)[0]
    assert v.periodic
    assert np.all(abs(up.response[0, 1] - v.harmonics[0]) <= 2e-3 * a), v.table()


def test_a_band_on_a_resonance_is_entered_by_raising_the_drive():
    """Member 11 of the default run's draw (eight beams), H = 9, on a band of three
    frequencies across the first resonance (16.25, 16.30, 16.35 Hz): no start of the
    sweep converges anywhere (a damper passes from stick to slip there), so no point had
    a converged neighbour. After the sweep, the drive is raised from rest at 16.30 Hz
    (``FROM_REST``), 16.25 Hz follows from it going down (``FROM_ABOVE``) and 16.35 Hz going
    up again (status 0); all three agree with time integration (0.03 % measured)."""
    model = mcfric.preset("eight-beam")
    mu0 = np.array([0.1480835639777564, 0.1512639133823857, 0.9796939936940636,
                    0.2255887163914661, 0.4740560492311327, 0.015271488390993737,
                    0.8726645689523591])
    kc = np.array([14344.539399573845, 10624.271837677967, 4758.935271281215,
                   13004.112092920555, 11293.30030453962, 3014.0063031699046,
                   2150.856724929356])
    f = np.array([16.25, 16.30, 16.35])
    r = hbm.solve(model, f, mu0[None], kc[None], 0.5, harmonics=9, n_threads=1)
    assert r.status.tolist() == [[FROM_ABOVE, FROM_REST, 0]], r.status
    for k, v in enumerate(verify(model, f, mu0, kc, 0.5, harmonics=9)):
        assert v.periodic
        a = abs(v.harmonics[0]).max()
        assert np.all(abs(r.response[0, k] - v.harmonics[0]) <= 2e-3 * a), v.table()


def test_a_static_offset_depends_on_the_start_and_leaves_the_odd_harmonics():
    """Eight beams at 21 Hz: the integration settles with a mean offset of every beam
    that depends on where it started; the odd harmonics do not, and match the balance."""
    model = mcfric.preset("eight-beam")
    runs = [verify(model, 21.0, 0.5, 6000.0, 0.5, harmonics=3, start=s)[0]
            for s in ("single", "rest")]
    a1 = abs(runs[0].harmonics[0])
    even = [v.even / a1 for v in runs]
    assert all(v.periodic for v in runs)
    assert np.all(even[0] > 1e-3) and np.all(abs(even[1] / even[0] - 1) > 0.5)
    assert np.all(abs(runs[0].harmonics - runs[1].harmonics) <= 1e-5 * a1)


def test_multi_harmonic_on_a_mistuned_ring_agrees_with_time_integration():
    """A mistuned ring of four blades (2 % in the first two modes): the bordered ring
    step of the multi-harmonic solver and per-beam modes at H = 9, against
    time integration at four slipping points. At 33 Hz the 3rd harmonic is ~23 % of the
    fundamental and the single-harmonic balance misses by ~10 %: the test can tell."""
    model = ring(4, mistuned=True)
    freqs = [33.0, 50.0, 92.0, 106.0]
    single = hbm.solve(model, freqs, 0.3, 10000.0, 0.5)
    assert single.converged.all() and np.all(single.s.min(axis=2) < 1.0)   # slipping
    vs = verify(model, freqs, 0.3, 10000.0, 0.5, harmonics=9)
    for v in vs:
        assert v.periodic, v.table()
        td1, td3 = v.harmonics[0], v.harmonics[1]
        a1 = abs(td1)
        assert np.all(abs(v.multi[0] - td1) <= 2e-3 * a1), v.table()
        assert np.all(abs(v.multi[1] - td3) <= 0.01 * np.maximum(abs(td3), 0.01 * a1)), \
            v.table()
        assert np.all(v.even <= 1e-7 * a1), v.table()
    assert np.max(abs(vs[0].single - vs[0].harmonics[0]) / abs(vs[0].harmonics[0])) > 0.05


@pytest.mark.parametrize("argv, message", [
    (["hbm", "two-beam", "--harmonics", "4", "--n-freq", "5"], "odd"),
    (["hbm", "two-beam", "--harmonics", "0", "--n-freq", "5"], "odd"),
    (["hbm", "two-beam", "--harmonics", "9", "--n-time", "16", "--n-freq", "5"], "n-time"),
    (["hbm", "eight-beam", "--harmonics", "99", "--n-freq", "2000000"], "GiB"),
    (["verify", "two-beam", "--harmonics", "2", "--f", "20"], "odd"),
    (["verify", "two-beam", "--harmonics", "1", "--f", "20"], "integer in 3..99"),
    (["verify", "two-beam", "--f", "-3"], "freq"),
    # a period of 1e300 s: the step count in three digits, not three hundred
    (["verify", "two-beam", "--f", "1e-300"], "a period needs 1.55e+304 time steps (at most"),
    (["verify", "two-beam", "--f", "1e-310"], "a period needs too many time steps (at most"),
    (["verify", "two-beam", "--f", "5e-324"], "a period needs too many time steps (at most"),
    # argparse's order put SOURCE after --f in the usage line; --f took it as a number
    (["verify", "--f", "20", "two-beam"], "SOURCE goes before --f: mcfric verify two-beam"),
    (["verify", "two-beam", "--f", "20x"], "--f: expected a frequency in Hz, got '20x' ("),
])
def test_bad_harmonics_input_one_line_exit_2_nothing_written(argv, message, tmp_path,
                                                            monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    rc = cli.main(argv + ["-o", str(tmp_path / "out.csv")])
    _, err = capsys.readouterr()
    assert rc == 2 and err.count("\n") == 1 and message in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_run_whose_harmonics_the_solve_would_refuse_is_refused_up_front(tmp_path,
                                                                          monkeypatch, capsys):
    """The solve's fixed limit on a multi-harmonic call (13.7 GiB on two threads here)
    refused the first chunk after the partial file existed, in a traceback; the run now
    checks it first, with or without --skip-space-check."""
    monkeypatch.chdir(tmp_path)
    argv = ["run", "eight-beam", "--harmonics", "99", "--samples", "2", "--n-freq", "400000",
            "--no-bounds", "--no-progress", "--no-figure"]
    for extra in ([], ["--skip-space-check"]):
        rc = cli.main(argv + extra)
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1, err
        # the need counts a workspace per thread: the number depends on the machine's
        assert "harmonics: H = 99 needs " in err and "GiB for this model" in err
        assert "(limit 8 GiB)" in err
        assert list(tmp_path.iterdir()) == []


def test_indicator_without_a_fundamental_is_infinite_not_zero():
    """Slipping dampers whose harmonics reach outputs that have no fundamental: inf
    (it said 0, no harmonics); without harmonics there, 0; not converged, NaN."""
    from mcfric.core.harmonic_indicator import harmonic_indicator

    a, b = np.array([0]), np.array([1])
    one = np.ones((1, 1))
    s = np.array([[[0.5], [0.5], [np.nan], [0.5]]])            # 4 frequencies
    h3 = np.ones((1, 4, 2))
    h3[0, 1] = 0.0                                              # no path to the output
    h5 = h3.copy()
    y = np.zeros((1, 4, 2), complex)
    y[0, 3, 1] = 1e-3
    out = np.zeros((1, 4))
    harmonic_indicator(h3, h5, a, b, one, one, one, s, y, out)
    assert out[0, 0] == np.inf and out[0, 1] == 0.0 and np.isnan(out[0, 2])
    assert 0 < out[0, 3] < np.inf


def test_indicator_bounds_the_higher_harmonics_of_each_point(eight_beam):
    """The indicator (slip ratios only, triangle inequality) is >= the output's 3rd + 5th
    harmonics relative to the fundamental, computed with phases through the AFT."""
    from mcfric.core.receptance import contact_space

    model = eight_beam
    rng = np.random.default_rng(8)
    f = np.linspace(12, 60, 40)
    mu0, kc = rng.uniform(0, 1, (3, 7)), rng.uniform(0, 15000, (3, 7))
    r = hbm.solve(model, f, mu0, kc, 0.5, indicator=True)
    a, b = model.dampers
    orders = aft.harmonic_orders(5)
    Fv, dF, w = np.zeros(3, complex), np.zeros((6, 6)), np.zeros(aft.work_size(3, 32))
    om = 2 * np.pi * f
    cs = [contact_space(model.receptances(h * om)[0], model.force, a, b) for h in (1, 3, 5)]
    checked = 0
    for i in range(3):
        for k in range(len(f)):
            K = np.array([naive.describing_function(s, c) for s, c in zip(r.s[i, k], kc[i])])
            q = np.linalg.solve(np.eye(7) + cs[0][0][k] * K, cs[0][1][k])
            F3, F5 = np.zeros(7, complex), np.zeros(7, complex)
            for j in range(7):
                aft.jenkins(np.array([q[j], 0, 0]), orders, kc[i, j], mu0[i, j] * 0.5, 32, Fv,
                            dF, w)
                F3[j], F5[j] = Fv[1], Fv[2]
            y3, y5 = cs[1][3][k] @ F3, cs[2][3][k] @ F5
            exact = np.max(np.abs(y3) + np.abs(y5)) / np.max(np.abs(r.response[i, k]))
            assert r.harmonic_indicator[i, k] >= exact * (1 - 1e-9), (i, k)
            checked += exact > 1e-3
    assert checked > 10          # the test sees points with real harmonics
    # a NaN response at finite slip ratios is flagged, not dropped by the maximum
    params = (mu0, np.full(mu0.shape, 0.5), kc)
    np.testing.assert_array_equal(hbm.harmonic_indicator(model, r, om, None, params),
                                  r.harmonic_indicator)
    assert r.status[1, 7] == 0
    r.response[1, 7, 3] = np.nan
    again = hbm.harmonic_indicator(model, r, om, None, params)
    assert np.isnan(again[1, 7])
    assert np.isnan(again).sum() == np.isnan(r.harmonic_indicator).sum() + 1


def test_multi_harmonic_run_is_identical_for_any_threads_and_chunks(tmp_path, capsys):
    runs = []
    for n, extra in enumerate((["--threads", "1", "--chunk", "3"], ["--threads", "2"])):
        out = tmp_path / f"r{n}.h5"
        rc = cli.main(["run", "two-beam", "--samples", "7", "--n-freq", "30", "--harmonics",
                       "5", "-o", str(out), "--no-progress", "--no-figure", *extra])
        assert rc == 0
        runs.append(out)
    text = capsys.readouterr().out
    assert "odd harmonics 1..5 balanced" in text
    with mcfric.open_results(runs[0]) as A, mcfric.open_results(runs[1]) as B:
        for name in ("response", "response_peak", "converged", "from_above", "from_rest"):
            assert A[name].values.tobytes() == B[name].values.tobytes()
        conv, up, rest = (A[n].values for n in ("converged", "from_above", "from_rest"))
        # how a point was reached: one way at most, and only for converged points
        assert not (up & rest).any() and not ((up | rest) & ~conv).any()
        assert int(A.attrs["harmonics"]) == 5
        assert "peak_metric" not in A and "harmonic_indicator" not in A



def test_full_period_peak_against_a_dense_time_grid(two_beam):
    """response_peak is max |y(t)| of the stored harmonics (it may be below |y_1|: a
    flattened, square-like wave has a fundamental larger than its peak)."""
    rng = np.random.default_rng(9)
    r = hbm.solve(two_beam, np.linspace(10, 150, 30), rng.uniform(0, 1, (4, 1)),
                  rng.uniform(0, 15000, (4, 1)), 0.5, harmonics=5, store_harmonics=True)
    th = np.linspace(0, 2 * np.pi, 20001)
    e = np.exp(1j * np.outer(np.arange(1, 6, 2), th))                   # (n_h, n_t)
    y = np.real(np.einsum("sfhb,ht->sfbt", r.response_harmonics, e))
    dense = np.abs(y).max(axis=-1)
    ok = r.converged
    assert np.allclose(r.response_peak[ok], dense[ok], rtol=1e-7, atol=0)
    assert np.array_equal(r.response, r.response_harmonics[:, :, 0])


def test_verify_takes_a_member_of_a_results_file(tmp_path, capsys):
    res = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "4", "--n-freq", "20", "-o", str(res),
                     "--no-progress", "--no-figure"]) == 0
    with mcfric.open_results(res) as ds:
        assert "harmonic_indicator" in ds
    capsys.readouterr()
    out = tmp_path / "v.csv"
    assert cli.main(["verify", str(res), "--member", "2", "--f", "30", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "periodic after" in text
    # the line, and the figure's title made of it, name the member and its file
    assert text.startswith("mcfric verify: two-beam, member 2 of r.h5, mu0 = "), text
    table = np.genfromtxt(out, delimiter=",", names=True)
    assert table.shape == (2,) and out.with_suffix(".png").exists()
    rc = cli.main(["verify", str(res), "--member", "9", "--f", "30", "-o", str(out)])
    assert rc == 2
    # what the file holds at each frequency is said: a value, no value, not on the grid
    import h5py
    with h5py.File(res, "r+") as h:
        f = h["frequency"][()]
        m = h["metric"][2, 3]
        h["converged"][2, 5] = False
    capsys.readouterr()
    # as the run summary prints them (4 digits): taken as the grid frequencies
    typed = [f"{f[3]:.4g}", f"{f[5]:.4g}", "30"]
    assert cli.main(["verify", str(res), "--member", "2", "--f", *typed, "-o", str(out),
                     "--no-figure", "--harmonics", "3"]) == 0
    text = capsys.readouterr().out
    assert f"--f {typed[0]} Hz taken as the run's grid frequency {f[3]:.10g} Hz" in text
    assert f"at {f[3]:.10g} Hz the run stored M = {m:.6g} m (displacement" in text
    assert f"at {f[5]:.10g} Hz the run did not converge (no value stored)" in text
    assert "30 Hz is not a grid frequency of the run" in text
    assert "solved afresh" in text
    # the single-harmonic run's own balance, solved again, is the stored solution
    assert (f"at {f[3]:.10g} Hz the single-harmonic balance solved here gives M = {m:.6g}, "
            f"the stored value's solution") in text
    np.testing.assert_allclose(np.genfromtxt(out, delimiter=",", names=True)["frequency_hz"],
                               np.repeat([f[3], f[5], 30.0], 2), rtol=1e-9)   # verified there
    # a member not done holds zeros, not NaN: refused by its done flag
    with h5py.File(res, "r+") as h:
        h["done"][1] = 0
    capsys.readouterr()
    out.unlink()
    rc = cli.main(["verify", str(res), "--member", "1", "--f", "30", "-o", str(out)])
    assert rc == 2 and "not done" in capsys.readouterr().err and not out.exists()


def test_verify_says_when_the_run_reached_a_point_only_from_above(tmp_path, capsys):
    """A point a multi-harmonic run converged only from the next frequency's solution
    (``from_above``, set here by hand on a small run): verify's file lines say so and
    give the next grid frequency to add."""
    import h5py

    res = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "3", "--n-freq", "20", "--harmonics",
                     "3", "-o", str(res), "--no-progress", "--no-figure", "--no-bounds"]) == 0
    with h5py.File(res, "r+") as h:
        f = h["frequency"][()]
        assert not h["from_above"][()].any()
        h["from_above"][1, 4] = True
    capsys.readouterr()
    assert cli.main(["verify", str(res), "--member", "1", "--f", f"{f[4]:.10g}",
                     f"{f[6]:.10g}", "--harmonics", "3", "-o", str(tmp_path / "v.csv"),
                     "--no-figure"]) == 0
    text = capsys.readouterr().out
    assert (f"the run reached {f[4]:.10g} Hz only from its solution at the next grid "
            f"frequency (from_above); add its next grid frequency, --f {f[4]:.10g} "
            f"{f[5]:.10g}") in text
    assert text.count("only from its solution") == 1       # not at f[6]
    # with the next grid frequency given too, nothing to add
    assert cli.main(["verify", str(res), "--member", "1", "--f", f"{f[4]:.10g}",
                     f"{f[5]:.4g}", "--harmonics", "3", "-o", str(tmp_path / "v.csv"),
                     "--no-figure"]) == 0
    text = capsys.readouterr().out
    assert "only from its solution at the next grid frequency (from_above)\n" in text
    assert "add its next grid frequency" not in text


def test_verify_asks_for_the_next_grid_frequency_on_a_fine_grid(tmp_path, capsys):
    """On a grid finer than verify's 0.1 % snapping (20,000 frequencies over 10-150 Hz:
    steps of 0.07 % at 10 Hz), the from-above point's own frequency is not its next grid
    frequency: verify still asks for that one (it counted as given when any typed
    frequency lay within 0.1 % of it)."""
    import h5py

    res = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "2", "--n-freq", "20000", "--harmonics",
                     "3", "-o", str(res), "--no-progress", "--no-figure", "--no-bounds"]) == 0
    with h5py.File(res, "r+") as h:
        f = h["frequency"][()]
        h["from_above"][1, 4] = True
    assert abs(f[5] - f[4]) < 1e-3 * f[4]
    capsys.readouterr()
    assert cli.main(["verify", str(res), "--member", "1", "--f", f"{f[4]:.10g}",
                     "--harmonics", "3", "-o", str(tmp_path / "v.csv"), "--no-figure"]) == 0
    assert (f"add its next grid frequency, --f {f[4]:.10g} {f[5]:.10g}"
            in capsys.readouterr().out)


def test_verify_solves_a_members_points_with_the_runs_solver_settings(tmp_path, capsys,
                                                                      monkeypatch):
    from mcfric import verify as verify_module

    cfg = tmp_path / "c.toml"
    cfg.write_text('model.preset = "two-beam"\nsolver.tol = 1e-8\nsolver.max_iter = 30\n')
    res = tmp_path / "r.h5"
    assert cli.main(["run", str(cfg), "--samples", "2", "--n-freq", "10", "-o", str(res),
                     "--no-progress", "--no-figure", "--no-bounds"]) == 0
    seen = []
    solve = verify_module.solve
    monkeypatch.setattr(verify_module, "solve", lambda *a, **k: seen.append(k) or solve(*a, **k))
    assert cli.main(["verify", str(res), "--member", "1", "--f", "30", "--harmonics", "3",
                     "--no-figure", "-o", str(tmp_path / "v.csv")]) == 0
    assert len(seen) == 2 and all(k["tol"] == 1e-8 and k["max_iter"] == 30 for k in seen)
    assert "the run's tolerance and iterations" in capsys.readouterr().out


def test_verify_balances_a_multi_harmonic_files_own_truncation(tmp_path, capsys,
                                                               monkeypatch):
    """``verify FILE`` of a run with H = 5 and its own AFT samples balances H = 5 with
    them by default (it balanced H = 9, whatever the run's H): its multi-harmonic columns
    are the stored fundamentals, and a line says so; with another ``--harmonics`` a line
    says the columns are another truncation."""
    import h5py

    from mcfric import verify as verify_module

    cfg = tmp_path / "c.toml"
    cfg.write_text('model.preset = "two-beam"\nsolver.harmonics = 5\nsolver.n_time = 48\n')
    res = tmp_path / "r.h5"
    assert cli.main(["run", str(cfg), "--samples", "3", "--n-freq", "20", "-o", str(res),
                     "--no-progress", "--no-figure", "--no-bounds"]) == 0
    with h5py.File(res, "r") as h:
        f = h["frequency"][()]
        y = h["response"][1, 7]
        assert h["converged"][1, 7]
    seen = []
    solve = verify_module.solve
    monkeypatch.setattr(verify_module, "solve", lambda *a, **k: seen.append(k) or solve(*a, **k))
    capsys.readouterr()
    out = tmp_path / "v.csv"
    assert cli.main(["verify", str(res), "--member", "1", "--f", f"{f[7]:.10g}",
                     "--no-figure", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert seen[1]["harmonics"] == 5 and seen[1]["n_time"] == 48
    assert "time integration against harmonic balance (H = 1 and H = 5)" in text
    assert f"at {f[7]:.10g} Hz the H = 5 balance solved here gives M = " in text
    assert "the stored value's solution" in text
    table = np.genfromtxt(out, delimiter=",", names=True)
    np.testing.assert_allclose(table["mhb_fundamental_m"], np.abs(y), rtol=1e-8)
    seen.clear()
    assert cli.main(["verify", str(res), "--member", "1", "--f", f"{f[7]:.10g}",
                     "--harmonics", "3", "--no-figure", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert seen[1]["harmonics"] == 3 and seen[1]["n_time"] is None
    assert ("the run balanced H = 5, verify H = 3 (--harmonics): its multi-harmonic "
            "columns are another truncation, not the file's values") in text
    assert "balance solved here gives" not in text


def test_a_multi_harmonic_run_says_its_bounds_are_the_single_harmonic_models(tmp_path,
                                                                              capsys):
    """With H > 1 the members' fundamentals are compared with single-harmonic bounds:
    points outside are no fault, and the file, the check and the figure say so."""
    from mcfric import plot

    res = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "5", "--n-freq", "30", "--harmonics",
                     "3", "-o", str(res), "--no-progress", "--no-figure"]) == 0
    text = capsys.readouterr().out
    assert ("odd harmonics 1..3 balanced (multi-harmonic); metric and response hold the "
            "fundamental, response_peak the full-period peak") in text
    checks = [ln for ln in text.splitlines() if "bounds check:" in ln]
    assert len(checks) == 2, text
    for ln in checks:
        assert "single-harmonic model's" in ln and "H = 3: not a fault" in ln, ln
        assert "please report" not in ln
    with mcfric.open_results(res) as r:
        assert "fundamental (odd harmonics 1..3 balanced)" in r["metric"].attrs["long_name"]
        assert "fundamental" in r["response"].attrs["long_name"]
    drawn = plot.results_figure(res, tmp_path / "a.png")
    assert "upper bound (certified at the grid points; single-harmonic model)" \
        in drawn["legend"]
    assert "fundamental, H = 3" in drawn["ylabel"]
    # a single-harmonic run's check keeps its warning wording (none where none is outside)
    from mcfric.cli.run import _outside_note

    assert _outside_note(2, 1, "x") == " (x: please report)" and _outside_note(0, 1, "x") == ""
    # without the response the line names only what the file holds
    cfg = tmp_path / "m.toml"
    cfg.write_text('[model]\npreset = "two-beam"\n[output]\nkeep_response = false\n'
                   '[bounds]\nenabled = false\n')
    assert cli.main(["run", str(cfg), "--samples", "2", "--n-freq", "10", "--harmonics", "3",
                     "-o", str(tmp_path / "m.h5"), "--no-progress", "--no-figure"]) == 0
    assert ("odd harmonics 1..3 balanced (multi-harmonic); metric holds the fundamental\n"
            in capsys.readouterr().out)


def test_plot_marks_the_points_the_indicator_flags(tmp_path, capsys):
    """The figure's count of flagged points equals a plain count over the file."""
    import h5py

    from mcfric import plot

    res = tmp_path / "r.h5"
    # searched bounds only: the figure's band needs no certificate (it was nearly all of
    # the time)
    assert cli.main(["run", "eight-beam", "--samples", "6", "--n-freq", "40", "-o", str(res),
                     "--no-progress", "--no-figure", "--no-certify"]) == 0
    with h5py.File(res, "r") as h:
        plain = int(np.count_nonzero(h["converged"][...]
                                     & (h["harmonic_indicator"][...] > hbm.INDICATOR_THRESHOLD)))
    assert plain > 0
    assert plot.results_figure(res, tmp_path / "a.png")["n_flagged"] == plain
    assert plot.results_figure(res, tmp_path / "b.png", indicator=False)["n_flagged"] == 0
    capsys.readouterr()
    assert cli.main(["plot", str(res), "-o", str(tmp_path / "c.png"), "--no-indicator"]) == 0
    assert (tmp_path / "c.png").stat().st_size > 0


def test_a_time_integration_whose_state_is_nan_is_not_periodic(two_beam):
    """A state that is not finite (a blown-up integration) never reads as settled: the
    kernel reports no periodic state and a NaN change (``max`` drops a NaN, so a
    change computed by it alone read 0, "settled")."""
    from mcfric.core.aft import harmonic_orders
    from mcfric.core.time_integration import integrate

    fr, z, u = two_beam.modal_arrays()
    w = 2 * np.pi * fr
    uc, uo, ud = (np.ascontiguousarray(u[:, :, i]) for i in range(3))
    a, b = (x.astype(np.int64) for x in two_beam.dampers)
    orders = harmonic_orders(3)
    eta0 = np.full_like(w, np.nan)
    y_h = np.zeros((len(orders), two_beam.n_beams), complex)
    q_h = np.zeros((len(orders), two_beam.n_dampers), complex)
    periods, change, _ = integrate(
        w, np.ascontiguousarray(z), uc, uo, ud,
        np.ascontiguousarray(two_beam.force, dtype=np.complex128), 2 * np.pi * 20.0, a, b,
        np.array([6000.0]), np.array([0.25]), eta0, np.zeros_like(w),
        np.zeros(two_beam.n_dampers), orders, 1024, 1e-9, 3, 0, 20, y_h, q_h,
        np.zeros(two_beam.n_beams), np.zeros((1024, two_beam.n_beams)))
    # the periods it integrated (one: NaN from the start), not the limit of 20
    assert periods == -1 and np.isnan(change)


def test_an_integration_in_many_calls_is_bit_for_bit_one_call(two_beam, monkeypatch):
    """verify integrates in kernel calls of at most ``STEPS_PER_CALL`` steps, so that
    Ctrl-C acts between them; the state carries over between calls, so one period per
    call gives what one call gives, to the bit: settled and not settled."""
    from mcfric import verify as verify_module

    def run(steps_per_call, **kw):
        monkeypatch.setattr(verify_module, "STEPS_PER_CALL", steps_per_call)
        return verify_module.verify(two_beam, [20.0, 47.0], 0.3, 6000.0, 0.5, harmonics=3,
                                    **kw)

    for kw in ({}, {"max_periods": 3}):         # settled (after 5 calm periods); not
        one, many = run(10**9, **kw), run(1, **kw)
        for x, y in zip(one, many, strict=True):
            assert (x.periodic, x.periods) == (y.periodic, y.periods)
            assert (x.periodic and x.periods > 5) if not kw else (
                not x.periodic and x.periods == 3)
            for name in ("history", "harmonics", "peak", "even"):
                assert np.array_equal(getattr(x, name), getattr(y, name)), name
            assert x.change == y.change


def test_the_memory_check_counts_the_threads_the_solve_uses(two_beam, monkeypatch):
    """The Newton workspaces are per thread: a limit between the need on one thread and
    on two refuses two threads and lets one run (the check once ran before the thread
    count was set, with the process's count)."""
    import numba
    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("needs two threads")
    H, n_f = 5, 4
    n_h = (H + 1) // 2
    # what the kernel allocates per sample (one sample per thread at a time)
    per_thread = hbm.multi_harmonic_scratch(two_beam.n_dampers, n_h, n_f,
                                            hbm.check_harmonics(H)[1])
    one = 16.0 * n_h * n_f * 4 * two_beam.n_beams + per_thread
    monkeypatch.setattr(hbm, "MAX_HARMONIC_BYTES", one + per_thread / 2)
    f = np.linspace(20, 30, n_f)
    with pytest.raises(ValueError, match="harmonics: H = 5 needs"):
        hbm.solve(two_beam, f, 0.3, 6000.0, 0.5, harmonics=H, n_threads=2)
    assert hbm.solve(two_beam, f, 0.3, 6000.0, 0.5, harmonics=H, n_threads=1).status.shape


def test_a_multi_harmonic_ring_takes_the_bordered_step_and_agrees_with_the_dense_lu():
    """A mistuned eight-blade ring at H = 3: the sweep on the bordered step against the
    same sweep on the dense LU (the dampers numbered from the second: no known layout).
    The same points converge, to 1e-9, in about the same Newton iterations. (Here, not in
    test_rings.py: beside the other multi-harmonic tests, one xdist worker compiles the
    multi-harmonic kernel, not both.)"""
    from mcfric.core import multi_harmonic as mh

    model = ring(8, True)
    rng = np.random.default_rng(3)
    mu0 = rng.uniform(0, 1, (3, 8))
    kc = rng.uniform(0, 15000.0, (3, 8))
    f = np.linspace(10.0, 150.0, 40)
    bordered = mcfric.solve(model, f, mu0, kc, 0.5, harmonics=3)
    kernel = mh.sweep_multi_harmonic

    def renumbered(rech, force, a, b, orders, omega, mu0, N0, kc, n_time, s1, tol,
                   max_iter, y, y_peak, s, status, iterations, residual):
        def roll(x, axis):
            return np.ascontiguousarray(np.roll(x, -1, axis=axis))
        s_rolled = np.empty_like(s)
        kernel(rech, force, roll(a, 0), roll(b, 0), orders, omega, roll(mu0, 1),
               roll(N0, 1), roll(kc, 1), n_time, roll(s1, 2), tol, max_iter, y, y_peak,
               s_rolled, status, iterations, residual)
        s[...] = np.roll(s_rolled, 1, axis=2)
    try:
        hbm._multi_harmonic.sweep_multi_harmonic = renumbered
        dense = mcfric.solve(model, f, mu0, kc, 0.5, harmonics=3)
    finally:
        hbm._multi_harmonic.sweep_multi_harmonic = kernel
    assert bordered.n_not_converged == 0 and dense.n_not_converged == 0
    assert np.array_equal(bordered.status, dense.status)
    scale = np.abs(dense.response).max(axis=-1, keepdims=True)
    assert np.max(np.abs(bordered.response - dense.response) / scale) <= 1e-9
    assert abs(bordered.iterations.sum() / dense.iterations.sum() - 1.0) <= 0.02
