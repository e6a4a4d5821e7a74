"""PhaseClock: exclusive seconds per phase (nested phases pause the outer one), per label too."""

import time

from classic_bake.kernels.measure.phase_clock import PhaseClock


def busy(seconds: float) -> None:
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        pass


def test_nested_phase_pauses_the_outer_one():
    clock = PhaseClock()
    start = time.perf_counter()
    with clock("outer"):
        busy(0.02)
        with clock("inner"):
            busy(0.03)
        busy(0.01)
    wall = time.perf_counter() - start
    seconds = clock.as_dict()["seconds"]
    assert seconds["inner"] >= 0.03
    assert 0.03 <= seconds["outer"] <= wall - seconds["inner"]  # the inner's time not again
    assert 0.06 <= sum(seconds.values()) <= wall  # the phases add up to the time inside them


def test_labels_split_the_same_phase():
    clock = PhaseClock()
    for label in ("depth 0", "depth 1"):
        clock.label = label
        with clock("traversal"):
            busy(0.005)
    by_label = clock.as_dict()["by_label"]
    assert set(by_label) == {"depth 0", "depth 1"}
    assert abs(sum(v["traversal"] for v in by_label.values())
               - clock.seconds["traversal"]) < 1e-9
