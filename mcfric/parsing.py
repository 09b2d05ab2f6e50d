"""Small parsing helpers shared by the file readers: CSV rows, integers, lists in messages.

Each raises a one-line ``ValueError`` naming the file.
"""

from __future__ import annotations

import csv


def as_int(x, name, path):
    """``x`` as an int (also from a string of digits); a one-line error naming the file."""
    if isinstance(x, bool):
        raise ValueError(f"{path}: {name}: expected an integer, got {x!r}")
    try:
        i = int(x)
    except (TypeError, ValueError):
        raise ValueError(f"{path}: {name}: expected an integer, got {x!r}") from None
    if i != x and not (isinstance(x, str) and x.strip().lstrip("+-").isdigit()):
        raise ValueError(f"{path}: {name}: expected an integer, got {x!r}")
    return i


def short(seq, n=12):
    """The first ``n`` items of ``seq`` as text, for messages."""
    seq = list(seq)
    s = ", ".join(str(x) for x in seq[:n])
    return s + (", ..." if len(seq) > n else "")


def csv_rows(path, what="CSV file"):
    """Non-empty, non-comment rows of a CSV file as ``(line number, cells)``.

    Raises a one-line ValueError naming the file when it is not text or has no rows.
    """
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file") from None
    rows = [(i + 1, r) for i, r in enumerate(csv.reader(text.splitlines()))
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ValueError(f"{path}: empty {what}")
    return rows
