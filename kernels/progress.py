"""The one progress protocol of every long-running step.

A step is a generator that yields its progress as floats in [0, 1] and *returns* its result (a
typed dataclass or an array), so a caller never has to tell progress from result by its type:

    def solve_steps(scene, settings) -> Steps[Solution]:
        for k in range(n):
            ...
            yield (k + 1) / n
        return Solution(...)

A step that runs another one maps the inner progress onto a part of its own range and takes the
inner result from `yield from`:

    solution = yield from scaled(solve_steps(scene, settings), 0.0, 0.8)

Hosts either drain a step (`drain`, for scripts and tests) or advance it one yield at a time
(`advance`, for a modal operator's timer or a command line's progress bar).
"""

from __future__ import annotations

from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

R = TypeVar("R")

# A step: yields progress in [0, 1], returns R.
Steps = Generator[float, None, R]


def scaled(steps: Steps[R], start: float = 0.0, span: float = 1.0) -> Steps[R]:
    """Re-yield `steps`' progress mapped onto [start, start + span]; returns its result."""
    while True:
        try:
            p = next(steps)
        except StopIteration as stop:
            return stop.value
        yield start + span * float(p)


def drain(steps: Steps[R], on_progress: Callable[[float], Any] | None = None) -> R:
    """Run a step to its end; returns its result. `on_progress` sees every yielded fraction."""
    while True:
        try:
            p = next(steps)
        except StopIteration as stop:
            return stop.value
        if on_progress is not None:
            on_progress(float(p))


@dataclass
class Advance(Generic[R]):
    """One `advance` of a step: its progress, and the result once it has finished."""

    progress: float
    done: bool
    result: R | None = None


def advance(steps: Steps[R]) -> Advance[R]:
    """Advance a step by one yield (a modal operator's timer tick)."""
    try:
        return Advance(float(next(steps)), False)
    except StopIteration as stop:
        return Advance(1.0, True, stop.value)


def sequence(*parts: tuple[float, Callable[[], Steps[Any]]]) -> Steps[list]:
    """Run steps one after another, each given (weight, factory); progress is shared by weight and
    the results come back in a list."""
    total = sum(w for w, _ in parts) or 1.0
    start, results = 0.0, []
    for weight, make in parts:
        span = weight / total
        results.append((yield from scaled(make(), start, span)))
        start += span
    return results
