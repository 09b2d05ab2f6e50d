"""Rings (bladed disks) on the O(n_dampers) lockstep kernel.

References: the dense-LU kernel on the same equations (partial pivoting, one sample at a
time), the physical-space fsolve of naive.py, the closed-form stuck (linear) ring, and the
travelling-wave symmetry of a tuned ring.
"""

import math

import numpy as np
import pytest

import mcfric
from mcfric.core import sweep as _sweep
from mcfric.core.receptance import contact_space
from mcfric.model import TABLE_1, Excitation, Model

from . import naive
from .conftest import naive_beams, naive_pairs, ring

N0 = 0.5


def contact_arrays(model, f):
    """``G, q0, ylin, H`` of ``model`` at the frequencies ``f`` (Hz), C-contiguous as the
    kernels take them."""
    return [np.ascontiguousarray(x) for x in
            contact_space(model.receptances(2 * np.pi * f)[0], model.force, *model.dampers)]


def _solve_dense(monkeypatch, model, *args, **kw):
    """``mcfric.solve`` with the ring sent through the dense-LU kernel instead."""
    with monkeypatch.context() as m:
        m.setattr(_sweep, "sweep_chain",
                  lambda *a: _sweep.sweep_dense(*a, np.int64(0)))
        return mcfric.solve(model, *args, **kw)


@pytest.mark.parametrize("n", [3, 4, 8, 24])
@pytest.mark.parametrize("mistuned", [False, True], ids=["tuned", "mistuned"])
def test_ring_kernel_equals_the_dense_kernel(monkeypatch, n, mistuned):
    """Random friction, warm-started sweeps over the band: every point to 1e-8."""
    model = ring(n, mistuned)
    rng = np.random.default_rng(n + 7 * mistuned)
    n_s = 11                                # not a multiple of the lane count
    f = np.linspace(10.0, 150.0, 120)
    mu0 = rng.uniform(0, 1, (n_s, n))
    kc = rng.uniform(0, 15000.0, (n_s, n))
    fast = mcfric.solve(model, f, mu0, kc, N0)
    dense = _solve_dense(monkeypatch, model, f, mu0, kc, N0)
    assert fast.n_not_converged == 0 and dense.n_not_converged == 0
    scale = np.abs(dense.response).max(axis=-1, keepdims=True)
    assert np.max(np.abs(fast.response - dense.response) / scale) <= 1e-8
    finite = np.isfinite(dense.s) & (dense.s > 0) & (dense.s < 1e12)
    assert np.max(np.abs(fast.s - dense.s)[finite] / dense.s[finite]) <= 1e-8
    # the same damped Newton: a wrong Newton step would still converge (slowly, or in
    # the fallbacks), so the steps taken and the points needing a fallback must agree too
    assert abs(fast.iterations.sum() / dense.iterations.sum() - 1.0) <= 0.02
    assert np.sum(fast.status > 0) <= np.sum(dense.status > 0) + 1


@pytest.mark.parametrize("n", [3, 4, 8])
def test_ring_points_match_the_physical_space_reference(n):
    """Cold-started single points against fsolve on the full physical-space equations."""
    model = ring(n, mistuned=True)
    rng = np.random.default_rng(30 + n)
    for _ in range(12):
        f = rng.uniform(10.0, 150.0)
        mu0 = rng.uniform(0, 1, n)
        kc = rng.uniform(0, 15000.0, n)
        r = mcfric.solve(model, f, mu0, kc, N0)
        assert r.status[0, 0] >= 0
        roots = naive.solve_point(2 * np.pi * f, naive_beams(model), naive_pairs(model),
                                  model.force, mu0, np.full(n, N0), kc,
                                  starts=[np.ones(n)])
        assert roots, f"reference found no root at f={f}"
        err = min(np.max(np.abs(root["y_output"] - r.response[0, 0]))
                  / np.max(np.abs(root["y_output"])) for root in roots)
        assert err <= 1e-8, (f, err)


@pytest.mark.parametrize("n", [3, 8, 24])
def test_a_stuck_ring_is_its_linear_solution(n):
    """mu0 -> inf: every damper sticks and the ring is linear with K = kc."""
    model = ring(n, mistuned=True)
    f = np.linspace(10.0, 150.0, 71)
    kc = np.linspace(1000.0, 14000.0, n)
    r = mcfric.solve(model, f, mu0=1e9, kc=kc, N0=N0)
    assert r.n_not_converged == 0
    assert np.all(r.s >= 1)
    for k in range(0, len(f), 5):
        ref = naive.linear_stuck_response(2 * np.pi * f[k], naive_beams(model),
                                          naive_pairs(model), model.force, kc)
        np.testing.assert_allclose(r.response[0, k], ref, rtol=1e-11,
                                   atol=1e-11 * np.abs(ref).max())


@pytest.mark.parametrize("n, engine_order", [(8, 1), (24, 3), (24, 5)])
def test_a_tuned_ring_responds_as_a_travelling_wave(n, engine_order):
    """Equal dampers on a tuned ring, engine order E: equal amplitudes on every blade and
    phase steps of -2 pi E / n from one blade to the next (the drive's own steps)."""
    model = ring(n, mistuned=False, engine_order=engine_order)
    f = np.linspace(10.0, 150.0, 141)
    r = mcfric.solve(model, f, mu0=0.3, kc=9000.0, N0=N0)
    assert r.n_not_converged == 0
    y = r.response[0]                                   # (n_f, n_beams)
    amp = np.abs(y)
    np.testing.assert_allclose(amp, amp[:, :1].repeat(n, axis=1), rtol=1e-9)
    step = y[:, 1:] / y[:, :-1]
    expected = np.exp(-2j * np.pi * engine_order / n)
    assert np.max(np.abs(step / expected - 1.0)) <= 1e-9
    assert np.any(r.s < 1)                              # the dampers did slip


def test_turning_a_tuned_ring_turns_its_response():
    """The symmetry behind one-blade bounds, checked on the plain physical-space solve:
    the damper values turned by one blade give the response turned by one blade, times
    the drive's phase step; on a mistuned ring they do not."""
    rng = np.random.default_rng(11)
    for mistuned, holds in ((False, True), (True, False)):
        model = ring(6, mistuned, engine_order=2)
        beams, pairs = naive_beams(model), naive_pairs(model)
        for f in (17.0, 40.0, 95.0):
            K = rng.uniform(0, 15000.0, 6) + 1j * rng.uniform(0, 15000.0, 6)
            y = naive.beam_space_response(2 * np.pi * f, beams, pairs, model.force, K)
            y_turned = naive.beam_space_response(2 * np.pi * f, beams, pairs, model.force,
                                                 np.roll(K, 1))
            err = np.max(np.abs(y_turned["y_output"] - np.exp(-2j * np.pi * 2 / 6)
                                * np.roll(y["y_output"], 1))) / np.abs(y["y_output"]).max()
            assert (err <= 1e-12) == holds, (mistuned, f, err)


