"""Output paths and the files a command reads: defaults, and the checks that no output
replaces another or the command's input."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import UsageError

DEFAULT_DIR = Path("mcfric-results")


def _default_output(args, suffix, prefix=""):
    from ..presets import PRESETS

    if args.source is None:
        stem = "default"
    elif args.source in PRESETS:
        stem = args.source
    else:
        stem = Path(args.source).stem
    return DEFAULT_DIR / f"{prefix}{stem}{suffix}"


#: Default output directories this invocation made: removed at exit if still empty (a
#: run refused after its output path was chosen leaves nothing behind).
MADE_DIRS = []


def output_path(args, suffix, prefix="", figure=False):
    """The output path; the default directory is created, a given one must exist.

    ``figure``: the command also writes ``FILE.png`` next to it; the two must differ,
    and an existing ``FILE.png`` beside a results file or CSV of the other kind is that
    file's figure, not replaced until ``FILE`` itself exists.
    Neither may replace an HDF5 file unless the command writes HDF5 itself (``suffix``
    ``.h5``, whose own checks decide), nor the command's own input, nor be a directory,
    nor end in the other format's suffix (found now, not after the work).
    """
    if args.output is not None:
        out = file_name(args.output)
        if not out.parent.is_dir():
            raise UsageError(f"-o: directory {out.parent} does not exist")
        regular_or_none(out)
    else:
        out = _default_output(args, suffix, prefix)
        if not out.parent.is_dir():
            try:
                out.parent.mkdir(parents=True, exist_ok=True)
            except OSError as e:
                # a file of that name, or a directory that cannot be written
                raise UsageError(f"cannot make the default output directory {out.parent} "
                                 f"({e.strerror or e}); give -o FILE") from None
            MADE_DIRS.append(out.parent)
        regular_or_none(out, "")
    if suffix == ".h5" and out.is_symlink():
        # written through, as a CSV or a figure is: the link stays, its target gets the
        # results (and the .partial and the lock beside it)
        target = Path(os.path.realpath(out))
        if not target.parent.is_dir():
            raise UsageError(f"-o: directory {target.parent} (a link's target) does not "
                             f"exist")
        out = target
        regular_or_none(out, "-o: ")
    writable_dir(out)
    if suffix == ".h5":
        from ..store import partial_path

        regular_or_none(partial_path(out), "" if args.output is None else "-o: ")
    what = "results file" if suffix == ".h5" else f"{suffix[1:].upper()} output"
    if suffix == ".h5" and out.name.endswith(".partial"):
        raise UsageError(f"-o: {out.name} ends in .partial, the name of an interrupted "
                         f"run's file; give the final name ({out.name[:-8]})")
    if out.name.endswith(".lock"):
        # a run on the name without .lock takes FILE.lock as its lock and removes it
        raise UsageError(f"-o: {out.name} ends in .lock, the name of a run's lock file; "
                         f"choose another name")
    if suffix != ".h5":
        not_replacing_hdf5(out, what)
    _not_replacing_input(args, out, what)
    if figure:
        png = out.with_suffix(".png")
        if png == out:
            raise UsageError(f"-o: the {what} and its figure would both be {out}; give the "
                             f"{what} another suffix (e.g. {out.with_suffix(suffix).name})")
        if png.is_dir():
            raise UsageError(f"-o: the figure {png} is a directory; choose another -o")
        not_replacing_hdf5(png, "figure")
        _not_replacing_input(args, png, "figure")
        if png.is_symlink():
            writable_dir(png)        # written through: its target's directory
        not_replacing_sibling_figure(out, suffix, what)
    # a name that promises the other format (the reader would then fail on it)
    other = {".h5": (".csv", ".png", ".txt", ".toml"),
             ".csv": (".h5", ".hdf5", ".hdf", ".nc", ".png", ".toml")}[suffix]
    if out.suffix.lower() in other:
        fmt = "an HDF5 results file" if suffix == ".h5" else "CSV"
        raise UsageError(f"-o: {out.name}: this command writes {fmt}; give a name ending "
                         f"in {suffix}")
    return out


def not_replacing_sibling_figure(out, suffix, what, label="-o: "):
    """``FILE.png`` beside another command's ``FILE.h5`` (or ``FILE.csv``) is that file's
    figure (`run -o r.h5`, then `hbm -o r.csv`): not replaced by the figure of ``out``
    (of ``suffix``) until ``out`` itself exists, when the figure is its own."""
    png = out.with_suffix(".png")
    sibling = out.with_suffix(".csv" if suffix == ".h5" else ".h5")
    if png.exists() and sibling.is_file() and not out.exists():
        raise UsageError(f"{label}{png} exists beside {sibling.name}, whose figure it may "
                         f"be; the {what}'s figure would replace it: choose another -o, "
                         f"or --no-figure")


def file_name(value):
    """``-o``'s path: not empty, and not a directory's name (``out.h5/``, which a path
    would read as ``out.h5``)."""
    text = str(value)
    if not text.strip():
        raise UsageError('-o: expected a file name, got ""')
    if text.endswith(("/", os.sep)):
        raise UsageError(f"-o: {text} ends in {text[-1]}, a directory's name; give a file "
                         f"name")
    return Path(text)


def regular_or_none(path, label="-o: "):
    """Refuse an output name held by a directory, a device or a pipe (``--force`` would
    replace a device such as /dev/null with a results file; a pipe hangs)."""
    if path.is_dir():
        raise UsageError(f"{label}{path} is a directory")
    if path.exists() and not path.is_file():
        raise UsageError(f"{label}{path} is not a regular file (a device or a pipe)")


def writable_dir(out):
    """An output is renamed into its directory when complete: one that cannot be written
    is refused now, not after the work. An output is written through a symbolic link at
    ``out`` (CSV and figures: ``store.files.replacing``; a results file: the link's target
    is its path), so the link's target's directory is the one checked."""
    if out.is_symlink():
        out = Path(os.path.realpath(out))
        if not out.parent.is_dir():
            raise UsageError(f"-o: directory {out.parent} (a link's target) does not exist")
    # a file is made, not os.access asked: that says yes to root, and to /proc or a
    # read-only mount (without a name where the system allows, gone whatever happens)
    try:
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as e:
        raise UsageError(f"-o: directory {out.parent} is not writable "
                         f"({e.strerror or e})") from None


def _not_replacing_input(args, path, what):
    """No output replaces the configuration (or file) the command reads."""
    src = getattr(args, "source", None)
    if src and Path(src).is_file() and path.exists() and path.samefile(src):
        raise UsageError(f"-o: the {what} would replace the input {src}; choose another -o")


def not_replacing_hdf5(path, what):
    """No CSV or figure silently replaces a results file (HDF5)."""
    if path.is_file() and is_hdf5(path):
        raise UsageError(f"{path} is an HDF5 file (results?); the {what} would replace it: "
                         f"choose another -o")


def no_such_file(path):
    """The line for a results file that does not exist; it names the files an
    engine-order sweep writes for that ``-o`` (``FILE-eoE.h5``), where there are any."""
    import glob

    p = Path(path)
    # order_path's names, any order (its "-eo" and then digits: engine orders are >= 0)
    pattern = order_path(Path(glob.escape(str(p))), "*")
    names = sorted(Path(q).name for q in glob.glob(str(pattern))
                   if Path(q).stem[len(p.stem) + 3:].isdigit()) if p.suffix else []
    if not names:
        return f"{path}: no such file"
    shown = ", ".join(names[:4]) + (", ..." if len(names) > 4 else "")
    return (f"{path}: no such file; an engine-order sweep wrote {shown} (one file per "
            f"order): give one of them")


def checked_file(path):
    """:func:`~mcfric.results_check.check_file` of ``path``, then the keys of its stored
    configuration that the readers use (an edited file: one line, exit 2)."""
    from .. import config
    from ..results_check import CONFIG_KEYS, check_file
    from ..store import StoreError

    if Path(path).is_dir():
        raise UsageError(f"{path}: a directory, not a results file")
    if not Path(path).exists():
        raise UsageError(no_such_file(path))
    try:
        attrs, cfg = check_file(path)
    except StoreError as e:
        raise UsageError(str(e)) from None
    try:
        config.check_keys(cfg, CONFIG_KEYS)
    except config.ConfigError as e:
        raise UsageError(f"{path}: stored configuration: {e}") from None
    return attrs, cfg


def only_replacing_bounds(out):
    """``mcfric bounds`` replaces a bounds file of its own, nothing else (an ensemble's
    results file, its ``.partial``, or a file of another kind).

    A ``.partial`` left by a killed ``mcfric bounds`` (an HDF5 file without the root
    attributes, which go in last, or one with no members) is its own and is replaced; an
    ensemble's ``.partial`` (members, resumable by ``mcfric run``) or a file that is not
    HDF5 is refused.
    """
    from ..store import StoreError, partial_path, read_attrs

    part = partial_path(out)
    if part.exists() and not _own_partial(part, read_attrs, StoreError):
        raise UsageError(f"{part} exists (an interrupted run?); the bounds would replace "
                         f"it: choose another -o")
    if not out.exists():
        return
    try:
        attrs = read_attrs(out)
    except StoreError:
        attrs = {}
    if "layout_version" not in attrs or int(attrs.get("samples", -1)) != 0:
        kind = "an ensemble's results file" if "layout_version" in attrs else \
            "not an mcfric bounds file"
        raise UsageError(f"{out} exists and is {kind}; the bounds would replace it: "
                         f"choose another -o")


def _own_partial(part, read_attrs, StoreError):
    """Whether ``part`` is a ``.partial`` a killed ``mcfric bounds`` leaves (see
    :func:`only_replacing_bounds`)."""
    if not part.is_file() or not is_hdf5(part):
        return False
    try:
        attrs = read_attrs(part)
    except StoreError:
        return True             # torn while being written: nothing in it can be read
    return "layout_version" not in attrs or int(attrs.get("samples", -1)) == 0


def order_path(out, E):
    """The results file of engine order ``E`` in a sweep written to ``out``."""
    return out.with_name(f"{out.stem}-eo{E}{out.suffix}")


def is_hdf5(path):
    """Whether ``path`` is an HDF5 file (False where it cannot be read)."""
    import h5py

    try:
        return h5py.is_hdf5(path)
    except OSError:
        return False
