"""The memory this machine has free, and the check that a computation's arrays fit in it."""

from __future__ import annotations


class MemoryRefused(ValueError):
    """A computation refused before it allocates: its arrays would not fit in the memory
    available (a ``ValueError``, as for any input too large)."""


def available():
    """MemAvailable of ``/proc/meminfo``, bytes (None where there is no such file)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def human(n):
    """``n`` bytes as text with an SI prefix (``"3.2 GB"``)."""
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}" if unit != "bytes" else f"{n:.0f} bytes"
        n /= 1000.0


def check_fits(need, what, hint):
    """Raise :class:`MemoryRefused` (one line) if ``need`` bytes exceed the memory
    available.

    Parameters
    ----------
    need : float
        Bytes the computation's arrays take.
    what : str
        The computation, for the message.
    hint : str
        What to change.
    """
    free = available()
    if free is not None and need > free:
        raise MemoryRefused(f"{what} needs about {human(need)} of memory but {human(free)} "
                            f"is available: {hint}")
