"""Auto quality: the cheapest settings that met a target error on a measured ladder.

`compare` measures a technique's quality ladder (settings, seconds, relative MSE against a converged
Cycles reference) and records it with the scene's features. Given a target error and a new scene,
`pick` takes the ladder of the most similar measured scene (same technique; nearest in log-scaled
features: triangles, lights, pixels, specular objects) and returns its cheapest rung that met the
target — or, if none did, its most accurate rung, saying so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

FEATURES = ("triangles", "lights", "pixels", "specular_objects")


@dataclass(frozen=True)
class Pick:
    """The chosen rung and why."""

    setting: list  # the rung's command-line arguments
    expected_rel_mse: float
    expected_seconds: float
    scene: str  # the measured scene the ladder came from
    met_target: bool
    reason: str


def scene_distance(a: dict, b: dict) -> float:
    """Distance of two scenes' features: Euclidean in log2(1 + value), so 10 vs 20 triangles
    weighs like 1000 vs 2000."""
    return math.sqrt(sum((math.log2(1 + float(a.get(f, 0))) - math.log2(1 + float(b.get(f, 0)))) ** 2
                         for f in FEATURES))


def pick(records: list[dict], technique: str, features: dict, target_rel_mse: float) -> Pick:
    """records: [{"technique", "scene", "features": {...}, "rows": [{"argv", "seconds",
    "rel_mse"}]}]. Raises ValueError when nothing was measured for `technique`."""
    if not target_rel_mse > 0:
        raise ValueError(f"target error must be > 0, got {target_rel_mse}")
    same = [r for r in records if r.get("technique") == technique and r.get("rows")]
    if not same:
        raise ValueError(f"no measured ladder for {technique!r}: run `compare --technique "
                         f"{technique}` on a similar scene first")
    nearest = min(same, key=lambda r: scene_distance(r["features"], features))
    rows = nearest["rows"]
    good = [row for row in rows if row["rel_mse"] <= target_rel_mse]
    if good:
        row = min(good, key=lambda r: r["seconds"])
        return Pick(list(row["argv"]), row["rel_mse"], row["seconds"], nearest["scene"], True,
                    f"cheapest of {len(good)} settings that reached relMSE <= {target_rel_mse:g} on "
                    f"{nearest['scene']}")
    row = min(rows, key=lambda r: r["rel_mse"])
    return Pick(list(row["argv"]), row["rel_mse"], row["seconds"], nearest["scene"], False,
                f"no measured setting reached {target_rel_mse:g} on {nearest['scene']}: the most "
                f"accurate one ({row['rel_mse']:.3g}) was picked")
