"""Outputs that never lie: one owner per output, space checked before work, failures that
leave a resumable ``.partial``, and no command silently replacing another's output.

The adversarial cases are tables (``BAD_RUNS``, ``OVERWRITES``): add a row when a new
defect is found.
"""

import errno
import json
import os
import subprocess
import sys
import textwrap

import h5py
import numpy as np
import pytest

from mcfric import cli, ensemble, run_file, store
from mcfric.cli.inputs import load_config
from mcfric.cli.parser import build_parser
from mcfric.store import Store, writer
from mcfric.store.groups import groups_bytes
from mcfric.store.lock import OutputLock, lock_path

SMALL = ["two-beam", "--samples", "12", "--n-freq", "20", "--no-progress", "--no-figure"]


def holder(path):
    """A separate process that owns ``path`` until killed; returns it once it holds."""
    code = textwrap.dedent(f"""
        import time
        from mcfric.store.lock import OutputLock
        OutputLock({str(path)!r}, "test holder").acquire()
        print("holding", flush=True)
        time.sleep(120)
    """)
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "holding"
    return p


def stop(p):
    p.kill()
    p.wait()
    p.stdout.close()


def snapshot(directory):
    return {p.name: p.read_bytes() for p in sorted(directory.iterdir()) if p.is_file()}


@pytest.mark.parametrize("extra", [["--force"], ["--resume"], []])
def test_a_second_writer_is_refused_and_changes_nothing(tmp_path, capsys, extra):
    out = tmp_path / "same.h5"
    part = tmp_path / "same.h5.partial"
    part.write_bytes(b"another run's partial file")
    p = holder(out)
    try:
        before = snapshot(tmp_path)
        rc = cli.main(["run", *SMALL, "-o", str(out), *extra])
        err = capsys.readouterr().err.strip()
        assert rc == 2
        assert f"PID {p.pid}" in err and "test holder" in err and len(err.splitlines()) == 1
        assert snapshot(tmp_path) == before          # nothing deleted, renamed or written
        rc = cli.main(["bounds", "two-beam", "--n-freq", "20", "-o", str(out), "--no-figure"])
        assert rc == 2 and "being written by" in capsys.readouterr().err
        assert snapshot(tmp_path) == before
    finally:
        stop(p)


def test_an_engine_order_sweep_names_the_writer_of_any_order(tmp_path, capsys):
    """The sweep checks every order's files before the first order runs, under each
    order's lock: a writer of the second order is named, and nothing is written."""
    (tmp_path / "sweep.toml").write_text(
        '[model]\npreset = "disk-24"\nn_beams = 6\n[frequency]\nn = 20\n'
        '[sampling]\nsamples = 4\n[peaks]\nenabled = false\n[bounds]\ncertify = false\n'
        '[excitation]\nengine_orders = [1, 2]\n')
    (tmp_path / "s-eo2.h5.partial").write_bytes(b"another run's partial file")
    p = holder(tmp_path / "s-eo2.h5")
    try:
        before = snapshot(tmp_path)
        rc = cli.main(["run", str(tmp_path / "sweep.toml"), "-o", str(tmp_path / "s.h5"),
                       "--no-progress", "--no-figure"])
        err = capsys.readouterr().err.strip()
        assert rc == 2 and f"PID {p.pid}" in err and len(err.splitlines()) == 1, err
        assert snapshot(tmp_path) == before
    finally:
        stop(p)


def test_a_stale_lock_of_a_killed_run_blocks_nobody(tmp_path, capsys):
    out = tmp_path / "r.h5"
    p = holder(out)
    stop(p)                                          # SIGKILL
    assert lock_path(out).exists()                   # left behind by the dead owner
    assert cli.main(["run", *SMALL, "-o", str(out)]) == 0
    assert out.exists() and not lock_path(out).exists()


def test_the_lock_is_taken_once_per_process_and_released(tmp_path):
    out = tmp_path / "r.h5"
    with OutputLock(out, "first"):
        with pytest.raises(ensemble.RunError, match="being written by"):
            ensemble.run(load_config(build_parser().parse_args(["run", *SMALL])).spec, out)
    assert not lock_path(out).exists()
    assert not list(tmp_path.iterdir())


def test_a_refused_run_prints_its_one_line_and_nothing_on_stdout(tmp_path, capsys,
                                                                 monkeypatch):
    """A run refused for its files (another run there, a partial without --resume, no
    room) printed its header on stdout first: the docs promise one line on stderr. The
    header now comes once the run is accepted."""
    import shutil

    out = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL, "-o", str(out)]) == 0
    assert capsys.readouterr().out.startswith("mcfric run: two-beam")
    refused = [["run", *SMALL, "--seed", "3", "-o", str(out)]]        # another run there
    (tmp_path / "p.h5.partial").write_bytes(out.read_bytes())
    refused.append(["run", *SMALL, "-o", str(tmp_path / "p.h5")])     # a partial, no --resume
    for argv in refused:
        assert cli.main(argv) == 2
        o, e = capsys.readouterr()
        assert o == "" and len(e.strip().splitlines()) == 1, (argv, o, e)
    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda p: real(p)._replace(free=writer.MIN_FREE + (200 << 10)))
    assert cli.main(["run", *SMALL, "--samples", "300", "-o", str(tmp_path / "s.h5")]) == 2
    o, e = capsys.readouterr()
    assert o == "" and "free" in e and len(e.strip().splitlines()) == 1, (o, e)
    with pytest.raises(TypeError, match="started: expected None or a callable"):
        ensemble.run(load_config(build_parser().parse_args(["run", *SMALL])),
                     tmp_path / "t.h5", started="header")


def test_no_space_is_refused_before_any_work(tmp_path, capsys, monkeypatch):
    import shutil

    out = tmp_path / "r.h5"
    real = shutil.disk_usage
    # above the floor every results file needs (writer.MIN_FREE, and the bounds group
    # written at creation), below this run's size
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda p: real(p)._replace(free=writer.MIN_FREE + (200 << 10)))
    argv = ["run", *SMALL, "--samples", "300", "-o", str(out)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "needs" in err and "free" in err and "--skip-space-check" in err
    assert not list(tmp_path.iterdir())
    assert cli.main([*argv, "--skip-space-check"]) == 0
    # below the floor even --skip-space-check stops (HDF5 out of space at creation
    # crashed the process): one line, nothing left, and before the bounds' work
    out.unlink()
    import mcfric.bounds

    computed = []
    real_bounds = mcfric.bounds.from_spec
    monkeypatch.setattr(mcfric.bounds, "from_spec",
                        lambda *a, **k: computed.append(1) or real_bounds(*a, **k))
    monkeypatch.setattr(shutil, "disk_usage", lambda p: real(p)._replace(free=8 << 10))
    assert cli.main([*argv, "--skip-space-check"]) == 1
    err = capsys.readouterr().err.strip()
    assert "no space for the results file" in err and len(err.splitlines()) == 1, err
    assert not computed
    assert not list(tmp_path.iterdir())
    # past the floor, the bounds group written at creation must fit too (its size is
    # known before the bounds are computed)
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda p: real(p)._replace(free=writer.MIN_FREE + (4 << 10)))
    assert cli.main([*argv, "--skip-space-check"]) == 1
    err = capsys.readouterr().err.strip()
    assert "no space for the results file" in err and len(err.splitlines()) == 1, err
    assert not computed
    assert not list(tmp_path.iterdir())
    # an old .partial that --force would replace frees only its own blocks: a small one
    # does not lift the floor (it stays, as everything else)
    part = tmp_path / "r.h5.partial"
    part.write_bytes(b"x" * 4096)
    assert cli.main([*argv, "--skip-space-check", "--force"]) == 1
    err = capsys.readouterr().err.strip()
    assert "no space for the results file" in err and len(err.splitlines()) == 1, err
    assert not computed
    assert [q.name for q in tmp_path.iterdir()] == [part.name]


def test_an_old_partial_counts_as_room_only_if_removing_it_frees_its_blocks(tmp_path,
                                                                           monkeypatch):
    """`Store.require_floor` credits the blocks of an old ``.partial`` that `create`
    removes first: a regular file with one link frees them; a symbolic link (the target
    stays) or one of two hard links frees nothing."""
    import shutil

    out = tmp_path / "r.h5"
    part = tmp_path / "r.h5.partial"
    big = tmp_path / "big.bin"
    big.write_bytes(os.urandom(1 << 20))
    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda p: real(p)._replace(free=writer.MIN_FREE - (256 << 10)))
    with pytest.raises(store.StoreError, match="no space for the results file"):
        Store.require_floor(out)                             # nothing to remove
    os.link(big, part)                                       # one of two links
    with pytest.raises(store.StoreError, match="no space"):
        Store.require_floor(out)
    part.unlink()
    part.symlink_to(big)                                     # the target would stay
    with pytest.raises(store.StoreError, match="no space"):
        Store.require_floor(out)
    part.unlink()
    shutil.copyfile(big, part)                               # removed, 1 MiB freed
    assert part.stat().st_blocks * 512 >= 1 << 20
    Store.require_floor(out)
    with pytest.raises(store.StoreError, match="no space"):  # but not 1 MiB more
        Store.require_floor(out, extra_bytes=1 << 20)


@pytest.mark.parametrize("preset", ["two-beam", "eight-beam"])
def test_the_bounds_group_fits_the_room_checked_before_it_is_computed(preset):
    """The room a run asks for before computing the bounds (``group_bytes``: datasets,
    values per frequency and damper, attributes) holds the certified bounds group."""
    import mcfric
    from mcfric.bounds import compute_bounds, force_limit, to_group
    from mcfric.bounds import results as bounds_results

    model = mcfric.preset(preset, 1.1)
    f = np.array([16.0, 40.0, 90.0])
    B = compute_bounds(model, f, 15000.0, F_lim=force_limit(1.0, 0.5))
    variables, attrs = to_group(B)
    assert B.certificate is not None
    assert len(variables) <= bounds_results._DATASETS
    per_freq = sum(np.asarray(a).nbytes for _, a, _ in variables.values()) / len(f)
    assert per_freq <= bounds_results._PER_FREQ + bounds_results._PER_DAMPER * model.n_dampers
    assert sum(len(str(v)) for v in attrs.values()) <= 8192
    assert groups_bytes({"bounds": (variables, attrs)}) <= bounds_results.group_bytes(
        len(f), model.n_dampers)


