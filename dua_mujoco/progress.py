"""A dependency-free progress bar for long runs (stderr, one line, rate-limited)."""

from __future__ import annotations

import sys
import time
from typing import TextIO

from dua_mujoco.closing import Closing

__all__ = ["Progress"]


class Progress(Closing):
    """``with Progress(total, "label") as bar: bar.update()`` draws ``label [####    ] 40/100``.

    Args:
        total: Number of units of work.
        label: Text before the bar.
        enabled: False makes every call a no-op (``--no-progress``, tests).
        stream: Where to draw (default ``sys.stderr``).
        min_interval: Seconds between redraws, so drawing never costs more than the work.

    On a terminal the bar is redrawn in place; elsewhere (a CI log, a file) it prints a plain
    line at every tenth of the work, without carriage returns or escape codes.
    """

    def __init__(
        self,
        total: int,
        label: str = "",
        *,
        enabled: bool = True,
        stream: TextIO | None = None,
        min_interval: float = 0.1,
    ) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.enabled = enabled
        self.stream = stream if stream is not None else sys.stderr
        self.min_interval = min_interval
        self.count = 0
        self._start = time.perf_counter()
        self._last = 0.0
        isatty = getattr(self.stream, "isatty", None)
        self._tty = bool(isatty()) if callable(isatty) else False
        self._decile = 0  # tenths of the work reported so far (plain lines)

    def update(self, n: int = 1, *, note: str = "") -> None:
        """Advance by ``n`` units; redraw at most every ``min_interval`` seconds."""
        self.count += n
        if not self.enabled:
            return
        now = time.perf_counter()
        if not self._tty:
            decile = min(10 * self.count // self.total, 10)
            if decile > self._decile:
                self._decile = decile
                self._line(now, note)
        elif now - self._last >= self.min_interval or self.count >= self.total:
            self._last = now
            self._draw(now, note)

    def _line(self, now: float, note: str) -> None:
        extra = f" {note}" if note else ""
        self.stream.write(
            f"{self.label} {self.count}/{self.total} ({100 * self.count // self.total} %) "
            f"{now - self._start:.1f}s{extra}\n"
        )
        self.stream.flush()

    def _draw(self, now: float, note: str) -> None:
        frac = min(self.count / self.total, 1.0)
        width = 30
        filled = round(frac * width)
        elapsed = now - self._start
        # The first units often include one-off work (JIT compilation): no ETA from them.
        settled = self.count >= max(2, self.total // 50)
        eta = f"{elapsed / frac - elapsed:5.1f}s" if settled and frac > 0 else "  ...."
        bar = "#" * filled + " " * (width - filled)
        extra = f" {note}" if note else ""
        self.stream.write(
            f"\r{self.label} [{bar}] {self.count}/{self.total} "
            f"{elapsed:5.1f}s eta {eta}{extra}\x1b[K"
        )
        self.stream.flush()

    def close(self) -> None:
        """Finish the line."""
        if self.enabled:
            if self._tty:
                self._draw(time.perf_counter(), "")
                self.stream.write("\n")
                self.stream.flush()
            elif self._decile < 10:
                self._line(time.perf_counter(), "")
            self.enabled = False