def test_a_tuned_ring_has_the_same_upper_bound_on_every_blade():
    """Each blade's own search (a metric over that blade alone) finds the bound computed
    once for all blades; the shortcut applies to tuned rings under travelling waves only."""
    from mcfric.bounds import compute_bounds, force_limit, rotation_invariant

    model = ring(6, mistuned=False, engine_order=2, F0=0.5)
    assert rotation_invariant(model)
    assert not rotation_invariant(ring(6, mistuned=True))
    assert not rotation_invariant(mcfric.eight_beam())
    f = np.linspace(14.0, 60.0, 24)
    F_lim = force_limit(1.0, N0)
    # the searched bounds only: certification does not change them
    every = compute_bounds(model, f, 15000.0, F_lim=F_lim, n_threads=1, certified=False)
    for b in range(6):
        one = compute_bounds(model, f, 15000.0, F_lim=F_lim, beams=[b], n_threads=1,
                             seed=b, certified=False)
        np.testing.assert_allclose(one.upper, every.upper, rtol=1e-6)
        assert np.all(one.lower <= every.lower * (1 + 1e-9))     # min |y_b| <= min M


def test_amplitude_storage_is_the_complex_response_in_float32(tmp_path):
    """A 40-blade ring stores float32 amplitudes by default (auto), a quarter of the
    complex bytes, equal to abs(response) of the same run stored complex; both open with
    mcfric.open_results (xarray) with labelled dimensions."""
    import h5py

    from mcfric import config, ensemble

    raw = {"model": {"preset": "disk-24", "n_beams": 40}, "frequency": {"n": 30},
           "sampling": {"samples": 9, "seed": 3}, "bounds": {"enabled": False},
           "peaks": {"enabled": False}}
    auto = config.load(raw)
    assert auto.spec.response_format == "amplitude"
    full = auto.replace("output.response", "complex")
    for cfg, name in ((auto, "amp.h5"), (full, "full.h5")):
        ensemble.run(cfg, tmp_path / name, progress=False)
    with h5py.File(tmp_path / "amp.h5") as a, h5py.File(tmp_path / "full.h5") as c:
        assert "response" not in a and "amplitude" not in c
        amp, resp = a["amplitude"][...], c["response"][...]
        assert amp.dtype == np.float32 and amp.shape == resp.shape == (9, 30, 40)
        assert np.array_equal(amp, np.abs(resp).astype(np.float32))
        assert a["metric"][...].tobytes() == c["metric"][...].tobytes()
        assert a["amplitude"].id.get_storage_size() * 4 == c["response"].id.get_storage_size()
    with mcfric.open_results(tmp_path / "amp.h5") as ds:
        assert ds["amplitude"].dims == ("sample", "frequency", "beam")
        np.testing.assert_array_equal(ds["amplitude"].values, amp)


def test_disk_presets_are_tuned_rings_in_an_engine_order():
    for name, n, eo in (("disk-24", 24, 3), ("disk-72", 72, 8)):
        m = mcfric.preset(name)
        assert (m.n_beams, m.n_dampers, m.topology) == (n, n, "circular")
        assert m.excitation.pattern == "travelling" and m.excitation.engine_order == eo
        from mcfric.bounds import rotation_invariant
        assert rotation_invariant(m)


def test_an_engine_order_sweep_is_one_run_per_order(tmp_path, capsys):
    """engine_orders = [1, 2]: one complete file per order, each bitwise the run of that
    engine_order alone; a conflicting file of the second order refuses the sweep before
    the first order is written."""
    import h5py

    from mcfric import cli

    base = ('[model]\npreset = "disk-24"\nn_beams = 6\n[frequency]\nn = 30\n'
            '[sampling]\nsamples = 9\n[peaks]\nenabled = false\n'
            '[bounds]\ncertify = false\n')
    (tmp_path / "sweep.toml").write_text(base + "[excitation]\nengine_orders = [1, 2]\n")
    for E in (1, 2):
        (tmp_path / f"one{E}.toml").write_text(base + f"[excitation]\nengine_order = {E}\n")
    args = ["--no-progress", "--no-figure"]
    clash = tmp_path / "s-eo2.h5"
    assert cli.main(["run", str(tmp_path / "one1.toml"), "-o", str(clash)] + args) == 0
    assert cli.main(["run", str(tmp_path / "sweep.toml"), "-o", str(tmp_path / "s.h5")]
                    + args) == 2
    assert "s-eo2.h5 exists" in capsys.readouterr().err
    assert not (tmp_path / "s-eo1.h5").exists()
    # with --resume too (order 1 ran to the end before order 2 was refused)
    assert cli.main(["run", str(tmp_path / "sweep.toml"), "-o", str(tmp_path / "s.h5"),
                     "--resume"] + args) == 2
    assert "s-eo2.h5 exists" in capsys.readouterr().err
    assert not (tmp_path / "s-eo1.h5").exists()
    clash.unlink()
    assert cli.main(["run", str(tmp_path / "sweep.toml"), "-o", str(tmp_path / "s.h5")]
                    + args) == 0
    for E in (1, 2):
        single = tmp_path / f"one{E}.h5"
        assert cli.main(["run", str(tmp_path / f"one{E}.toml"), "-o", str(single)]
                        + args) == 0
        with h5py.File(tmp_path / f"s-eo{E}.h5") as a, h5py.File(single) as b:
            assert a.attrs["complete"] == 1
            for name in ("metric", "response", "mu0"):
                assert a[name][...].tobytes() == b[name][...].tobytes(), (E, name)
    assert cli.main(["bounds", str(tmp_path / "sweep.toml"), "-o",
                     str(tmp_path / "b.h5")]) == 2
    assert "engine_orders" in capsys.readouterr().err
    # `mcfric config` prints the sweep, the list kept
    assert cli.main(["config", str(tmp_path / "sweep.toml")]) == 0
    assert "engine_orders = [1, 2]" in capsys.readouterr().out


def test_a_sweep_replaces_an_engine_order_that_does_not_fit():
    """two-beam's engine_order (2, the template's) does not fit two beams; a sweep of
    engine orders 0 and 1 replaced it and was refused for it."""
    from mcfric import config

    cfg = config.load({"model": {"preset": "two-beam"},
                       "excitation": {"pattern": "travelling", "engine_orders": [0, 1]}})
    assert cfg.model().excitation.engine_order == 0
    with pytest.raises(config.ConfigError, match="excitation.engine_orders: expected "):
        config.load({"model": {"preset": "two-beam"},
                     "excitation": {"pattern": "travelling", "engine_orders": [0, 2]}})