def test_the_size_estimate_is_the_file_size(tmp_path):
    """The estimate that the space check uses against the real file (within metadata)."""
    out = tmp_path / "r.h5"
    args = build_parser().parse_args(["run", "two-beam", "--samples", "300", "--n-freq",
                                     "200"])
    spec = load_config(args).spec
    ensemble.run(spec, out, progress=False)
    size = out.stat().st_size
    assert 0.85 * size <= run_file.output_bytes(spec) <= size


def test_the_memory_check_counts_the_dense_fallbacks_scratch(monkeypatch):
    """One point of a 3000-blade ring: its output is kilobytes, but each thread's batch
    holds the dense fallback's scratch, 40 bytes per damper pair (0.36 GB each here),
    which the check did not count."""
    import mcfric
    from mcfric import config, memory

    model = config.load("disk-72").replace("model.n_beams", 3000).spec.model
    monkeypatch.setattr(memory, "available", lambda: 3 * 10**8)      # 0.3 GB free
    with pytest.raises(memory.MemoryRefused, match="of memory.*or on fewer threads"):
        mcfric.solve(model, [50.0], 0.3, 6000.0, n_threads=1)
    # a batch per thread, but no more batches than samples: one sample on two threads
    # holds 0.36 GB (it was counted twice), two samples on two threads 0.72 GB
    import numba

    if numba.config.NUMBA_NUM_THREADS >= 2:
        monkeypatch.setattr(memory, "available", lambda: 5 * 10**8)
        assert mcfric.solve(model, [50.0], 0.3, 6000.0, n_threads=2).converged.all()
        with pytest.raises(memory.MemoryRefused, match="of memory"):
            mcfric.solve(model, [50.0], [[0.3], [0.4]], 6000.0, n_threads=2)


def test_a_run_too_large_for_memory_is_refused(tmp_path, capsys, monkeypatch):
    from mcfric import memory

    monkeypatch.setattr(memory, "available", lambda: 10**9)       # 1 GB free
    cfg = tmp_path / "big.toml"
    assert cli.main(["config", "eight-beam"]) == 0
    text = capsys.readouterr().out.replace("n_beams = 8", "n_beams = 8000", 1)
    cfg.write_text(text)
    out = tmp_path / "big.h5"
    assert cli.main(["run", str(cfg), "--samples", "4", "--n-freq", "4", "-o", str(out),
                     "--no-figure"]) == 2
    err = capsys.readouterr().err
    assert "of memory" in err and len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.toml"]


