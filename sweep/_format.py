"""How numbers read in messages: counts, rates, sizes and durations, one format each.

Every message of the command line, the runner, the preflight and ``sweep info`` writes
counts as ``1 chunk`` / ``120,701 points`` (:func:`count`), rates as ``12,345 points/s``
(:func:`rate`), sizes in decimal units (:func:`format_bytes`) and durations as ``35 s`` /
``1 h 6 min`` (:func:`format_duration`). An error writing a file names that file
(:func:`naming`).

Floor 0: imports nothing of the package (standard library only).
"""
from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator

__all__ = ["count", "rate", "format_bytes", "format_duration", "naming"]


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``count(1, "chunk")`` -> ``"1 chunk"``, ``count(120701, "point")`` ->
    ``"120,701 points"``.

    Parameters
    ----------
    n : int
    noun : str
        Singular; the plural adds an ``s`` unless ``plural`` is given.
    plural : str, optional
    """
    word = noun if n == 1 else (plural or noun + "s")
    return f"{n:,} {word}"


def rate(per_second: float, unit: str = "points") -> str:
    """``12345.6`` -> ``"12,346 points/s"``; three significant digits below 100, ``n/a``
    when unknown (NaN or infinite: nothing was timed)."""
    if not math.isfinite(per_second):
        return f"n/a {unit}/s"
    if abs(per_second) >= 100:
        return f"{per_second:,.0f} {unit}/s"
    return f"{per_second:.3g} {unit}/s"


def format_bytes(n: float) -> str:
    """``1234567`` -> ``"1.23 MB"`` (decimal units)."""
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1000
    raise AssertionError("unreachable")  # pragma: no cover


def format_duration(seconds: float) -> str:
    """``4000`` -> ``"1 h 6 min"``; days and years for absurd designs."""
    if not math.isfinite(seconds):
        return "unknown"
    if seconds < 60:
        return f"{seconds:.2g} s"
    minutes = seconds / 60
    if minutes < 60:
        return f"{minutes:.0f} min"
    hours = minutes / 60
    if hours < 48:
        return f"{int(hours)} h {int(minutes % 60)} min"
    days = hours / 24
    return f"{days:.3g} days" if days < 730 else f"{days / 365.25:.3g} years"


@contextlib.contextmanager
def naming(path: str | os.PathLike) -> Iterator[None]:
    """Name ``path`` in an OSError raised inside that names no file.

    write(), close() and fsync() name none: a full disk said a bare "No space left on
    device", which a command then blamed on the file it read.

    Parameters
    ----------
    path : path-like
        The file written (``"<stdout>"`` for standard output, as Python names it).
    """
    try:
        yield
    except OSError as exc:
        if exc.filename is not None:
            raise
        # OSError(errno, ...) is the subclass of that errno again: BrokenPipeError stays one.
        raise OSError(exc.errno, exc.strerror or str(exc), os.fspath(path)) from exc
