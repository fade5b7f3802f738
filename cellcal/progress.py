"""Progress of a capture on a terminal: points done/total, rate, ETA, last error.

Written to stderr: refreshed in place (``\\r``) when the stream is a TTY and erased at
the end (the command's own summary line follows), plain lines otherwise (at most one
every ``interval_s``, plus every fault and the end). Disabled (quiet) under ``--json``.
A log record written to the same terminal erases the line first (:func:`erase_line`);
the next update draws it again.
"""

from __future__ import annotations

import sys
import time

#: the progress line drawn in place on a terminal now, if any
_drawn: Progress | None = None


def erase_line() -> None:
    """Erase the progress line drawn in place on the terminal, if any (a log record is
    about to be written there: :mod:`cellcal.logs`)."""
    if _drawn is not None:
        _drawn.erase()


def _fmt_s(s: float) -> str:
    if s != s or s == float("inf"):
        return "--:--"
    s = int(round(s))
    h, rem = divmod(s, 3600)
    m, sec = divmod(rem, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m:02d}:{sec:02d}"


class Progress:
    """Callable progress reporter for :class:`daq.executor.Executor`.

    Parameters
    ----------
    stream : text stream (default ``sys.stderr``)
    enabled : bool
        False prints nothing.
    interval_s : float
        Least time between two plain lines (non-TTY).
    tty : bool or None
        Force the TTY behaviour (None: ``stream.isatty()``).
    """

    def __init__(self, stream=None, *, enabled: bool = True, interval_s: float = 2.0,
                 tty: bool | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = enabled
        self.interval_s = interval_s
        try:
            self.tty = self.stream.isatty() if tty is None else tty
        except (AttributeError, ValueError):
            self.tty = False
        self._t0: float | None = None
        self._done0 = 0
        self._last_print = 0.0
        self._last_error: str | None = None
        self._width = 0

    def line(self, done: int, total: int, last_error: str | None) -> str:
        """The status line for ``done`` of ``total`` points."""
        now = time.monotonic()
        if self._t0 is None:
            self._t0, self._done0 = now, done
        dt = now - self._t0
        rate = (done - self._done0) / dt if dt > 0 and done > self._done0 else float("nan")
        eta = (total - done) / rate if rate == rate and rate > 0 else float("nan")
        pct = 100.0 * done / total if total else 100.0
        text = (f"{done}/{total} points ({pct:.0f} %)  "
                f"{rate:.1f} pt/s  ETA {_fmt_s(eta)}" if rate == rate else
                f"{done}/{total} points ({pct:.0f} %)  -- pt/s  ETA --:--")
        if last_error:
            text += f"  last error: {last_error[:80]}"
        return text

    def __call__(self, done: int, total: int, last_error: str | None = None) -> None:
        if not self.enabled:
            return
        text = self.line(done, total, last_error)
        now = time.monotonic()
        new_error = last_error is not None and last_error != self._last_error
        self._last_error = last_error
        if self.tty:
            global _drawn
            if now - self._last_print < 0.1 and done < total and not new_error:
                return
            pad = max(self._width - len(text), 0)
            self.stream.write("\r" + text + " " * pad)
            self._width = len(text)
            _drawn = self
        else:
            if now - self._last_print < self.interval_s and done < total and not new_error:
                return
            self.stream.write(text + "\n")
        self._last_print = now
        self.stream.flush()

    def erase(self) -> None:
        """Erase the in-place line (TTY), if drawn."""
        if self.enabled and self.tty and self._width:
            self.stream.write("\r" + " " * self._width + "\r")
            self.stream.flush()
            self._width = 0

    def close(self) -> None:
        """Erase the in-place line (TTY): the summary that follows says how it ended."""
        global _drawn
        self.erase()
        if _drawn is self:
            _drawn = None
