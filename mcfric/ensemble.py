"""Monte Carlo ensembles: sample -> kernel -> store, chunk by chunk, resumable.

:func:`run` draws the parameters of a chunk of samples (:mod:`mcfric.sampling`, one
``SeedSequence`` child per sample), solves them (:func:`mcfric.hbm.solve`, numba threads,
the GIL released) and hands the result to a writer thread, which computes the metric and
writes the chunk into the store (:mod:`mcfric.store`) while the kernel already solves the
next chunk. A queue of one chunk bounds the memory to about three chunks, whatever the
number of samples.

The file's layout, the chunk size and the run's size on disk and in memory are
:mod:`mcfric.run_file`'s; they are checked here before any work.

With ``[run] scheduler`` the chunks are solved on a Dask cluster instead
(:mod:`mcfric.distributed`); this process stays the only writer of the file.

Every sample's result depends only on its own parameters, so the results are bitwise
identical for any thread count, chunk size, interruption and resume, here or on a cluster.
"""

from __future__ import annotations

import json
import os
import queue
import shutil
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import hbm, stop_signals
from .config import first_difference, identity
from .indicator import file_report as indicator_report
from .memory import check_fits, human
from .metric import METRIC_UNITS
from .peaks import file_report as peak_report
from .peaks import report_text, unrefined_lines
from .results_check import check_file
from .run_file import (
    RECORD,
    bounds_bytes,
    chunk_samples,
    fingerprint,
    layout,
    output_bytes,
    peak_memory_bytes,
)
from .store import Store, StoreError, iter_records, partial_path, read_attrs
from .store.lock import LockError, OutputLock
from .threads import interruptible, threads
from .validators import show


class RunError(Exception):
    """The run cannot start as asked (existing files, a resume that does not match).

    Its message names the command line's flags, as ``mcfric run`` prints it: from
    Python, ``--force`` is :func:`run`'s ``force=True``, ``--resume`` its
    ``resume=True``, ``-o`` its ``path``."""


class Interrupted(Exception):
    """Ctrl-C: the chunks written so far are committed; ``summary`` says where."""

    def __init__(self, summary):
        super().__init__("interrupted")
        self.summary = summary


@dataclass
class Summary:
    """What a run did.

    Attributes
    ----------
    path : Path
        The results file (``FILE``, or ``FILE.partial`` if interrupted).
    samples, n_freq : int
        Ensemble size and frequencies per sample.
    samples_done : int
        Samples stored (== samples when complete).
    samples_this_session : int
        Samples computed by this call (0 if the file was already complete).
    not_converged : int
        Points (sample, frequency) that did not converge, over all stored samples.
    wall_s, kernel_s : float
        Time of this call, and of it the time spent in the kernel, s (on a cluster: the
        workers' time in their chunks, summed).
    bounds_s : float
        Of ``wall_s``, the bounds' computation (certification included), s; 0 where they
        were not computed in this call.
    complete, already_complete : bool
    peaks, harmonics : list of str or None
        Lines that :meth:`text` prints: the peak statistics (members' resonance peaks,
        folds; None without peak refinement) and the harmonic content (the multi-harmonic
        report, or the single-harmonic indicator's).
    notes : list of str
        Lines :meth:`text` prints last: e.g. a ``FILE.partial`` found beside a complete
        ``FILE``, which the run leaves as it is.
    cluster : str
        The Dask scheduler of this call (``"local:N"`` or an address); "" for none.
    startup_s : float
        Of ``wall_s``, the cluster's start-up (connection, workers' kernel load), s.
    bounds_computed : bool
        Whether this call computed the bounds (a new file), rather than finding them in
        an earlier session's partial or complete file.
    """

    path: Path
    samples: int
    n_freq: int
    samples_done: int
    samples_this_session: int
    not_converged: int
    wall_s: float
    kernel_s: float
    complete: bool
    already_complete: bool = False
    peaks: list | None = None
    harmonics: list | None = None
    cluster: str = ""
    startup_s: float = 0.0
    bounds_computed: bool = False
    bounds_s: float = 0.0
    notes: list = field(default_factory=list)

    @property
    def points(self):
        """Points (sample, frequency) stored."""
        return self.samples_done * self.n_freq

    def text(self):
        """The ensemble's summary printed at the end of a run, several lines. ``mcfric
        run`` adds the bounds' (:meth:`mcfric.bounds.Bounds.summary` of
        :func:`~mcfric.bounds.read_bounds`) and the members' check against them
        (:func:`~mcfric.bounds.check_members`)."""
        pts = self.points
        pct = 100.0 * self.not_converged / max(pts, 1)
        ens_s = self.wall_s - self.bounds_s
        rate = self.samples_this_session * self.n_freq / max(ens_s, 1e-9)
        lines = [f"samples: {self.samples_done} of {self.samples}, "
                 f"{self.n_freq} frequencies each: {pts:,} points",
                 f"not converged: {self.not_converged:,} points ({pct:.3g} %)"]
        if self.samples_this_session:
            of = (f"bounds {self.bounds_s:.2f} s, ensemble {ens_s:.2f} s"
                  if self.bounds_s else f"ensemble {ens_s:.2f} s")
            lines.append(f"wall time: {self.wall_s:.2f} s for {self.samples_this_session} "
                         f"samples: {of} (kernel {self.kernel_s:.2f} s), {rate:,.0f} "
                         f"points/s in the ensemble")
            if self.cluster:
                lines.append(f"cluster:   {self.cluster}; start-up {self.startup_s:.2f} s "
                             f"of the wall time; kernel time summed over the workers")
        lines += list(self.peaks or [])
        lines += list(self.harmonics or [])
        lines.append(f"results: {self.path}")
        return "\n".join(lines + list(self.notes))


