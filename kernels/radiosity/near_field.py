"""Near-field splits: patches that another surface faces at less than their own size.

A patch sends one radiosity value B to every receiver. Far away that mean is what a receiver
sees; at close range it is not: the back of a box 16 cm from a wall is dark near the floor and
lit at its top, the wall behind it sees each part at a different distance, and one mean for a
0.9 m patch spreads the top's light down to the floor. The final gather places each receiver's
own light (`elements.py`) but cannot place a source's variation. Splitting the patches whose
view is largely taken by surfaces nearer than their own longest edge gives the near field the
resolution the form factor's 1/r^2 needs there, and leaves the open parts of a room coarse.

The test, per patch: rays cosine-distributed over its hemisphere from n x n points
(`NEAR_POINTS_PER_SIDE`), each a shadow ray of length NEAR_DISTANCE x the patch's longest edge;
the share of them that meet a surface is the share of the patch's form factor (its view,
cosine-weighted) taken by surfaces that near. A patch splits when that share reaches
NEAR_SHARE.
"""

from __future__ import annotations

import numpy as np

from ..shading.world_light import cosine_directions
from . import patches as patching
from .sources import lifted_samples

# A surface counts as near within this many times the patch's longest edge: there the form factor
# 1/r^2 changes by a factor of about four across the patch, which one mean cannot stand for.
NEAR_DISTANCE = 1.0
# The cosine-weighted share of a patch's view that near surfaces must take for it to split. A
# floor patch beside a wall whose edge is its own size sees the wall in ~0.15 of its view (the
# room's corners would all split at 0.1); a patch facing a box 16 cm away across a
# 0.9 m gap sees it in ~0.8.
NEAR_SHARE = 0.25
# Points per side of each patch the rays leave from (midpoints), and rays per point.
NEAR_POINTS_PER_SIDE = 2
NEAR_RAYS_PER_POINT = 4
# The rays' directions are random per point (stratified); fixed so one scene splits the same way.
NEAR_SEED = 0x5EED


def near_shares(patches: patching.Patches, occluded, scale: float) -> np.ndarray:
    """(N,) the cosine-weighted share of each patch's hemisphere met by a surface within
    NEAR_DISTANCE x its longest edge. occluded(origins, directions, t_min, t_max) -> (R,) bool:
    the BVH's shadow-ray query (None: nothing is near). scale: the scene's diagonal, m (rays
    leave `lifted_samples`' origins)."""
    count = len(patches)
    if occluded is None or count == 0:
        return np.zeros(count)
    weights, _, normals, origins = lifted_samples(patches, NEAR_POINTS_PER_SIDE, scale)
    samples = weights.shape[1]
    directions = cosine_directions(normals, NEAR_RAYS_PER_POINT,
                                   np.random.default_rng(NEAR_SEED))  # (N S, k, 3)
    k = directions.shape[1]
    reach = np.repeat(NEAR_DISTANCE * patching.longest_edges(patches.corners), samples * k)
    hit = occluded(np.repeat(origins, k, axis=0), directions.reshape(-1, 3),
                   np.zeros(len(reach)), reach)
    return np.asarray(hit, np.float64).reshape(count, samples * k).mean(axis=1)


def near_field(patches: patching.Patches, occluded, scale: float) -> np.ndarray:
    """(N,) bool: the patches whose near share (`near_shares`) reaches NEAR_SHARE."""
    return near_shares(patches, occluded, scale) >= NEAR_SHARE