@pytest.mark.parametrize("F0", [0.25, 1.1])
def test_every_member_of_a_24_blade_disk_lies_within_its_bounds(F0):
    """500 members of the disk-24 preset, the paper's distributions, 71 frequencies."""
    from mcfric.bounds import compute_bounds, force_limit

    model = mcfric.preset("disk-24", F0)
    f = np.linspace(10.0, 150.0, 71)
    rng = np.random.default_rng(24)
    r = mcfric.solve(model, f, rng.uniform(0, 1, (500, 24)),
                     rng.uniform(0, 15000.0, (500, 24)), N0)
    B = compute_bounds(model, f, 15000.0, F_lim=force_limit(1.0, N0))
    assert B.n_failed == 0 and r.n_not_converged == 0
    M = r.metric()
    inside = B.contains(M, rtol=1e-9)
    assert np.all(inside), (np.count_nonzero(~inside), np.nanmax(M / B.upper),
                            np.nanmin(M / B.lower))
    assert np.nanmax(M / B.upper) > 0.3        # the bound is not vacuous
    # and inside the certificate (the relaxation's, a tuned ring of 24 blades)
    C = B.certificate
    assert C.relaxed and np.all(C.contains(M))
    assert np.count_nonzero(C.lower > 0) >= len(f) // 2      # more than 0 proved


def test_bad_ring_input_is_one_line_and_writes_nothing(tmp_path, monkeypatch, capsys):
    from mcfric import cli

    monkeypatch.chdir(tmp_path)
    cases = {
        'model.preset = "disk-24"\nexcitation.engine_order = 24':
            "excitation.engine_order: expected engine orders in 0..23",
        'model.preset = "disk-24"\nexcitation.engine_orders = [3, 30]':
            "excitation.engine_orders: expected engine orders in 0..23",
        'model.preset = "disk-24"\nmodel.n_beams = 2':
            'model.topology: "circular" needs n_beams >= 3',
        'model.preset = "disk-24"\nmetric.beams = [25]':
            "metric.beams: expected beam numbers in 1..24",
    }
    for text, message in cases.items():
        (tmp_path / "bad.toml").write_text(text + "\n")
        assert cli.main(["run", "bad.toml", "-o", "out.h5"]) == 2
        err = capsys.readouterr().err
        assert err.startswith("mcfric: error: " + message) and err.count("\n") == 1, err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]
    with pytest.raises(ValueError, match="engine_order"):
        ring(6, False, engine_order=6)


@pytest.mark.parametrize("n", [5, 24, 72])
def test_the_ring_elimination_of_the_bounds_searches_equals_numpy(n):
    """The bounds' searches factor a ring's I + G diag(K) by bordering (O(n)): the same
    solution as numpy's dense solve, and of the transposed system; a chain is not taken
    for a ring."""
    from mcfric.core.linalg import (
        cyclic_factor,
        cyclic_factor_stable,
        cyclic_solve,
        cyclic_solve_transposed,
        is_cyclic,
    )

    rng = np.random.default_rng(n)
    for topology in ("circular", "linear"):
        model = Model.identical(TABLE_1, n, excitation=Excitation("travelling", 1.1),
                                topology=topology)
        f = np.array([17.0, 60.0, 110.0])
        G, q0, _, _ = contact_space(model.receptances(2 * np.pi * f)[0], model.force,
                                    *model.dampers)
        for k in range(len(f)):
            Gk = np.ascontiguousarray(G[k])
            assert is_cyclic(Gk, model.n_dampers) == (topology == "circular")
            if topology == "linear":
                continue
            for _ in range(10):
                K = rng.uniform(0, 15000, n) + 1j * rng.uniform(0, 15000, n)
                F = np.empty((4, n), complex)
                assert cyclic_factor(Gk, K, F, n) == 0
                x = q0[k].copy()
                cyclic_solve(Gk, K, F, x, n)
                T = np.eye(n) + Gk * K[None, :]
                ref = np.linalg.solve(T, q0[k])
                np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
                # the adjoint solve of the smoothed-gradient search
                assert cyclic_factor_stable(Gk, K, F, n)
                b = rng.normal(size=n) + 1j * rng.normal(size=n)
                x = b.copy()
                cyclic_solve_transposed(Gk, K, F, x, n)
                ref = np.linalg.solve(T.T, b)
                np.testing.assert_allclose(x, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_the_ring_coordinate_search_takes_the_bordered_elimination():
    """On a 24-blade ring the coordinate search and the smoothed gradient solve by the
    ring's O(n) elimination (structure code 2), and the value the search returns is M at
    the point it returns, by numpy's dense solve."""
    from mcfric.bounds.search import sparsity
    from mcfric.core.coordinate_search import coordinate_search, workspace
    from mcfric.core.projected_gradient import projected_gradient

    model = Model.identical(TABLE_1, 24, excitation=Excitation("travelling", 1.1),
                            topology="circular")
    f = np.array([18.0, 45.0])
    G, q0, ylin, H = contact_arrays(model, f)
    hr, gr = sparsity(G, H)
    w = workspace(24, 24, hr, gr)
    for k in range(len(f)):
        for want_max, b1 in ((False, 24), (True, 1)):
            K = np.full(24, 7500.0 + 7500.0j)
            v = coordinate_search(G[k], q0[k], ylin[k], H[k], 15000.0, 15000.0, K, want_max,
                                  0, b1, 20, 1e-11, w)
            assert w[14][0] == 2
            q = np.linalg.solve(np.eye(24) + G[k] * K[None, :], q0[k])
            ref = np.abs(ylin[k, :b1] - H[k, :b1] @ (K * q)).max()
            assert abs(v - ref) <= 1e-9 * ref
        K = np.full(24, 7500.0 + 7500.0j)
        v = projected_gradient(G[k], q0[k], ylin[k], H[k], 15000.0, 15000.0, K, 1.0, 0, 24,
                               w, 20)
        assert w[14][0] == 2
        q = np.linalg.solve(np.eye(24) + G[k] * K[None, :], q0[k])
        ref = np.abs(ylin[k] - H[k] @ (K * q)).max()
        assert abs(v - ref) <= 1e-9 * ref


def test_tuned_rings_above_seven_dampers_are_certified_by_the_relaxation():
    """Tuned rings of 8 and 12 blades under travelling waves, six frequencies: the
    relaxation of the whole box tightens Eq. 10 and 0, with one relaxation per frequency
    and bound (the other blades take its multipliers turned), and the certificate
    encloses 3000 random admissible points per frequency (physical-space solves). The
    upper witness, climbed from the relaxation's rounded points, is above all of them
    (before the climb it was up to 40 % below the best at 120 Hz), and both witnesses
    are admissible and attain their values. A mistuned ring is not turned and keeps
    Eq. 10 and 0."""
    from mcfric.bounds import compute_bounds

    from .test_certified import F_LIM, K_MAX, check_witnesses, random_admissible

    f = np.array([12.0, 15.0, 80.0, 90.0, 104.0, 120.0])
    for n, eo in ((8, 1), (12, 2)):
        model = mcfric.disk(n, eo, 1.1)
        B = compute_bounds(model, f, K_MAX, F_lim=F_LIM)
        C = B.certificate
        assert C.relaxed and C.first_order[1] == 0
        assert C.first_order[0] <= 2 * len(f)
        assert np.count_nonzero(C.upper < 0.8 * B.upper_force) >= 4
        assert np.count_nonzero(C.lower > 0) >= 4
        assert np.all(C.upper >= C.upper_witness) and np.all(C.lower <= C.lower_witness)
        for k, fk in enumerate(f):
            M = random_admissible(model, fk, 3000, 10 * n + k)
            assert len(M) > 300
            assert C.lower[k] <= M.min() and M.max() <= C.upper[k], (n, fk)
            assert M.max() <= C.upper_witness[k], (n, fk)
        check_witnesses(model, f, C)
    mistuned = ring(8, mistuned=True, F0=1.1)
    C = compute_bounds(mistuned, f, K_MAX, F_lim=F_LIM).certificate
    assert not C.relaxed and np.all(C.lower == 0)


def test_a_tuned_ring_with_some_blades_in_the_metric_takes_the_whole_rings_upper_bound():
    """With only blades 1 and 6 of an 8-blade tuned ring in the metric, the ring's
    relaxation (which needs every blade) still tightens the upper bound: the whole
    ring's bound holds for any subset, and a turn of its witness puts the largest blade
    on one of the subset's. Before, the certificate was Eq. 10 there and the witness six
    solves, 0.19-0.56 of the bound where admissible points reach it (disk-24, 30 Hz:
    0.24). Checked on physical-space solves: the witness is admissible, attains its
    value on the subset's metric and lies above 3000 random admissible points per
    frequency, all below the certified bound; the lower witness, the subset's own, is
    admissible and attains its value too."""
    from mcfric.bounds import compute_bounds

    from .test_certified import F_LIM, K_MAX, physical_grid, random_admissible

    f = np.array([12.0, 30.0, 65.0, 104.0, 120.0])
    beams = [0, 5]
    model = mcfric.disk(8, 1, 1.1)
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, beams=beams)
    C = B.certificate
    assert C.relaxed
    assert np.count_nonzero(C.upper < 0.8 * B.upper_force) >= 2
    assert np.count_nonzero(C.upper <= C.upper_witness * 1.01) >= 2
    assert np.all(C.upper >= C.upper_witness) and np.all(C.lower <= C.lower_witness)
    for k, fk in enumerate(f):
        K = C.K_upper[k]
        assert np.all((K.real >= 0) & (K.real <= K_MAX) & (K.imag >= 0) & (K.imag <= K_MAX))
        M, force = physical_grid(model, fk, K[None, :], beams=beams)
        assert force[0] <= 1 + 1e-9 and M[0] == pytest.approx(C.upper_witness[k], rel=1e-9)
        M = random_admissible(model, fk, 3000, 70 + k, beams=beams)
        assert len(M) > 300
        assert C.lower[k] <= M.min() and M.max() <= C.upper[k], fk
        assert M.max() <= C.upper_witness[k] * (1 + 1e-9), fk
        K = C.K_lower[k]
        M, force = physical_grid(model, fk, K[None, :], beams=beams)
        assert force[0] <= 1 + 1e-9
        assert M[0] == pytest.approx(C.lower_witness[k], rel=1e-9, abs=1e-15)
    # the upper bound and witness are the whole ring's
    every = compute_bounds(model, f, K_MAX, F_lim=F_LIM).certificate
    np.testing.assert_allclose(C.upper, every.upper, rtol=1e-12)
    np.testing.assert_allclose(C.upper_witness, every.upper_witness, rtol=1e-9)


