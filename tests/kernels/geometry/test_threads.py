"""kernels/threads.py: row ranges cover every row once, on any thread count, and a worker's
exception reaches the caller."""

from __future__ import annotations

import numpy as np
import pytest

from classic_bake.kernels.geometry.threads import for_ranges


@pytest.mark.parametrize(("count", "chunk", "threads"), [(1, 4, 2), (10, 3, 1), (1000, 64, 2),
                                                         (999, 1000, 4)])
def test_every_row_is_worked_once(count, chunk, threads):
    hits = np.zeros(count, int)
    sizes = []

    def work(a, b):
        hits[a:b] += 1
        sizes.append(b - a)

    for_ranges(work, count, chunk, threads)
    assert (hits == 1).all()
    assert max(sizes) <= chunk


def test_a_worker_exception_is_raised_to_the_caller():
    def work(a, b):
        if a > 0:
            raise RuntimeError("row range failed")

    with pytest.raises(RuntimeError, match="row range failed"):
        for_ranges(work, 1000, 100, threads=2)