def _stored_config(attrs, path):
    try:
        return json.loads(attrs["config_json"])
    except (KeyError, ValueError, TypeError):
        raise RunError(f"{path}: not an mcfric results file (no readable config)") from None


def _same_run(spec, attrs, path):
    """None if ``attrs`` describe the same run as ``spec``, else the first differing key
    with both values: ``"sampling.samples = 20000 there, 2000 here"``."""
    stored = json.loads(json.dumps(identity(_stored_config(attrs, path))))
    key = first_difference(spec.identity, stored)
    if key is None:
        return None

    def at(d):
        for k in key.split("."):
            if not isinstance(d, dict) or k not in d:
                return "unset"
            d = d[k]
        return show(d)
    return f"{key} = {at(stored)} there, {at(spec.identity)} here"


def _count_not_converged(path):
    n = 0
    for _, arrays in iter_records(path, ["converged"]):
        n += int(np.count_nonzero(~arrays["converged"]))
    return n


def _pending_chunks(done, chunk):
    """Contiguous ranges of records not done, split into chunks of at most ``chunk``."""
    idx = np.flatnonzero(~done)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) != 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    stops = np.concatenate([idx[breaks] + 1, [idx[-1] + 1]])
    out = []
    for a, b in zip(starts.tolist(), stops.tolist()):
        for s in range(a, b, chunk):
            out.append((s, min(b, s + chunk)))
    return out


def _check_output_place(final):
    """Refuse an output whose directory is missing, or that is a directory itself (which
    ``force`` cannot replace: the run would fail only at its final rename)."""
    if not final.parent.is_dir():
        raise RunError(f"{final.parent}: output directory does not exist")
    if final.is_dir():
        raise RunError(f"{final} is a directory, not a results file; choose another path")


