"""Method A: the ray-cast hemicube (Cohen & Greenberg 1985), rows F_i* from hemicubes at n x n
points of patch i (see `form_factors`)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ...geometry.frames import RAY_OFFSET_REL, tangent_frames
from .point_polygon import TWO_PI, contour_sum
from .rays import MAX_RAYS_PER_CALL, ClosestHit
from .sampling import SampleRule, as_corners, check_rule, patch_geometry, sample_patches


@dataclass(frozen=True)
class HemicubeSettings:
    """Method A, the hemicube (Cohen & Greenberg 1985), one ray per hemicube pixel centre.

    | field             | range          | default | meaning                                      |
    |-------------------|----------------|---------|----------------------------------------------|
    | resolution        | even, >= 2     | 64      | top-face pixels per side; each of the 4 side |
    |                   |                |         | faces is resolution x resolution/2 pixels    |
    | points_per_side   | >= 1           | 4       | hemicubes per patch: n x n points; 1 with    |
    |                   |                |         | "midpoint" is the patch centre of 1985       |
    | point_rule        | gauss /        | gauss   | where the points go and their weights        |
    |                   | stratified /   |         | (`sample_patches`)                           |
    |                   | midpoint       |         |                                              |
    | rotate            | bool           | True    | turn each hemicube by a random angle about   |
    |                   |                |         | the normal (decorrelates aliasing)           |
    | delta_rule        | exact/midpoint | exact   | pixel factors: exact (contour formula over   |
    |                   |                |         | the pixel, sums to 1) or the 1985 midpoint   |
    |                   |                |         | 1/(pi (x^2+y^2+1)^2) dA, z/(pi(..)^2) dA     |
    | seed              | int            | 0       | RNG seed; row i uses the stream (seed, i)    |
    | ray_offset        | >= 0, None     | None    | m; None: RAY_OFFSET_REL x scene diagonal     |
    | max_rays_per_call | >= 1           | 2^18    | rays per closest_hit call                    |

    Rays per patch: points_per_side^2 x 3 resolution^2 (4 x 4 x 12288 = 196 608 by default).
    """

    resolution: int = 64
    points_per_side: int = 4
    point_rule: SampleRule = "gauss"
    rotate: bool = True
    delta_rule: Literal["exact", "midpoint"] = "exact"
    seed: int = 0
    ray_offset: float | None = None
    max_rays_per_call: int = MAX_RAYS_PER_CALL

    def __post_init__(self) -> None:
        if self.resolution < 2 or self.resolution % 2:
            raise ValueError(f"hemicube resolution must be even and >= 2, got {self.resolution}")
        if self.points_per_side < 1:
            raise ValueError(f"points_per_side must be >= 1, got {self.points_per_side}")
        check_rule(self.point_rule)
        if self.delta_rule not in ("exact", "midpoint"):
            raise ValueError(f"delta_rule must be 'exact' or 'midpoint', got {self.delta_rule!r}")
        if self.ray_offset is not None and not self.ray_offset >= 0.0:
            raise ValueError(f"ray_offset must be >= 0 m, got {self.ray_offset}")
        if self.max_rays_per_call < 1:
            raise ValueError(f"max_rays_per_call must be >= 1, got {self.max_rays_per_call}")


def hemicube_pixels(
    resolution: int, rule: Literal["exact", "midpoint"] = "exact"
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centre directions and delta form factors of a unit hemicube.

    The hemicube sits on the tangent plane (local +z is the normal): top face z = 1,
    -1 <= x, y <= 1, R x R pixels; side faces x = +-1 and y = +-1, 0 <= z <= 1, R x R/2 pixels each;
    pixel side 2/R. Returns directions (3 R^2, 3) float64 (unit, local frame) and deltas
    (3 R^2,) float64: top (index ix R + iy), then the faces x = +1, x = -1, y = +1, y = -1
    (index ia R/2 + iz, a the face's other axis).
    'midpoint': 1/(pi (x^2+y^2+1)^2) dA (top), z/(pi (y^2+z^2+1)^2) dA (sides), as in 1985; their
    sum approaches 1 as O(R^-2). 'exact': each pixel's own point-to-polygon factor; sums to 1.
    """
    r = resolution
    step = 2.0 / r
    across = -1.0 + step * (np.arange(r) + 0.5)  # (R,) pixel centres along a full side
    up = step * (np.arange(r // 2) + 0.5)  # (R/2,) pixel centres along z on a side face
    gx, gy = np.meshgrid(across, across, indexing="ij")
    top = np.stack([gx.ravel(), gy.ravel(), np.ones(r * r)], axis=1)
    ga, gz = np.meshgrid(across, up, indexing="ij")
    a, z = ga.ravel(), gz.ravel()
    one = np.ones_like(a)
    sides = [
        np.stack([one, a, z], axis=1),
        np.stack([-one, a, z], axis=1),
        np.stack([a, one, z], axis=1),
        np.stack([a, -one, z], axis=1),
    ]
    centres = np.concatenate([top, *sides])  # (3 R^2, 3) on the cube
    directions = centres / np.linalg.norm(centres, axis=1, keepdims=True)
    if rule == "midpoint":
        area = step * step
        top_delta = area / (math.pi * (gx.ravel() ** 2 + gy.ravel() ** 2 + 1.0) ** 2)
        side_delta = z * area / (math.pi * (a * a + z * z + 1.0) ** 2)
        return directions, np.concatenate([top_delta, np.tile(side_delta, 4)])
    # Exact: each pixel as a square polygon (corner offsets in the face's two in-plane axes).
    half = 0.5 * step
    offsets = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    face_axes = [(0, 1), (1, 2), (1, 2), (0, 2), (0, 2)]  # in-plane axes: top, x+-, y+-
    polygons = np.repeat(centres[:, None, :], 4, axis=1)
    start = 0
    for face, (p, q) in enumerate(face_axes):
        stop = start + (r * r if face == 0 else r * r // 2)
        polygons[start:stop, :, p] += offsets[:, 0]
        polygons[start:stop, :, q] += offsets[:, 1]
        start = stop
    deltas = np.abs(contour_sum(polygons, np.broadcast_to([0.0, 0.0, 1.0], (len(centres), 3))))
    return directions, deltas


def hemicube_gather(
    points: np.ndarray,
    normals: np.ndarray,
    weights: np.ndarray,
    closest_hit: ClosestHit,
    tri_patch: np.ndarray,
    target_normals: np.ndarray,
    settings: HemicubeSettings,
    rng: np.random.Generator | None,
    *,
    ray_offset: float,
    pixels: tuple[np.ndarray, np.ndarray] | None = None,
    skip: int = -1,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Weighted hemicube form factors from P receiver points to N patches.

    points (P, 3), normals (P, 3) unit, weights (P,) summing to 1 (area-average weights);
    tri_patch (T,) int: the patch each triangle belongs to (-1: an occluder only); target_normals
    (N, 3): a pixel counts for the patch it hits only on that patch's front side; `skip`: a patch
    that never receives (the shooter itself). Returns (N,) float64 sum_p w_p sum_pixels delta.
    """
    tri_patch = np.asarray(tri_patch)
    count = target_normals.shape[0]
    result = np.zeros(count, np.float64) if out is None else out
    result[...] = 0.0
    local, deltas = pixels if pixels is not None else hemicube_pixels(
        settings.resolution, settings.delta_rule
    )
    t1, t2 = tangent_frames(normals)
    if rng is not None and settings.rotate:
        angle = rng.random(len(points)) * TWO_PI
        c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
        t1, t2 = c * t1 + s * t2, c * t2 - s * t1
    frames = np.stack([t1, t2, normals], axis=1)  # (P, 3, 3): rows are the local axes
    per_call = max(1, settings.max_rays_per_call // len(local))
    for start in range(0, len(points), per_call):
        sl = slice(start, start + per_call)
        dirs = np.einsum("dk,pkc->pdc", local, frames[sl]).reshape(-1, 3)  # world, unit
        origins = points[sl] + ray_offset * normals[sl]
        origins = np.repeat(origins, len(local), axis=0)
        _, tri = _unpack_hits(closest_hit(origins, dirs, 0.0, math.inf))
        patch = np.where(tri >= 0, tri_patch[np.maximum(tri, 0)], -1)
        hit = patch >= 0
        front = np.zeros_like(hit)
        front[hit] = np.einsum("rc,rc->r", dirs[hit], target_normals[patch[hit]]) < 0.0
        keep = front & (patch != skip)
        contribution = (weights[sl, None] * deltas[None, :]).ravel()
        result += np.bincount(patch[keep], weights=contribution[keep], minlength=count)
    return result


def hemicube_item_buffer(
    point: np.ndarray,
    normal: np.ndarray,
    closest_hit: ClosestHit,
    tri_patch: np.ndarray,
    resolution: int,
    *,
    ray_offset: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The patch each pixel of one hemicube sees (1985's item buffer), to inspect or dump as
    images when debugging a row; no rotation, so local x, y are `tangent_frames(normal)`.

    Returns top (R, R) int64, row 0 at local +y, columns from local x = -1 to +1; and sides
    (4, R/2, R) int64 for the faces x = +1, x = -1, y = +1, y = -1, row 0 at the top (z = 1),
    columns along the face's other axis from -1 to +1. -1: a miss or a triangle of no patch.
    """
    r = resolution
    local, _ = hemicube_pixels(r, "midpoint")
    n = np.asarray(normal, np.float64)[None]
    t1, t2 = tangent_frames(n)
    dirs = local @ np.concatenate([t1, t2, n])  # (3 R^2, 3) world
    origins = np.broadcast_to(np.asarray(point, np.float64) + ray_offset * n[0], dirs.shape)
    _, tri = _unpack_hits(closest_hit(np.ascontiguousarray(origins), dirs, 0.0, math.inf))
    tri_patch = np.asarray(tri_patch)
    ids = np.where(tri >= 0, tri_patch[np.maximum(tri, 0)], -1).astype(np.int64)
    top = ids[: r * r].reshape(r, r).T[::-1]
    sides = ids[r * r :].reshape(4, r, r // 2).transpose(0, 2, 1)[:, ::-1]
    return top, sides


class HemicubeFormFactors:
    """Method A: rows F_i* from hemicubes at n x n points of patch i (see the module doc).

    corners (N, K, 3) patches; closest_hit: the ray callback; tri_patch (T,) int, the patch of each
    triangle the callback can return (-1: occluder that is not a patch).
    """

    def __init__(
        self,
        corners: np.ndarray,
        closest_hit: ClosestHit,
        tri_patch: np.ndarray,
        settings: HemicubeSettings | None = None,
    ) -> None:
        self.corners = as_corners(corners)
        self.geometry = patch_geometry(self.corners)
        self.closest_hit = closest_hit
        self.tri_patch = np.asarray(tri_patch, np.int64)
        self.settings = settings or HemicubeSettings()
        self.pixels = hemicube_pixels(self.settings.resolution, self.settings.delta_rule)
        offset = self.settings.ray_offset
        self.ray_offset = RAY_OFFSET_REL * self.geometry.scale if offset is None else offset

    @property
    def areas(self) -> np.ndarray:
        return self.geometry.areas

    def item_buffer(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """`hemicube_item_buffer` at the centre of patch i (debugging: what row i sees)."""
        g = self.geometry
        return hemicube_item_buffer(
            g.centres[i], g.normals[i], self.closest_hit, self.tri_patch,
            self.settings.resolution, ray_offset=self.ray_offset,
        )

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        s = self.settings
        rng = np.random.default_rng((s.seed, i))
        points, weights = sample_patches(
            self.corners[i : i + 1], s.points_per_side, s.point_rule, rng
        )
        normals = np.broadcast_to(self.geometry.normals[i], points[0].shape)
        return hemicube_gather(
            points[0], np.ascontiguousarray(normals), weights[0], self.closest_hit,
            self.tri_patch, self.geometry.normals, s, rng, ray_offset=self.ray_offset,
            pixels=self.pixels, skip=i, out=out,
        )


def _unpack_hits(hits: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t, tri) from a callback result: a (t, tri) pair or an object with .t and .tri."""
    if hasattr(hits, "tri"):
        return np.asarray(hits.t), np.asarray(hits.tri)
    t, tri = hits
    return np.asarray(t), np.asarray(tri)
