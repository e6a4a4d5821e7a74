"""Time estimates before work (pipeline/time_estimate.py): parts that grow with the work, the
flag that lowers each, and the rough figure printed."""

from classic_bake.pipeline.time_estimate import LOWER_WITH, estimate_seconds, rough_seconds


def test_the_estimate_grows_with_each_part_of_the_work():
    base = {"rays": 100, "texels": 100, "triangles": 10, "patches": 10, "unwrap_triangles": 10}
    small = sum(s for s, _, _ in estimate_seconds("radiosity", base))
    for key in base:
        sizes = {**base, key: 10 ** 6}
        parts = estimate_seconds("radiosity", sizes)
        assert sum(s for s, _, _ in parts) > small
        seconds, what, flag = max(parts)
        assert flag == LOWER_WITH[key] and f"{10 ** 6:,}" in what


def test_a_run_without_work_costs_its_start_up_only():
    parts = estimate_seconds("trace", {})
    assert len(parts) == 1 and parts[0][2] == ""


def test_rough_figures():
    assert rough_seconds(0.42) == "~0.42 s"
    assert rough_seconds(42.0) == "~42 s"
    assert rough_seconds(600.0) == "~10 min"
    assert rough_seconds(7200.0) == "~2 h"
    assert rough_seconds(1e6) == "~278 h"
