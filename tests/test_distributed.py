"""Ensembles on a Dask cluster: the same file as a local run, through worker and client
kills; an unreachable scheduler or a missing Dask gives one line and no file.

The reference is always a plain local run of the same configuration (in this process),
never an earlier cluster run.
"""

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from mcfric import cli, config, ensemble
from mcfric.distributed import DASHBOARD
from mcfric.store import partial_path

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
# 1000 members in 250 chunks of 4: long enough (several seconds on a cluster) to be
# killed mid-run, small enough for the default suite. The bounds are computed on the
# client, not the cluster: their certification (tested elsewhere) is left out here.
CONFIG = ('[model]\npreset = "eight-beam"\n[frequency]\nn = 100\n'
          '[sampling]\nsamples = 1000\nseed = 11\n[run]\nchunk = 4\n'
          '[bounds]\ncertify = false\n')


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The configuration file and its local run (which also warms the kernel cache that
    the workers load)."""
    d = tmp_path_factory.mktemp("reference")
    toml = d / "cfg.toml"
    toml.write_text(CONFIG)
    out = d / "local.h5"
    ensemble.run(config.load(toml, {"run.chunk": (64, "--chunk")}), out, progress=False)
    return toml, out


def datasets(path):
    """``{name: bytes}`` of every dataset of a results file, groups included."""
    out = {}
    with h5py.File(path, "r") as h5:
        h5.visititems(lambda name, obj: out.__setitem__(name, obj[...].tobytes())
                      if isinstance(obj, h5py.Dataset) else None)
    return out


def assert_same_file(path, ref):
    a, b = datasets(path), datasets(ref)
    assert sorted(a) == sorted(b)
    assert "metric" in a and "response" in a and "bounds/upper" in a
    for name in b:
        assert a[name] == b[name], name
    with h5py.File(path, "r") as h5, h5py.File(ref, "r") as r:
        assert h5.attrs["complete"] == 1 and h5.attrs["samples"] == r.attrs["samples"]
        assert h5.attrs["n_not_converged"] == r.attrs["n_not_converged"]
        assert h5.attrs["solver_fingerprint"] == r.attrs["solver_fingerprint"]


def cli_cmd(toml, out, *extra):
    return [sys.executable, "-m", "mcfric", "run", str(toml), "-o", str(out),
            "--no-progress", "--no-figure", *extra]


def done(out):
    """Samples marked done in ``out``'s partial file (read while another process writes)."""
    try:
        with h5py.File(partial_path(out), "r", locking=False) as h5:
            return int(h5["done"][...].sum())
    except (OSError, KeyError):
        return 0


def wait_for_progress(p, out, target, timeout=300):
    deadline = time.monotonic() + timeout
    while p.poll() is None and done(out) < target and time.monotonic() < deadline:
        time.sleep(0.005)
    n = done(out)
    assert p.poll() is None, "the run ended before it could be killed"
    assert target <= n, n
    return n


def test_local_cluster_gives_the_local_file(reference, tmp_path, capsys):
    toml, ref = reference
    out = tmp_path / "cluster.h5"
    rc = cli.main(["run", str(toml), "-o", str(out), "--scheduler", "local:2",
                   "--no-figure"])
    text = capsys.readouterr().out
    assert rc == 0
    assert "cluster: local:2, 2 workers, 2 threads" in text
    assert_same_file(out, ref)


def test_a_worker_killed_mid_run_loses_nothing(reference, tmp_path):
    from distributed import Client, LocalCluster

    toml, ref = reference
    out = tmp_path / "cluster.h5"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=DASHBOARD) as cluster, Client(cluster) as client:
        pids = client.run(os.getpid)
        p = subprocess.Popen(cli_cmd(toml, out, "--scheduler", cluster.scheduler_address),
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True)
        try:
            wait_for_progress(p, out, 100)
            # a worker computing a chunk (an idle one would lose nothing)
            deadline = time.monotonic() + 60
            while not (busy := [w for w, keys in client.processing().items() if keys]):
                assert time.monotonic() < deadline, "no worker is computing a chunk"
                time.sleep(0.01)
            victim = pids[busy[0]]
            os.kill(victim, signal.SIGKILL)
            stdout, stderr = p.communicate(timeout=300)
        finally:
            if p.poll() is None:
                p.kill()
        assert p.returncode == 0, stderr
        # the cluster lost a worker process (its nanny started another)
        assert victim not in client.run(os.getpid).values()
    assert_same_file(out, ref)


ACTIVE = {"now": 0, "peak": 0}
ACTIVE_LOCK = threading.Lock()


def slow_chunk(spec, start, stop):
    """A chunk task that takes 0.2 s and counts how many run at once."""
    with ACTIVE_LOCK:
        ACTIVE["now"] += 1
        ACTIVE["peak"] = max(ACTIVE["peak"], ACTIVE["now"])
    time.sleep(0.2)
    with ACTIVE_LOCK:
        ACTIVE["now"] -= 1
    return {"converged": np.ones(stop - start, bool)}