def prepare(spec, path, *, resume=False, force=False):
    """Decide what a run of ``spec`` (a :class:`~mcfric.spec.RunSpec`) must do with ``path``.

    Returns ``("complete", attrs)``, ``("resume", (store, not_converged_so_far))`` or
    ``("new", None)``. Raises :class:`RunError` when it must not proceed (nothing is
    written in that case).
    """
    final = Path(path)
    part = partial_path(final)
    _check_output_place(final)
    if final.exists() and not force:
        try:
            attrs = read_attrs(final)
        except StoreError as e:
            if not (resume and part.exists()):
                raise RunError(f"{e}; use --force to replace it") from None
            attrs = None
        if (attrs is not None and int(attrs.get("samples", -1)) == 0
                and not (resume and part.exists())):
            # its configuration can equal this run's: not "this run, by other code"
            raise RunError(f"{final} exists and holds bounds alone (mcfric bounds), no "
                           f"members; use --force to replace it, or choose another -o")
        diff = None if attrs is None else _same_run(spec, attrs, final)
        if (attrs is not None and diff is None and attrs.get("complete") == 1
                and not (resume and part.exists()
                         and attrs.get("solver_fingerprint") != fingerprint())):
            # the same run by other code or libraries: its bits need not be this code's
            # (with --resume and a partial file: the recomputation --force started)
            _check_fingerprint(attrs, f"{final} holds this run, made by other solver code, "
                                      f"numpy/scipy/numba/llvmlite versions or kind of CPU",
                               "use --force to recompute it" + (
                                   f", --resume to continue {part}" if part.exists() else "")
                               + ", or choose another -o")
            try:
                check_file(final)       # edited or damaged: not "this run, nothing to do"
            except StoreError as e:
                raise RunError(f"{e}; use --force to replace it") from None
            return "complete", attrs
        if not (resume and part.exists()):
            raise RunError(f"{final} exists and holds a different run (first difference: "
                           f"{diff}); use --force to replace it, or choose another -o")
        # --resume with a partial file: an interrupted run that was to replace FILE
        # (started with --force); it is checked below and replaces FILE when complete
    if part.exists() and not force:
        try:
            attrs = read_attrs(part)
            done = int(np.count_nonzero(iter_done(part)))
        except StoreError as e:
            if resume:
                raise RunError(f"cannot resume: {e}; use --force to start again") from None
            raise RunError(f"{e}; use --force to start again") from None
        if not resume:
            raise RunError(f"{part} exists (an interrupted run, {done} of "
                           f"{attrs.get('samples')} samples done): add --resume to "
                           f"continue it, or --force to start again")
        diff = _same_run(spec, attrs, part)
        if diff is not None:
            raise RunError(f"cannot resume {part}: it was started with another "
                           f"configuration ({diff}); continue it with its own (`mcfric "
                           f"config {part} > run.toml`, then `mcfric run run.toml -o "
                           f"{final} --resume`), or discard its samples with --force")
        _check_fingerprint(attrs, f"cannot resume {part}: the solver code, numpy/scipy/"
                                  f"numba/llvmlite or this machine's kind of CPU changed "
                                  f"since it was started",
                           "results would mix two versions; use --force to start again")
        try:
            # read before reopening: HDF5 refuses a second handle with other locking flags
            not_conv = _count_not_converged(part)
            return "resume", (Store.reopen(final, RECORD), not_conv)
        except StoreError as e:
            raise RunError(f"cannot resume: {e}; use --force to start again") from None
    return "new", None


def _partial_beside(spec, final):
    """Lines on a ``FILE.partial`` beside the complete ``final`` (an interrupted run, e.g.
    one started with --force and cut short): said, and left as it is."""
    part = partial_path(final)
    if not part.exists():
        return []
    try:
        attrs = read_attrs(part)
        done = int(np.count_nonzero(iter_done(part)))
        diff = _same_run(spec, attrs, part)
    except (StoreError, RunError) as e:
        return [f"note: {part} beside it cannot be read ({e}); it is left as it is"]
    if diff is None:
        return [f"note: {part} beside it is an interrupted copy of this run ({done} of "
                f"{attrs.get('samples')} samples); it is left as it is and may be deleted"]
    what = (f"{part} beside it is an interrupted run of another configuration ({diff}; "
            f"{done} of {attrs.get('samples')} samples), left as it is")
    if attrs.get("solver_fingerprint") != fingerprint():
        # --resume would refuse it: its bits are another code's
        return [f"note: {what}; made by other solver code or libraries, it cannot be "
                f"continued here: delete it"]
    return [f"note: {what}: `mcfric config {part} > run.toml`, then `mcfric run run.toml "
            f"-o {final} --resume` continues it (it replaces {final} when complete), or "
            f"delete it"]


