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


def core_count() -> int:
    return os.cpu_count() or 1


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
