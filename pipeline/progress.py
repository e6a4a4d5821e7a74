"""A progress bar with the time left, for the command line, driven by the kernels' progress.

A job is a step (kernels/progress.py) that yields its progress as floats in [0, 1]; `drain(step,
bar)` hands every fraction to the bar. The bar draws on stderr, and only when stderr is a
terminal, so logs and pipes stay clean:

    trace  42% [##########..............] 0:05 elapsed, ~0:07 left

| verbosity | terminal                               | not a terminal (a log, a pipe)            |
|-----------|----------------------------------------|-------------------------------------------|
| quiet     | nothing                                | nothing                                   |
| normal    | the bar, redrawn at most 10 times a second | nothing                               |
| verbose   | the bar                                | one line per tenth done, with the time left |

The time left is the time so far scaled by what is left, elapsed x (1 - p) / p: kernels' progress is
roughly proportional to work within a phase but not across phases (a snapshot's 0.1 may take
longer than a solve's 0.1), so the estimate is shown with a "~" and only once 1% is done and half
a second has passed. No dependency: neither tqdm nor rich is in the pinned environments, and the
bar needs twenty lines.
"""

from __future__ import annotations

import shutil
import sys
import time
from collections.abc import Callable
from typing import TextIO

QUIET, NORMAL, VERBOSE = -1, 0, 1
REDRAW_INTERVAL_S = 0.1  # a terminal redraw costs ~0.1 ms; ten a second look continuous
ESTIMATE_AFTER_FRACTION = 0.01  # below this the rate is mostly start-up cost: no estimate yet
ESTIMATE_AFTER_S = 0.5
VERBOSE_STEP = 0.1  # verbose, not a terminal: a line each time another tenth is done
MIN_BAR_WIDTH, MAX_BAR_WIDTH = 10, 40


def clock_text(seconds: float) -> str:
    """0:07, 12:30, 1:02:03."""
    seconds = int(round(max(seconds, 0.0)))
    hours, rest = divmod(seconds, 3600)
    minutes, secs = divmod(rest, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def time_left(fraction: float, elapsed: float) -> float | None:
    """Seconds left at `fraction` done after `elapsed` seconds, or None before an estimate means
    anything."""
    if fraction < ESTIMATE_AFTER_FRACTION or elapsed < ESTIMATE_AFTER_S:
        return None
    return elapsed * (1.0 - fraction) / fraction


class ProgressBar:
    """`bar(fraction)` for every progress yield, `bar.close(done)` at the end (see the module
    docstring). `stream` and `clock` are parameters for tests."""

    def __init__(self, label: str, verbosity: int = NORMAL, stream: TextIO | None = None,
                 clock: Callable[[], float] = time.monotonic, width: int | None = None):
        self.label = label
        self.stream = sys.stderr if stream is None else stream
        self.clock = clock
        is_terminal = bool(getattr(self.stream, "isatty", lambda: False)())
        self.draws = verbosity > QUIET and is_terminal  # the redrawn bar
        self.logs = verbosity >= VERBOSE and not is_terminal  # a line per tenth
        self.width = width
        self.began = clock()
        self.fraction = 0.0
        self._drawn_at: float | None = None
        self._drawn_length = 0
        self._logged_steps = 0
        self.closed = False

    @property
    def shows(self) -> bool:
        return self.draws or self.logs

    def __call__(self, fraction: float) -> None:
        if self.closed:
            return
        self.fraction = min(max(float(fraction), 0.0), 1.0)
        now = self.clock()
        if self.draws and (self._drawn_at is None or now - self._drawn_at >= REDRAW_INTERVAL_S):
            self._draw(self.line(now))
            self._drawn_at = now
        if self.logs and int(self.fraction / VERBOSE_STEP + 1e-9) > self._logged_steps:
            self._logged_steps = int(self.fraction / VERBOSE_STEP + 1e-9)
            self.stream.write(self.text(now) + "\n")
            self.stream.flush()

    def _times(self, now: float) -> str:
        """"0:05 elapsed, ~0:07 left" (no estimate yet, or done: the elapsed time only)."""
        elapsed = now - self.began
        left = time_left(self.fraction, elapsed)
        tail = f", ~{clock_text(left)} left" if left is not None and self.fraction < 1.0 else ""
        return f"{clock_text(elapsed)} elapsed{tail}"

    def text(self, now: float) -> str:
        """"trace  42% 0:05 elapsed, ~0:07 left": a log line, without the bar."""
        return f"{self.label} {self.fraction:4.0%} {self._times(now)}"

    def line(self, now: float) -> str:
        """The terminal line, the bar as wide as the terminal allows (10-40 cells), cut to it."""
        columns = self.width or shutil.get_terminal_size((80, 24)).columns
        head, times = f"{self.label} {self.fraction:4.0%}", self._times(now)
        cells = max(MIN_BAR_WIDTH, min(MAX_BAR_WIDTH, columns - len(head) - len(times) - 5))
        filled = int(round(self.fraction * cells))
        bar = "#" * filled + "." * (cells - filled)
        return f"{head} [{bar}] {times}"[: max(columns - 1, 1)]

    def _draw(self, text: str) -> None:
        pad = " " * max(self._drawn_length - len(text), 0)  # wipe a longer previous line
        self.stream.write("\r" + text + pad)
        self.stream.flush()
        self._drawn_length = len(text)

    def close(self, done: bool = True) -> None:
        """Finish: a finished bar stays as its last line ("100% [####] 0:12 elapsed"); an
        interrupted one is wiped so the error message starts on a clean line."""
        if self.closed:
            return
        self.closed = True
        now = self.clock()
        if self.draws:
            if done:
                self.fraction = 1.0
                self._draw(self.line(now))
                self.stream.write("\n")
            else:
                self.stream.write("\r" + " " * self._drawn_length + "\r")
            self.stream.flush()
        elif self.logs and done and self._logged_steps < round(1 / VERBOSE_STEP):
            self.fraction = 1.0
            self.stream.write(self.text(now) + "\n")
            self.stream.flush()

    def __enter__(self) -> ProgressBar:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        self.close(done=kind is None)
