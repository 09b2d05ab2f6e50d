"""A configuration as TOML text: every key, in schema order, with its comment."""

from __future__ import annotations

import json
import math

from .schema import BEAM, DEFAULT_PRESET, DIST_DOC, SECTION_DOC, SPEC, TABLE, defaults
from .validation import validate


def _toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)       # a TOML basic string for printable text
    if isinstance(v, float):
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot render {v!r}")


def _lines(table, spec, comments, pad=28):
    out = []
    for k, v in table.items():
        if isinstance(v, dict) or isinstance(spec.get(k), dict):
            continue   # sub-tables ([model.table], [[model.beam]], [sampling.mu0]) follow
        line = f"{k} = {_toml_value(v)}"
        doc = spec.get(k, (None, ""))[1] if isinstance(spec.get(k), tuple) else ""
        if comments and doc:
            line = f"{line:<{pad}} # {doc}"
        out.append(line)
    return out


def render(data, comments=True):
    """A configuration dict as TOML text, sections in schema order, with comments."""
    out = []
    if comments:
        out += ["# mcfric run configuration (TOML). Units: Hz, N, N/m, m.",
                "# Start from `mcfric config PRESET`; run with `mcfric run THIS.toml -o out.h5`.",
                ""]

    def header(name, array=False):
        h = f"[[{name}]]" if array else f"[{name}]"
        if comments and name in SECTION_DOC:
            h = f"{h:<28} # {SECTION_DOC[name]}"
        out.append(h)

    for sec, spec in SPEC.items():
        table = data[sec]
        header(sec)
        out.extend(_lines(table, spec, comments))
        out.append("")
        if sec == "model":
            header("model.table")
            out.extend(_lines(table["table"], TABLE, comments))
            out.append("")
            if table["beam"]:
                for b in table["beam"]:
                    header("model.beam", array=True)
                    out.extend(_lines(b, BEAM, comments))
                    out.append("")
            elif comments:
                out += ["# [[model.beam]]            # e.g. the paper's Fig. 10b: beam 2 "
                        "with f2 = 108 Hz",
                        "# beam = 2", "# freq_hz = [16.2, 108.0]", ""]
        if sec == "sampling":
            for k in ("mu0", "kc", "N0"):
                h = f"[sampling.{k}]"
                if comments:
                    h = f"{h:<28} # {DIST_DOC[k]}"
                out.append(h)
                out.extend(_lines(table[k], {}, comments))
                out.append("")
    if comments:
        out += ["# distributions: fixed(value), uniform(low, high), normal(mean, std; "
                "mean >= 3 std),",
                "#   truncnormal(mean, std, low, high; high may be inf), "
                "lognormal(median, sigma = std of ln)"]
    return "\n".join(out).rstrip() + "\n"


def template(preset=DEFAULT_PRESET):
    """The complete, commented configuration of a preset (``mcfric config PRESET``)."""
    return render(validate(defaults(preset)).data)
