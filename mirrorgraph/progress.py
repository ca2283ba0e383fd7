"""A small progress reporter for long steps.

Draws a one-line bar on stderr when stderr is a terminal; silent when it is
not (pipes, CI, notebooks' captured streams) or when ``quiet`` is set, so
logs stay clean. Steps that report through it: reading per-frame JSON folders,
the robust initialisation and the graph's iterations.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class Progress:
    """Progress of one step with a known or unknown total.

    Args:
        label: what is being done, e.g. ``"reading frames"``.
        total: number of units, or ``None`` when unknown.
        enabled: draw at all (``False`` makes every call a no-op).
        stream: where to draw (default ``sys.stderr``).
    """

    def __init__(self, label: str, total: int | None = None, *, enabled: bool = True,
                 stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = bool(enabled) and _is_tty(self.stream)
        self.label, self.total, self.done = label, total, 0
        self._last = 0.0
        self._start = time.perf_counter()

    def update(self, advance: int = 1, *, info: str = "") -> None:
        """Advance by ``advance`` units; redraw at most 10 times a second."""
        self.done += advance
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < 0.1 and (self.total is None or self.done < self.total):
            return
        self._last = now
        self._draw(info)

    def _draw(self, info: str) -> None:
        elapsed = time.perf_counter() - self._start
        if self.total:
            frac = min(self.done / self.total, 1.0)
            bar = "#" * int(24 * frac) + "-" * (24 - int(24 * frac))
            text = f"\r{self.label} [{bar}] {self.done}/{self.total} {elapsed:5.1f}s {info}"
        else:
            text = f"\r{self.label} {self.done} {elapsed:5.1f}s {info}"
        self.stream.write(text[:120].ljust(80))
        self.stream.flush()

    def close(self, info: str = "") -> None:
        """Finish the line (nothing is drawn if nothing was reported)."""
        if self.enabled and self.done > 0:
            self._draw(info)
            self.stream.write("\n")
            self.stream.flush()
            self.enabled = False

    def callback(self, done: int, total: int) -> None:
        """``(done, total)`` callback form, as the folder readers call it."""
        self.total = total
        self.update(done - self.done)

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _is_tty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