def _check_fingerprint(attrs, what, remedy):
    """Raise :class:`RunError` ``"{what} (fingerprint X vs Y); {remedy}"`` when the file's
    solver fingerprint (``attrs``) is not this process's."""
    fp = fingerprint()
    if attrs.get("solver_fingerprint") != fp:
        raise RunError(f"{what} (fingerprint {attrs.get('solver_fingerprint')} vs {fp}); "
                       f"{remedy}")


def iter_done(path):
    """The ``done`` mask of a results file (complete or partial), bool (samples,)."""
    from .store import read
    return read(path, "done").astype(bool)


def _put(q, item, writer, err):
    """``q.put`` that gives up if the writer died (its exception is re-raised)."""
    while True:
        if err:
            raise err[0]
        try:
            q.put(item, timeout=0.2)
            return
        except queue.Full:
            if not writer.is_alive():
                raise err[0] if err else RuntimeError("the writer thread stopped")


def run(spec, path, *, resume=False, force=False, progress=True, groups="auto",
        space_check=True, started=None):
    """Run (or continue) the Monte Carlo ensemble of ``spec`` into the results file ``path``.

    Parameters
    ----------
    spec : mcfric.spec.RunSpec or mcfric.config.Config
        The run (a validated configuration stands for its ``spec``).
    path : str or Path
        Results file. The run writes ``path + ".partial"`` and renames it when complete.
    resume : bool
        Continue ``path + ".partial"`` (its configuration and solver fingerprint must
        match; ``[run]`` settings may differ). Without one, a fresh run starts.
    force : bool
        Replace an existing results file or partial file that holds another run.
    progress : bool
        Show a tqdm progress bar on stderr.
    groups : callable, "auto" or None
        Called only when a new results file is created; returns ``{group: (variables,
        attrs)}`` written with it, so that the file never changes but for its chunks
        afterwards. ``"auto"`` (default): the ``bounds/`` group when the spec has
        bounds (``[bounds] enabled``; computed before the ensemble); None: no groups.
    space_check : bool
        Refuse, before any work, a run whose file needs more than the free space of its
        file system (:func:`check_space`). False skips the check.
    started : callable or None
        Called with no arguments once the run is accepted (the files, the model and the
        space checked), before any work or any connection to a cluster: ``mcfric run``
        prints its header there, so a refused run prints its one line only.

    Returns
    -------
    Summary

    Raises
    ------
    TypeError, ValueError
        ``spec`` is neither a configuration nor the unchanged spec of one (one changed
        with :func:`dataclasses.replace` is checked by nothing, and the file's record of
        its configuration would describe another run: change the configuration with
        :meth:`~mcfric.config.Config.replace` instead), or another argument is of the
        wrong type.
    RunError
        Existing files do not allow the run as asked (nothing was written). The message
        names the command line's flags: ``--resume`` and ``--force`` are ``resume=True``
        and ``force=True`` here.
    StoreError
        A new file's directory has less free than 256 kB and the bounds group (checked
        before any work, even with ``space_check=False``), or a write failed (one
        line).
    Interrupted
        Ctrl-C: the samples finished so far are committed in ``path + ".partial"``.
    """
    t_start = time.perf_counter()
    spec = _own_spec(spec)
    for name, value in (("resume", resume), ("force", force), ("progress", progress),
                        ("space_check", space_check)):
        if not isinstance(value, (bool, np.bool_)):
            raise TypeError(f"{name}: expected True or False, got {value!r}")
    if not (groups is None or groups == "auto" or callable(groups)):
        raise TypeError(f"groups: expected 'auto', None or a callable, got {groups!r}")
    if not (started is None or callable(started)):
        raise TypeError(f"started: expected None or a callable, got {started!r}")
    if not isinstance(path, (str, os.PathLike)) or not os.fspath(path):
        # Path(None) was a TypeError from os; Path("") the current directory
        raise RunError(f"path: expected a results file's path, got {path!r}")
    final = Path(path)
    if final.name.endswith((".lock", ".partial")):
        # the names of a run's lock and partial files: a run on the stem would take this
        # file for its own and remove or replace it
        raise RunError(f"{final.name}: ends in {final.suffix}, the name of a run's "
                       f"{'lock' if final.suffix == '.lock' else 'interrupted'} file; "
                       f"choose another name")
    _check_output_place(final)        # before the lock: a refusal writes nothing
    # one owner per output, from the first look at the files to the last rename
    lock = OutputLock(final, "mcfric run")
    try:
        lock.acquire()
    except LockError as e:
        raise RunError(str(e)) from None
    try:
        return _run_locked(spec, final, resume, force, progress, groups, t_start,
                           space_check, started or (lambda: None))
    finally:
        lock.release()


