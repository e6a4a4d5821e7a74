"""Where a bake is evaluated: lightmap texel centres and mesh corners, as world points and normals.

A lightmap texel (i, j) (row 0 at the top) is baked at its centre u = (j + 0.5) / W,
v = 1 - (i + 0.5) / H, on the triangle whose lightmap-UV footprint covers that centre — as Cycles
bakes. Texels no triangle covers are "unbaked": `dilate` fills the padding ring around the charts
from their baked neighbours so bilinear lookups at chart edges never read black.
Finding the covering triangle is rasterisation in UV space: the lightmap is an orthographic image
of the UV triangles, drawn by `raster.py` with its top-left rule (no texel claimed twice).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .raster import Projection, rasterize
from .scene import Scene, geometric_normals

# Barycentric coordinates are clamped to [0, 1] after solving: texel centres on a shared edge may
# land a rounding error outside the triangle the rasteriser gave them to.
BARY_CLAMP = (0.0, 1.0)


@dataclass(frozen=True, eq=False)
class BakeTargets:
    """N points to evaluate a bake at, and where their values go back.

    points       (N, 3) float64  world, m
    normals      (N, 3) float64  interpolated shading normals, unit
    geo_normals  (N, 3) float64  face normals of the triangles, unit
    triangles    (N,) int64      scene triangle of each point
    bary         (N, 3) float64  barycentric weights of each point in its triangle
    Lightmaps: `mask` (H, W) bool marks the baked texels, `rows`/`cols` (N,) their indices.
    Corners: `corner_index` (N,) int64 = scene triangle * 3 + corner.
    """

    points: np.ndarray
    normals: np.ndarray
    geo_normals: np.ndarray
    triangles: np.ndarray
    bary: np.ndarray
    mask: np.ndarray | None = None
    rows: np.ndarray | None = None
    cols: np.ndarray | None = None
    corner_index: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def to_image(self, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """Scatter (N, C) or (N,) values into an (H, W, C) float32 lightmap; unbaked texels = fill."""
        values = np.asarray(values, np.float32)
        if values.ndim == 1:
            values = values[:, None]
        height, width = self.mask.shape
        image = np.full((height, width, values.shape[1]), fill, np.float32)
        image[self.rows, self.cols] = values
        return image


def lightmap_targets(scene: Scene, object_index: int, resolution: int) -> BakeTargets:
    """The texels of object `object_index`'s square lightmap (`resolution`^2) that it covers."""
    if scene.lightmap_uv is None:
        raise ValueError("the scene snapshot has no lightmap UVs (request them by name)")
    sl = scene.object_slice(object_index)
    uv = scene.lightmap_uv[sl].astype(np.float64)  # (T, 3, 2)
    tris_uv = np.concatenate([uv, -np.ones(uv.shape[:2] + (1,))], axis=2)  # at view depth 1
    projection = Projection.orthographic(np.eye(4), (0.0, 1.0, 0.0, 1.0), 0.5, 1.5)
    raster = rasterize(tris_uv.astype(np.float32), projection, resolution, resolution,
                       with_triangle_ids=True)
    local = raster.triangle  # (H, W) int, -1 where uncovered
    mask = local >= 0
    rows, cols = np.nonzero(mask)
    tri_local = local[rows, cols].astype(np.int64)
    centre = np.stack([(cols + 0.5) / resolution, 1.0 - (rows + 0.5) / resolution], 1)
    bary = _barycentric_2d(uv[tri_local], centre)
    return _targets(scene, sl.start + tri_local, bary, mask=mask, rows=rows, cols=cols)


def corner_targets(scene: Scene, object_index: int) -> BakeTargets:
    """Every triangle corner of object `object_index` (for corner-domain colour attributes)."""
    sl = scene.object_slice(object_index)
    tri = np.repeat(np.arange(sl.start, sl.stop, dtype=np.int64), 3)
    bary = np.tile(np.eye(3), (sl.stop - sl.start, 1))
    corners = np.arange(sl.start * 3, sl.stop * 3, dtype=np.int64)
    return _targets(scene, tri, bary, corner_index=corners)


def _barycentric_2d(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Barycentric weights (N, 3) of 2-D points p (N, 2) in triangles (N, 3, 2)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    denom = d00 * d11 - d01 * d01
    safe = np.where(np.abs(denom) > 0, denom, 1.0)
    v = np.where(np.abs(denom) > 0, (d11 * d20 - d01 * d21) / safe, 1.0 / 3.0)
    w = np.where(np.abs(denom) > 0, (d00 * d21 - d01 * d20) / safe, 1.0 / 3.0)
    bary = np.clip(np.stack([1.0 - v - w, v, w], 1), *BARY_CLAMP)
    return bary / bary.sum(1, keepdims=True)


def _targets(scene: Scene, tri: np.ndarray, bary: np.ndarray, **where) -> BakeTargets:
    corners = scene.triangles[tri].astype(np.float64)  # (N, 3, 3)
    points = np.einsum("nc,ncj->nj", bary, corners)
    normals = np.einsum("nc,ncj->nj", bary, scene.normals[tri].astype(np.float64))
    geo = geometric_normals(scene.triangles[tri])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.where(length > 1e-12, normals / np.maximum(length, 1e-12), geo)
    return BakeTargets(points=points, normals=normals, geo_normals=geo, triangles=tri, bary=bary,
                       **where)


def dilate(image: np.ndarray, mask: np.ndarray, texels: int, out: np.ndarray | None = None) -> np.ndarray:
    """Grow baked texels `texels` rings outward: each unbaked texel next to baked ones takes their
    mean (8-neighbourhood), ring by ring. image (H, W, C); mask (H, W) bool. Returns (H, W, C)."""
    out = np.array(image, np.float32, copy=True) if out is None else out
    if out is not image:
        out[...] = image
    filled = mask.copy()
    height, width = mask.shape
    for _ in range(texels):
        acc = np.zeros_like(out)
        count = np.zeros((height, width), np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                src = (slice(max(dy, 0), height + min(dy, 0)), slice(max(dx, 0), width + min(dx, 0)))
                dst = (slice(max(-dy, 0), height + min(-dy, 0)), slice(max(-dx, 0), width + min(-dx, 0)))
                acc[dst] += out[src] * filled[src][..., None]
                count[dst] += filled[src]
        grow = ~filled & (count > 0)
        if not grow.any():
            break
        out[grow] = acc[grow] / count[grow][:, None]
        filled |= grow
    return out
