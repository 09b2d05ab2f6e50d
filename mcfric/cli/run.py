"""``mcfric run``: an ensemble (or a sweep of engine orders) into a results file, and its
summary."""

from __future__ import annotations

import json
import sys

from .errors import EXIT_FAIL, EXIT_INTERRUPTED, EXIT_OK, UsageError, interrupted_after, one_line
from .inputs import load_config, settings_notes
from .outputs import (
    not_replacing_hdf5,
    not_replacing_sibling_figure,
    order_path,
    output_path,
    regular_or_none,
)


def _kept_bounds_note(cfg, out):
    """A note where ``out`` (resumed, or complete already) keeps bounds made with other
    ``[bounds]`` settings than ``cfg``'s (they are not part of a run's identity), else
    None."""
    from ..config.configuration import first_difference
    from ..store import read_attrs

    try:
        stored = json.loads(read_attrs(out)["config_json"]).get("bounds", {})
    except (KeyError, ValueError, TypeError):
        return None
    diff = first_difference(cfg.data["bounds"], stored, "bounds")
    if diff is None:
        return None
    kept = (f"{out} has no bounds (the session that created it had [bounds] enabled = "
            f"false)" if not stored.get("enabled", True) else
            f"{out} keeps the bounds of the session that created it, whose [bounds] differ "
            f"from this configuration's (first difference: {diff})")
    return (f"note: {kept}; `mcfric bounds` computes this configuration's into a file of "
            f"their own, --force recomputes the run")


def _outside_note(n, H, fault, mistuned=False):
    """What ``n`` member points outside the bounds mean in a run balancing ``H``
    harmonics: a ``fault`` to report where ``H = 1``; with ``H > 1`` none, as the bounds
    rest on the describing function's constraints (the single-harmonic model) and a
    multi-harmonic fundamental need not keep to them; with random mistuning none, as the
    bounds are the nominal rig's."""
    if mistuned:
        return (" (the bounds are the nominal rig's, the members mistuned: not a fault)"
                if n else "")
    if H > 1:
        return (f" (the bounds are the single-harmonic model's, these points the "
                f"fundamentals of H = {H}: not a fault)")
    return f" ({fault}: please report)" if n else ""


def cmd_run(args):
    """``mcfric run``: run (or resume) an ensemble, check it against its bounds, draw it;
    with ``excitation.engine_orders``, one such run and file per engine order."""
    from .. import ensemble
    from ..store import partial_path
    from ..store.lock import LockError, OutputLock

    if args.resume and args.force:
        # --force won silently and threw a resumable partial away
        raise UsageError("--force: discards FILE.partial, --resume continues it; give one")
    cfg = load_config(args)
    orders = cfg.data["excitation"]["engine_orders"]
    # a sweep draws each order's figure (FILE-eoE.png), checked below, not FILE.png
    out = output_path(args, ".h5", figure=not args.no_figure and not orders)
    if not orders:
        return _run_one(args, cfg, out)
    runs = [(cfg.replace("excitation.engine_order", E).replace("excitation.engine_orders",
                                                                 []), order_path(out, E))
            for E in orders]
    # the refusals of every order's files before the first order starts (with --resume
    # too: a later order's file of another run was found only after the earlier orders)
    for c, o in runs:
        # the checks output_path makes of -o's own names, for each order's
        for path in (o, partial_path(o)) + (() if args.no_figure else (o.with_suffix(".png"),)):
            regular_or_none(path, f"engine order {c.data['excitation']['engine_order']}: ")
        if not args.no_figure:
            not_replacing_hdf5(o.with_suffix(".png"), "figure")
            not_replacing_sibling_figure(
                o, ".h5", "results file",
                f"engine order {c.data['excitation']['engine_order']}: ")
        try:
            # under the order's lock: a writer of it is named, as for one run
            with OutputLock(o, "mcfric run (checking an engine order's files)"):
                kind, got = ensemble.prepare(c.spec, o, resume=args.resume,
                                             force=args.force)
                if kind == "resume":
                    got[0].close()          # reopened in its turn
        except (ensemble.RunError, LockError) as e:
            raise UsageError(str(e)) from None
    print(f"mcfric run: engine orders {', '.join(map(str, orders))}: one results file "
          f"each ({', '.join(o.name for _, o in runs)})", flush=True)
    for c, o in runs:
        print(f"== engine order {c.data['excitation']['engine_order']}: {o}", flush=True)
        rc = _run_one(args, c, o, resume_as=out)
        if rc != EXIT_OK:
            return rc
    return EXIT_OK