def test_disk_full_mid_run_leaves_a_partial_that_resumes_to_the_same_bits(
        tmp_path, capsys, monkeypatch):
    straight = tmp_path / "straight.h5"
    assert cli.main(["run", *SMALL, "--chunk", "4", "-o", str(straight)]) == 0
    out = tmp_path / "r.h5"
    real = Store.write
    calls = []

    def full(self, *a, **k):
        calls.append(1)
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, *a, **k)

    monkeypatch.setattr(Store, "write", full)
    assert cli.main(["run", *SMALL, "--chunk", "4", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "No space left on device" in err and len(err.splitlines()) == 1
    assert not out.exists() and (tmp_path / "r.h5.partial").exists()
    assert not lock_path(out).exists()
    monkeypatch.setattr(Store, "write", real)
    assert cli.main(["run", *SMALL, "--chunk", "4", "-o", str(out), "--resume"]) == 0
    with h5py.File(out) as a, h5py.File(straight) as b:
        for name in ("response", "metric", "converged", "mu0", "kc", "N0"):
            assert a[name][...].tobytes() == b[name][...].tobytes(), name


# -- no command silently replaces another's output ------------------------------------

def _results(tmp_path):
    res = tmp_path / "results.h5"
    assert cli.main(["run", *SMALL, "-o", str(res)]) == 0
    return res


OVERWRITES = [
    # (argv with {res} = an existing results file, {dir} = the directory, message)
    (["run", *SMALL[:-1], "-o", "{dir}/clash.png"], "both be"),
    (["hbm", "two-beam", "--n-freq", "10", "-o", "{res}"], "is an HDF5 file"),
    (["hbm", "two-beam", "--n-freq", "10", "-o", "{dir}/results.csv"], "is an HDF5 file"),
    (["verify", "two-beam", "--f", "30", "-o", "{res}"], "is an HDF5 file"),
    (["bounds", "two-beam", "--n-freq", "10", "-o", "{res}", "--no-figure"],
     "ensemble's results file"),
    (["plot", "{res}", "-o", "{dir}/other.png"], "is an HDF5 file"),
    (["run", *SMALL, "-o", ""], 'got ""'),
    (["hbm", "two-beam", "-o", ""], 'got ""'),
    (["plot", "{res}", "-o", ""], 'got ""'),
    # a path reads "out.h5/" as "out.h5": the run wrote a file where a directory was meant
    (["run", *SMALL, "-o", "{dir}/out.h5/"], "a directory's name"),
    (["hbm", "two-beam", "--n-freq", "10", "-o", "{dir}/h.csv/"], "a directory's name"),
    (["plot", "{res}", "-o", "{dir}/f.png/"], "a directory's name"),
    # a run on FILE takes FILE.lock as its lock and removes it at the end
    (["run", *SMALL, "-o", "{dir}/next.h5.lock"], "ends in .lock"),
    (["bounds", "two-beam", "--n-freq", "10", "-o", "{dir}/next.lock", "--no-figure"],
     "ends in .lock"),
]


@pytest.mark.parametrize("argv, message", OVERWRITES)
def test_no_output_silently_replaces_another(tmp_path, capsys, argv, message):
    res = _results(tmp_path)
    # an HDF5 file where a figure or CSV would go (e.g. from an older `-o results.png`)
    for name in ("results.png", "other.png", "results.csv"):
        (tmp_path / name).write_bytes(res.read_bytes())
    capsys.readouterr()
    before = snapshot(tmp_path)
    rc = cli.main([a.format(res=res, dir=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1, err
    assert snapshot(tmp_path) == before


def test_bounds_replaces_the_partial_a_killed_bounds_left_and_no_other(tmp_path, capsys):
    """A `mcfric bounds` killed while writing leaves FILE.partial (torn, or without the root
    attributes, which go in last): the next `mcfric bounds -o FILE` replaces it. An
    ensemble's .partial (members a resume would use) or a file that is not HDF5 stays
    refused, untouched."""
    res = _results(tmp_path)
    out = tmp_path / "b.h5"
    part = tmp_path / "b.h5.partial"
    argv = ["bounds", "two-beam", "--n-freq", "10", "--no-figure", "-o", str(out)]
    with h5py.File(part, "w") as h5:                  # killed before the attributes
        h5.create_dataset("freq_hz", data=np.zeros(10))
    torn = res.read_bytes()[:96]                      # killed as the file began
    assert h5py.is_hdf5(part)
    for content in (part.read_bytes(), torn):
        part.write_bytes(content)
        capsys.readouterr()
        assert cli.main(argv) == 0, capsys.readouterr().err
        assert out.exists() and not part.exists() and not lock_path(out).exists()
        assert store.read_attrs(out)["samples"] == 0
        out.unlink()
    for content in (res.read_bytes(), b"notes, not HDF5\n"):
        part.write_bytes(content)
        capsys.readouterr()
        before = snapshot(tmp_path)
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert "b.h5.partial exists" in err and len(err.splitlines()) == 1, err
        assert snapshot(tmp_path) == before


def test_a_figure_beside_another_commands_output_is_not_replaced(tmp_path, capsys):
    """`run -o r.h5` draws r.png; `hbm -o r.csv` would draw r.png too: refused in one
    line before any work, nothing touched; with --no-figure it goes on. The other way
    round the same; once r.csv exists, r.png is its own."""
    hbm = ["hbm", "two-beam", "--n-freq", "8"]
    assert cli.main(["run", *SMALL[:-1], "-o", str(tmp_path / "r.h5")]) == 0
    assert cli.main([*hbm, "-o", str(tmp_path / "s.csv")]) == 0
    capsys.readouterr()
    before = snapshot(tmp_path)
    for argv, beside in ([*hbm, "-o", str(tmp_path / "r.csv")], "r.h5"),\
            (["run", *SMALL[:-1], "-o", str(tmp_path / "s.h5")], "s.csv"):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert f"beside {beside}" in err and len(err.splitlines()) == 1, err
        assert snapshot(tmp_path) == before
    assert cli.main([*hbm, "-o", str(tmp_path / "r.csv"), "--no-figure"]) == 0
    assert snapshot(tmp_path)["r.png"] == before["r.png"]
    assert cli.main([*hbm, "-o", str(tmp_path / "r.csv")]) == 0     # r.csv's own now


@pytest.mark.parametrize("command", [["run", *SMALL], ["bounds", "two-beam", "--n-freq",
                                                        "10", "--no-figure"]])
def test_a_file_of_another_kind_at_the_lock_name_is_neither_emptied_nor_removed(
        tmp_path, capsys, command):
    res = _results(tmp_path)
    (tmp_path / "new.h5.lock").write_bytes(res.read_bytes())
    capsys.readouterr()
    before = snapshot(tmp_path)
    assert cli.main([*command, "-o", str(tmp_path / "new.h5")]) == 2
    err = capsys.readouterr().err.strip()
    assert "is not a lock file" in err and len(err.splitlines()) == 1, err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("name", ["r.h5.lock", "r.h5.partial"])
def test_the_python_api_refuses_a_lock_or_partial_name(tmp_path, name):
    spec = load_config(build_parser().parse_args(["run", *SMALL])).spec
    with pytest.raises(ensemble.RunError, match="choose another name"):
        ensemble.run(spec, tmp_path / name)
    assert not list(tmp_path.iterdir())


TINY = ["--n-freq", "5", "--no-progress"]
REFUSED_BEFORE_WORK = [
    # (argv, {dir} = the directory, holding fig.png/ and c.toml; message)
    (["run", "two-beam", "--samples", "4", *TINY, "-o", "{dir}/fig.h5"], "is a directory"),
    (["bounds", "two-beam", "--no-certify", "--n-freq", "5", "-o", "{dir}/fig.h5"],
     "is a directory"),
    (["hbm", "two-beam", "--n-freq", "5", "-o", "{dir}/fig.csv"], "is a directory"),
    (["hbm", "{dir}/c.toml", "--n-freq", "5", "-o", "{dir}/c.toml", "--no-figure"],
     "would replace the input"),
    (["verify", "{dir}/c.toml", "--f", "30", "-o", "{dir}/c.toml", "--no-figure"],
     "would replace the input"),
    (["run", "two-beam", "--samples", "4", *TINY, "-o", "{dir}/r.h5.partial"],
     "ends in .partial"),
    # a name promising the other format (`mcfric info x.h5` then failed on the CSV)
    (["hbm", "two-beam", "--n-freq", "5", "-o", "{dir}/x.h5"], "this command writes CSV"),
    (["run", "two-beam", "--samples", "4", *TINY, "-o", "{dir}/r.csv"],
     "writes an HDF5 results file; give a name ending in .h5"),
    # --force replaced a device with a results file (as root, /dev/null); a pipe hung
    (["run", "two-beam", "--samples", "4", *TINY, "-o", "{dir}/fifo.h5", "--force"],
     "is not a regular file"),
    # --force won silently and threw a resumable partial away
    (["run", "two-beam", "--samples", "4", *TINY, "-o", "{dir}/r.h5", "--resume",
      "--force"], "--force: discards FILE.partial, --resume continues it"),
    # an empty file read as an empty TOML ran the default ensemble
    (["run", "{dir}/c.toml.h5", "--samples", "4", *TINY], "an empty file, not a TOML"),
    (["verify", "two-beam", "--f", "0.001", "--harmonics", "3"], "--f: at 0.001 Hz"),
    (["verify", "two-beam", "--f", "nan"], "--f:"),
    (["verify", "two-beam", "--f", "20", "--harmonics", "1"], "--harmonics: expected an "
     "odd integer in 3..99"),
    # said "in 1..99" (the run's range) for verify, which needs 3 or more
    (["verify", "two-beam", "--f", "20", "--harmonics", "101"], "--harmonics: expected an "
     "odd integer in 3..99"),
    # a blank name titled the results file and its plots with nothing
    (["run", "{dir}/blank.toml", "--samples", "4", *TINY], "model.name: expected a "
     "non-blank name"),
    (["run", "two-beam", *TINY, "--no-peaks", "--peaks", "3", "-o", "{dir}/r.h5"],
     "--peaks: a setting of the peak refinement; not with --no-peaks"),
    (["bounds", "eight-beam", "--no-certify", "--moments", "-o", "{dir}/b.h5"],
     "--moments: the order of the certification; not with --no-certify"),
    (["run", "two-beam", *TINY, "--no-certify", "--first-order", "-o", "{dir}/r.h5"],
     "--first-order: the order"),
    (["run", "two-beam", *TINY, "--no-bounds", "--moments", "-o", "{dir}/r.h5"],
     "--moments: the order of the certification; not with --no-bounds"),
]


def test_no_bounds_runs_without_them(tmp_path, capsys):
    from mcfric.bounds import read_bounds

    out = tmp_path / "r.h5"
    assert cli.main(["run", "two-beam", "--samples", "4", *TINY, "--no-bounds",
                     "--no-figure", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert read_bounds(out) is None and "bounds" not in store.dataset_names(out)
    assert "searched bounds" not in text and "certified" not in text


@pytest.mark.parametrize("argv, message", REFUSED_BEFORE_WORK)
def test_outputs_that_cannot_be_made_are_refused_before_the_work(tmp_path, capsys,
                                                                  monkeypatch, argv, message):
    """A figure path that is a directory, an output that is the command's own input, a
    results file named like an interrupted one, a frequency too low to integrate: one
    line, exit 2, before any work, nothing written (not even the default directory)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "fig.png").mkdir()
    assert cli.main(["config", "two-beam"]) == 0
    (tmp_path / "c.toml").write_text(capsys.readouterr().out)
    if "c.toml.h5" in " ".join(argv):
        (tmp_path / "c.toml.h5").write_bytes(b"")
    if "fifo.h5" in " ".join(argv):
        os.mkfifo(tmp_path / "fifo.h5")
    if "blank.toml" in " ".join(argv):
        (tmp_path / "blank.toml").write_text('[model]\nname = "  "\n')
    before = snapshot(tmp_path)
    rc = cli.main([a.format(dir=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1, err
    assert snapshot(tmp_path) == before
    assert sorted(p.name for p in tmp_path.iterdir()
                  if p.name not in ("c.toml.h5", "fifo.h5", "blank.toml")) == ["c.toml",
                                                                                 "fig.png"]


def test_bounds_replaces_its_own_bounds_file(tmp_path, capsys):
    out = tmp_path / "b.h5"
    argv = ["bounds", "two-beam", "--n-freq", "10", "-o", str(out), "--no-figure"]
    assert cli.main(argv) == 0
    assert cli.main(argv) == 0
    with h5py.File(out) as h:
        assert np.all(np.isfinite(h["bounds/upper"][...]))


def test_bounds_without_room_for_its_file_is_one_line_and_leaves_nothing(
        tmp_path, capsys, monkeypatch):
    """HDF5 that runs out of space while it closes a file can crash the process (a
    review: exit 139 and a .partial that blocked the name): the room is checked first."""
    import collections
    import shutil

    usage = collections.namedtuple("usage", "total used free")
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage(10**9, 10**9 - 5000, 5000))
    out = tmp_path / "b.h5"
    rc = cli.main(["bounds", "two-beam", "--n-freq", "10", "-o", str(out), "--no-figure"])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and "no space for the file" in err and len(err.splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


def test_a_run_stopped_as_it_renames_its_complete_file_is_finished_by_resume(
        tmp_path, capsys, monkeypatch):
    """Stopped between marking its .partial complete and the rename (a review), a run
    leaves a .partial that `info` calls complete but not renamed, and `--resume`
    renames it: a complete file, nothing recomputed."""
    out = tmp_path / "r.h5"
    argv = ["run", *SMALL, "--no-bounds", "-o", str(out)]
    real = os.replace

    def stopped(a, b):
        if str(a).endswith(".partial"):
            raise KeyboardInterrupt
        return real(a, b)

    monkeypatch.setattr(os, "replace", stopped)
    assert cli.main(argv) == 130
    monkeypatch.undo()
    part = tmp_path / "r.h5.partial"
    assert part.exists() and not out.exists()
    capsys.readouterr()
    assert cli.main(["info", str(part)]) == 0
    assert "complete, but not renamed" in capsys.readouterr().out
    assert cli.main([*argv, "--resume"]) == 0
    assert out.exists() and not part.exists()
    assert store.read_attrs(out)["complete"] == 1
    assert store.read_attrs(out)["samples"] == 12


def test_a_pipe_given_as_a_results_file_is_refused_not_waited_on(tmp_path):
    """A named pipe without a writer: HDF5 would wait on it for ever; a device without
    end as a configuration filled the memory (a review)."""
    fifo = tmp_path / "p.h5"
    os.mkfifo(fifo)
    for argv, words in ((["info", str(fifo)], "not a regular file"),
                        (["plot", str(fifo)], "not a regular file"),
                        (["config", str(fifo)], "not a regular file"),
                        (["verify", str(fifo), "--f", "50", "--member", "0"],
                         "not a regular file"),
                        (["run", "/dev/zero"], "more than 16 MiB")):
        r = subprocess.run([sys.executable, "-m", "mcfric", *argv],
                           capture_output=True, text=True, timeout=120, cwd=tmp_path)
        err = r.stderr.strip()
        assert r.returncode == 2 and words in err, (argv, err)
        assert len(err.splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.h5"]


# -- bad input: one line, the documented exit code, nothing written --------------------

def _edit(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


def _lognormal_kc(text):
    i, j = text.index("[sampling.kc]"), text.index("[sampling.N0]")
    return (text[:i] + '[sampling.kc]\ndist = "lognormal"\nmedian = 6000.0\nsigma = 1000.0\n\n'
            + text[j:])


BAD_RUNS = [
    # (edit of the two-beam configuration, extra arguments, words of the message)
    (lambda t: '"weird\\nkey" = 1\n' + t, [], "weird key: unknown section"),
    (lambda t: _edit(t, "zeta = [0.0017, 0.0071]", "zeta = [0.0, 0.0]"), [],
     "model.table.zeta: the bounds need every mode damped"),
    (lambda t: _edit(t, 'k_max = "auto"', "k_max = 1e308"), [], "bounds.k_max: expected at most"),
    (_lognormal_kc, [], "sampling.kc.sigma"),
    (lambda t: _edit(t, 'name = "two-beam"', 'name = "a\\u0000b"'), [],
     "model.name: expected text without control characters"),
    (lambda t: 'sampling = "x"\n', ["--samples", "4"], "sampling: expected a table"),
    (lambda t: _edit(t, "shapes = [[2.55, 0.99, 0.48], [-1.84, 2.18, 1.42]]",
                     "shapes = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]"), [], "all zero"),
]


@pytest.mark.parametrize("edit, extra, message", BAD_RUNS)
def test_bad_configurations_give_one_line_and_no_file(tmp_path, capsys, edit, extra, message):
    assert cli.main(["config", "two-beam"]) == 0
    cfg = tmp_path / "c.toml"
    cfg.write_text(edit(capsys.readouterr().out))
    rc = cli.main(["run", str(cfg), "--n-freq", "10", "-o", str(tmp_path / "r.h5"),
                   "--no-progress", *extra])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.toml"]


def _damaged(tmp_path, how):
    res = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL, "-o", str(res)]) == 0
    with h5py.File(res, "r+") as h:
        how(h)
    return res


@pytest.mark.parametrize("how, words", [
    (lambda h: h.__delitem__("bounds/K_upper"), "bounds/K_upper is missing"),
    (lambda h: h.__delitem__("bounds/upper_certified"), "bounds/upper_certified is missing"),
    (lambda h: h["bounds"].attrs.__delitem__("F_lim"), "lacks the attribute F_lim"),
    (lambda h: h["bounds"].attrs.__setitem__("k_max_re", "abc"), "bounds/ is not readable"),
])
def test_read_bounds_names_a_damaged_group(tmp_path, how, words):
    """read_bounds alone (as the Python API calls it): a KeyError or ValueError before."""
    from mcfric.bounds import read_bounds

    res = _damaged(tmp_path, how)
    with pytest.raises(store.StoreError) as e:
        read_bounds(res)
    assert str(e.value).startswith(f"{res}: ") and words in str(e.value), e.value
    assert "\n" not in str(e.value)


def test_an_infinite_indicator_is_counted_and_named(tmp_path, capsys):
    """inf (higher harmonics, no fundamental at the outputs) is flagged, not left out of
    the count as a non-finite value."""
    def inf(v):
        v[:] = 0.0
        v[4, 7] = np.inf
    out = _info_with(tmp_path, capsys, "harmonic_indicator", inf)
    assert "harmonics:   single-harmonic; 1 of 240 converged points" in out, out
    assert "member 4 at " in out and "(inf)" in out


def _info_with(tmp_path, capsys, name, edit):
    """What ``mcfric info`` prints for a small run's file whose dataset ``name`` was
    edited in place by ``edit(values)``."""
    def how(h):
        v = h[name][...]
        edit(v)
        h[name][...] = v
    res = _damaged(tmp_path, how)
    capsys.readouterr()
    assert cli.main(["info", str(res)]) == 0
    return capsys.readouterr().out


def _stored(section, key, value):
    """An edit of the stored configuration's ``[section] key``."""
    def how(h):
        cfg = json.loads(h.attrs["config_json"])
        cfg[section][key] = value
        h.attrs["config_json"] = json.dumps(cfg)
    return how


def _replace(name, fn):
    def how(h):
        data = h[name][...]
        del h[name]
        h[name] = fn(data)
    return how


DAMAGED = [
    # (edit of a complete results file, words of the one-line error)
    # a dimension scale deleted: named, not HDF5's or Python's internal text
    *[((lambda h, s=s: h.__delitem__(s)), "its scale dataset is missing")
      for s in ("beam", "frequency", "sample", "damper", "peak")],
    (lambda h: h.__delitem__("metric"), "dataset metric is missing"),
    (lambda h: h.__delitem__("converged"), "dataset converged is missing"),
    (_replace("metric", lambda d: d[:, :5]), "dataset metric"),
    (_replace("metric", lambda d: d.astype("S8")), "expected float"),
    (lambda h: h.attrs.__delitem__("config_json"), "no configuration record"),
    (lambda h: h.attrs.__setitem__("config_json", "{}"), "lacks"),
    (_stored("sampling", "mu0", {"dist": "gamma"}), "stored configuration: sampling.mu0.dist"),
    (_stored("sampling", "kc", {"dist": "uniform", "low": "0"}),
     "stored configuration: sampling.kc.low"),
    (_stored("model", "n_beams", "two"), "stored configuration: model.n_beams"),
    # a record that contradicts the data (it would describe another run)
    (_stored("model", "n_beams", 5), "the configuration record says model.n_beams = 5"),
    (_stored("frequency", "n", 9), "the configuration record says frequency.n = 9"),
    (lambda h: h["frequency"].__setitem__(3, np.nan), "frequency is not finite, positive"),
    (lambda h: h["frequency"].__setitem__(3, h["frequency"][2]), "and rising"),
    (_stored("frequency", "f_min", None), "stored configuration: frequency.f_min"),
    (_stored("metric", "quantity", "force"), "stored configuration: metric.quantity"),
    (lambda h: h.attrs.__setitem__("layout_version", 99), "layout_version 99"),
    # a sample not done in a file marked complete (info called it complete and left the
    # sample out of its counts; plot drew the rest)
    (lambda h: h["done"].__setitem__(5, 0), "marked complete, but 1 of 12 samples are not"),
    # the bounds group: everything its reader uses
    (lambda h: h["bounds"].__delitem__("upper_box"), "bounds/upper_box is missing"),
    (lambda h: h["bounds"].__delitem__("upper_witness"), "bounds/upper_witness is missing"),
    # the certificate's first dataset: the file read as "not certified (--no-certify)"
    (lambda h: h["bounds"].__delitem__("upper_certified"),
     "bounds/upper_certified is missing"),
    (_replace("bounds/K_upper", lambda d: d[:3]), "bounds/K_upper is missing or not 20"),
    (lambda h: h["bounds"].attrs.__delitem__("k_max_re"), "lacks the attribute k_max_re"),
]


@pytest.mark.parametrize("how, message", DAMAGED)
def test_edited_results_files_give_one_line_exit_2(tmp_path, capsys, how, message):
    res = _damaged(tmp_path, how)
    capsys.readouterr()
    for argv in (["info", str(res)], ["plot", str(res), "-o", str(tmp_path / "f.png")],
                 ["verify", str(res), "--f", "50", "--member", "0", "-o",
                  str(tmp_path / "v.csv"), "--no-figure", "--no-progress"]):
        rc = cli.main(argv)
        err = capsys.readouterr().err.strip()
        assert rc == 2 and message in err and len(err.splitlines()) == 1, (argv, err)
    assert not (tmp_path / "f.png").exists() and not (tmp_path / "v.csv").exists()


@pytest.mark.parametrize("how, message", [
    (lambda h: h.__delitem__("converged"), "dataset converged is missing"),
    (lambda h: h["done"].__setitem__(5, 0), "marked complete, but 1 of 12 samples are not"),
    (lambda h: h["bounds"].__delitem__("upper_box"), "bounds/upper_box is missing"),
], ids=["converged", "done", "bounds"])
def test_a_run_of_an_edited_complete_file_refuses_it_in_one_line(tmp_path, capsys, how,
                                                                  message):
    """A run whose output is a complete file of the same run, edited or damaged, is not
    "nothing to do": it refuses in one line, exit 2, before anything is written (before,
    it said "already holds this run", printed a summary, then failed with exit 1, or
    with a sample not done exited 0)."""
    res = _damaged(tmp_path, how)
    before = res.read_bytes()
    capsys.readouterr()
    rc = cli.main(["run", *SMALL, "-o", str(res)])
    out, err = capsys.readouterr()
    assert rc == 2 and message in err and "--force" in err and len(err.splitlines()) == 1
    assert "nothing to do" not in out and res.read_bytes() == before


def test_a_partial_marked_complete_with_samples_not_done_is_refused(tmp_path, capsys,
                                                                    monkeypatch):
    """A partial file marked complete (the state between the last commit and the rename)
    whose ``done`` says otherwise: info and plot refuse it in one line instead of calling
    it complete; --resume computes the missing samples and renames it."""
    from .test_cli import _before_third_solve

    def stop():
        raise KeyboardInterrupt

    out = tmp_path / "p.h5"
    argv = ["run", "two-beam", "--samples", "30", "--n-freq", "8", "--chunk", "10",
            "--no-progress", "--no-figure", "--no-certify", "-o", str(out)]
    with monkeypatch.context() as m:
        _before_third_solve(m, stop)
        assert cli.main(argv) == 130
    part = store.partial_path(out)
    with h5py.File(part, "r+") as h:
        assert int(h["done"][...].sum()) == 20
        h.attrs["complete"] = np.int8(1)
    capsys.readouterr()
    for command in (["info", str(part)], ["plot", str(part), "-o", str(tmp_path / "f.png")]):
        rc = cli.main(command)
        err = capsys.readouterr().err.strip()
        assert rc == 2 and "marked complete, but 10 of 30 samples are not done" in err
        assert len(err.splitlines()) == 1, err
    assert cli.main(argv + ["--resume"]) == 0
    with h5py.File(out, "r") as h:
        assert h["done"][...].all() and h.attrs["complete"] == 1
    assert not part.exists()


@pytest.mark.parametrize("how, commands", [
    # attributes edited into another type (info gave a traceback; verify reads neither)
    (lambda h: h.attrs.__setitem__("harmonics", "x"), ("info", "plot")),
    (lambda h: h["bounds"].attrs.__setitem__("k_max_re", "x"), ("info", "plot")),
    # a peak dataset missing (info exited 1; plot draws without it)
    (lambda h: h.__delitem__("fold"), ("info",)),
], ids=["harmonics", "k_max_re", "fold"])
def test_info_and_plot_on_edited_attributes_are_one_line_exit_2(tmp_path, capsys, how,
                                                                 commands):
    res = _damaged(tmp_path, how)
    capsys.readouterr()
    for command in commands:
        argv = [command, str(res)] + (["-o", str(tmp_path / "f.png")]
                                      if command == "plot" else [])
        rc = cli.main(argv)
        err = capsys.readouterr().err.strip()
        assert rc == 2 and len(err.splitlines()) == 1, (argv, err)
        assert "'x'" in err or "'fold'" in err, err
    assert not (tmp_path / "f.png").exists()


def test_a_nan_metric_marked_converged_is_reported_not_ranged(tmp_path, capsys):
    out = _info_with(tmp_path, capsys, "metric", lambda m: m.__setitem__((0, 0), np.nan))
    assert "inf" not in out.split("metric:")[1].splitlines()[0]
    assert "1 points marked converged hold no finite metric" in out


def test_config_of_a_file_without_its_toml_copy_is_rebuilt_from_the_record(tmp_path, capsys):
    res = _damaged(tmp_path, lambda h: h.attrs.__delitem__("config"))
    capsys.readouterr()
    assert cli.main(["config", str(res)]) == 0
    (tmp_path / "again.toml").write_text(capsys.readouterr().out)
    # the rebuilt configuration runs the same members: the file resumes as complete
    assert cli.main(["run", str(tmp_path / "again.toml"), "-o", str(res), "--resume",
                     "--no-progress", "--no-figure"]) == 0
    assert "already holds this run" in capsys.readouterr().out
    (tmp_path / "b").mkdir()
    broken = _damaged(tmp_path / "b", lambda h: (h.attrs.__delitem__("config"),
                                                  _stored("model", "n_beams", "two")(h)))
    capsys.readouterr()
    assert cli.main(["config", str(broken)]) == 2
    err = capsys.readouterr().err.strip()
    assert "stored configuration: model.n_beams" in err and len(err.splitlines()) == 1


def test_a_number_marked_not_converged_and_a_wrong_count_are_reported(tmp_path, capsys):
    def unflag(h):
        c = h["converged"][...]
        assert c[1, 2]
        c[1, 2] = False
        h["converged"][...] = c
    res = _damaged(tmp_path, unflag)
    capsys.readouterr()
    assert cli.main(["info", str(res)]) == 0
    out = capsys.readouterr().out
    assert "(1 not converged)" in out
    assert "1 points marked not converged hold a number" in out
    assert "attribute n_not_converged = 0, but 1 points" in out
    (tmp_path / "clean").mkdir()
    clean = _damaged(tmp_path / "clean", lambda h: None)
    capsys.readouterr()
    assert cli.main(["info", str(clean)]) == 0
    assert "WARNING" not in capsys.readouterr().out


def test_a_closed_stdout_is_not_an_error(tmp_path, capsys):
    res = _damaged(tmp_path, lambda h: None)
    p = subprocess.Popen([sys.executable, "-m", "mcfric", "info", str(res)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    p.stdout.close()
    err = p.stderr.read()
    p.stderr.close()
    assert p.wait() == 0 and err == b""


def test_a_run_whose_stdout_goes_away_still_makes_its_files(tmp_path):
    """`mcfric run ... | head -1`: the run stopped at its second line, exit 0 with no
    results file; it now drops the rest of its output and makes its files."""
    out = tmp_path / "p.h5"
    p = subprocess.Popen([sys.executable, "-m", "mcfric", "run", "two-beam", "--samples", "4",
                          "--n-freq", "10", "-o", str(out), "--no-progress"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert p.stdout.readline().startswith(b"mcfric run:")
    p.stdout.close()
    err = p.stderr.read()
    p.stderr.close()
    assert p.wait() == 0 and err == b""
    assert out.exists() and out.with_suffix(".png").exists()
    with h5py.File(out) as h:
        assert h.attrs["complete"] == 1


def test_sigterm_stops_a_run_resumably(tmp_path):
    out = tmp_path / "r.h5"
    argv = [sys.executable, "-m", "mcfric", "run", "eight-beam", "--samples", "4000",
            "--n-freq", "300", "--chunk", "64", "-o", str(out), "--no-progress",
            "--no-figure", "--no-certify"]
    p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert "mcfric run:" in p.stdout.readline()
    import time
    # signal once the ensemble has begun writing (the bounds come first, not certified
    # here: their time, a numba compile included, depends on the machine's load)
    partial = tmp_path / "r.h5.partial"
    deadline = time.monotonic() + 600
    while not partial.exists() and time.monotonic() < deadline and p.poll() is None:
        time.sleep(0.1)
    time.sleep(1)
    p.send_signal(15)
    _, err = p.communicate()
    assert p.returncode == 130, err
    assert "--resume" in err and (tmp_path / "r.h5.partial").exists()
    assert not out.exists() and not lock_path(out).exists()
    # the command it prints continues the run to a complete file
    r = subprocess.run(argv + ["--resume"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert "samples: 4000 of 4000" in r.stdout and not partial.exists()
    with h5py.File(out, "r") as h5:
        assert h5.attrs["complete"] == 1 and h5["done"][...].all()


def test_sigterm_stops_a_run_inside_a_long_chunk(tmp_path):
    """A chunk can run for minutes (two members of a 200-blade ring at H = 5: about a
    minute here; a 3000-beam chain's ignored SIGTERM for over ten minutes before the wait
    became interruptible); SIGTERM during it ends the run within seconds, resumably."""
    import time

    cfg = tmp_path / "ring.toml"
    cfg.write_text('[model]\npreset = "disk-72"\nn_beams = 200\n[sampling]\nsamples = 2\n'
                   '[solver]\nharmonics = 5\n')
    out = tmp_path / "mh.h5"
    p = subprocess.Popen([sys.executable, "-m", "mcfric", "run", str(cfg), "--no-bounds",
                          "--no-progress", "--no-figure", "-o", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = tmp_path / "mh.h5.partial"
    try:
        deadline = time.monotonic() + 600
        while not partial.exists() and time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.1)
        time.sleep(3)               # inside the first chunk (or compiling it)
        assert p.poll() is None
        t0 = time.monotonic()
        p.send_signal(15)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()                    # a run that ignored the signal does not live on
        p.communicate()             # and its pipes are closed whatever happened
    assert p.returncode == 130, err
    assert time.monotonic() - t0 < 15
    assert "0 of 2 samples saved" in err and "--resume" in err
    assert partial.exists() and not out.exists()


def test_an_interruptible_call_returns_raises_and_keeps_the_thread_count():
    import threading

    import numba

    from mcfric.threads import interruptible, leaving_on_interrupt, threads

    if numba.config.NUMBA_NUM_THREADS < 2:
        pytest.skip("one numba thread: a count passed on is not told from the default")
    with leaving_on_interrupt():
        with threads(1):
            assert interruptible(numba.get_num_threads) == 1
        assert interruptible(lambda a, b=0: a + b, 2, b=3) == 5
        with pytest.raises(ValueError, match="bad"):
            interruptible(lambda: (_ for _ in ()).throw(ValueError("bad")))
        assert interruptible(threading.current_thread).name == "mcfric-kernel"
    # outside (the Python API): a plain call, nothing left behind by an interrupt
    assert interruptible(threading.current_thread) is threading.main_thread()


def test_an_interrupted_call_is_left_and_the_next_waits_for_it():
    """Ctrl-C reaches the caller at once; the abandoned call finishes in the background
    before the next one starts (two parallel kernels never run at once)."""
    import _thread
    import threading
    import time

    from mcfric.threads import interruptible, leaving_on_interrupt

    release, order = threading.Event(), []

    def slow():
        release.wait(30)
        order.append("slow")

    with leaving_on_interrupt():
        threading.Timer(0.3, _thread.interrupt_main).start()
        t0 = time.monotonic()
        with pytest.raises(KeyboardInterrupt):
            interruptible(slow)
        assert time.monotonic() - t0 < 5 and order == []
        threading.Timer(0.5, release.set).start()
        interruptible(lambda: order.append("next"))
    assert order == ["slow", "next"]


def test_a_left_pool_stops_its_running_tasks_at_their_next_check():
    """A task of many steps (a frequency's second-order relaxations: many Clarabel solves)
    ran to its end after Ctrl-C, which waited for it: 15 s into `mcfric bounds
    eight-beam`. Left by an interrupt or by another task's error, the pool's running
    tasks now stop at their next `threads.check()`."""
    import signal
    import threading
    import time

    import numba

    from mcfric import threads

    if numba.get_num_threads() < 2:
        pytest.skip("one numba thread: in_threads runs the tasks in the caller")
    steps = []

    def task(i):
        for _ in range(300):         # 30 s unless stopped
            threads.check()
            time.sleep(0.1)
            steps.append(i)

    main = threading.main_thread().ident
    # a real signal at the main thread: the pool's wait wakes for it, as for Ctrl-C
    threading.Timer(0.5, signal.pthread_kill, (main, signal.SIGINT)).start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        threads.in_threads(task, range(4))
    assert time.monotonic() - t0 < 3
    n = len(steps)
    time.sleep(0.3)
    assert len(steps) == n and 0 < n < 40

    def failing(i):
        if i == 0:
            raise ValueError("bad item")
        task(i)

    t0 = time.monotonic()
    with pytest.raises(ValueError, match="bad item"):
        threads.in_threads(failing, range(2))
    assert time.monotonic() - t0 < 3
    threads.check()                  # outside a pool: nothing to stop


def test_F_lim_none_on_the_command_line_as_in_toml(tmp_path, capsys):
    out = tmp_path / "b.h5"
    assert cli.main(["bounds", "two-beam", "--n-freq", "10", "--F-lim", "none", "-o",
                     str(out), "--no-figure"]) == 0
    assert "F_lim = inf N" in capsys.readouterr().out


def test_measured_beams_beyond_the_model_are_refused(tmp_path, capsys):
    res = _results(tmp_path)
    csv = tmp_path / "m.csv"
    csv.write_text("frequency_hz,beam99\n20,1e-5\n30,2e-5\n")
    capsys.readouterr()
    rc = cli.main(["plot", str(res), "--measured", str(csv), "-o", str(tmp_path / "f.png")])
    err = capsys.readouterr().err
    assert rc == 2 and "beam 99 is measured, but the model has 2 beams" in err


ZERO_DAMPING = __import__("mcfric").model.ModalTable([20.0], [0.0], [[1.0, 1.0, 1.0]])

API_CASES = [
    # 1e-150 N solved, and a fifth of the members fell outside their bounds (underflow)
    (lambda m: m.with_F0(1e-150), "F0: expected a finite number >= 1e-12"),
    (lambda m: __import__("mcfric").two_beam(1e-150), "F0: expected a finite number >= 1e-12"),
    (lambda m: __import__("mcfric").solve(m, [20.0], "0.3", 5000.0), "mu0: expected real"),
    (lambda m: __import__("mcfric").solve(m, [20.0], True, 5000.0), "got booleans"),
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.3, 5000.0 + 1j), "got complex"),
    (lambda m: __import__("mcfric").solve(m, ["20"], 0.3, 5000.0), "freq_hz: expected real"),
    (lambda m: __import__("mcfric").bounds.force_limit(-1, 0.5), "mu_max"),
    # 0 was returned, and compute_bounds then refused F_lim = 0
    (lambda m: __import__("mcfric").bounds.force_limit(0, 0.5), "^mu_max: expected"),
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.3, 5e3).metric(beams=[2]),
     "0-based beam indices in 0..1"),
    # 1e160 came back as the free answer (the slip ratio overflowed), marked converged
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.5, 1e160), "kc: expected at most"),
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.5, 5e3, n_threads=0),
     "^n_threads: expected 1.."),
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.5, 5e3, harmonics=3, indicator=True),
     "indicator: for single-harmonic solves"),
    (lambda m: __import__("mcfric").solve(m, [20.0], 0.5, 5e3, store_harmonics=True),
     "store_harmonics: for multi-harmonic solves"),
    # a numba ZeroDivisionError from the search
    (lambda m: __import__("mcfric").bounds.compute_bounds(
        __import__("mcfric").model.Model((ZERO_DAMPING,) * 2), [21.0], 15e3, certified=False),
     "beam 1 has a mode without damping"),
    (lambda m: __import__("mcfric.verify").verify.verify(m, 1.0, 0.3, 1e12),
     "^kc: 1e.12 N/m makes a period at 1 Hz need"),
    # numpy parsed the string; a list gave "setting an array element with a sequence"
    (lambda m: __import__("mcfric").model.TABLE_1.with_frequency(2, "108"), "^freq_hz:"),
    (lambda m: __import__("mcfric").model.TABLE_1.with_frequency(2, [108, 1]), "^freq_hz:"),
    (lambda m: __import__("mcfric").model.Model(3), "^beams: expected a sequence"),
    (lambda m: __import__("mcfric").preset(["two-beam"]), "^preset: expected one of"),
    (lambda m: __import__("mcfric").bounds.compute_bounds(m, [20.0, 30.0], 15e3,
                                                          certified=False).contains([1.0]),
     r"^metric: expected shape \(\.\.\., 2\)"),
    # inf ("no force limit") and 0 from a product that overflows or underflows
    (lambda m: __import__("mcfric").bounds.force_limit(1e300, 1e300), "^mu_max: .*overflows"),
    (lambda m: __import__("mcfric").bounds.force_limit(1e-300, 1e-300), "^mu_max: .*overflows"),
    # a tolerance below rounding and 1e9 periods ran for hours in one kernel call
    (lambda m: __import__("mcfric.verify").verify.verify(m, 20.0, 0.3, 5e3, tol=1e-300),
     r"^tol: expected a number in \[1e-14, 1\)"),
    (lambda m: __import__("mcfric.verify").verify.verify(m, 20.0, 0.3, 5e3,
                                                         max_periods=10**9),
     r"^max_periods: expected"),
    # a word is a true value: "no" meant the opposite
    (lambda m: __import__("mcfric.verify").verify.verify(m, 20.0, 0.3, 5e3, progress="no"),
     "^progress: expected True or False"),
    (lambda m: __import__("mcfric.measured").measured.fraction_inside(
        __import__("mcfric.measured").measured.Measurement([20.0], [[1.0]], beams=(1,)),
        [10.0, 30.0], [0.0, 0.0], [2.0, 2.0], check_lower="no"),
     "^check_lower: expected True or False"),
]


@pytest.mark.parametrize("call, message", API_CASES)
def test_the_python_api_refuses_what_it_cannot_use(call, message):
    """Each an ``InputError`` (a ``ValueError`` naming what was wrong, with its name in
    ``.key``), as the guarantees page says of these cases."""
    import mcfric
    from mcfric.validators import InputError

    with pytest.raises(InputError, match=message):
        call(mcfric.two_beam(0.22))


def test_a_solve_larger_than_the_free_memory_is_refused(monkeypatch):
    """numpy's "Unable to allocate 298. GiB" named nothing, and a request just below the
    machine's memory would end in the system killing the process (the free memory is
    set here: the test does not depend on the machine)."""
    import numpy as np

    import mcfric
    from mcfric import memory

    monkeypatch.setattr(memory, "available", lambda: 10**9)       # 1 GB free
    model = mcfric.two_beam(0.22)
    f = np.linspace(10, 150, 1000)
    with pytest.raises(ValueError, match=r"^the solve of 100,000 samples x 1,000 "
                                         r"frequencies needs about 5\.\d GB of memory but "
                                         r"1 GB is available"):
        mcfric.solve(model, f, np.broadcast_to(0.5, (10**5, 1)), 5e3)
    assert mcfric.solve(model, f[:10], np.broadcast_to(0.5, (10, 1)), 5e3).converged.all()


def test_a_chunk_refused_for_memory_mid_run_is_one_line_and_resumable(monkeypatch, tmp_path,
                                                                       capsys):
    """Past the run's own check (--skip-space-check here; or free memory falling mid-run),
    a chunk's solve refuses for memory: that was a traceback. It is one line, exit 1,
    naming the partial kept, which resumes to a complete file once memory is free (the
    free memory is set here: the test does not depend on the machine)."""
    from mcfric import cli, memory

    monkeypatch.setattr(memory, "available", lambda: 1000)        # 1 kB free
    out = tmp_path / "r.h5"
    argv = ["run", "two-beam", "--samples", "4", "--n-freq", "50", "--no-bounds", "-o",
            str(out), "--no-progress", "--no-figure"]
    assert cli.main(argv + ["--skip-space-check"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("mcfric: error: the solve of ") and err.count("\n") == 1
    assert "of memory but 1 kB is available" in err
    assert f"continue with `mcfric run ... -o {out} --resume` when memory is free" in err
    assert not out.exists()
    monkeypatch.undo()
    assert cli.main(argv + ["--resume"]) == 0 and out.exists()


# -- crash-resume soak (slow; CI runs it as a separate step) ---------------------------

SOAK_KILLS = 20


@pytest.mark.slow
def test_soak_twenty_sigkills_then_resume_is_bitwise_identical(tmp_path):
    """20 `kill -9` of one run at random moments (random progress, then a random delay
    so that some land mid-chunk), each followed by `--resume`; the finished file equals a
    straight run in every dataset."""
    import time
    from pathlib import Path

    from mcfric import config
    from mcfric.store import partial_path

    root = Path(__file__).resolve().parents[1]
    toml = tmp_path / "cfg.toml"
    toml.write_text('[model]\npreset = "two-beam"\n[frequency]\nn = 200\n'
                    '[sampling]\nsamples = 4000\nseed = 3\n'
                    '[run]\nchunk = 4\ncheckpoint_s = 0.0\n')
    out = tmp_path / "soak.h5"
    env = dict(os.environ, PYTHONPATH=str(root))
    cmd = [sys.executable, "-m", "mcfric", "run", str(toml), "-o", str(out), "--resume",
           "--no-progress", "--no-figure"]
    rng = np.random.default_rng(2026)

    def done():
        try:
            with h5py.File(partial_path(out), "r", locking=False) as h5:
                return int(h5["done"][...].sum())
        except (OSError, KeyError):
            return 0

    killed = []
    for _ in range(SOAK_KILLS):
        start = done()
        target = start + int(rng.integers(4, 120))
        p = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE)
        deadline = time.monotonic() + 600             # allows a numba compile
        while p.poll() is None and done() < target and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(float(rng.uniform(0.0, 0.05)))
        p.send_signal(9)
        _, err = p.communicate()
        assert p.returncode == -9, err.decode()     # killed mid-run, not finished
        assert not out.exists()
        killed.append(done())
    assert killed[-1] < 4000 and len(set(killed)) > SOAK_KILLS // 2
    r = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    assert not lock_path(out).exists()
    straight = tmp_path / "straight.h5"
    ensemble.run(config.load(toml, {"run.chunk": (512, "--chunk")}), straight,
                 progress=False)
    with h5py.File(out) as a, h5py.File(straight) as b:
        names = [k for k in b if isinstance(b[k], h5py.Dataset)]
        assert "response" in names
        for k in names:
            assert a[k][...].tobytes() == b[k][...].tobytes(), k


@pytest.fixture
def small_fs(tmp_path):
    """A 1 MB tmpfs (root only; skipped elsewhere), unmounted afterwards."""
    mnt = tmp_path / "small"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)],
                       capture_output=True)
    if r.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here (needs root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


BIG = ["two-beam", "--samples", "2000", "--n-freq", "100", "--chunk", "16", "--no-progress",
       "--no-figure"]


def test_a_file_that_cannot_fit_fails_before_any_work(small_fs, capsys, monkeypatch):
    """A real full disk: even past the estimate (--skip-space-check), the file is
    checked against the free space when it is created, so the run stops there, in one
    line. A file larger than the free space is not handed to fallocate at all (on ext4 a
    failing one held every free block until it gave up, and the line then said "0 bytes
    free")."""
    tried = []
    monkeypatch.setattr(writer, "_fallocate", lambda fd, size: tried.append(size))
    out = small_fs / "r.h5"
    rc = cli.main(["run", *BIG, "-o", str(out), "--skip-space-check"])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and "no space for the results file" in err and len(err.splitlines()) == 1
    assert not tried and ", 0 bytes free)" not in err, err
    assert not list(small_fs.iterdir())


def test_a_reservation_refused_by_the_file_system_is_one_line(tmp_path, capsys,
                                                               monkeypatch):
    """A file that fits the free space but whose fallocate fails (a quota: EDQUOT): one
    line that names the quota (the disk's free space, larger than the file, said
    nothing), exit 1, nothing left."""
    def quota(fd, size):
        raise OSError(errno.EDQUOT, "Disk quota exceeded")

    monkeypatch.setattr(writer, "_fallocate", quota)
    out = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL, "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert "no space for the results file" in err and len(err.splitlines()) == 1, err
    assert "needed: disk quota exceeded)" in err and " free)" not in err, err
    assert not list(tmp_path.iterdir())


def test_a_full_disk_while_the_file_is_created_is_one_line(tmp_path, capsys, monkeypatch):
    """h5py reports a full disk met while it allocates a dataset as a ValueError (seen
    with 1e10 samples and --skip-space-check): one line, exit 1, nothing left."""
    def full(*a, **k):
        raise ValueError("Unable to synchronously create dataset (file write failed: time "
                         "= Tue Dec  1 04:00:00 2026, filename = 'r.h5.partial', file "
                         "descriptor = 5, errno = 28, error message = 'No space left on "
                         "device', buf = 0x1, total write size = 8, bytes this sub-write "
                         "= 8, bytes actually written = 18446744073709551615, offset = 0)")

    monkeypatch.setattr(writer, "_create_allocated", full)
    out = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL, "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err == f"mcfric: error: {out}: cannot be written (No space left on device)", err
    assert not list(tmp_path.iterdir())


def test_a_disk_that_fills_mid_run_leaves_a_resumable_partial(small_fs, tmp_path, capsys,
                                                              monkeypatch):
    """Without the reservation (a file system without fallocate), a real ENOSPC mid-run
    must still end in one line, exit 1, and a .partial that resumes to the same bits
    once there is space: the chunk cache is flushed while the error can still raise."""
    monkeypatch.setattr(writer, "reserve", lambda path: None)
    out = small_fs / "r.h5"
    rc = cli.main(["run", *BIG, "-o", str(out), "--skip-space-check"])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and "No space left on device" in err, err
    assert len(err.splitlines()) == 1
    assert not out.exists() and (small_fs / "r.h5.partial").exists()
    assert not lock_path(out).exists()
    subprocess.run(["mount", "-o", "remount,size=64m", str(small_fs)], check=True)
    monkeypatch.undo()
    assert cli.main(["run", *BIG, "-o", str(out), "--resume"]) == 0
    straight = tmp_path / "straight.h5"
    assert cli.main(["run", *BIG, "-o", str(straight)]) == 0
    with h5py.File(out) as a, h5py.File(straight) as b:
        for name in ("response", "metric", "converged", "done", "mu0", "kc", "N0"):
            assert a[name][...].tobytes() == b[name][...].tobytes(), name


def test_an_interrupted_csv_leaves_the_old_file_and_nothing_else(tmp_path, capsys,
                                                                  monkeypatch):
    """`mcfric hbm -o keep.csv` cut short while the CSV is written (here: Ctrl-C after
    part of it): the old keep.csv stays as it was, and no partial file is left."""
    out = tmp_path / "keep.csv"
    out.write_text("old\n")

    def cut(path, *a, **k):
        with open(path, "w") as fh:
            fh.write("frequency_hz,half a row")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savetxt", cut)
    rc = cli.main(["hbm", "two-beam", "--n-freq", "20", "--no-figure", "-o", str(out)])
    assert rc == 130
    assert out.read_text() == "old\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.csv"]


def test_a_figure_that_cannot_be_written_is_named_and_leaves_no_partial(tmp_path, capsys,
                                                                         monkeypatch):
    """A full disk while the figure of `mcfric hbm` is saved: one line naming the
    figure, exit 1, the old figure unchanged, no partial file; the CSV is complete."""
    from matplotlib.figure import Figure

    out = tmp_path / "h.csv"
    png = tmp_path / "h.png"
    png.write_bytes(b"old")

    def full(self, path, *a, **k):
        with open(path, "wb") as fh:
            fh.write(b"\x89PNG half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Figure, "savefig", full)
    rc = cli.main(["hbm", "two-beam", "--n-freq", "20", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1 and len(err.strip().splitlines()) == 1, err
    assert f"mcfric: error: figure {png}: No space left on device" in err
    assert png.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.csv", "h.png"]
    assert len(np.genfromtxt(out, delimiter=",", names=True)) == 20


def _interrupted(*a, **k):
    raise KeyboardInterrupt


@pytest.mark.parametrize("where", ["mcfric.plot.results_figure",
                                   "mcfric.ensemble.peak_report"])
def test_an_interrupt_after_the_results_are_complete_says_so(tmp_path, capsys,
                                                             monkeypatch, where):
    """Ctrl-C while a run draws its figure, or after the rename while it reads its peaks
    for the summary (0.9 s of the 1.2 s after it on a 2000 x 500 run; that one said
    "interrupted" only): the results file is complete, and the message says so and how
    to draw the figure (not a lost run)."""
    monkeypatch.setattr(where, _interrupted)
    out = tmp_path / "r.h5"
    rc = cli.main(["run", *SMALL[:-1], "--no-bounds", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 130
    assert f"interrupted: {out} is complete" in err and f"mcfric plot {out}" in err, err
    assert store.read_attrs(out)["complete"] == 1


def test_an_interrupt_around_the_rename_is_judged_by_the_files(tmp_path, capsys,
                                                               monkeypatch):
    """After a --force run's rename the file is complete again; before the rename (the
    sweep done, the file not yet renamed) it is not called complete, the partial is
    named, and --resume finishes it."""
    from mcfric import ensemble

    out = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL[:-1], "--no-bounds", "-o", str(out)]) == 0
    monkeypatch.setattr(ensemble, "peak_report", _interrupted)
    capsys.readouterr()
    rc = cli.main(["run", *SMALL[:-1], "--no-bounds", "-o", str(out), "--force"])
    assert rc == 130 and "is complete" in capsys.readouterr().err
    monkeypatch.setattr(ensemble.Store, "finish", _interrupted)
    new = tmp_path / "s.h5"
    rc = cli.main(["run", *SMALL[:-1], "--no-bounds", "-o", str(new)])
    err = capsys.readouterr().err
    assert rc == 130 and "is complete" not in err, err
    assert f"kept in {new}.partial; continue with `mcfric run ... -o {new} --resume`" in err
    monkeypatch.undo()
    assert cli.main(["run", *SMALL[:-1], "--no-bounds", "-o", str(new), "--resume"]) == 0
    assert store.read_attrs(new)["complete"] == 1 and not (tmp_path / "s.h5.partial").exists()


def test_an_interrupt_before_the_sweep_claims_no_file(tmp_path, capsys, monkeypatch):
    """Ctrl-C before this run wrote anything: the plain message, whatever lies there. An
    older run's partial that --force is to replace (still there while the bounds are
    computed) is not called this run's samples, and an interrupt at the first line
    (before the files were looked at) is no traceback."""
    import mcfric.bounds
    from mcfric import ensemble
    from mcfric.cli import run as cli_run

    interrupted = _interrupted
    out = tmp_path / "t.h5"
    monkeypatch.setattr(ensemble.Store, "finish", interrupted)
    assert cli.main(["run", *SMALL[:-1], "--seed", "5", "--no-bounds", "-o", str(out)]) == 130
    assert (tmp_path / "t.h5.partial").exists()
    monkeypatch.undo()
    monkeypatch.setattr(mcfric.bounds, "from_spec", interrupted)
    capsys.readouterr()
    assert cli.main(["run", *SMALL[:-1], "-o", str(out), "--force"]) == 130
    assert capsys.readouterr().err.strip() == "mcfric: interrupted"
    monkeypatch.setattr(cli_run, "settings_notes", interrupted)
    assert cli.main(["run", *SMALL[:-1], "-o", str(tmp_path / "u.h5")]) == 130
    assert capsys.readouterr().err.strip() == "mcfric: interrupted"


def test_an_output_directory_that_cannot_be_written_is_refused_before_the_work(
        tmp_path, capsys, monkeypatch):
    """A directory the user may not write (a read-only mount): refused in one line
    before anything is solved, not after."""
    import tempfile

    real = tempfile.TemporaryFile

    def refused(*a, dir=None, **k):
        if str(dir) == str(tmp_path):
            raise PermissionError(13, "Permission denied")
        return real(*a, dir=dir, **k)

    monkeypatch.setattr(tempfile, "TemporaryFile", refused)
    rc = cli.main(["hbm", "two-beam", "--n-freq", "20", "-o", str(tmp_path / "h.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and f"-o: directory {tmp_path} is not writable" in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["info", "plot"])
def test_an_empty_file_name_is_named_as_such(command, capsys):
    """`mcfric info ""` (an unset shell variable) read the current directory: "., a
    directory"."""
    assert cli.main([command, ""]) == 2
    assert "argument file: expected a file name, got ''" in capsys.readouterr().err


def test_keep_harmonics_that_stores_nothing_is_said(tmp_path, capsys):
    """[output] keep_harmonics = true with a single-harmonic run was ignored silently."""
    toml = tmp_path / "k.toml"
    toml.write_text('model.preset = "two-beam"\n[output]\nkeep_harmonics = true\n'
                    '[bounds]\nenabled = false\n')
    out = tmp_path / "k.h5"
    assert cli.main(["run", str(toml), *SMALL[1:], "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert ("note: output.keep_harmonics = true does nothing: solver.harmonics = 1" in text
            and text.count("note: output.keep_harmonics") == 1), text
    # with H > 1 it stores the harmonics, unless the response is not kept
    toml.write_text('model.preset = "two-beam"\n[output]\nkeep_harmonics = true\n'
                    'keep_response = false\n[solver]\nharmonics = 3\n'
                    '[bounds]\nenabled = false\n')
    small = ["--samples", "2", "--n-freq", "4", "--no-progress", "--no-figure"]
    assert cli.main(["run", str(toml), *small, "-o", str(tmp_path / "k3.h5")]) == 0
    text = capsys.readouterr().out
    assert ("note: output.keep_harmonics = true does nothing: output.keep_response = "
            "false" in text), text


def test_settings_that_do_nothing_are_named_and_the_rest_are_not(tmp_path, capsys):
    """A peak setting with the peaks off, solver.n_time with one harmonic, a bounds
    setting with the bounds off, excitation.mode with a single-beam pattern,
    sampling.mistuning_per without mistuning: each was accepted in silence. Each is
    named in a note; a complete file from `mcfric config` (every key, at its default) and
    the same settings where they act give none."""
    small = ["--samples", "2", "--n-freq", "4", "--no-progress", "--no-figure"]
    idle = ('model.preset = "two-beam"\n[peaks]\nenabled = false\nrtol = 1e-3\n'
            '[solver]\nn_time = 64\n[bounds]\nenabled = false\nn_starts = 5\n'
            '[excitation]\nmode = 1\n[sampling]\nmistuning_per = "mode"\n')
    toml = tmp_path / "idle.toml"
    toml.write_text(idle)
    assert cli.main(["run", str(toml), *small, "-o", str(tmp_path / "a.h5")]) == 0
    notes = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note:")]
    assert sorted(notes) == sorted([
        "note: peaks.rtol = 0.001 does nothing: peaks.enabled = false",
        "note: solver.n_time = 64 does nothing: solver.harmonics = 1 (the describing "
        "function is exact there; AFT is multi-harmonic)",
        "note: bounds.n_starts = 5 does nothing: bounds.enabled = false",
        'note: excitation.mode = 1 does nothing: excitation.pattern is not "mode"',
        "note: sampling.mistuning_per = \"mode\" does nothing: sampling.mistuning = 0"]), notes
    # where they act: no note
    acting = ('model.preset = "two-beam"\n[peaks]\nrtol = 1e-3\n[solver]\nharmonics = 3\n'
              'n_time = 64\n[bounds]\nenabled = false\n[excitation]\npattern = "mode"\n'
              'mode = 1\n[sampling]\nmistuning = 0.01\nmistuning_per = "mode"\n')
    toml.write_text(acting)
    assert cli.main(["run", str(toml), *small, "-o", str(tmp_path / "b.h5")]) == 0
    notes = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note:")]
    assert notes == ["note: peaks.rtol = 0.001 does nothing: peaks are refined in "
                     "single-harmonic runs only"], notes
    # a complete file holds every key at its default: nothing to say
    assert cli.main(["config", "two-beam"]) == 0
    toml.write_text(capsys.readouterr().out)
    assert cli.main(["run", str(toml), *small, "--no-bounds", "-o", str(tmp_path / "c.h5")]) == 0
    assert "note:" not in capsys.readouterr().out


def test_bounds_names_the_idle_settings_of_the_tables_it_reads(tmp_path, capsys):
    """`mcfric bounds` named no idle setting: a certify_* setting with certify = false
    went by in silence. It names those of [bounds], [peaks] and [excitation], and not the
    ensemble's settings it never reads."""
    toml = tmp_path / "idle.toml"
    toml.write_text('model.preset = "two-beam"\n[peaks]\nenabled = false\nrtol = 1e-3\n'
                    '[solver]\nn_time = 64\n[bounds]\ncertify = false\n'
                    'certify_budget = 7\n[excitation]\nmode = 1\n')
    args = ["bounds", str(toml), "--n-freq", "4", "--no-progress", "--no-figure"]
    assert cli.main([*args, "-o", str(tmp_path / "b.h5")]) == 0
    notes = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("note:")]
    assert sorted(notes) == sorted([
        "note: peaks.rtol = 0.001 does nothing: peaks.enabled = false",
        "note: bounds.certify_budget = 7 does nothing: bounds.certify = false",
        'note: excitation.mode = 1 does nothing: excitation.pattern is not "mode"']), notes


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_a_figure_linked_into_an_unwritable_directory_is_refused_first(tmp_path, capsys):
    """A figure name that is a symbolic link is written through; hbm wrote its CSV and
    then failed on the figure. Its target's directory is checked before the work."""
    (tmp_path / "h.png").symlink_to("/proc/mcfric-test.png")
    assert cli.main(["hbm", "two-beam", "--n-freq", "5", "-o", str(tmp_path / "h.csv")]) == 2
    assert "directory /proc is not writable" in capsys.readouterr().err
    assert not (tmp_path / "h.csv").exists()


@pytest.mark.parametrize("command", [["run", *SMALL], ["bounds", "two-beam", "--n-freq",
                                                        "10", "--no-figure"]])
def test_a_results_file_name_that_is_a_link_is_written_through(tmp_path, capsys, command):
    """-o LINK, as for a CSV or a figure: the link stays and its target gets the results
    (it was replaced by a regular file, the target never made: a link to a larger disk
    silently ignored). A link into a directory that does not exist: one line, exit 2,
    nothing made."""
    (tmp_path / "disk").mkdir()
    out = tmp_path / "r.h5"
    out.symlink_to(tmp_path / "disk" / "target.h5")
    assert cli.main([*command, "-o", str(out)]) == 0, capsys.readouterr().err
    assert out.is_symlink() and (tmp_path / "disk" / "target.h5").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["disk", "r.h5"]
    with h5py.File(out) as f:            # through the link: a whole results file
        assert "layout_version" in f.attrs
    if command[0] == "run":             # the figure beside the results, at the target
        capsys.readouterr()
        assert cli.main(["plot", str(out)]) == 0, capsys.readouterr().err
        assert (tmp_path / "disk" / "target.png").is_file()
        (tmp_path / "disk" / "target.png").unlink()
    capsys.readouterr()
    dangling = tmp_path / "d.h5"
    dangling.symlink_to(tmp_path / "nodir" / "d.h5")
    before = snapshot(tmp_path)
    assert cli.main([*command, "-o", str(dangling)]) == 2
    err = capsys.readouterr().err.strip()
    assert "(a link's target) does not exist" in err and len(err.splitlines()) == 1, err
    assert snapshot(tmp_path) == before and dangling.is_symlink()


def test_verify_takes_every_frequency_given():
    """`verify --f 30 --f 40` verified 40 Hz only (the second --f replaced the first)."""
    parse = build_parser().parse_args
    assert parse(["verify", "--f", "30", "--f", "40", "45"]).f == [30.0, 40.0, 45.0]
    assert parse(["verify", "--f", "30", "40"]).f == [30.0, 40.0]


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
@pytest.mark.parametrize("argv", [["hbm", "two-beam", "--n-freq", "20"],
                                  ["verify", "two-beam", "--f", "30"]])
def test_a_directory_that_takes_no_files_is_refused_before_the_work(argv, capsys):
    """/proc passes os.access for root (as a read-only mount does): hbm and verify
    computed, then failed to write. A file is made in the directory first."""
    assert cli.main([*argv, "-o", "/proc/mcfric-test.csv"]) == 2
    out, err = capsys.readouterr()
    assert "-o: directory /proc is not writable" in err and out == "", (out, err)


def test_verify_of_an_interrupted_run_names_its_partial_file(tmp_path, capsys):
    """`verify FILE` where only FILE.partial exists (an interrupted run) points to it, as
    `plot` does, instead of "no such file" alone."""
    res = tmp_path / "r.h5"
    assert cli.main(["run", *SMALL, "--no-bounds", "-o", str(res)]) == 0
    res.rename(tmp_path / "r.h5.partial")
    capsys.readouterr()
    rc = cli.main(["verify", str(res), "--member", "0", "--f", "30", "--no-figure",
                   "-o", str(tmp_path / "v.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and "r.h5.partial holds the interrupted run" in err, err
    assert not (tmp_path / "v.csv").exists()


def test_replacing_keeps_permissions_and_writes_through_a_symlink(tmp_path):
    """A CSV or figure written over a symbolic link replaces the link's target, not the
    link, and an existing file keeps its permission bits (0600 stays private)."""
    import stat

    from mcfric.store import replacing

    target = tmp_path / "target.csv"
    target.write_text("old")
    os.chmod(target, 0o600)
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    with replacing(link, "CSV") as tmp:
        tmp.write_text("new")
    assert link.is_symlink() and target.read_text() == "new"
    assert stat.S_IMODE(target.stat().st_mode) == 0o600
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.csv", "target.csv"]


def test_a_replaced_results_or_bounds_file_keeps_its_permissions(tmp_path, capsys):
    """A results file made again with --force, and a bounds file replaced by its own
    command, are renamed from a new file: they keep the old file's permission bits (a
    private 0600 file did become 0644, the umask's)."""
    old = os.umask(0o022)
    try:
        _replaced_files_keep_their_permissions(tmp_path, capsys)
    finally:
        os.umask(old)


def _replaced_files_keep_their_permissions(tmp_path, capsys):
    import stat

    res, bnd = tmp_path / "r.h5", tmp_path / "b.h5"
    for argv, out in ((["run", "two-beam", "--samples", "3", "--n-freq", "5", "--no-bounds",
                        "--no-progress", "--no-figure", "-o", str(res)], res),
                      (["bounds", "two-beam", "--n-freq", "5", "--no-certify", "--no-figure",
                        "-o", str(bnd)], bnd)):
        assert cli.main(argv) == 0, capsys.readouterr().err
        assert stat.S_IMODE(out.stat().st_mode) == 0o644
        os.chmod(out, 0o600)
        assert cli.main(argv + (["--seed", "8", "--force"] if out == res else [])) == 0, \
            capsys.readouterr().err
        assert stat.S_IMODE(out.stat().st_mode) == 0o600, argv


def test_a_missing_file_names_the_files_of_an_engine_order_sweep(tmp_path, capsys):
    """`mcfric run ... -o x.h5` with `engine_orders` writes x-eo1.h5, x-eo2.h5: `info`,
    `plot` and `verify` of x.h5 name them instead of "no such file" alone."""
    for name in ("x-eo1.h5", "x-eo2.h5", "x-eox.h5"):
        (tmp_path / name).write_bytes(b"")
    x = str(tmp_path / "x.h5")
    for argv in (["info", x], ["plot", x], ["verify", x, "--member", "0", "--f", "30"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err
        assert (f"{x}: no such file; an engine-order sweep wrote x-eo1.h5, x-eo2.h5 (one "
                f"file per order)") in err, (argv, err)
    assert cli.main(["info", str(tmp_path / "y.h5")]) == 2
    assert capsys.readouterr().err.strip().endswith("y.h5: no such file")