def test_the_metric_is_a_set_of_beams_whose_order_and_repeats_change_nothing():
    """Every blade of an 8-blade tuned ring listed backwards, one of them twice: the
    bounds are those of every blade in order, bit for bit, certificate included (the
    ring's relaxations, which need every blade in the metric, run for this list too;
    before, it took the path of a subset: a lower bound of 0 at twice the time). The
    listed beams are kept as given."""
    from mcfric.bounds import compute_bounds

    from .test_certified import F_LIM, K_MAX

    f = np.array([30.0, 104.0])
    model = mcfric.disk(8, 1, 1.1)
    every = compute_bounds(model, f, K_MAX, F_lim=F_LIM)
    listed = (7, 6, 5, 4, 3, 2, 1, 0, 3)
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, beams=listed)
    assert B.beams == listed
    assert np.all(every.certificate.lower > 0)
    for name in ("upper", "lower", "K_upper", "K_lower"):
        np.testing.assert_array_equal(getattr(B, name), getattr(every, name))
    for name in ("upper", "lower", "upper_witness", "lower_witness", "K_upper", "K_lower"):
        np.testing.assert_array_equal(getattr(B.certificate, name),
                                      getattr(every.certificate, name))


def test_an_upper_only_certificate_is_the_upper_half_of_the_full_one():
    """``certify(..., lower=False)`` (the whole ring's certificate behind a blade
    subset's) gives the full certificate's upper bound and witness bit for bit, and for
    the lower bound only the trivial 0, marked as not met and without a witness."""
    from mcfric.bounds.certified import certify

    from .test_certified import F_LIM, K_MAX

    model = mcfric.disk(8, 1, 1.1)
    f = np.array([30.0, 104.0])
    G, q0, ylin, H = contact_arrays(model, f)
    K0 = np.full((2, 8), 0.5 * K_MAX * (1 + 1j))
    full, upper = (certify(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, K0, K0, np.ones(2),
                           turned=True, lower=lower) for lower in (True, False))
    for name in ("upper", "upper_witness", "K_upper"):
        np.testing.assert_array_equal(getattr(upper, name), getattr(full, name))
    np.testing.assert_array_equal(upper.converged[0], full.converged[0])
    assert np.all(full.lower > 0)
    assert np.all(upper.lower == 0) and not upper.converged[1].any()
    assert np.isnan(upper.lower_witness).all() and np.isnan(upper.K_lower).all()


