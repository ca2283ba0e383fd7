"""A small progress reporter for long steps.

Draws a one-line bar on stderr when stderr is a terminal; silent when it is
not (pipes, CI, notebooks' captured streams) or when ``quiet`` is set, so
logs stay clean. Steps that report through it: reading per-frame JSON folders,
the robust initialisation, the graph's iterations, drawing the report's
figures, sampling and rendering video frames.

Every bar counts up monotonically. A total is shown only when it is known: a
step whose total is a running estimate (the adaptive RANSAC, which stops once
it is confident enough) shows its count and a bar that never moves back, and
its final line shows the real total (``50/50``). :class:`SolveProgress` turns
the ``(iteration, error)`` callback of a solver that runs several passes, each
minimising its own objective, into a line whose error never rises within a
pass.
"""

from __future__ import annotations

import sys
import time
from typing import Callable, TextIO

__all__ = ["Progress", "SolveProgress", "end_open_lines"]

#: Streams on which a bar's line is drawn and not yet ended (id -> stream).
_OPEN_LINES: dict[int, TextIO] = {}


def end_open_lines() -> None:
    """End every bar line left open (a step that raised before closing its bar), so that
    what is printed next, an error for instance, starts on a line of its own."""
    for stream in list(_OPEN_LINES.values()):
        try:
            stream.write("\n")
            stream.flush()
        except (OSError, ValueError):         # a closed stream: nothing to end
            pass
    _OPEN_LINES.clear()


class Progress:
    """Progress of one step with a known, estimated or unknown total.

    Args:
        label: what is being done, e.g. ``"reading frames"``.
        total: number of units, or ``None`` when unknown.
        enabled: draw at all (``False`` makes every call a no-op).
        stream: where to draw (default ``sys.stderr``).

    Example:
        >>> with Progress("drawing the report", total=5, enabled=False) as bar:
        ...     for name in ("a", "b"):
        ...         bar.update(info=name)
        >>> bar.done
        2
    """

    #: Least seconds between two redraws (the last unit is always drawn).
    min_interval = 0.1

    def __init__(self, label: str, total: int | None = None, *, enabled: bool = True,
                 stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self.enabled = bool(enabled) and _is_tty(self.stream)
        self.label, self.total, self.done = label, total, 0
        self.closed = False
        self._estimate: int | None = None     # running estimate of the total, not shown
        self._frac = 0.0                      # drawn fraction: never decreases
        self._info = ""
        self._last = -float("inf")
        self._start = time.perf_counter()

    @property
    def started(self) -> bool:
        """Whether any unit was reported."""
        return self.done > 0

    def update(self, advance: int = 1, *, info: str = "") -> None:
        """Advance by ``advance`` units; redraw at most every :attr:`min_interval` s."""
        if self.closed:
            return
        self.done += max(int(advance), 0)
        self._info = info
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self._last < self.min_interval and (self.total is None or self.done < self.total):
            return
        self._last = now
        self._draw()

    def callback(self, done: int, total: int) -> None:
        """``(done, total)`` callback form with a known total, as the folder readers call it."""
        self.total = total
        self.update(done - self.done)

    def estimate(self, done: int, planned: int) -> None:
        """``(done, planned)`` callback form where ``planned`` is a running estimate of the
        total that may shrink or grow (an adaptive RANSAC): the count and a bar that never
        moves back are drawn, the total only by :meth:`close`, once it is known."""
        self._estimate = max(int(planned), int(done), 1)
        self.update(done - self.done)

    def _fraction(self) -> float | None:
        if self.total:
            frac = self.done / self.total
        elif self._estimate:
            frac = self.done / self._estimate
        else:
            return None
        self._frac = max(self._frac, min(frac, 1.0))
        return self._frac

    def _draw(self) -> None:
        elapsed = time.perf_counter() - self._start
        frac = self._fraction()
        count = f"{self.done}/{self.total}" if self.total else f"{self.done}"
        if frac is None:
            text = f"\r{self.label} {count} {elapsed:5.1f}s {self._info}"
        else:
            bar = "#" * int(24 * frac) + "-" * (24 - int(24 * frac))
            text = f"\r{self.label} [{bar}] {count} {elapsed:5.1f}s {self._info}"
        self.stream.write(text.rstrip()[:120].ljust(80))
        self.stream.flush()
        _OPEN_LINES[id(self.stream)] = self.stream

    def close(self, info: str | None = None) -> None:
        """Finish the line (nothing is drawn if nothing was reported); later calls are
        ignored. A step whose total was estimated ends with its real total, the count."""
        if self.closed:
            return
        self.closed = True
        if info is not None:
            self._info = info
        if self.enabled and self.done > 0:
            if self._estimate is not None and not self.total:
                self.total = self.done
            self._draw()
            self.stream.write("\n")
            self.stream.flush()
            _OPEN_LINES.pop(id(self.stream), None)
        self.enabled = False

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SolveProgress:
    """``(iteration, error)`` callback of a multi-pass solver, drawn on a :class:`Progress`.

    The graph is solved in passes (a warm start on a few frames, the full graph,
    the graph once more without the outliers, or chunk after chunk), each with its
    own objective: the error of an accepted step never rises within a pass but
    starts afresh at the next. A rise therefore starts a new pass; the line shows
    the accepted steps so far and the current pass's error from its first step:
    ``solving the graph 9 pass 2: error 6636 -> 5625``.

    Args:
        bar: where to draw.
        on_first: called before the first step is drawn (e.g. to close a previous bar).
    """

    def __init__(self, bar: Progress, on_first: Callable[[], None] | None = None) -> None:
        self.bar, self.on_first = bar, on_first
        self.passes, self.first, self.last = 0, None, None

    def __call__(self, iteration: int, error: float) -> None:
        error = float(error)
        if self.last is None and self.on_first is not None:
            self.on_first()
        if self.last is None or error > self.last:
            self.passes += 1
            self.first = error
        self.last = error
        self.bar.update(1, info=self.info)

    @property
    def info(self) -> str:
        """The text after the count, e.g. ``pass 2: error 6636 -> 5625``."""
        if self.last is None:
            return ""
        return f"pass {self.passes}: error {self.first:.5g} -> {self.last:.5g}"


def _is_tty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
