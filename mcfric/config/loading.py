"""Loading a configuration: preset defaults, then a TOML file, then command-line overrides.

Later layers win key by key; a ``[sampling.<param>]`` distribution table and the
``[[model.beam]]`` list are replaced whole, not merged. Modal tables given as files
(``[model.table] file = ...``) are read here, once, so that the validated configuration
holds the numbers.
"""

from __future__ import annotations

import copy
import os
import shlex
import tomllib
from pathlib import Path

from ..presets import PRESETS
from ..validators import InputError, choices, is_int, show
from .schema import DEFAULT_PRESET, SPEC, defaults
from .validation import validate


def _merge(base, top, path=""):
    """``top`` over ``base``; distribution tables and [[model.beam]] replace whole."""
    out = dict(base)
    for k, v in top.items():
        key = f"{path}.{k}" if path else k
        whole = key in ("sampling.mu0", "sampling.kc", "sampling.N0", "model.beam")
        if isinstance(v, dict) and isinstance(out.get(k), dict) and not whole:
            out[k] = _merge(out[k], v, key)
        else:
            out[k] = copy.deepcopy(v)
    return out


def set_key(tree, dotted, value):
    """Set ``tree[a][b][c] = value`` for ``dotted = "a.b.c"``, creating tables."""
    *head, last = dotted.split(".")
    done = []
    for h in head:
        done.append(h)
        tree = tree.setdefault(h, {})
        if not isinstance(tree, dict):
            # e.g. `sampling = "x"` in the file and --samples on the command line
            raise InputError(".".join(done), f"expected a table, got {show(tree)}")
    tree[last] = value


#: Largest configuration file read (a modal table inline is a few kB).
MAX_TOML_BYTES = 16 * 2**20


def read_toml(path):
    """Parse a TOML file; problems become a one-line :class:`ConfigError` naming the file."""
    p = Path(path)
    if not str(path).strip():
        raise InputError('""', f"expected a preset ({choices(PRESETS)}) or a TOML file")
    if p.is_dir():
        raise InputError(str(path), "a directory, not a TOML file")
    if p.suffix.lower() in (".h5", ".hdf5", ".partial") and p.exists() and not p.is_file():
        # a results file's name on a pipe without a writer: reading it would never end
        raise InputError(str(path), "not a regular file (a pipe or a device), not a "
                         "results file")
    try:
        with open(p, "rb") as fh:
            # a pipe (`<(...)`) is read; a device without end (/dev/zero) is not
            data = fh.read(MAX_TOML_BYTES + 1)
        # before the size: a results file is often larger than any configuration
        if data.startswith(b"\x89HDF"):
            cmd = f"mcfric config {shlex.quote(str(path))} > run.toml"
            raise InputError(str(path), f"an HDF5 file (results?), not a TOML configuration "
                             f"(`{cmd}` writes a results file's)")
        if len(data) > MAX_TOML_BYTES:
            raise InputError(str(path), f"more than {MAX_TOML_BYTES // 2**20} MiB, not a "
                             f"TOML configuration")
        if p.suffix.lower() in (".h5", ".hdf5", ".partial") and not data.strip():
            # an empty file read as an empty TOML ran the default ensemble
            raise InputError(str(path), "an empty file, not a TOML configuration (nor a "
                             "results file)")
        # a byte-order mark (as some Windows editors write) is no TOML error
        text = data.decode("utf-8-sig")
    except FileNotFoundError:
        raise InputError(str(path), "no such file (and not a preset: "
                         f"{choices(PRESETS)})") from None
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(str(path), f"cannot read: {e}") from None
    try:
        user = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise InputError(str(path), f"invalid TOML: {e}") from None
    if not user and not p.is_file():
        # /dev/null, or a pipe that gave no key, ran the default ensemble; an empty
        # regular file stays a configuration of defaults
        raise InputError(str(path), "no key read from a device or a pipe: give a TOML "
                         "configuration or a preset")
    return user


def load(source=None, overrides=None):
    """Resolve and validate a configuration.

    Parameters
    ----------
    source : str, Path, dict or None
        A preset name, a TOML file path, an already-parsed dict (as from a TOML file), or
        None (the default preset, eight-beam).
    overrides : dict, optional
        ``{dotted key: (value, label)}``, e.g. ``{"sampling.samples": (500, "--samples")}``;
        errors in an override name its label. A None value is ignored.

    Returns
    -------
    Config
    """
    if source is None:
        user = {}
    elif isinstance(source, dict):
        user = copy.deepcopy(source)
    elif isinstance(source, str) and source in PRESETS:
        user = {"model": {"preset": source}}
    elif isinstance(source, (str, os.PathLike)):
        user = read_toml(source)
        _expand_modal_files(user, Path(source).parent)
    else:
        # Path() raised a TypeError that named no argument
        raise InputError("source", f"expected a preset name, a TOML file's path, a dict or "
                         f"None, got {type(source).__name__}")
    model = user.get("model", {})
    base_name = model.get("preset", DEFAULT_PRESET) if isinstance(model, dict) else DEFAULT_PRESET
    if not isinstance(base_name, str) or base_name not in PRESETS:
        raise InputError("model.preset", f"expected one of {choices(PRESETS)}, "
                         f"got {show(base_name)}")
    base = defaults(base_name)
    n_preset = base["model"]["n_beams"]
    raw = _merge(base, user)
    labels = {}
    if not isinstance(overrides, (dict, type(None))) or not all(
            isinstance(v, tuple) and len(v) == 2 for v in (overrides or {}).values()):
        # a bare value ({"sampling.samples": 5}) failed in tuple unpacking
        raise InputError("overrides", f"expected {{dotted key: (value, label)}}, e.g. "
                                      f"{{'sampling.samples': (500, '--samples')}}, got "
                                      f"{overrides!r}")
    for key, (value, label) in (overrides or {}).items():
        if value is None:
            continue
        _check_replaced(user, key, label)
        set_key(raw, key, value)
        labels[key] = label
    _rename(raw, user, labels, base_name, n_preset)
    return validate(raw, labels)


