"""A progress bar on stderr: redrawn in place on a terminal, a plain line every tenth of the way (and at
most every 30 s) when stderr is a file or a pipe."""
from __future__ import annotations

import sys
import time

from psvs._budget import duration


class Progress:
    """``total`` tasks to compute (``skipped`` more were already done); :meth:`update` after each finished
    batch, :meth:`close` at the end."""

    def __init__(self, label: str, total: int, skipped: int = 0, stream=None):
        self.label, self.total, self.skipped = label, total, skipped
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.done = self.failed = 0
        self.t0 = self._shown_t = time.monotonic()
        self._shown_step, self._shown_done = 0, -1

    def update(self, done: int, failed: int = 0) -> None:
        """Count ``done`` more finished tasks (``failed`` of them raised) and show the progress when due: on a
        terminal at most 5 times a second, in a log at every tenth of the run or every 30 s."""
        self.done, self.failed = self.done + done, self.failed + failed
        now = time.monotonic()
        step = (10 * self.done) // max(self.total, 1)
        if self.tty and now - self._shown_t >= 0.2 or not self.tty and (step > self._shown_step
                                                                         or now - self._shown_t >= 30):
            self._show(now)
            self._shown_t, self._shown_step, self._shown_done = now, step, self.done

    def _show(self, now: float, end: str = "") -> None:
        n, total = self.done, self.total
        elapsed = now - self.t0
        rate = n / elapsed if elapsed > 0 else 0.0
        eta = f", {duration((total - n) / rate)} left" if 0 < n < total and rate > 0 else ""
        extra = (f", {self.failed} failed" if self.failed else "") + (
            f" ({self.skipped} done before)" if self.skipped else "")
        if self.tty:
            width = 30
            fill = int(width * n / max(total, 1))
            text = f"\r{self.label} [{'#' * fill}{'.' * (width - fill)}] {n}/{total}{extra}{eta}\x1b[K{end}"
        else:
            text = f"{self.label}: {n}/{total}{extra}, {duration(elapsed)}{eta}\n"
        self.stream.write(text)
        self.stream.flush()

    def close(self) -> None:
        """Show the final count (on its own line) unless it was just shown."""
        if self.tty or self._shown_done != self.done:
            self._show(time.monotonic(), end="\n")