def _own_spec(spec):
    """The RunSpec of ``spec`` (a Config or a RunSpec), checked to be its own
    configuration's: every check of the configuration then holds for it."""
    from .config import Config, validate
    from .spec import RunSpec

    if isinstance(spec, Config):
        spec = spec.spec             # checked below too: a Config may be built by hand
    if not isinstance(spec, RunSpec):
        hint = (f" (load it first: mcfric.config.load({spec!r}))"
                if isinstance(spec, (str, Path)) else "")
        raise TypeError(f"spec: expected a mcfric.config.Config or its .spec, got "
                        f"{type(spec).__name__}{hint}")
    if not spec.matches(validate(json.loads(spec.config_json)).spec):
        raise ValueError("spec: differs from its own configuration (changed with "
                         "dataclasses.replace?): nothing checks such a spec, and the file "
                         "would record another run; change the configuration instead, "
                         "e.g. cfg.replace(\"run.threads\", 1), and run that")
    return spec


def check_solvable(spec):
    """Refuse, before any file, a multi-harmonic run whose chunks the solve would refuse
    (its fixed limit on the receptances and workspaces, :func:`mcfric.hbm.
    check_harmonic_memory`): not skipped by ``--skip-space-check``."""
    if spec.solver.harmonics == 1:
        return
    chunk = chunk_samples(spec)
    try:
        with threads(spec.execution.threads):
            hbm.check_harmonic_memory(spec.model, spec.solver.harmonics, spec.solver.n_time,
                                      len(spec.freq_hz), chunk if spec.mistuned else 1,
                                      per="chunk")
    except ValueError as e:
        raise RunError(str(e)) from None


def check_space(spec, final, resume):
    """Refuse a run that cannot fit on disk or in memory (before any work).

    A fresh run needs the whole file; a resumed one what its ``.partial`` has not yet
    written (the chunks are allocated up front but sparse until written). The memory
    estimate is :func:`peak_memory_bytes` against the available memory.
    """
    try:
        check_fits(peak_memory_bytes(spec), "the run", "use fewer beams or frequencies, a "
                   "smaller [run] chunk, or --skip-space-check if the estimate is wrong")
    except ValueError as e:                  # a refused run, as the disk check's below
        raise RunError(str(e)) from None
    need = output_bytes(spec)
    part = partial_path(final)
    if resume and part.exists():
        need = max(0, need - part.stat().st_blocks * 512)
    free = shutil.disk_usage(final.parent).free
    # 1 % and 1 MB of headroom for the metadata and the figure
    room = need + need // 100 + (1 << 20)
    if room > free:
        raise RunError(f"the results file needs {human(need)} ({human(room)} with room for "
                       f"its metadata and the figure) but {final.parent} has "
                       f"{human(free)} free: use fewer samples or frequencies, "
                       f"[output] keep_response = false (metric only), another -o, or "
                       f"--skip-space-check if the estimate is wrong")


