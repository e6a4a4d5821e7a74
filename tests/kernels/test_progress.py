"""The progress protocol: steps yield floats in [0, 1] and return their result."""

from classic_bake.kernels.progress import advance, drain, scaled, sequence


def _steps(n, result):
    for k in range(n):
        yield (k + 1) / n
    return result


def test_drain_returns_the_result_and_reports_every_fraction():
    seen = []
    assert drain(_steps(4, "done"), seen.append) == "done"
    assert seen == [0.25, 0.5, 0.75, 1.0]


def test_scaled_maps_progress_and_passes_the_result_through():
    def outer():
        inner = yield from scaled(_steps(2, 7), 0.5, 0.5)
        return inner * 2

    seen = []
    assert drain(outer(), seen.append) == 14
    assert seen == [0.75, 1.0]


def test_advance_steps_one_yield_at_a_time():
    steps = _steps(2, [1, 2])
    first, second, last = advance(steps), advance(steps), advance(steps)
    assert (first.progress, first.done) == (0.5, False)
    assert (second.progress, second.done) == (1.0, False)
    assert last.done and last.result == [1, 2]


def test_sequence_shares_progress_by_weight():
    seen = []
    results = drain(sequence((1.0, lambda: _steps(1, "a")), (3.0, lambda: _steps(2, "b"))), seen.append)
    assert results == ["a", "b"]
    assert seen == [0.25, 0.625, 1.0]
