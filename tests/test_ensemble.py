"""The ensemble driver: identical results for any threads / chunking / interruption,
stored values equal to independent re-solves, honest non-convergence counts, refusals."""

import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time
import tomllib
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest

from mcfric import config, ensemble, hbm
from mcfric.ensemble import Interrupted, RunError
from mcfric.store import partial_path

ROOT = Path(__file__).resolve().parents[1]


def two_beam(samples=130, n=30, **sections):
    raw = {"model": {"preset": "two-beam"}, "frequency": {"n": n},
           "sampling": {"samples": samples, "seed": 11}}
    for dotted, v in sections.items():
        sec, key = dotted.split("__")
        raw.setdefault(sec, {})[key] = v
    return config.load(raw)


def run(cfg, path, **kw):
    return ensemble.run(cfg, path, progress=False, **kw)


def load(path, names=None):
    """The file's datasets (every root dataset by default: the peaks, folds and the
    harmonic indicator are computed on threads too), by name."""
    with h5py.File(path, "r") as h5:
        names = names or [k for k in h5 if isinstance(h5[k], h5py.Dataset)]
        return {k: h5[k][...] for k in names if k in h5}


def assert_bitwise(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
        assert a[k].tobytes() == b[k].tobytes(), f"{k} differs"


def contract_uniforms(seed, i, n):
    child = np.random.SeedSequence(seed).spawn(i + 1)[i]
    return np.random.Generator(np.random.PCG64(child)).random(n) + 2.0 ** -54


def test_threads_and_chunk_sizes_do_not_change_results(tmp_path):
    base = two_beam()
    ref = run(base.replace("run.threads", 1), tmp_path / "ref.h5")
    assert ref.complete and ref.samples_done == 130
    want = load(tmp_path / "ref.h5")
    for i, (threads, chunk) in enumerate([(2, 0), (2, 1), (1, 64), (2, 64), (2, 1000)]):
        cfg = base.replace("run.threads", threads).replace("run.chunk", chunk)
        run(cfg, tmp_path / f"r{i}.h5")
        assert_bitwise(load(tmp_path / f"r{i}.h5"), want)


def test_eight_beam_mistuned_threads_chunks_and_independent_resolve(tmp_path):
    # the bounds are searched, not certified: nothing here reads them, and two
    # certifications were nearly all of the time
    raw = {"frequency": {"n": 20}, "sampling": {"samples": 24, "seed": 5, "mistuning": 0.02,
                                                "mistuning_per": "mode"},
           "bounds": {"certify": False}}
    base = config.load(raw)
    run(base.replace("run.threads", 1).replace("run.chunk", 24), tmp_path / "a.h5")
    run(base.replace("run.threads", 2).replace("run.chunk", 5), tmp_path / "b.h5")
    a, b = load(tmp_path / "a.h5"), load(tmp_path / "b.h5")
    assert {"modal_freq_hz", "peak_metric", "harmonic_indicator"} <= a.keys()
    assert_bitwise(a, b)
    # sample 17 solved on its own, from its stored parameters
    m, f = base.model(), base.frequencies()
    i = 17
    r = hbm.solve(m, f, a["mu0"][i:i + 1], a["kc"][i:i + 1], a["N0"][i:i + 1],
                  modal_freq_hz=a["modal_freq_hz"][i:i + 1])
    assert r.response[0].tobytes() == a["response"][i].tobytes()
    nominal = m.modal_arrays()[0]
    assert not np.allclose(a["modal_freq_hz"][i], nominal)


def test_stored_sample_equals_its_contract_parameters_and_a_lone_solve(tmp_path):
    cfg = two_beam()
    run(cfg, tmp_path / "r.h5")
    d = load(tmp_path / "r.h5")
    m, f = cfg.model(), cfg.frequencies()
    with h5py.File(tmp_path / "r.h5", "r") as h5:
        np.testing.assert_array_equal(h5["frequency"][...], np.linspace(10, 150, 30))
    for i in (0, 57, 129):
        u = contract_uniforms(11, i, 3)                 # mu0, kc, N0 of one damper
        assert d["mu0"][i, 0] == u[0]
        assert d["kc"][i, 0] == 15000.0 * u[1]
        assert d["N0"][i, 0] == 0.5
        r = hbm.solve(m, f, u[0], 15000.0 * u[1], 0.5)
        assert r.response[0].tobytes() == d["response"][i].tobytes()
        # the metric is max over beams of |y| (docs/theory.md, "Response metric"), computed
        # here independently
        y = d["response"][i]
        np.testing.assert_allclose(d["metric"][i], np.sqrt(y.real ** 2 + y.imag ** 2)
                                   .max(axis=1), rtol=1e-15)
        np.testing.assert_array_equal(d["converged"][i], r.status[0] >= 0)
    # the driver's fast metric is bitwise the hbm definition
    assert d["metric"].tobytes() == hbm.response_metric(d["response"], f).tobytes()


def test_metric_only_and_other_metric(tmp_path):
    full = two_beam(metric__quantity="velocity", metric__beams=[2])
    run(full, tmp_path / "full.h5")
    slim = full.replace("output.keep_response", False)
    run(slim, tmp_path / "slim.h5")
    a, b = load(tmp_path / "full.h5"), load(tmp_path / "slim.h5")
    assert "response" in a and "response" not in b
    assert a["metric"].tobytes() == b["metric"].tobytes()
    omega = 2 * np.pi * full.frequencies()
    np.testing.assert_allclose(a["metric"], np.abs(a["response"][:, :, 1]) * omega,
                               rtol=1e-15)
    assert a["metric"].tobytes() == hbm.response_metric(a["response"], full.frequencies(),
                                                        "velocity", [1]).tobytes()
    with h5py.File(tmp_path / "slim.h5") as h5:
        assert h5["metric"].attrs["units"] == "m/s"


def test_non_converged_points_are_flagged_and_counted(tmp_path):
    # one Newton iteration per attempt on eight beams slipping: some points must fail
    cfg = config.load({"model": {"preset": "eight-beam"}, "frequency": {"n": 40},
                       "sampling": {"samples": 20, "seed": 11,
                                    "mu0": {"dist": "fixed", "value": 0.1},
                                    "kc": {"dist": "fixed", "value": 6000.0}},
                       "bounds": {"enabled": False}, "solver": {"max_iter": 1}})
    s = run(cfg, tmp_path / "r.h5")
    d = load(tmp_path / "r.h5")
    bad = int(np.count_nonzero(~d["converged"]))
    assert bad > 0
    assert s.not_converged == bad
    assert np.isnan(d["metric"]).sum() == bad
    assert np.all(np.isnan(d["response"][~d["converged"]]))
    with h5py.File(tmp_path / "r.h5") as h5:
        assert h5.attrs["n_not_converged"] == bad
    assert f"not converged: {bad:,} points" in s.text()


def test_ctrl_c_keeps_finished_chunks_and_resume_is_bitwise(tmp_path, monkeypatch):
    cfg = two_beam(samples=100, run__chunk=10, run__checkpoint_s=0.0)
    run(cfg.replace("run.chunk", 1000), tmp_path / "straight.h5")
    calls = {"n": 0}
    real = hbm.solve

    def flaky(*a, **k):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(ensemble.hbm, "solve", flaky)
    out = tmp_path / "r.h5"
    with pytest.raises(Interrupted) as e:
        run(cfg, out)
    assert e.value.summary.samples_done == 30 and not e.value.summary.complete
    assert not out.exists() and partial_path(out).exists()
    monkeypatch.setattr(ensemble.hbm, "solve", real)
    with pytest.raises(RunError, match="--resume"):
        run(cfg, out)
    s = run(cfg.replace("run.chunk", 7), out, resume=True)
    assert s.complete and s.samples_this_session == 70
    assert_bitwise(load(out), load(tmp_path / "straight.h5"))


def test_writer_failure_surfaces_and_leaves_only_a_partial(tmp_path, monkeypatch):
    from mcfric import store

    def full(self, start, arrays):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(store.Store, "write", full)
    from mcfric.store.lock import lock_path

    with pytest.raises(OSError, match="No space"):
        run(two_beam(samples=40, run__chunk=10), tmp_path / "r.h5")
    assert not (tmp_path / "r.h5").exists()
    # the partial file is kept (the remedy: free space, then --resume) and the lock gone
    assert partial_path(tmp_path / "r.h5").exists()
    assert not lock_path(tmp_path / "r.h5").exists()


def test_refusals_and_the_already_done_case(tmp_path):
    cfg = two_beam(samples=20, n=10)
    out = tmp_path / "r.h5"
    run(cfg, out)
    again = run(cfg.replace("run.threads", 1), out)        # [run] differs: same run
    assert again.already_complete and again.samples_this_session == 0
    with pytest.raises(RunError, match="first difference: sampling.seed"):
        run(cfg.replace("sampling.seed", 1), out)
    s = run(cfg.replace("sampling.seed", 1), out, force=True)
    assert s.complete
    assert json.loads(h5py.File(out, "r").attrs["config_json"])["sampling"]["seed"] == 1
    with pytest.raises(RunError, match="does not exist"):
        run(cfg, tmp_path / "nodir" / "r.h5")


def test_a_directory_as_the_output_is_refused_before_the_work_even_with_force(tmp_path):
    """With ``force=True`` a directory at the output path ran the whole ensemble, then
    failed at the rename (IsADirectoryError) and left its ``.partial`` behind."""
    cfg = two_beam(samples=4, n=5)
    out = tmp_path / "d.h5"
    out.mkdir()
    for kw in ({}, {"force": True}, {"resume": True}):
        with pytest.raises(RunError, match=r"d\.h5 is a directory, not a results file; "
                                           r"choose another path$"):
            run(cfg, out, **kw)
    assert [p.name for p in tmp_path.iterdir()] == ["d.h5"] and not any(out.iterdir())
    # Path(None) was a TypeError from os, Path("") the current directory
    for bad in (None, 5, ""):
        with pytest.raises(RunError, match="^path: expected a results file's path"):
            run(cfg, bad)


def test_a_groups_callable_of_the_wrong_shape_is_named_and_writes_nothing(tmp_path):
    """Its result failed inside the store: "too many values to unpack (expected 2)"."""
    cfg = two_beam(samples=4, n=5)
    for made in ({"g": "bad"}, 5, {"g": ({}, {}, {})}):
        with pytest.raises(RunError, match="^groups: the callable must return"):
            run(cfg, tmp_path / "r.h5", groups=lambda made=made: made)
        assert list(tmp_path.iterdir()) == []
    assert run(cfg, tmp_path / "r.h5", groups=lambda: {}).complete



def test_a_spec_changed_behind_its_configuration_is_refused_before_any_file(tmp_path):
    """``dataclasses.replace`` on a RunSpec skips every check of the configuration (0
    threads, 0 samples, a NaN frequency went as far as the kernel or the writer, leaving a
    partial file that blocked the corrected call) and the file would record the
    configuration, not the run: refused, nothing written. A string is not loaded."""
    import dataclasses
    spec = two_beam(samples=4, n=10, bounds__enabled=False).spec
    out = tmp_path / "r.h5"
    f = np.array(spec.freq_hz)
    f[3] = np.nan
    for bad in (dataclasses.replace(spec, samples=0),
                dataclasses.replace(spec, freq_hz=f),
                dataclasses.replace(spec, execution=dataclasses.replace(spec.execution,
                                                                        threads=0))):
        with pytest.raises(ValueError, match="spec: differs from its own configuration"):
            run(bad, out)
    with pytest.raises(TypeError, match=r"load it first: mcfric.config.load\('two-beam'\)"):
        run("two-beam", out)
    # a Config built by hand is checked as well
    data = json.loads(spec.config_json)
    data["frequency"]["f_min"] = float("nan")
    with pytest.raises(ValueError, match="frequency.f_min"):
        run(config.Config(data), out)
    with pytest.raises(TypeError, match="progress: expected True or False"):
        ensemble.run(spec, out, progress="no")
    assert list(tmp_path.iterdir()) == []
    assert run(spec, out).complete              # the spec itself is its configuration's

@contextlib.contextmanager
def ctrl_c_at_chunk_3(monkeypatch):
    """Within the block, Ctrl-C while the third chunk of a run is solved."""
    real = hbm.solve
    calls = {"n": 0}

    def stop_at_3(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt
        return real(*a, **k)

    monkeypatch.setattr(ensemble.hbm, "solve", stop_at_3)
    try:
        yield
    finally:
        monkeypatch.setattr(ensemble.hbm, "solve", real)


def interrupt_at_chunk_3(monkeypatch, cfg, out, **kw):
    """Run ``cfg`` into ``out`` with Ctrl-C while its third chunk is solved."""
    with ctrl_c_at_chunk_3(monkeypatch), pytest.raises(Interrupted):
        run(cfg, out, **kw)


def test_an_interrupt_that_cuts_the_last_put_short_neither_hangs_nor_loses(tmp_path,
                                                                              monkeypatch):
    """Ctrl-C can land while the main thread hands the writer its stop marker; the
    writer then waited for it forever and the run hung with its chunks uncommitted
    (`checkpoint_s > 0`, 3 of 14 tries). The writer now also stops when told to by an
    event, and commits what it wrote."""
    cfg = two_beam(samples=50, n=10, run__chunk=10, run__checkpoint_s=1000.0)
    out = tmp_path / "r.h5"
    real_put = ensemble._put

    def lost_marker(q, item, writer, err):
        if item is None:
            raise KeyboardInterrupt          # the signal lands inside this put
        return real_put(q, item, writer, err)

    monkeypatch.setattr(ensemble, "_put", lost_marker)
    done = []
    with ctrl_c_at_chunk_3(monkeypatch):
        t = threading.Thread(target=lambda: done.append(
            pytest.raises(Interrupted, run, cfg, out)), daemon=True)
        t.start()
        t.join(timeout=120)
    assert not t.is_alive(), "the run hung after the interrupt"
    assert len(done) == 1                          # it stopped as interrupted
    with h5py.File(partial_path(out), "r") as h5:
        assert int(h5["done"][()].sum()) == 20            # the two chunks written before


def test_a_run_with_overrides_resumes_from_its_own_configuration(tmp_path, monkeypatch,
                                                                   capsys):
    """`mcfric config FILE.partial` prints the configuration the run was made with
    (command-line overrides included); that file resumes it to the file a straight run
    writes."""
    from mcfric import cli

    argv = ["run", "two-beam", "--samples", "50", "--n-freq", "10", "--chunk", "10",
            "--no-bounds", "--no-figure", "--no-progress"]
    out = tmp_path / "r.h5"
    with ctrl_c_at_chunk_3(monkeypatch):
        assert cli.main(argv + ["-o", str(out)]) == cli.EXIT_INTERRUPTED
    capsys.readouterr()
    # the preset alone is another run: refused
    assert cli.main(["run", "two-beam", "-o", str(out), "--resume", "--no-figure"]) == 2
    err = capsys.readouterr().err
    # both values, and the remedy (the one the next lines follow) before --force
    assert "another configuration (frequency.n = 10 there, 1000 here)" in err
    assert err.index(f"mcfric config {partial_path(out)}") < err.index("--force")
    assert cli.main(["config", str(partial_path(out))]) == 0
    toml = tmp_path / "run.toml"
    toml.write_text(capsys.readouterr().out)
    assert cli.main(["run", str(toml), "-o", str(out), "--resume", "--no-figure",
                     "--no-progress"]) == 0
    assert cli.main(argv + ["-o", str(tmp_path / "straight.h5")]) == 0
    assert_bitwise(load(out), load(tmp_path / "straight.h5"))


def test_info_on_a_partial_names_its_live_writer(tmp_path, monkeypatch, capsys):
    """`mcfric info FILE.partial` told to continue with --resume even while a run was
    writing it (the lock would refuse that run): it names the writer instead."""
    from mcfric import cli

    cfg = two_beam(samples=50, n=10, run__chunk=10)
    out = tmp_path / "r.h5"
    interrupt_at_chunk_3(monkeypatch, cfg, out)
    assert cli.main(["info", str(partial_path(out))]) == 0
    assert "--resume" in capsys.readouterr().out
    code = ("import time\nfrom mcfric.store.lock import OutputLock\n"
            f"OutputLock({str(out)!r}, 'mcfric run').acquire()\n"
            "print('holding', flush=True)\ntime.sleep(120)\n")
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "holding"
        assert cli.main(["info", str(partial_path(out))]) == 0
        text = capsys.readouterr().out
        assert f"being written now by PID {p.pid} on " in text and "(mcfric run)" in text
        assert "--resume" not in text
    finally:
        p.kill()
        p.wait()
        p.stdout.close()
    # a lock whose owner ended blocks nothing and names no one
    assert cli.main(["info", str(partial_path(out))]) == 0
    assert "--resume" in capsys.readouterr().out


def test_resume_refuses_other_config_or_other_solver_code(tmp_path, monkeypatch):
    cfg = two_beam(samples=50, n=10, run__chunk=10, run__checkpoint_s=0.0)
    out = tmp_path / "r.h5"
    interrupt_at_chunk_3(monkeypatch, cfg, out)
    with pytest.raises(RunError,
                       match=r"another configuration \(frequency.n = 10 there, 11 here\)"):
        run(cfg.replace("frequency.n", 11), out, resume=True)
    monkeypatch.setattr(ensemble, "fingerprint", lambda: "0000")
    with pytest.raises(RunError, match=r"cannot resume .*solver code.*\(fingerprint "
                                        r"[0-9a-f]+ vs 0000\); results would mix"):
        run(cfg, out, resume=True)
    monkeypatch.undo()
    assert run(cfg, out, resume=True).complete


def test_an_interrupted_replacement_resumes_and_replaces_the_old_file(tmp_path, monkeypatch):
    """`--force` into a file holding another run, interrupted: `--resume` continues the
    partial file (it was refused because the old file differs) and replaces the file."""
    out = tmp_path / "r.h5"
    run(two_beam(samples=10, n=10), out)                       # the old run
    cfg = two_beam(samples=50, n=12, run__chunk=10, run__checkpoint_s=0.0)
    interrupt_at_chunk_3(monkeypatch, cfg, out, force=True)
    assert partial_path(out).exists()
    with pytest.raises(RunError, match="holds a different run"):      # without --resume
        run(cfg, out)
    s = run(cfg, out, resume=True)
    assert s.complete and s.samples_this_session == 30
    run(cfg, tmp_path / "straight.h5")
    assert_bitwise(load(out), load(tmp_path / "straight.h5"))


@pytest.mark.parametrize("resume", [False, True])
def test_a_partial_file_of_another_kind_is_refused_in_one_line(tmp_path, resume):
    """A valid HDF5 partial without a ``done`` dataset (a bounds file killed before its
    rename): a one-line refusal, not h5py's KeyError."""
    out = tmp_path / "z.h5"
    with h5py.File(partial_path(out), "w") as h5:
        h5.attrs["x"] = 1
    with pytest.raises(RunError, match=r"not an mcfric results file \(no 'done' dataset\)"):
        run(two_beam(samples=5, n=5), out, resume=resume)
    assert not out.exists()


def test_resume_without_a_partial_file_just_runs(tmp_path):
    s = run(two_beam(samples=10, n=10), tmp_path / "r.h5", resume=True)
    assert s.complete and s.samples_this_session == 10


def test_memory_does_not_grow_with_samples(tmp_path):
    # imports and caches first, once
    run(two_beam(samples=64, n=50, run__chunk=64), tmp_path / "warm.h5")

    def peak(samples):
        cfg = two_beam(samples=samples, n=50, run__chunk=64)
        tracemalloc.start()
        run(cfg, tmp_path / f"m{samples}.h5")
        _, p = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        return p

    small, large = peak(256), peak(4096)
    assert large < 1.5 * small + 2e6, (small, large)


def test_sigkill_mid_run_then_resume_is_bitwise_identical(tmp_path):
    """A real `kill -9` of `python -m mcfric run` after some chunks, then --resume."""
    toml = tmp_path / "cfg.toml"
    toml.write_text('[model]\npreset = "two-beam"\n[frequency]\nn = 200\n'
                    '[sampling]\nsamples = 3000\nseed = 7\n'
                    '[run]\nchunk = 1\ncheckpoint_s = 0.0\n')
    out = tmp_path / "k.h5"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    cmd = [sys.executable, "-m", "mcfric", "run", str(toml), "-o", str(out),
           "--no-progress", "--no-figure"]
    err = tmp_path / "stderr.txt"
    with open(err, "wb") as fh:
        p = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=fh)
    done, deadline = 0, time.monotonic() + 600        # allows a numba compile
    try:
        while p.poll() is None and time.monotonic() < deadline:
            try:
                with h5py.File(partial_path(out), "r", locking=False) as h5:
                    done = int(h5["done"][...].sum())
            except (OSError, KeyError):
                pass
            if done >= 150:
                p.send_signal(signal.SIGKILL)
                break
            time.sleep(0.01)
    finally:
        if p.poll() is None and done < 150:
            p.kill()
        p.wait()
    assert p.returncode == -signal.SIGKILL, err.read_text()
    assert not out.exists()                            # nothing that looks complete
    with h5py.File(partial_path(out), "r") as h5:
        assert h5.attrs["complete"] == 0
        left = int(h5["done"][...].sum())
    assert 150 <= left < 3000
    r = subprocess.run(cmd + ["--resume", "--chunk", "64", "--threads", "1"], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "wall time" in r.stdout and str(out) in r.stdout
    cfg = config.load(toml, {"run.chunk": (5000, "--chunk")})
    run(cfg, tmp_path / "straight.h5")
    assert_bitwise(load(out), load(tmp_path / "straight.h5"))


def test_results_file_opens_with_h5py_and_xarray_with_labelled_dims(tmp_path):
    import numba
    import xarray as xr

    import mcfric

    cfg = two_beam(samples=12, n=9, sampling__mistuning=0.01)
    out = tmp_path / "r.h5"
    run(cfg, out)
    with h5py.File(out, "r") as h5:
        labels = {name: tuple(d[0].name.lstrip("/") for d in h5[name].dims)
                  for name in ("response", "metric", "converged", "mu0", "kc", "N0",
                               "modal_freq_hz")}
        assert h5.attrs["numba_version"] == numba.__version__
        assert h5.attrs["mcfric_version"] == mcfric.__version__
        # the package says the version it is installed as
        pyproject = Path(__file__).parents[1] / "pyproject.toml"
        assert mcfric.__version__ == tomllib.loads(pyproject.read_text())["project"]["version"]
        assert h5.attrs["seed"] == 11 and h5.attrs["complete"] == 1
        assert config.validate(tomllib.loads(h5.attrs["config"])).data == cfg.data
    with xr.open_dataset(out, engine="h5netcdf") as ds:
        for name, dims in labels.items():
            assert ds[name].dims == dims
        assert ds["response"].dims == ("sample", "frequency", "beam")
        assert ds["mu0"].dims == ("sample", "damper")
        assert ds["modal_freq_hz"].dims == ("sample", "beam", "mode")
        np.testing.assert_array_equal(ds["frequency"].values, cfg.frequencies())
        assert ds["frequency"].attrs["units"] == "Hz"
        np.testing.assert_array_equal(ds["beam"].values, [1, 2])
        np.testing.assert_array_equal(ds["sample"].values, np.arange(12))
        np.testing.assert_array_equal(ds["damper"].attrs["beam_b"], [2])
        assert ds["response"].dtype == np.complex128 and ds["converged"].dtype == bool
        assert int(ds["done"].sum()) == 12
    with mcfric.open_results(out) as ds:
        m = ds["metric"].sel(frequency=cfg.frequencies()[4]).values
        assert m.shape == (12,) and np.all(m > 0)