def test_turned_multipliers_prove_the_bound_of_every_blade():
    """An 8-blade tuned ring, three frequencies: the whole box's upper bound with each
    blade's relaxation solved (no turning) and with the first blade's multipliers turned
    for the others agree to 1e-6, the latter with one relaxation per frequency."""
    from mcfric.core.box_relaxation import relax_frequencies

    from .test_certified import F_LIM, K_MAX

    model = mcfric.disk(8, 1, 1.1)
    f = np.array([15.0, 80.0, 120.0])
    arrays = contact_arrays(model, f)
    got = {}
    for turn in (False, True):
        out = np.empty(3)
        stats = np.zeros(4, np.int64)
        relax_frequencies(*arrays, K_MAX, K_MAX, F_LIM, True, np.zeros(3), np.zeros(3),
                          np.arange(3, dtype=np.int64), out, np.full((3, 2, 8), np.nan + 0j),
                          np.full((3, 8), np.inf), stats, turn, np.int64(0))
        got[turn] = out, stats[2]
    np.testing.assert_allclose(got[True][0], got[False][0], rtol=1e-6)
    assert got[True][1] == 3 and got[False][1] > 12


@pytest.mark.parametrize("mistuned", [False, True])
def test_tied_multipliers_give_the_lower_relaxation_of_a_tuned_ring(mistuned):
    """A 12-blade ring, five frequencies: the lower bound's relaxation with every
    damper's multipliers tied (``tied_relaxation``: 7 unknowns) proves what the full
    relaxation (84) proves, to 0.2 %, on a tuned ring, and lies below 3000 random
    admissible points per frequency (physical-space solves). A mistuned ring's damper
    block is not circulant: the tied relaxation (whose Fourier barrier assumes it)
    declines with ``nan``, and the full relaxation's bound still lies below every
    random admissible point."""
    from mcfric.core.relaxation import buffers, relaxed_bound
    from mcfric.core.tied_relaxation import tied_lower

    from .test_certified import F_LIM, K_MAX, random_admissible

    model = ring(12, mistuned=True, F0=1.1) if mistuned else mcfric.disk(12, 1, 1.1)
    f = np.array([14.0, 40.0, 75.0, 104.0, 130.0])
    G, q0, ylin, H = contact_arrays(model, f)
    nd, nb = q0.shape[1], ylin.shape[1]
    lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
    tied_ok = 0
    for k, fk in enumerate(f):
        buf = buffers(nd, nb, True, True)
        full = relaxed_bound(G[k], q0[k], ylin[k], H[k], lo, hi, F_LIM, np.int64(-1), np.inf,
                             *buf, np.zeros(5, np.int64), np.full(len(buf[3]) + 1, np.nan),
                             lo, hi)
        tied = tied_lower(G[k], q0[k], ylin[k], H[k], lo, hi, F_LIM, np.inf,
                          *buffers(nd, nb, True, True), np.zeros(5, np.int64))
        M = random_admissible(model, fk, 3000, 40 + k)
        assert len(M) > 300
        assert full <= M.min()
        if not np.isnan(tied):
            tied_ok += 1
            assert tied <= M.min(), fk
        if not mistuned:
            assert abs(tied / full - 1) < 2e-3, fk
    assert tied_ok == (0 if mistuned else len(f))


def test_the_whole_box_lower_bound_of_a_tuned_ring_is_tied():
    """An 8-blade tuned ring, three frequencies: the whole box's lower bound with
    ``turn`` (multipliers tied across dampers) proves what the full relaxation proves,
    to 0.2 %, and its rounded points are set; a frequency whose data are not finite
    verifies nothing either way, is counted as one failed relaxation (the tied attempt
    uncounted) and keeps 0."""
    from mcfric.core.box_relaxation import relax_frequencies

    from .test_certified import F_LIM, K_MAX

    model = mcfric.disk(8, 1, 1.1)
    f = np.array([15.0, 80.0, 120.0, 120.0])
    arrays = contact_arrays(model, f)
    arrays[1][3, 2] = np.nan
    got = {}
    for turn in (False, True):
        out = np.full(4, -1.0)
        K_round = np.full((4, 2, 8), np.nan + 0j)
        stats = np.zeros(4, np.int64)
        relax_frequencies(*arrays, K_MAX, K_MAX, F_LIM, False, np.zeros(4), np.full(4, np.inf),
                          np.arange(4, dtype=np.int64), out, K_round,
                          np.full((4, 8), np.inf), stats, turn, np.int64(0))
        got[turn] = out
        assert np.isfinite(K_round[:3]).all() and np.isnan(K_round[3]).all()
        assert stats[2] == 4 and stats[3] == 1 and out[3] == 0.0
    assert np.all(got[True][:3] > 0)
    np.testing.assert_allclose(got[True][:3], got[False][:3], rtol=2e-3)


def test_tuned_rings_above_24_blades_get_tied_relaxations():
    """A 32-blade tuned ring, three frequencies: above ``MAX_TURNED`` the upper
    certificate is the partly tied relaxation's (multipliers free near the beam), at or
    below Eq. 10, and the lower one the tied relaxation's, above 0: one relaxation per
    frequency and bound; both enclose 2000 random admissible points per frequency
    (physical-space solves); one thread gives the same bits as two."""
    from mcfric.bounds import compute_bounds

    from .test_certified import F_LIM, K_MAX, random_admissible

    model = mcfric.disk(32, 2, 1.1)
    f = np.array([30.0, 90.0, 125.0])
    B = compute_bounds(model, f, K_MAX, F_lim=F_LIM, n_threads=2)
    C = B.certificate
    # and the same bits on one thread
    C1 = compute_bounds(model, f, K_MAX, F_lim=F_LIM, n_threads=1).certificate
    for name in ("upper", "lower", "upper_witness", "lower_witness"):
        assert np.array_equal(getattr(C1, name), getattr(C, name)), name
    assert C.relaxed and C.first_order[0] == 2 * len(f) and C.first_order[1] == 0
    # Eq. 10 as the certificate takes it (rounded outwards), and below it at 90 Hz
    assert np.all(C.upper <= B.upper_force * (1 + 1e-9)) and np.all(C.upper >= C.upper_witness)
    assert C.upper[1] < 0.5 * B.upper_force[1]
    assert np.all(C.lower > 0) and np.all(C.lower <= C.lower_witness)
    for k, fk in enumerate(f):
        M = random_admissible(model, fk, 2000, 70 + k)
        assert len(M) > 200
        assert C.lower[k] <= M.min() and M.max() <= C.upper[k], fk


