"""NumPy work over row ranges, spread over the machine's cores.

NumPy releases the GIL inside its loops, so threads running the same vectorised function on
disjoint row ranges of large arrays overlap almost fully (elementwise work on 2 cores: ~1.7-1.9x).
Small ranges do not pay: a range costs a task hand-off (~20-50 us).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

_POOLS: dict[int, ThreadPoolExecutor] = {}
# The most cores every kernel's "one per core" takes (0: all of them); `set_core_limit`.
_core_limit = 0


def set_core_limit(cores: int) -> None:
    """Let every kernel that takes one thread per core take at most `cores` (0: all cores):
    the add-on's Threads preference. Settings that name their own thread count keep it."""
    global _core_limit
    if cores < 0:
        raise ValueError(f"cores must be >= 0, got {cores}")
    _core_limit = int(cores)


def core_count() -> int:
    """The machine's cores (os.cpu_count, which PYTHON_CPU_COUNT overrides on Python 3.13), at
    most the limit `set_core_limit` set."""
    cores = os.cpu_count() or 1
    return min(cores, _core_limit) if _core_limit else cores


def pool(threads: int) -> ThreadPoolExecutor:
    """A process-wide pool of `threads` workers, started on first use (starting threads per call
    would cost ~0.1 ms each)."""
    found = _POOLS.get(threads)
    if found is None:
        found = _POOLS[threads] = ThreadPoolExecutor(threads, thread_name_prefix="classic-bake")
    return found


def for_ranges(work: Callable[[int, int], None], count: int, chunk: int, threads: int = 0,
               min_rows: int = 1) -> None:
    """work(a, b) over [0, count) cut into equal shares of at most `chunk` rows, on `threads`
    threads (0: one per core), fewer when a thread would get under `min_rows` rows. Each thread
    takes the same number of shares; a worker's exception is raised here."""
    if count <= 0:
        return
    threads = max(1, min(threads or core_count(), count // max(min_rows, 1)))
    shares = threads * -(-count // (threads * max(chunk, 1)))
    ends = [count * k // shares for k in range(shares + 1)]
    if threads == 1:
        for a, b in zip(ends[:-1], ends[1:], strict=True):
            work(a, b)
        return
    for _ in pool(threads).map(work, ends[:-1], ends[1:]):
        pass