def _run_locked(spec, final, resume, force, progress, groups, t_start, space_check,
                started):
    n_f = len(spec.freq_hz)
    what, found = prepare(spec, final, resume=resume, force=force)
    if what == "complete":
        started()
        return Summary(final, spec.samples, n_f, spec.samples, 0,
                       int(found.get("n_not_converged", -1)), time.perf_counter() - t_start,
                       0.0, True, already_complete=True,
                       notes=_partial_beside(spec, final))
    # the refusals before anything is written; a resumed store is closed on any of them
    try:
        check_solvable(spec)
        if space_check:
            check_space(spec, final, what == "resume")
        if what == "new":
            # the bounds group that "auto" computes after this (a callable's is unknown)
            Store.require_floor(final, bounds_bytes(spec)
                                if groups == "auto" and spec.bounds else 0)
        started()
        cluster = _connect(spec, progress) if spec.execution.scheduler else None
    except BaseException:
        if what == "resume":
            found[0].close()
        raise
    try:
        return _run_store(spec, final, what, found, progress, groups, t_start, cluster)
    finally:
        if cluster is not None:
            cluster.close()


def _connect(spec, verbose):
    """The Dask cluster of ``[run] scheduler``, every worker ready (RunError if not)."""
    from .distributed import Cluster, ClusterError

    try:
        return Cluster.connect(spec.execution.scheduler, spec=spec, task=solve_records,
                               fingerprint=fingerprint, verbose=verbose)
    except ClusterError as e:
        raise RunError(str(e)) from None


def _run_store(spec, final, what, found, progress, groups, t_start, cluster):
    timing = {"bounds_s": 0.0}
    if what == "new":
        if groups == "auto":
            groups = _bounds_groups(spec, progress, timing) if spec.bounds else None
        coords, variables, attrs, placeholders = layout(spec)
        made = groups() if groups else None
        if made is not None and not (isinstance(made, dict) and all(
                isinstance(k, str) and isinstance(v, tuple) and len(v) == 2
                for k, v in made.items())):
            # a wrong shape failed inside the store ("too many values to unpack")
            raise RunError(f"groups: the callable must return {{group name: (variables, "
                           f"attrs)}}, got {made!r:.200}")
        store = Store.create(final, record_dim=RECORD, n_records=spec.samples, coords=coords,
                             variables=variables, attrs=attrs, placeholders=placeholders,
                             groups=made)
        done = np.zeros(spec.samples, bool)
        not_conv_before = 0
    else:
        store, not_conv_before = found
        done = store.done()
    try:
        summary = _drive(spec, store, done, not_conv_before, progress, t_start, cluster,
                         bounds_s=timing["bounds_s"])
        summary.bounds_computed = what == "new" and bool(groups)
        return summary
    finally:
        store.close()


def _bounds_groups(spec, verbose, timing):
    """A callable giving ``{"bounds": (variables, attrs)}``: the bounds of the nominal
    model, computed when called (before the ensemble); their time, s, is added to
    ``timing["bounds_s"]``."""
    def group():
        from .bounds import from_spec, to_group

        if verbose and spec.mistuned:
            print("note: the bounds are for the nominal rig; mistuned members need not lie "
                  "inside them", flush=True)
        t = time.perf_counter()
        B = from_spec(spec, progress=None if verbose else False)
        variables, attrs = to_group(B)
        if spec.peaks:
            from .bounds.peak import peak_attrs

            attrs.update(peak_attrs(spec.model, B, spec.peaks.rtol))
        timing["bounds_s"] += time.perf_counter() - t
        if verbose:
            print(f"{B.summary()} ({timing['bounds_s']:.1f} s)", flush=True)
        return {"bounds": (variables, attrs)}
    return group


def solve_chunk(spec, d):
    """Solve one chunk of drawn members as the run does (peaks, harmonics, indicator).

    Parameters
    ----------
    spec : mcfric.spec.RunSpec
    d : mcfric.sampling.Draw
        The chunk's parameters.

    Returns
    -------
    mcfric.hbm.Result
    """
    return hbm.solve(spec.model, spec.freq_hz, d.mu0, d.kc, d.N0,
                     modal_freq_hz=d.modal_freq_hz, tol=spec.solver.tol,
                     max_iter=spec.solver.max_iter, n_threads=spec.execution.threads,
                     peaks=spec.peaks, harmonics=spec.solver.harmonics,
                     n_time=spec.solver.n_time,
                     store_harmonics=(spec.keep_harmonics and spec.keep_response
                                      and spec.solver.harmonics > 1),
                     indicator=spec.solver.harmonics == 1)