def test_tuned_rings_above_96_blades_get_tied_relaxations(monkeypatch):
    """A 100-blade tuned ring (engine order 8) at 14 and 90 Hz: the tied relaxations
    certify it too (they stopped at 96 blades once, above which the certificate was Eq.
    10 and 0): the lower bound above 0, the upper one below Eq. 10, both enclosing 1000
    random admissible points per frequency (physical-space solves). The search's optima
    are left out (uniform candidates): the bounds' validity does not rest on them. Above
    ``MAX_TIED`` the certificate is Eq. 10 and 0."""
    from mcfric.bounds import certified
    from mcfric.bounds.certified import certify

    from .test_certified import F_LIM, K_MAX, random_admissible

    model = mcfric.disk(100, 8, 1.1)
    f = np.array([14.0, 90.0])
    G, q0, ylin, H = contact_arrays(model, f)
    K0 = np.zeros(q0.shape, complex)
    C = certify(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, K0, K0, np.ones(len(f)), turned=True)
    assert C.relaxed and C.first_order[0] == 2 * len(f)
    eq10 = (np.abs(ylin) + F_LIM * np.abs(H).sum(axis=2)).max(axis=1)
    assert np.all(C.upper < eq10) and np.all(C.upper >= C.upper_witness)
    assert np.all(C.lower > 0) and np.all(C.lower <= C.lower_witness)
    for k, fk in enumerate(f):
        M = random_admissible(model, fk, 1000, 110 + k)
        assert len(M) > 100
        assert C.lower[k] <= M.min() and M.max() <= C.upper[k], fk
    monkeypatch.setattr(certified, "MAX_TIED", 99)
    C = certify(G, q0, ylin, H, K_MAX, K_MAX, F_LIM, K0, K0, np.ones(len(f)), turned=True)
    assert not C.relaxed and np.all(C.lower == 0)
    assert np.allclose(C.upper, eq10, rtol=1e-6)


def test_the_tied_relaxation_reaches_the_lower_bound_of_72_blades_near_resonance():
    """``disk-72``'s rings (72 blades, engine order 8) at 10 and 14 Hz: the tied
    relaxation proves a lower bound above 0 (with 40 Newton steps per barrier weight it
    proved only 0 there, its iterates left uncentred) and below 1000 random admissible
    points (physical-space solves)."""
    from mcfric.core.relaxation import buffers
    from mcfric.core.tied_relaxation import tied_lower

    from .test_certified import F_LIM, K_MAX, random_admissible

    model = mcfric.disk(72, 8, 1.1)
    f = np.array([10.0, 14.0])
    G, q0, ylin, H = contact_arrays(model, f)
    nd = q0.shape[1]
    lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
    for k, fk in enumerate(f):
        tied = tied_lower(G[k], q0[k], ylin[k], H[k], lo, hi, F_LIM, np.inf,
                          *buffers(nd, nd, True, True), np.zeros(5, np.int64))
        M = random_admissible(model, fk, 1000, 90 + k)
        assert len(M) > 100
        assert 0 < tied <= M.min(), fk


def test_the_fourier_spectrum_of_a_tied_tuned_ring():
    """A 12-blade tuned ring at 40 Hz, tied multipliers drawn at random: the Fourier
    eigenvalues ``tied_relaxation`` takes from the first column of ``Z``'s damper block
    are that block's eigenvalues (``numpy.linalg.eigvalsh`` of the dense ``Z``), the
    constant's column lies in one Fourier mode, and ``log det Z`` from them is the dense
    one; a mistuned ring's block is not circulant."""
    from mcfric.core.relaxation import _assemble, buffers, forms, per_damper, weights
    from mcfric.core.tied_relaxation import CIRCULANT_TOL, _departure, _expand, _spectrum

    from .test_certified import F_LIM, K_MAX

    rng = np.random.default_rng(3)
    for mistuned in (False, True):
        model = ring(12, mistuned=True, F0=1.1) if mistuned else mcfric.disk(12, 1, 1.1)
        G, q0, ylin, H = (x[0] for x in contact_arrays(model, np.array([40.0])))
        nd = len(q0)
        lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
        V, idx, S, x, cvec, pos, simplex, grow, ws = buffers(nd, nd, True, True)
        shift, ys = forms(G, q0, ylin, H, lo, hi, F_LIM, np.int64(-1), V, idx, S, x, cvec,
                          pos, simplex, grow)
        per = per_damper(True)
        w = np.empty(len(x))
        weights(S, nd, per, w)
        y = rng.uniform(0.5, 2.0, per + 1)
        _expand(y, w, nd, per, nd, shift, simplex, x)
        C, T, Z = ws[0], ws[1], ws[2]
        _assemble(x, 1.0, V, idx, S, C, T, Z, len(x))
        Zd = Z.copy()
        if mistuned:
            assert _departure(Zd, nd) > 1e3 * CIRCULANT_TOL
            continue
        assert _departure(Zd, nd) < CIRCULANT_TOL
        lam, beta = np.empty(nd), np.empty(nd, complex)
        gamma = _spectrum(x, 1.0, V, idx, S, C, T, len(x), lam, beta)
        np.testing.assert_allclose(np.sort(lam), np.linalg.eigvalsh(Zd[:nd, :nd]),
                                   rtol=1e-9, atol=1e-12 * abs(lam).max())
        k0 = np.argmax(abs(beta))
        assert np.delete(abs(beta), k0).max() < 1e-9 * abs(beta[k0])
        assert gamma == Zd[nd, nd].real
        # log det from the spectrum against the dense one (made definite by a shift)
        d = 1.0 - min(0.0, lam.min()) + abs(beta[k0]) ** 2 / (lam[k0] + 1.0 - min(0.0, lam.min()))
        lam_s = lam + 1.0 - min(0.0, lam.min())
        g_s = gamma + abs(gamma) + d + 1.0
        Zs = Zd + np.diag(np.r_[np.full(nd, 1.0 - min(0.0, lam.min())), abs(gamma) + d + 1.0])
        fourier = np.log(np.delete(lam_s, k0)).sum() + np.log(lam_s[k0] * g_s
                                                               - abs(beta[k0]) ** 2)
        np.testing.assert_allclose(fourier, np.linalg.slogdet(Zs)[1], rtol=1e-9)