def _check_replaced(user, key, label):
    """The file's own value of ``key``, which an override replaces, checked on its own:
    a bad value in a file is an error even where a flag hides it (the file would fail
    when run without the flag). Cross-key rules are left to the whole configuration,
    which the override may have made consistent."""
    *head, last = key.split(".")
    tree = user
    for h in head:
        tree = tree.get(h) if isinstance(tree, dict) else None
    if not isinstance(tree, dict) or last not in tree:
        return
    entry = SPEC.get(head[0], {}).get(last) if len(head) == 1 else None
    if isinstance(entry, tuple) and callable(entry[0]):
        try:
            entry[0](tree[last], key)
        except InputError as e:
            who = f"this command sets {key}" if label == key else f"{label} replaces it"
            raise InputError(key, f"{e.message} (in the configuration file, though "
                                  f"{who})") from None


def _rename(raw, user, labels, base_name, n_preset):
    """Give ``raw`` the preset's :func:`automatic_name` unless a name is given."""
    m = raw.get("model")
    given = isinstance(user.get("model"), dict) and "name" in user["model"]
    if not isinstance(m, dict) or given or "model.name" in labels:
        return
    if is_int(m.get("n_beams")):
        m["name"] = automatic_name(base_name, m["n_beams"], n_preset)


def automatic_name(preset, n_beams, n_preset):
    """The name of ``preset`` with ``n_beams`` beams (``n_preset`` its own count): a
    preset's name with another beam count is not that preset, so ``disk-72`` with 120
    is ``disk-72 (120 beams)`` (headers, plots, ``mcfric info`` and the results file; not
    ``disk-120``, which would hide the engine order that comes with the preset)."""
    return preset if n_beams == n_preset else f"{preset} ({n_beams} beams)"


MODAL_FILE_KEYS = ("file", "nodes", "direction", "modes", "max_imag")


def _expand_modal_files(user, base):
    """Replace ``[model.table] file = ...`` (and per-beam ``file``) by the table read.

    The file (UFF 55, CSV or TOML; :func:`mcfric.modal_io.read_modal_table`) is read
    once, here: the validated configuration holds the numbers, so a results file records
    the modal data it was computed with. ``nodes = {contact, output, drive}`` maps the
    file's node numbers (CSV/TOML: position labels) to positions 1, 2, 3.
    """
    m = user.get("model")
    if not isinstance(m, dict):
        return
    beams = m.get("beam") if isinstance(m.get("beam"), list) else []
    items = [("model.table", m.get("table"))] + [(f"model.beam[{n}]", b)
                                                  for n, b in enumerate(beams, 1)]
    for key, t in items:
        if not isinstance(t, dict) or "file" not in t:
            continue
        extra = set(t) - set(MODAL_FILE_KEYS) - ({"beam"} if key != "model.table" else set())
        table_keys = {"freq_hz", "zeta", "shapes", "positions"}
        if extra & table_keys:
            raise InputError(f"{key}.{sorted(extra & table_keys)[0]}", "cannot be given "
                             "together with file (the file holds the whole table)")
        if extra:
            raise InputError(f"{key}.{sorted(extra)[0]}", "unknown key (with file: "
                             + ", ".join(MODAL_FILE_KEYS) + ")")
        nodes = t.get("nodes")
        if (not isinstance(nodes, dict) or set(nodes) != {"contact", "output", "drive"}
                or not all(is_int(v) for v in nodes.values())):
            raise InputError(f"{key}.nodes", "expected {contact = N, output = N, drive = N} "
                             f"(node numbers in the file), got {show(nodes)}")
        if not isinstance(t["file"], str):
            raise InputError(f"{key}.file", f"expected a file name, got {show(t['file'])}")
        path = Path(t["file"])
        if not path.is_absolute():
            path = base / path
        from ..modal_io import read_modal_table
        try:
            table = read_modal_table(
                path, positions={1: nodes["contact"], 2: nodes["output"], 3: nodes["drive"]},
                direction=t.get("direction"), modes=t.get("modes"),
                max_imag=t.get("max_imag", 0.05))
        except (ValueError, ImportError, OSError) as e:
            raise InputError(f"{key}.file", str(e).splitlines()[0]) from None
        new = {"freq_hz": table.freq_hz.tolist(), "zeta": table.zeta.tolist(),
               "shapes": table.shapes.tolist()}
        if key == "model.table":
            new["positions"] = list(table.positions)
        else:
            new["beam"] = t.get("beam")
        t.clear()
        t.update(new)
        if key == "model.table":
            for role, label in (("contact", 1), ("output", 2), ("drive", 3)):
                if m.get(role, label) != label:
                    raise InputError(f"model.{role}", "is set by model.table.nodes when the "
                                     "table comes from a file; remove it")