def solve_records(spec, start, stop):
    """Draw, solve and record samples ``start .. stop - 1``: the task of a cluster run.

    Returns
    -------
    dict
        ``{variable: array}`` as :func:`record_arrays`.
    """
    d = spec.sampler.draw(np.arange(start, stop))
    return record_arrays(spec, d, solve_chunk(spec, d))


def record_arrays(spec, d, res):
    """``{variable: array}`` of one solved chunk, as :func:`layout` declares them."""
    freq, quantity, beams = spec.freq_hz, spec.metric.quantity, spec.metric.beams
    arrays = {"metric": hbm.response_metric(res.response, freq, quantity, beams),
              "converged": res.converged, "mu0": d.mu0, "kc": d.kc, "N0": d.N0}
    if res.harmonic_indicator is not None:
        arrays["harmonic_indicator"] = res.harmonic_indicator.astype(np.float32)
    if spec.solver.harmonics > 1:
        arrays["from_above"] = res.from_above
        arrays["from_rest"] = res.from_rest
    if spec.keep_response:
        amp = spec.response_format == "amplitude"
        if amp:
            arrays["amplitude"] = np.abs(res.response).astype(np.float32)
        else:
            arrays["response"] = res.response
        if res.response_peak is not None:
            arrays["response_peak"] = (res.response_peak.astype(np.float32) if amp
                                       else res.response_peak)
        if res.response_harmonics is not None:
            arrays["response_harmonics"] = res.response_harmonics
    if res.peaks is not None:
        pk = res.peaks
        arrays.update({"peak_metric": pk.metric, "peak_frequency": pk.freq_hz,
                       "peak_status": pk.status, "fold": pk.fold,
                       "peak_metric_down": pk.metric_down,
                       "peak_frequency_down": pk.freq_hz_down})
        if spec.keep_response:
            arrays["peak_response"] = pk.response
    if d.modal_freq_hz is not None:
        arrays["modal_freq_hz"] = d.modal_freq_hz
    return arrays


def local_chunks(spec, chunks, timing):
    """Solve ``chunks`` in this process, one after the other.

    Parameters
    ----------
    spec : mcfric.spec.RunSpec
    chunks : list of (start, stop)
        Sample ranges to solve.
    timing : dict
        ``timing["kernel_s"]`` is increased by the kernel time of every chunk, s.

    Yields
    ------
    start : int
        First sample of the chunk.
    arrays : callable
        Returns the chunk's ``{variable: array}`` (:func:`record_arrays`); called by the
        writer thread, so that the metric is computed while the kernel solves the next
        chunk.
    """
    if not chunks:
        return
    # the next chunk's parameters are drawn (numpy, GIL) while the kernel runs (no GIL)
    prefetch = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mcfric-sampler")
    try:
        nxt = prefetch.submit(spec.sampler.draw, np.arange(*chunks[0]))
        for n, (a, b) in enumerate(chunks):
            d = nxt.result()
            nxt = (prefetch.submit(spec.sampler.draw, np.arange(*chunks[n + 1]))
                   if n + 1 < len(chunks) else None)
            t0 = time.perf_counter()
            # a stop signal ends the wait for a chunk at once; the chunk is dropped (its
            # kernel runs on until the process exits) and solved again on resume
            res = interruptible(solve_chunk, spec, d)
            timing["kernel_s"] += time.perf_counter() - t0
            yield a, (lambda d=d, res=res: record_arrays(spec, d, res))
            del res, d
    finally:
        prefetch.shutdown(wait=True, cancel_futures=True)