def test_the_partly_tied_barrier_is_the_dense_one():
    """A 16-blade tuned ring at 15 and 40 Hz, beam 5, two and six free dampers each
    side, multipliers drawn at random (the near ones apart from the tied): the barrier,
    its gradient and its Hessian that ``partly_tied_relaxation`` forms from the Fourier
    spectrum and the low-rank part are those of the dense ``Z`` (numpy's ``slogdet`` and
    ``tr(Z^-1 B_a)``, ``tr(Z^-1 B_a Z^-1 B_b)`` of the full forms)."""
    from mcfric.core import partly_tied_relaxation as pt
    from mcfric.core.relaxation import _assemble, buffers, shifted

    from .test_certified import F_LIM, K_MAX

    rng = np.random.default_rng(5)
    model = mcfric.disk(16, 2, 1.1)
    f = np.array([15.0, 40.0])
    arrays = contact_arrays(model, f)
    nd = 16
    lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
    for k in range(len(f)):
        for r in (2, 6):
            G, q0, ylin, H = (x[k] for x in arrays)
            V, idx, S, x, cvec, pos, simplex, grow, ws = buffers(nd, nd, True, False)
            (shift, ys, per, w, LA, GA, BE, k0, near, W, T, pa, pb, Sd,
             gconst) = pt._setup(G, q0, ylin, H, lo, hi, F_LIM, np.int64(5), V, idx, S, x,
                                 cvec, pos, simplex, grow, ws, np.int64(r))
            assert k0 >= 0 and W.shape[1] < T.shape[1]    # banded: some q dependent
            nt, nx = per + 1, 2 * r * per
            v = np.zeros(nt + nx)
            v[:per] = rng.uniform(0.5, 2.0, per) * w[:per]
            v[per - 1] *= 100.0
            v[nt:] = rng.uniform(-0.3, 0.3, nx) * np.tile(v[:per], 2 * r)
            pt._expand(v, w, nd, per, near, shift, x)
            least = shifted(x, shift, V, idx, S, pos, simplex, ws)
            assert np.isfinite(least)
            v[per] = least + 1.0 + abs(least)
            mu = abs(v[per]) / 50.0
            work = pt._work(nd, W.shape[1], T.shape[1], nt)
            got = pt._value(v, mu, per, cvec[shift], LA, GA, BE, k0, W, T, gconst, pa, pb,
                            Sd, work)
            g, Hm = np.empty(nt + nx), np.empty((nt + nx, nt + nx))
            pt._derivatives(v, mu, per, cvec[shift], LA, GA, BE, k0, T, pa, pb, Sd, work,
                            g, Hm)

            # the dense reference: Z and each variable's form assembled in full
            def dense(u, coef):
                pt._expand(u, w, nd, per, near, shift, x)
                Z = np.empty_like(ws[2])
                _assemble(x, coef, V, idx, S, ws[0], ws[1], Z, len(x))
                return Z

            Z = dense(v, 1.0)
            B = [dense(np.eye(nt + nx)[i], 0.0) for i in range(nt + nx)]
            Zi = np.linalg.inv(Z)
            s = v[:per][np.arange(nx) % per] + v[nt:]
            ref = (v[per] / mu - np.linalg.slogdet(Z)[1] - np.log(v[:per]).sum()
                   - np.log(s).sum())
            assert abs(got - ref) <= 1e-9 * abs(ref), (k, r)
            gref = np.array([-np.trace(Zi @ Bi).real for Bi in B])
            gref[per] += 1.0 / mu
            Href = np.array([[np.trace(Zi @ Bi @ Zi @ Bj).real for Bj in B] for Bi in B])
            for d in range(nx):
                f_ = d % per
                gref[f_] -= 1.0 / s[d]
                gref[nt + d] -= 1.0 / s[d]
                for i in (f_, nt + d):
                    for j in (f_, nt + d):
                        Href[i, j] += 1.0 / s[d] ** 2
            gref[:per] -= 1.0 / v[:per]
            Href[np.arange(per), np.arange(per)] += 1.0 / v[:per] ** 2
            np.testing.assert_allclose(g, gref, rtol=1e-7, atol=1e-7 * abs(gref).max())
            np.testing.assert_allclose(Hm, Href, rtol=1e-6, atol=1e-7 * abs(Href).max())


def test_partly_tied_multipliers_bound_a_tuned_ring_from_above():
    """A 16-blade tuned ring, four frequencies: the whole box's upper bound of
    ``max_b |y_b|`` with the multipliers tied but at the dampers next to the beam
    (``near``: two and six each side) lies above 2000 random admissible points per
    frequency (physical-space solves), never below the full relaxation's bound by more
    than its tolerance and at most 15 % (two) or 2 % (six) above it; one relaxation per
    frequency (the other beams take its multipliers turned). A mistuned ring verifies
    nothing: the first beam keeps Eq. 10, and the others, no higher, are not tried."""
    from mcfric.core.box_relaxation import relax_frequencies
    from mcfric.core.branch_bound import force_bounds

    from .test_certified import F_LIM, K_MAX, random_admissible

    f = np.array([15.0, 40.0, 90.0, 140.0])
    n_f = len(f)
    got = {}
    for name, model in (("tuned", mcfric.disk(16, 2, 1.1)),
                        ("mistuned", ring(16, mistuned=True, engine_order=2, F0=1.1))):
        arrays = contact_arrays(model, f)
        for near in ((0, 2, 6) if name == "tuned" else (6,)):
            out = np.empty(n_f)
            stats = np.zeros(4, np.int64)
            beams = np.full((n_f, 16), np.inf)
            relax_frequencies(*arrays, K_MAX, K_MAX, F_LIM, True, np.zeros(n_f),
                              np.zeros(n_f), np.arange(n_f, dtype=np.int64), out,
                              np.full((n_f, 2, 16), np.nan + 0j), beams, stats, True,
                              np.int64(near))
            got[name, near] = out, stats, beams
    full = got["tuned", 0][0]
    for near, slack in ((2, 0.15), (6, 0.02)):
        out, stats, _ = got["tuned", near]
        assert stats[2] == n_f and stats[3] == 0, near
        assert np.all(out >= full * (1 - 1e-3)) and np.all(out <= full * (1 + slack)), near
    model = mcfric.disk(16, 2, 1.1)
    for k, fk in enumerate(f):
        M = random_admissible(model, fk, 2000, 110 + k)
        assert len(M) > 200
        assert M.max() <= got["tuned", 6][0][k], fk
    out, stats, beams = got["mistuned", 6]
    assert stats[3] == stats[2] == n_f
    eq10 = np.empty((n_f, 16))
    for k in range(n_f):
        force_bounds(arrays[2][k], arrays[3][k], F_LIM, eq10[k])
    np.testing.assert_array_equal(beams, eq10)


def test_the_partly_tied_relaxation_declines_what_it_cannot_tie():
    """``partly_tied_upper`` returns ``nan`` (no exception) where the beam's response is
    not finite or ``2 r`` is not below the number of dampers, and ``relax_frequencies``
    runs the full relaxation there: on an 8-blade ring ``near = 6`` gives the bits of
    ``near = 0``."""
    from mcfric.core.box_relaxation import relax_frequencies
    from mcfric.core.partly_tied_relaxation import partly_tied_upper
    from mcfric.core.relaxation import buffers

    from .test_certified import F_LIM, K_MAX

    model = mcfric.disk(16, 2, 1.1)
    G, q0, ylin, H = (x[0] for x in contact_arrays(model, np.array([40.0])))
    lo, hi = np.zeros(16, complex), np.full(16, K_MAX * (1 + 1j))

    def upper(H, r):
        return partly_tied_upper(G, q0, ylin, H, lo, hi, F_LIM, np.int64(5), 0.0,
                                 *buffers(16, 16, True, False), np.zeros(5, np.int64),
                                 np.int64(r))

    assert np.isfinite(upper(H, 2))
    bad = H.copy()
    bad[5, 3] = np.nan
    assert np.isnan(upper(bad, 2))
    assert np.isnan(upper(H, 8))
    model = mcfric.disk(8, 1, 1.1)
    f = np.array([15.0, 80.0])
    arrays = contact_arrays(model, f)
    got = []
    for near in (0, 6):
        out = np.empty(2)
        relax_frequencies(*arrays, K_MAX, K_MAX, F_LIM, True, np.zeros(2), np.zeros(2),
                          np.arange(2, dtype=np.int64), out, np.full((2, 2, 8), np.nan + 0j),
                          np.full((2, 8), np.inf), np.zeros(4, np.int64), True,
                          np.int64(near))
        got.append(out)
    assert np.array_equal(got[0], got[1])


