"""Auto quality (kernels/auto_quality.py): cheapest rung meeting the target on the nearest scene."""

import pytest

from classic_bake.kernels.measure.auto_quality import pick, scene_distance

LADDER = [{"argv": ["--adaptive", "0"], "seconds": 0.8, "rel_mse": 7e-3},
          {"argv": ["--adaptive", "2"], "seconds": 2.5, "rel_mse": 2e-3},
          {"argv": ["--adaptive", "4"], "seconds": 8.0, "rel_mse": 5e-4}]
RECORDS = [
    {"technique": "trace", "scene": "small", "rows": LADDER,
     "features": {"triangles": 100, "lights": 1, "pixels": 76800, "specular_objects": 2}},
    {"technique": "trace", "scene": "huge", "rows": [dict(r, seconds=r["seconds"] * 50) for r in LADDER[:1]],
     "features": {"triangles": 10**6, "lights": 8, "pixels": 2 * 10**6, "specular_objects": 0}},
    {"technique": "shadowmap", "scene": "small", "rows": LADDER, "features": {"triangles": 100}},
]


def test_cheapest_rung_meeting_the_target():
    p = pick(RECORDS, "trace", {"triangles": 120, "lights": 1, "pixels": 80000, "specular_objects": 2}, 3e-3)
    assert p.setting == ["--adaptive", "2"] and p.met_target and p.scene == "small"
    assert "cheapest" in p.reason


def test_unreachable_target_picks_the_most_accurate_and_says_so():
    p = pick(RECORDS, "trace", {"triangles": 100, "lights": 1, "pixels": 76800}, 1e-6)
    assert p.setting == ["--adaptive", "4"] and not p.met_target and "no measured" in p.reason


def test_nearest_scene_wins():
    p = pick(RECORDS, "trace", {"triangles": 900000, "lights": 6, "pixels": 10**6}, 1.0)
    assert p.scene == "huge"
    assert scene_distance({"triangles": 10}, {"triangles": 20}) == pytest.approx(
        scene_distance({"triangles": 1000}, {"triangles": 2000}), abs=0.1)


def test_errors():
    with pytest.raises(ValueError, match="no measured ladder"):
        pick(RECORDS, "radiosity", {}, 1e-3)
    with pytest.raises(ValueError, match="> 0"):
        pick(RECORDS, "trace", {}, 0.0)