def _drive(spec, store, done, not_conv_before, progress, t_start, cluster=None,
           bounds_s=0.0):
    """Solve the pending chunks (here, or on ``cluster``), write and commit them."""
    from tqdm import tqdm

    n_f = len(spec.freq_hz)
    ex = spec.execution
    chunks = _pending_chunks(done, chunk_samples(spec))
    n_before = int(np.count_nonzero(done))

    bar = tqdm(total=spec.samples, initial=n_before, unit="sample", disable=not progress,
               dynamic_ncols=True, smoothing=0.1, file=sys.stderr)
    q = queue.Queue(maxsize=1)      # one chunk in flight: memory stays flat
    err = []
    stats = {"not_converged": 0, "written": 0}

    stop = threading.Event()

    def writer():
        pending = []
        last = time.monotonic()
        try:
            while True:
                try:
                    item = q.get(timeout=0.2)
                except queue.Empty:
                    # the main thread stopped feeding (an interrupt can cut its last put
                    # short): what is written is committed, nothing is waited for
                    if stop.is_set():
                        break
                    continue
                if item is None:
                    break
                start, make_arrays = item
                arrays = make_arrays()
                del item, make_arrays
                conv = arrays["converged"]
                n = len(conv)
                store.write(start, arrays)
                del arrays
                pending.append((start, start + n))
                stats["not_converged"] += int(np.count_nonzero(~conv))
                if time.monotonic() - last >= ex.checkpoint_s:
                    store.commit(pending)
                    stats["written"] += sum(b - a for a, b in pending)
                    pending = []
                    last = time.monotonic()
                bar.update(n)
            store.commit(pending)
            stats["written"] += sum(b - a for a, b in pending)
        except BaseException as e:   # re-raised by the main thread, which stops feeding
            err.append(e)

    w = threading.Thread(target=writer, name="mcfric-writer", daemon=True)
    w.start()
    timing = {"kernel_s": 0.0}
    source = (cluster.chunks(solve_records, spec, chunks, timing) if cluster is not None
              else local_chunks(spec, chunks, timing))
    interrupted = False
    try:
        for item in source:
            stop_signals.check()    # a KeyboardInterrupt dropped in a callback from C
            _put(q, item, w, err)
            del item
    except KeyboardInterrupt:
        interrupted = True
    finally:
        source.close()
        stop.set()
        if w.is_alive():
            try:
                _put(q, None, w, err)
            except BaseException:
                pass
        w.join()
        bar.close()
    kernel_s = timing["kernel_s"]
    on_cluster = ({"cluster": cluster.address, "startup_s": cluster.startup_s}
                  if cluster is not None else {})
    if err:
        raise err[0]
    n_done = n_before + stats["written"]
    not_conv = not_conv_before + stats["not_converged"]
    wall = time.perf_counter() - t_start
    if interrupted or n_done < spec.samples:
        s = Summary(store.path, spec.samples, n_f, n_done, stats["written"], not_conv, wall,
                    kernel_s, False, bounds_s=bounds_s, **on_cluster)
        if interrupted:
            raise Interrupted(s)
        return s
    final = store.finish({"n_not_converged": np.int64(not_conv),
                          "wall_time_s": np.float64(wall),
                          "kernel_time_s": np.float64(kernel_s),
                          "bounds_time_s": np.float64(bounds_s),
                          "finished_unix": np.float64(time.time())})
    report = peak_report(final) if spec.peaks else None
    return Summary(final, spec.samples, n_f, n_done, stats["written"], not_conv,
                   wall, kernel_s, True, bounds_s=bounds_s,
                   peaks=report_text(report, METRIC_UNITS[spec.metric.quantity])
                   if report else unrefined_lines(spec.solver.harmonics) if n_done else None,
                   harmonics=indicator_report(final), **on_cluster)


def summary_of_file(path):
    """Counts of a results file without loading it: samples, done, non-converged points."""
    attrs = read_attrs(path)
    done = iter_done(path)
    return {"attrs": attrs, "samples": int(attrs.get("samples", len(done))),
            "done": int(np.count_nonzero(done)),
            "not_converged": _count_not_converged(path),
            "complete": attrs.get("complete") == 1}