def test_workers_that_join_mid_run_get_chunks(monkeypatch):
    """The client looks at the cluster's threads during a run: after three workers join
    the one it connected to, four chunks compute at once (with the chunks in flight fixed
    at the start, two would)."""
    from distributed import Client, LocalCluster

    from mcfric import distributed

    # workers as threads of this process, so the kernel lock would serialise them
    monkeypatch.setattr(distributed, "_KERNEL_LOCK", contextlib.nullcontext())
    ACTIVE.update(now=0, peak=0)
    spec = config.load("two-beam").spec
    timing = {"kernel_s": 0.0}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=DASHBOARD) as cluster, Client(cluster) as client:
        c = distributed.Cluster(client, None, cluster.scheduler_address)
        c.n_threads = 1
        source = c.chunks(slow_chunk, spec, [(i, i + 1) for i in range(60)], timing)
        starts = [next(source)[0]]
        cluster.scale(4)
        client.wait_for_workers(4, timeout=60)
        starts += [a for a, _ in source]
    assert sorted(starts) == list(range(60))
    assert ACTIVE["peak"] == 4, ACTIVE
    assert timing["kernel_s"] >= 60 * 0.2


def test_a_run_whose_workers_all_left_stops_instead_of_waiting(monkeypatch):
    """With every worker gone mid-run the chunks would wait forever: after
    WORKER_TIMEOUT_S without a worker the run stops with a ClusterError (the CLI keeps
    the finished chunks and says how to resume)."""
    from distributed import Client, LocalCluster

    from mcfric import distributed

    monkeypatch.setattr(distributed, "_KERNEL_LOCK", contextlib.nullcontext())
    monkeypatch.setattr(distributed, "WORKER_TIMEOUT_S", 2.0)
    ACTIVE.update(now=0, peak=0)
    spec = config.load("two-beam").spec
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=DASHBOARD) as cluster, Client(cluster) as client:
        c = distributed.Cluster(client, None, cluster.scheduler_address)
        c.n_threads = 1
        source = c.chunks(slow_chunk, spec, [(i, i + 1) for i in range(60)],
                          {"kernel_s": 0.0})
        next(source)
        cluster.scale(0)
        t = time.monotonic()
        with pytest.raises(distributed.ClusterError, match="no workers for 2 s"):
            for _ in source:
                pass
        assert time.monotonic() - t < 30


def test_a_client_killed_mid_run_resumes_to_the_same_file(reference, tmp_path):
    toml, ref = reference
    out = tmp_path / "cluster.h5"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    # its own session: the kill takes the client and its local cluster's processes at once
    p = subprocess.Popen(cli_cmd(toml, out, "--scheduler", "local:2"), env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                         start_new_session=True)
    try:
        wait_for_progress(p, out, 100)
    finally:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
    assert p.returncode == -signal.SIGKILL
    assert not out.exists() and partial_path(out).exists()
    r = subprocess.run(cli_cmd(toml, out, "--scheduler", "local:2", "--resume"), env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    assert_same_file(out, ref)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1",
                                     "tls://127.0.0.1:1"])   # a TypeError traceback before
