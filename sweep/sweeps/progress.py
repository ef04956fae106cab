"""Progress of a run, on a terminal and off it.

Owns :func:`progress`: a tqdm bar when stderr is a terminal; when it is not (batch jobs,
CI logs, notebooks) a plain line every :data:`sweep.sweeps.limits.PROGRESS_INTERVAL_S`
seconds and one at the end, e.g.::

    doe.nc: 393,216/1,000,000 points (39%) in 16 s, 24,576 points/s, ETA 25 s

(a bar redrawn with carriage returns is unreadable in a log file, and tqdm, disabled there,
said nothing for minutes); nothing at all when quiet.

Floor 4: may import :mod:`sweep._format`, :mod:`sweep.sweeps.limits` and, lazily, tqdm.
"""
from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from sweep._format import count, format_duration, rate
from sweep.sweeps import limits

__all__ = ["progress", "LineProgress", "DroppingStream"]


class DroppingStream:
    """A text stream that drops everything, silently, from the first write that fails.

    A run's messages and progress are not its result: a stderr that fails (its reader left,
    ``2>/dev/full``) must neither stop the run nor be blamed on the output file, which
    said "cannot write X.partial: Broken pipe" and lost the run.

    Parameters
    ----------
    stream : file
        Where the text goes while it can (``sys.stderr``).

    Attributes
    ----------
    failed : bool
        A write or flush failed: nothing more is written.
    """

    def __init__(self, stream: TextIO | None) -> None:
        self.stream = stream
        # None: Python started without the file descriptor (``2>&-``, a daemon).
        self.failed = stream is None

    def _attempt(self, method: str, *args: Any) -> None:
        if self.failed:
            return
        try:
            getattr(self.stream, method)(*args)
        except (OSError, ValueError):  # ValueError: the stream was closed
            self.failed = True

    def write(self, text: str) -> int:
        """Write ``text`` unless a write has failed; returns its length either way."""
        self._attempt("write", text)
        return len(text)

    def flush(self) -> None:
        """Flush the stream unless a write has failed."""
        self._attempt("flush")

    def isatty(self) -> bool:
        """Whether the stream is a terminal (False if it cannot say)."""
        try:
            return bool(self.stream.isatty())
        except (AttributeError, OSError, ValueError):
            return False

    def __getattr__(self, name: str) -> Any:
        # fileno, encoding, ...: as the stream has them (tqdm sizes its bar by fileno)
        return getattr(self.stream, name)


class LineProgress:
    """Plain progress lines: every ``interval`` seconds of ``clock`` and at the end.

    Parameters
    ----------
    total : int
        Points of the run.
    initial : int
        Points already done when it starts (resumed): counted as done, not in the rate.
    desc : str
        Prefix of every line (the output's name).
    interval : float
        Seconds between two lines [s]; 0: a line at every update.
    stream : file
        Where the lines go.
    clock : callable
        Seconds of a monotonic clock (tests pass a fake one).
    """

    def __init__(self, total: int, initial: int, desc: str, interval: float,
                 stream: TextIO, clock: Callable[[], float] = time.monotonic) -> None:
        self.total, self.n, self._initial = total, initial, initial
        self.desc, self.interval, self.stream, self.clock = desc, interval, stream, clock
        self._start = self._last = clock()

    def line(self, now: float, final: bool = False) -> str:
        """The progress line at clock time ``now`` [s]."""
        elapsed = now - self._start
        per_s = (self.n - self._initial) / elapsed if elapsed > 0 else float("nan")
        percent = 100 * self.n / self.total if self.total else 100.0
        text = (f"{self.desc + ': ' if self.desc else ''}{self.n:,}/"
                f"{count(self.total, 'point')} ({percent:.0f}%) in "
                f"{format_duration(elapsed)}, {rate(per_s)}")
        if not final:
            eta = (self.total - self.n) / per_s if per_s > 0 else float("nan")
            text += f", ETA {format_duration(eta)}"
        return text

    def update(self, n: int) -> None:
        """``n`` more points are done (negative: fewer, e.g. a resumed chunk rejected)."""
        self.n += n
        now = self.clock()
        if now - self._last >= self.interval:
            self._last = now
            print(self.line(now), file=self.stream, flush=True)

    def close(self) -> None:
        """The final line (when anything was done)."""
        if self.n > self._initial:
            print(self.line(self.clock(), final=True), file=self.stream, flush=True)

    def __enter__(self) -> LineProgress:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:  # an interrupted run says so itself
            self.close()


class _Silent:
    """No progress at all (``--quiet``)."""

    def update(self, n: int) -> None:
        pass

    def __enter__(self) -> _Silent:
        return self

    def __exit__(self, *exc) -> None:
        pass


def progress(total: int, initial: int = 0, *, quiet: bool = False, desc: str = "",
             interval: float | None = None, stream: TextIO | None = None,
             clock: Callable[[], float] = time.monotonic) -> Any:
    """The progress indicator of a run: a context manager with ``update(n)``.

    Parameters
    ----------
    total, initial : int
        Points of the run, and those already done (resumed).
    quiet : bool
        Nothing at all.
    desc : str
        Label (the output's name).
    interval : float, optional
        Seconds between two plain lines off a terminal [s] (default
        :data:`sweep.sweeps.limits.PROGRESS_INTERVAL_S`).
    stream : file, optional
        Default ``sys.stderr`` (looked up at the call) in a :class:`DroppingStream`.
    clock : callable
        Monotonic clock of the plain lines [s].

    Returns
    -------
    tqdm bar, LineProgress or a silent stand-in
    """
    if quiet:
        return _Silent()
    stream = DroppingStream(sys.stderr) if stream is None else stream
    isatty = getattr(stream, "isatty", None)
    if isatty is not None and isatty():
        from tqdm.auto import tqdm

        return tqdm(total=total, initial=initial, unit="pt", unit_scale=True, desc=desc,
                    file=stream, dynamic_ncols=True, smoothing=0.1)
    interval = limits.PROGRESS_INTERVAL_S if interval is None else interval
    return LineProgress(total, initial, desc, interval, stream, clock)