def _run_one(args, cfg, out, resume_as=None):
    """One ensemble run into ``out``; ``resume_as``: the -o to give ``--resume``."""
    from .. import ensemble
    from ..distributed import ClusterError
    from ..memory import MemoryRefused
    from ..store import partial_path

    spec = cfg.spec
    resume = f"`mcfric run ... -o {resume_as or out} --resume`"
    # which files were there: an interrupt outside the sweep is judged by what changed
    before, partial_before = _identity(out), _identity(partial_path(out))
    # every refusal (bad config, existing files) happens before anything is written;
    # the notes only where this run computes its bounds: a file resumed or complete
    # keeps the bounds it was made with ([bounds] is no part of a run's identity)
    fresh = args.force or not (out.exists() or partial_path(out).exists())

    def started():
        # once every refusal is made: a refused run prints its one line (stderr) only
        model = spec.model
        print(f"mcfric run: {model.name}, {spec.samples} samples x {len(spec.freq_hz)} "
              f"frequencies, {model.n_beams} beams, F0 = {model.excitation.F0:g} N, "
              f"seed {spec.seed}", flush=True)
        if fresh:
            settings_notes(cfg)

    try:
        summary = ensemble.run(cfg, out, resume=args.resume, force=args.force,
                               progress=not args.no_progress,
                               space_check=not args.skip_space_check, started=started)
    except KeyboardInterrupt:
        # after the rename the run still reads its peaks and indicator for the summary:
        # a file this run renamed into place is whole (a FILE is always complete)
        if _identity(out) in (None, before):
            partial = _identity(partial_path(out))
            # a partial this run created, or the one it resumes (not an older run's
            # that --force was to replace, still there while the bounds are computed)
            if partial is None or (partial == partial_before and not args.resume):
                raise
            # e.g. between the sweep's last chunk and the rename: what was written is kept
            print(f"interrupted: the run's samples are kept in {partial_path(out)}; "
                  f"continue with {resume}", file=sys.stderr)
            return EXIT_INTERRUPTED
        return interrupted_after(
            out, rest=f"; the sweep's other engine orders: {resume}" if resume_as else "")
    except ensemble.RunError as e:
        raise UsageError(str(e)) from None
    except ensemble.Interrupted as e:
        s = e.summary
        print(f"interrupted: {s.samples_done} of {s.samples} samples saved in {s.path}; "
              f"continue with {resume}", file=sys.stderr)
        return EXIT_INTERRUPTED
    except ClusterError as e:
        # the committed chunks are in the partial file (the writer commits before stopping)
        print(f"mcfric: error: {e}; the finished chunks are kept: continue with {resume}",
              file=sys.stderr)
        return EXIT_FAIL
    except MemoryRefused as e:
        # a chunk's solve found too little free memory (after --skip-space-check, or as
        # the machine's free memory fell): what was committed stays, to resume
        kept = (f"; the finished chunks are kept: continue with {resume} when memory is "
                f"free" if partial_path(out).exists() else "")
        print(f"mcfric: error: {one_line(e)}{kept}", file=sys.stderr)
        return EXIT_FAIL
    try:
        _report_run(args, cfg, out, summary)
    except KeyboardInterrupt:
        if not summary.complete:
            raise
        return interrupted_after(
            out, rest=f"; the sweep's other engine orders: {resume}" if resume_as else "")
    return EXIT_OK


def _identity(path):
    """``(device, inode)`` of ``path``, None where there is none: a rename changes it."""
    try:
        st = path.stat()
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _report_run(args, cfg, out, summary):
    """What ``mcfric run`` prints and draws once the run is over: the summary, the bounds'
    lines, the members' check against them, the figure."""
    from .. import plot

    if summary.already_complete:
        print(f"{out} already holds this run (same configuration, [run] and [bounds] "
              f"aside, and seed): nothing to do; --force recomputes it")
    print(summary.text())
    if summary.complete and not summary.bounds_computed:
        note = _kept_bounds_note(cfg, out)
        if note:
            print(note)
    if summary.complete and (args.no_progress or not summary.bounds_computed):
        # the bounds' summary was printed as they were computed only with progress on,
        # and not at all where they came from an earlier session's file
        from ..bounds import read_bounds

        B = read_bounds(out)
        if B is not None:
            print(B.summary())
    if summary.complete:
        from ..bounds import members_check

        check = members_check.check_members(out)
        if check is not None:
            outside, total, outside_cert, left_out, unbounded, uncertified, bad = check
            from ..store import read_attrs

            H = int(read_attrs(out).get("harmonics", 1))
            mis = cfg.data["sampling"]["mistuning"] > 0
            if left_out:
                print(f"bounds check: {left_out:,} of {summary.samples:,} members have "
                      f"friction outside the bounds' constraints ([bounds] k_max, k_max_im, "
                      f"F_lim), for which the bounds need not hold: left out of the checks")
            # a search may miss extremes; with certified bounds that hold, no fault
            held = outside_cert == 0
            note = (" (the search missed them; the certified bounds hold them)"
                    if outside and held and H == 1 and not mis else
                    _outside_note(outside, H, "the bounds search missed them", mis))
            print(f"searched bounds check: {outside} of {total:,} converged member points "
                  f"outside [lower, upper]" + note
                  + (f"; {unbounded:,} at the frequencies where the search failed, which "
                     f"have no searched bounds, not checked" if unbounded else "")
                  + (f"; {bad:,} whose stored value is not finite (a damaged file), not "
                     f"checked" if bad else ""))
            if outside_cert is not None:
                print(f"certified bounds check: {outside_cert} outside [lower_certified, "
                      f"upper_certified]" + _outside_note(outside_cert, H,
                                                          "a broken certificate", mis)
                      + (f"; {uncertified:,} at frequencies without certified bounds (a "
                         f"failed search), not checked" if uncertified else ""))
    if summary.complete and not args.no_figure:
        png = out.with_suffix(".png")
        plot.results_figure(out, png)
        print(f"figure: {png}")