def test_an_unreachable_scheduler_gives_one_line_and_no_file(tmp_path, capsys, monkeypatch,
                                                             address):
    from mcfric import distributed

    monkeypatch.setattr(distributed, "CONNECT_TIMEOUT_S", 2.0)
    out = tmp_path / "r.h5"
    rc = cli.main(["run", "two-beam", "--samples", "4", "--n-freq", "10", "-o", str(out),
                   "--scheduler", address, "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and f"cannot reach the Dask scheduler at {address}" \
        in err, err
    assert list(tmp_path.iterdir()) == []


def test_without_dask_the_flag_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)       # import fails
    out = tmp_path / "r.h5"
    rc = cli.main(["run", "two-beam", "--samples", "4", "--n-freq", "10", "-o", str(out),
                   "--scheduler", "local:2", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert 'pip install ".[dask]" in the clone' in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("address", ["local:0", "local:x", "8786", "tcp:/host", "local: 2"])
def test_a_bad_scheduler_address_is_refused(tmp_path, capsys, address):
    rc = cli.main(["run", "two-beam", "-o", str(tmp_path / "r.h5"), "--scheduler",
                   address])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "scheduler" in err, err
    assert list(tmp_path.iterdir()) == []


def test_a_task_runs_with_the_workers_threads_and_the_same_numbers(reference):
    """``run_task`` outside a worker: one thread, and exactly what the local run stored."""
    from mcfric.distributed import run_task

    toml, ref = reference
    spec = config.load(toml).spec
    start, arrays, seconds = run_task(ensemble.solve_records, spec, 8, 12)
    assert start == 8 and seconds > 0
    with h5py.File(ref, "r") as h5:
        for name in ("metric", "converged", "response", "mu0"):
            assert np.array_equal(arrays[name], h5[name][8:12]), name


SOLVE_RECORDS = ensemble.solve_records


def fail_on_sample_8(spec, start, stop):
    """A chunk task that fails for the chunk starting at sample 8, wherever it runs."""
    if start == 8:
        raise MemoryError("a worker ran out of memory")
    return SOLVE_RECORDS(spec, start, stop)


def test_a_chunk_that_fails_everywhere_stops_resumably(reference, tmp_path, capsys,
                                                       monkeypatch):
    """After Dask's retry, a failing chunk ends the run: one line, exit 1, and a partial
    file that `--resume` (here: locally) completes to the local run's file."""
    from distributed import LocalCluster

    toml, ref = reference
    out = tmp_path / "cluster.h5"
    monkeypatch.setattr(ensemble, "solve_records", fail_on_sample_8)
    # threads in this process, so that the replaced task is the one the workers run
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=DASHBOARD) as cluster:
        rc = cli.main(["run", str(toml), "-o", str(out), "--scheduler",
                       cluster.scheduler_address, "--no-progress", "--no-figure"])
    err = capsys.readouterr().err
    assert rc == 1 and err.count("\n") == 1, err
    assert "samples 8..11 failed on the cluster: MemoryError" in err and "--resume" in err
    assert not out.exists() and 0 < done(out) < 1000
    monkeypatch.undo()
    assert cli.main(["run", str(toml), "-o", str(out), "--resume", "--no-progress",
                     "--no-figure"]) == 0
    assert_same_file(out, ref)


def test_a_scheduler_without_workers_gives_one_line_and_no_file(tmp_path, capsys,
                                                                 monkeypatch):
    from distributed import LocalCluster

    from mcfric import distributed

    monkeypatch.setattr(distributed, "WORKER_TIMEOUT_S", 1.0)
    out = tmp_path / "r.h5"
    with LocalCluster(n_workers=0, processes=False, dashboard_address=DASHBOARD) as cluster:
        rc = cli.main(["run", "two-beam", "--samples", "4", "--n-freq", "10", "-o",
                       str(out), "--scheduler", cluster.scheduler_address, "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "has no workers" in err, err
    assert list(tmp_path.iterdir()) == []


def fingerprint_by_side():
    """A solver fingerprint that differs between the workers and the client."""
    from distributed import get_worker

    try:
        get_worker()
        return "worker-solver"
    except ValueError:
        return "client-solver"


def test_a_worker_with_another_solver_is_refused(tmp_path, capsys, monkeypatch):
    from distributed import LocalCluster

    monkeypatch.setattr(ensemble, "fingerprint", fingerprint_by_side)
    out = tmp_path / "r.h5"
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=DASHBOARD) as cluster:
        rc = cli.main(["run", "two-beam", "--samples", "4", "--n-freq", "10", "-o",
                       str(out), "--scheduler", cluster.scheduler_address, "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1, err
    assert "runs another solver (fingerprint worker-solver, here client-solver)" in err
    assert list(tmp_path.iterdir()) == []


def test_a_chunk_refuses_a_worker_with_another_solver():
    """Workers that join after the start were never checked: every chunk compares its
    worker's fingerprint with the client's and refuses to solve on a mismatch."""
    from mcfric.distributed import run_task

    def task(spec, start, stop):
        raise AssertionError("solved on a worker with another solver")

    with pytest.raises(RuntimeError, match="runs another solver .fingerprint late, the "
                                           "client's first"):
        run_task(task, None, 0, 1, lambda: "late", "first")
    assert run_task(lambda spec, a, b: {"a": a}, _spec(), 0, 1, lambda: "same", "same")[1] \
        == {"a": 0}


def _spec():
    return config.validate(config.defaults()).spec


def test_a_stop_while_the_local_cluster_starts_is_held_and_its_workers_ignore_ctrl_c(
        monkeypatch):
    """A Ctrl-C while the local cluster started was lost (SIGINT was ignored in the
    client meanwhile, so that the workers inherited it): the run went on and exited 0.
    The stop is now held until the cluster exists, then raised, and the cluster closed;
    the workers still ignore SIGINT (a terminal's Ctrl-C reaches them too), forked from
    a fork server that ignores it, and the Dask setting that does it is left after."""
    import dask
    import distributed as dd

    from mcfric import distributed as md

    if threading.current_thread() is not threading.main_thread():
        pytest.skip("signal handlers are the main thread's")
    method = dask.config.get("distributed.worker.multiprocessing-method")
    made, ignoring = [], {}

    class Interrupted(dd.LocalCluster):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            made.append(self)
            with dd.Client(self) as c:
                ignoring.update(c.run(lambda: signal.getsignal(signal.SIGINT)
                                      == signal.SIG_IGN))
            os.kill(os.getpid(), signal.SIGINT)       # still inside the start-up
            time.sleep(0.2)                          # its handler runs here

    monkeypatch.setattr(dd, "LocalCluster", Interrupted)
    # Python's own handler (a pytest-xdist worker ignores SIGINT: held, then ignored too)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            md.Cluster.connect("local:2", spec=None, task=None, fingerprint=None)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert len(made) == 1 and made[0].status.name == "closed"
    assert len(ignoring) == 2 and all(ignoring.values()), ignoring
    assert dask.config.get("distributed.worker.multiprocessing-method") == method
