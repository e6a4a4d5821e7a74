"""Seconds per phase of a kernel, exclusive of the phases nested inside it.

    clock = PhaseClock()
    with clock("shading"):
        ...
        with clock("traversal"):  # shading's seconds stop while traversal runs
            ...
    clock.seconds  # {"shading": ..., "traversal": ...}

A phase entered inside another pauses the outer one, so the phases' seconds add up to the time
spent inside any of them: a profile that says where the time went, not a sum that counts nested
work twice. `depth` tags what follows with a label (the tracer's wavefront depth), kept in
`by_label` as {label: {phase: seconds}}. One `perf_counter` per entry and exit: about a
microsecond, negligible against the vectorised work it times.
"""

from __future__ import annotations

import time
from collections import defaultdict
from contextlib import contextmanager


class PhaseClock:
    """Exclusive seconds per phase name, and per phase within a label (e.g. a depth)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.by_label: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
        self.label: str | None = None
        self._stack: list[str] = []
        self._since = 0.0

    def _charge(self, now: float) -> None:
        if self._stack:
            spent = now - self._since
            phase = self._stack[-1]
            self.seconds[phase] += spent
            if self.label is not None:
                self.by_label[self.label][phase] += spent
        self._since = now

    @contextmanager
    def __call__(self, phase: str):
        self._charge(time.perf_counter())
        self._stack.append(phase)
        try:
            yield
        finally:
            self._charge(time.perf_counter())
            self._stack.pop()

    def as_dict(self) -> dict:
        """{"seconds": {phase: s}, "by_label": {label: {phase: s}}}, plain dicts for JSON."""
        return {"seconds": dict(self.seconds),
                "by_label": {k: dict(v) for k, v in self.by_label.items()}}