def _failing(real, n_fail, failed):
    """``real`` but for its first ``n_fail`` calls, which return ``failed(*args)``; and
    the list its calls are counted in."""
    calls = []

    def wrapped(*args):
        calls.append(None)
        return failed(*args) if len(calls) <= n_fail else real(*args)
    return wrapped, calls


def test_the_tied_relaxations_walk_back_when_their_last_round_does_not_verify(monkeypatch):
    """Where the last round's multipliers do not verify on the full forms, the tied lower
    relaxation (12-blade ring) and the partly tied upper one (16 blades, ``r = 2``) check
    the rounds before, latest first: the kernels run as Python (``py_func``) with their
    check failing the first one or two times. Each walks back exactly that far and
    returns a bound that still encloses 1000 random admissible points (physical-space
    solves), close to the unpatched one; with every check failing the lower one proves
    nothing (``nan``, uncounted) and the upper one keeps its verified start."""
    from mcfric.core import partly_tied_relaxation as pt
    from mcfric.core import tied_relaxation as tr
    from mcfric.core.relaxation import buffers, forms

    from .test_certified import F_LIM, K_MAX, random_admissible

    f = np.array([40.0, 104.0])
    for nd in (12, 16):
        model = mcfric.disk(nd, nd // 12, 1.1)
        G, q0, ylin, H = contact_arrays(model, f)
        lo, hi = np.zeros(nd, complex), np.full(nd, K_MAX * (1 + 1j))
        for k, fk in enumerate(f):
            M = random_admissible(model, fk, 1000, 120 + k)
            assert len(M) > 100
            if nd == 12:
                args = (G[k], q0[k], ylin[k], H[k], lo, hi, F_LIM, np.inf)
                plain = tr.tied_lower(*args, *buffers(nd, nd, True, True),
                                      np.zeros(5, np.int64))
                for n_fail in (1, 2, 1000):
                    check, calls = _failing(tr.shifted, n_fail, lambda *a: np.nan)
                    monkeypatch.setattr(tr, "shifted", check)
                    stats = np.zeros(5, np.int64)
                    got = tr.tied_lower.py_func(*args, *buffers(nd, nd, True, True), stats)
                    monkeypatch.undo()
                    if n_fail < 1000:
                        assert len(calls) == n_fail + 1 and stats[2] == 1, (fk, n_fail)
                        assert 0.99 * plain < got <= M.min(), (fk, n_fail)
                    else:
                        assert np.isnan(got) and stats[2] == 0 and len(calls) == stats[1]
            else:
                args = (G[k], q0[k], ylin[k], H[k], lo, hi, F_LIM, np.int64(5), 0.0)
                _, ys = forms(*args[:8], *buffers(nd, nd, True, False)[:8])
                plain = math.sqrt(ys * pt.partly_tied_upper(
                    *args, *buffers(nd, nd, True, False), np.zeros(5, np.int64),
                    np.int64(2)))
                for n_fail in (1, 2, 1000):
                    check, calls = _failing(pt._kept, n_fail, lambda *a: (False, a[-1]))
                    monkeypatch.setattr(pt, "_kept", check)
                    stats = np.zeros(5, np.int64)
                    got = math.sqrt(ys * pt.partly_tied_upper.py_func(
                        *args, *buffers(nd, nd, True, False), stats, np.int64(2)))
                    monkeypatch.undo()
                    assert stats[2] == 1 and M.max() <= got, (fk, n_fail)
                    if n_fail < 1000:
                        assert len(calls) == n_fail + 1, (fk, n_fail)
                        assert plain <= got < 1.02 * plain, (fk, n_fail)
                    else:
                        assert got > 2 * plain and len(calls) == stats[1]


def _blocks_dense(G, dF):
    """``I + G dF`` of the multi-harmonic Newton step as one real matrix, written plainly."""
    n_h, nd, _ = G.shape
    m2 = 2 * n_h
    J = np.eye(nd * m2)
    for j in range(nd):
        for l in range(nd):
            for h in range(n_h):
                g = G[h, j, l]
                rot = np.array([[g.real, -g.imag], [g.imag, g.real]])
                J[j * m2 + 2 * h:j * m2 + 2 * h + 2, l * m2:(l + 1) * m2] += \
                    rot @ dF[l, 2 * h:2 * h + 2]
    return J


@pytest.mark.parametrize("layout", ["chain", "ring"])
def test_the_multi_harmonic_newton_step_of_chains_and_rings_is_a_dense_solve(layout):
    """The block Thomas step of a chain and the bordered one of a ring against numpy's
    dense solve: random receptances of the layout, damper Jacobians general, stuck
    (``c I``) or force-free (0), 2 to 11 dampers (2: the ring's two couplings in one
    entry), 1 to 4 harmonics."""
    from mcfric.core import multi_harmonic as mh
    code = mh.CHAIN if layout == "chain" else mh.RING
    rng = np.random.default_rng(5 + code)
    for _ in range(60):
        nd = int(rng.integers(2, 12))
        n_h = int(rng.integers(1, 5))
        m2 = 2 * n_h
        G = np.zeros((n_h, nd, nd), complex)
        for j in range(nd):
            for l in (j - 1, j, j + 1):
                if code == mh.RING or 0 <= l < nd:
                    G[:, j, l % nd] += rng.normal(size=n_h) + 1j * rng.normal(size=n_h)
        dF = 0.5 * rng.normal(size=(nd, m2, m2))
        kind = rng.integers(0, 3, nd)
        dF[kind == 1] = np.eye(m2) * rng.uniform(0.1, 2)
        dF[kind == 2] = 0.0
        R = rng.normal(size=(nd, n_h)) + 1j * rng.normal(size=(nd, n_h))
        n = nd * m2
        dx = np.zeros(n)
        ok = mh._newton_step(G, dF, R, np.zeros((3 * n + m2, m2)), np.zeros(n, np.int64),
                             dx, nd, n_h, code)
        rhs = -np.column_stack([R.real, R.imag]).reshape(nd, 2, n_h).transpose(0, 2, 1)
        ref = np.linalg.solve(_blocks_dense(G, dF), rhs.ravel())
        assert ok
        assert np.max(np.abs(dx - ref)) <= 1e-9 * np.max(np.abs(ref)), (nd, n_h)
