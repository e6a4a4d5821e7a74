"""How many threads a large BVH query takes: the count that has been faster lately, measured.

A query of many rays can run on one worker thread or on several (`bvh.py`). On an idle machine
two threads trace large batches faster; on a machine where another process keeps a core busy,
the threads share one core, contend for the GIL and lose to one thread. Ray counts alone cannot
tell the two apart, so the choice is measured: each option's seconds per ray are kept as a running
mean over the calls that used it, the faster option is taken, and every EXPLORE_EVERY-th call
tries the other one, so a change in the machine's load is noticed within a few calls.

Seconds per ray differ between calls (coherent camera rays, incoherent bounces, short shadow
rays); exploring in turn gives both options the same mix over time, and the running mean forgets
old calls (weight RECENT), so the comparison follows the current work and load.
"""

from __future__ import annotations

import threading

# Every this many choices, the option not in favour is tried once (a 1-in-8 exploration costs at
# most ~1/8 of the difference between the two while it is the slower one).
EXPLORE_EVERY = 8
# Weight of the newest call in an option's running mean of seconds per ray.
RECENT = 0.3


class ThreadChoice:
    """The running comparison of one thread against `threads` threads, shared by every query of
    the process (the machine's load is the same for all of them)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._per_ray: dict[bool, float] = {}  # threaded? -> running mean seconds per ray
        self._calls = 0

    def threaded(self) -> bool:
        """Whether the next large query should use several threads."""
        with self._lock:
            self._calls += 1
            for option in (True, False):  # measure each option once first
                if option not in self._per_ray:
                    return option
            best = self._per_ray[True] <= self._per_ray[False]
            return (not best) if self._calls % EXPLORE_EVERY == 0 else best

    def record(self, threaded: bool, rays: int, seconds: float) -> None:
        """A finished query: `rays` traced in `seconds` of wall time."""
        if rays <= 0 or seconds <= 0.0:
            return
        per_ray = seconds / rays
        with self._lock:
            old = self._per_ray.get(threaded)
            self._per_ray[threaded] = per_ray if old is None else (
                RECENT * per_ray + (1.0 - RECENT) * old)

    def reset(self) -> None:
        with self._lock:
            self._per_ray.clear()
            self._calls = 0


# The process-wide record the BVH's queries share.
CHOICE = ThreadChoice()
