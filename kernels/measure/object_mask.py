"""Which pixels of a camera view show one object: the mask comparisons over a single object use
(a mirror ball's pixels, say), arrays in, a boolean image out."""

from __future__ import annotations

import numpy as np

from ..geometry.bvh import BVH
from ..geometry.camera import camera_rays
from ..geometry.scene import Scene


def interior_pixels(scene: Scene, resolution: tuple[int, int], object_index: int) -> np.ndarray:
    """(H, W) bool: pixels whose centre's camera ray first meets object `object_index` and whose
    four neighbours' rays do too. Silhouette pixels are left out: each renderer's pixel filter
    mixes the object and what lies behind it differently there.

    | parameter    | range / unit                                   |
    |--------------|------------------------------------------------|
    | scene        | a snapshot with a camera                       |
    | resolution   | (W, H) pixels, each >= 1                       |
    | object_index | index into scene.objects                       |
    """
    width, height = resolution
    origins, dirs = camera_rays(scene.camera, width, height)
    hits = BVH.build(scene.triangles).intersect(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    owner = np.where(hits.tri >= 0, scene.object_ids[np.maximum(hits.tri, 0)], -1)
    seen = (owner == object_index).reshape(height, width)
    # A pixel on the image border has no neighbour beyond it: not interior.
    p = np.pad(seen, 1)
    return seen & p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
