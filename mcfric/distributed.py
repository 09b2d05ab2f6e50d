"""Ensembles on a Dask cluster: the chunks of a run as ``dask.distributed`` tasks.

:class:`Cluster` connects to a scheduler (``"tcp://host:port"``) or starts a local cluster
of worker processes (``"local:N"``), checks that every worker computes what this process
would (the solver fingerprint), loads the kernels on each worker once, and then runs a
task per chunk. The caller (:func:`mcfric.ensemble.run`) stays the single writer of the
results file: results come back here, a bounded number at a time, and are placed by their
sample index, so the file does not depend on where or in which order chunks were solved.

A worker that dies loses only its unfinished chunks: the scheduler runs them again
elsewhere. Every chunk's numbers depend on its samples' own seeds alone, so the file is
the same. Dask is an optional dependency (``pip install "mcfric[dask]"``); this module
imports it only when a cluster is asked for.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import signal
import threading
import time

#: Seconds to wait for a scheduler to answer.
CONNECT_TIMEOUT_S = 10.0
#: Seconds to wait for the first worker of a remote scheduler, and for any worker when
#: all have left during a run.
WORKER_TIMEOUT_S = 60.0
#: Chunks in flight per worker thread: one solving, one waiting, so none idles while
#: its last result travels to the client.
IN_FLIGHT_PER_THREAD = 2
#: Seconds between two looks at the cluster's thread count during a run.
THREADS_REFRESH_S = 1.0
#: Dashboard address of a ``local:N`` cluster: any free port on this machine. (None is
#: not "no dashboard" in distributed: it falls back to 8787, and warns when that is taken.)
DASHBOARD = "127.0.0.1:0"
INSTALL_HINT = ('needs Dask, an optional extra: pip install ".[dask]" in the clone '
                '("mcfric[dask]" where mcfric comes from a package index)')

# one kernel at a time per worker process: numba's default (workqueue) threading layer
# must not be entered from two threads at once
_KERNEL_LOCK = threading.Lock()


class ClusterError(Exception):
    """The cluster cannot be used (unreachable, no workers, other solver) or failed."""


def _count(n, word):
    return f"{n} {word}" + ("" if n == 1 else "s")


def _first_line(e):
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0]}" if text else type(e).__name__


def _worker_threads():
    """The numba threads of a task on this worker: the worker's thread count, at most the
    cores numba may use (one kernel runs at a time, see ``_KERNEL_LOCK``)."""
    import numba
    from distributed import get_worker

    try:
        n = get_worker().state.nthreads
    except (ValueError, AttributeError):     # not on a worker (tests call it directly)
        n = 1
    return max(1, min(int(n), numba.config.NUMBA_NUM_THREADS))


def run_task(task, spec, start, stop, fingerprint=None, expected=None):
    """Run ``task(spec, start, stop)`` on a worker, with the worker's thread count.

    Parameters
    ----------
    task : callable
        Module-level function (pickled by name) that solves samples ``start..stop`` of
        ``spec`` and returns their ``{variable: array}``.
    spec : mcfric.spec.RunSpec
    start, stop : int
        The chunk's sample range.
    fingerprint : callable, optional
        Returns this worker's solver fingerprint; with ``expected``, a worker whose
        fingerprint differs refuses the chunk (workers that joined after the start were
        never checked).
    expected : str, optional
        The client's fingerprint.

    Returns
    -------
    start : int
    arrays : dict
    seconds : float
        Time in ``task``, s.
    """
    if expected is not None and fingerprint() != expected:
        raise RuntimeError(f"this worker runs another solver (fingerprint {fingerprint()}, "
                           f"the client's {expected}): install the same mcfric, numpy, "
                           f"scipy, numba and llvmlite, on the same kind of CPU")
    n = _worker_threads()
    spec = dataclasses.replace(spec, execution=dataclasses.replace(spec.execution,
                                                                   threads=n))
    with _KERNEL_LOCK:
        t0 = time.perf_counter()
        arrays = task(spec, start, stop)
        return start, arrays, time.perf_counter() - t0


def _worker_ready(fingerprint, task, spec):
    """On one worker: its solver fingerprint, after one sample (loads or compiles the
    kernels, so the first chunk is not slow)."""
    run_task(task, spec, 0, 1)
    return fingerprint()


def _workers_ignore_ctrl_c():
    """Make the local cluster's worker processes ignore SIGINT; returns the Dask
    configuration to leave (``__exit__``) when the cluster is closed.

    Ctrl-C in a terminal reaches the whole process group, and only the client should act
    on it (it commits, then stops the cluster) instead of every worker printing a
    traceback. A spawned worker cannot be made to ignore it (exec resets Python's
    handlers, and distributed runs nothing of ours before its start-up), so the workers
    are forked from multiprocessing's fork server, started here with SIGINT ignored:
    its children inherit that. (Ignoring SIGINT in the client while the cluster started
    lost a Ctrl-C pressed then: the run went on.) The fork server is the process's own:
    one already running (started by other code without SIGINT ignored) gives workers
    that do not ignore it, and the one started here keeps ignoring it for later
    fork-server children of this process.
    """
    import multiprocessing.forkserver

    import dask
    from distributed.utils import get_mp_context

    config = dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"})
    try:
        get_mp_context()                 # distributed's preload of the fork server
        if threading.current_thread() is threading.main_thread():
            old = signal.signal(signal.SIGINT, signal.SIG_IGN)
            try:
                multiprocessing.forkserver.ensure_running()
            finally:
                signal.signal(signal.SIGINT, old)
    except BaseException:
        config.__exit__(None, None, None)
        raise
    return config


class _HeldStops:
    """Hold the client's stop signals while a local cluster starts, until it exists.

    A SIGINT, SIGTERM or SIGHUP meanwhile is noted and replayed by :meth:`replay` once
    the cluster exists and can be closed (a stop inside the start-up left distributed's
    exit handler a half-started cluster and a traceback). A second one stops at once.
    """

    NAMES = ("SIGINT", "SIGTERM", "SIGHUP")

    def __init__(self):
        self.held, self.old = [], {}

    def __enter__(self):
        if threading.current_thread() is not threading.main_thread():
            return self

        def note(signum, frame):
            self.held.append(signum)
            if len(self.held) > 1:          # pressed again: stop now, whatever is left
                raise KeyboardInterrupt(signal.Signals(signum).name)

        for name in self.NAMES:
            if hasattr(signal, name):
                sig = getattr(signal, name)
                if signal.getsignal(sig) != signal.SIG_IGN:     # ignored stays ignored
                    self.old[sig] = signal.signal(sig, note)
        return self

    def __exit__(self, *exc):
        for sig, h in self.old.items():
            signal.signal(sig, h)
        return False

    def replay(self):
        """Act on the first stop signal noted, as its own handler would have (a Python
        handler is called; the default action is taken as Ctrl-C's, a stop)."""
        if not self.held:
            return
        sig = self.held[0]
        h = self.old.get(sig)
        if callable(h):
            h(sig, None)
        else:
            raise KeyboardInterrupt(signal.Signals(sig).name)


def _close_local(local, config):
    """Stop a local cluster (None: none) and leave its Dask configuration."""
    try:
        if local is not None:
            local.close()
    finally:
        if config is not None:
            config.__exit__(None, None, None)


class Cluster:
    """A connection to a Dask cluster that solves chunks of a run.

    Use :meth:`connect`; :meth:`chunks` yields solved chunks; :meth:`close` ends the
    connection (and a local cluster).

    Attributes
    ----------
    address : str
        As given: ``"local:N"`` or the scheduler's address.
    n_workers, n_threads : int
        Workers at connection, and their threads in all.
    startup_s : float
        Seconds to connect (or start the local cluster) and load the kernels on every
        worker.
    """

    def __init__(self, client, local, address):
        self.client = client
        self._local = local
        self.address = address
        self.n_workers = 0
        self.n_threads = 0
        self.startup_s = 0.0
        # the fingerprint function and the client's value, checked by every chunk
        self._fingerprint = (None, None)
        self._config = None         # the Dask configuration of a local cluster's workers

    @classmethod
    def connect(cls, address, *, spec, task, fingerprint, verbose=False):
        """Connect to ``address`` (or start ``"local:N"``) and make every worker ready.

        Parameters
        ----------
        address : str
            ``"local:N"``: a local cluster of N worker processes with one thread each;
            otherwise a scheduler address such as ``"tcp://10.0.0.5:8786"``.
        spec : mcfric.spec.RunSpec
            The run; each worker solves its sample 0 once to load the kernels.
        task : callable
            What a chunk runs (see :func:`run_task`).
        fingerprint : callable
            Returns the solver fingerprint; every worker's must equal this process's.
        verbose : bool
            Print one line on the cluster when it is ready.

        Raises
        ------
        ClusterError
            Dask is not installed, the scheduler cannot be reached or has no workers, or
            a worker runs another solver (one line each).
        """
        t0 = time.perf_counter()
        try:
            import distributed
        except ImportError:
            raise ClusterError(f"scheduler {address!r} {INSTALL_HINT}") from None
        local = config = None
        try:
            if address.startswith("local:"):
                n = int(address.split(":", 1)[1])
                config = _workers_ignore_ctrl_c()
                # CRITICAL: a worker that dies makes the scheduler log ERROR lines
                # ("Couldn't gather keys") for chunks that Dask then recomputes; a chunk
                # that really fails is reported by chunks(), in one line
                with _HeldStops() as stops:
                    local = distributed.LocalCluster(
                        n_workers=n, threads_per_worker=1, processes=True,
                        dashboard_address=DASHBOARD, silence_logs=logging.CRITICAL)
                stops.replay()
                client = distributed.Client(local, timeout=CONNECT_TIMEOUT_S)
            else:
                client = distributed.Client(address, timeout=CONNECT_TIMEOUT_S)
        except Exception as e:
            # OSError, TimeoutError, ValueError; a tls:// or ucx:// address without its
            # security settings or package is a TypeError or ImportError deep in distributed
            _close_local(local, config)
            raise ClusterError(f"cannot reach the Dask scheduler at {address}: "
                               f"{_first_line(e)}") from None
        except BaseException:
            # Ctrl-C or a stop signal once the local cluster exists: close it
            _close_local(local, config)
            raise
        self = cls(client, local, address)
        self._config = config
        try:
            self._ready(spec, task, fingerprint)
        except BaseException:
            self.close()
            raise
        self.startup_s = time.perf_counter() - t0
        if verbose:
            print(f"cluster: {address}, {_count(self.n_workers, 'worker')}, "
                  f"{_count(self.n_threads, 'thread')}; ready in {self.startup_s:.1f} s "
                  f"(start-up and kernel load)", flush=True)
        return self

    def _ready(self, spec, task, fingerprint):
        client = self.client
        try:
            client.wait_for_workers(1, timeout=WORKER_TIMEOUT_S)
        except (TimeoutError, OSError):
            raise ClusterError(f"the Dask scheduler at {self.address} has no workers after "
                               f"{WORKER_TIMEOUT_S:.0f} s: start some with `dask worker "
                               f"{self.address}`") from None
        workers = client.scheduler_info()["workers"]
        self.n_workers = len(workers)
        self.n_threads = sum(int(w.get("nthreads", 1)) for w in workers.values())
        futures = {w: client.submit(_worker_ready, fingerprint, task, spec, workers=[w],
                                    allow_other_workers=False, pure=False)
                   for w in workers}
        mine = fingerprint()
        self._fingerprint = (fingerprint, mine)
        for w, f in futures.items():
            try:
                theirs = f.result()
            except Exception as e:
                raise ClusterError(f"worker {w} cannot solve this run: "
                                   f"{_first_line(e)}") from None
            if theirs != mine:
                raise ClusterError(f"worker {w} runs another solver (fingerprint {theirs}, "
                                   f"here {mine}): install the same mcfric, numpy, scipy, "
                                   f"numba and llvmlite on every worker, on one kind of "
                                   f"CPU")

    def chunks(self, task, spec, chunks, timing):
        """Solve ``chunks`` on the cluster, yielding each as it completes.

        At most ``IN_FLIGHT_PER_THREAD`` chunks per worker thread (the threads the
        cluster has now: workers may join or leave) are submitted and not yet received,
        so the client's memory does not grow with the number of samples.

        Parameters
        ----------
        task : callable
            See :func:`run_task`.
        spec : mcfric.spec.RunSpec
        chunks : list of (start, stop)
        timing : dict
            ``timing["kernel_s"]`` is increased by each chunk's time on its worker, s.

        Yields
        ------
        start : int
        arrays : callable
            Returns the chunk's ``{variable: array}``.

        Raises
        ------
        ClusterError
            A chunk failed on the cluster (also after Dask's retry), or the cluster had
            no worker, or its scheduler did not answer, for ``WORKER_TIMEOUT_S``.
        """
        from distributed import as_completed

        todo = iter(chunks)
        live = {}          # key: (future, range) of every chunk submitted, not yet yielded
        running = as_completed(loop=self.client.loop)
        # when the threads were counted, the count, and whether the scheduler answered
        checked = [-math.inf, self.n_threads, True]

        def next_done():
            # the next finished chunk (None when all are); with no worker (or no answer
            # from the scheduler) for WORKER_TIMEOUT_S the chunks would wait forever
            alone_since = None
            while not running.has_ready():
                if running.is_empty():
                    return None
                n = threads()
                if not n:
                    alone_since = alone_since or time.monotonic()
                    if time.monotonic() - alone_since > WORKER_TIMEOUT_S:
                        why = ("has had no workers" if n == 0 else
                               "scheduler has not answered")
                        raise ClusterError(
                            f"the cluster {why} for {WORKER_TIMEOUT_S:.0f} s "
                            f"({_count(len(live), 'chunk')} waiting): start workers with "
                            f"`dask worker {self.address}`, or check the scheduler")
                else:
                    alone_since = None
                with running.thread_condition:
                    running.thread_condition.wait(timeout=0.1)
            return next(running)

        def threads():
            # workers may join or leave during a run: their thread count is asked again
            # at most once a second, so new workers get chunks and the client's memory
            # stays bounded by the threads there are (None: the scheduler did not answer)
            now = time.monotonic()
            if now - checked[0] >= THREADS_REFRESH_S:
                try:
                    checked[1] = sum(self.client.nthreads().values())
                    checked[2] = True
                except Exception:
                    checked[2] = False
                checked[0] = now
            return checked[1] if checked[2] else None

        def fill():
            limit = max(2, IN_FLIGHT_PER_THREAD * (threads() or checked[1]))
            while len(live) < limit:
                ab = next(todo, None)
                if ab is None:
                    return
                f = self.client.submit(run_task, task, spec, *ab, *self._fingerprint,
                                       pure=False, retries=1)
                live[f.key] = (f, ab)
                running.add(f)

        try:
            fill()
            while (f := next_done()) is not None:
                a, b = live.pop(f.key)[1]
                try:
                    start, arrays, seconds = f.result()
                except Exception as e:
                    raise ClusterError(f"samples {a}..{b - 1} failed on the cluster: "
                                       f"{_first_line(e)}") from None
                f.release()
                del f
                fill()
                timing["kernel_s"] += seconds
                yield start, (lambda arrays=arrays: arrays)
                del arrays
        finally:
            # an interrupt or an error: nothing more is computed for this run
            running.clear()
            if live:
                self.client.cancel([f for f, _ in live.values()])
            live.clear()

    def close(self):
        """Close the connection, and stop the local cluster if this started one."""
        try:
            self.client.close()
        finally:
            _close_local(self._local, self._config)

