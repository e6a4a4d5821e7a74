"""Padding a normal map's charts outward across their UV borders.

A texel outside every UV chart has no value of its own, yet mip-mapping and bilinear lookups at a
chart's edge read it: left flat (or black) it shows as a seam. So the chart's border texels are
grown outward `padding` rings (each empty texel next to filled ones takes their mean over its
8-neighbourhood, `bake.bake_targets.dilate`, the same padding the other bakes use), the grown
normals normalised again, and whatever lies further away set to the flat normal.

Arrays: normals (H, W, 3) tangent space; masks (H, W) bool, True on texels inside a chart; UV
triangles (T, 3, 2); images with row 0 at the top.
"""

from __future__ import annotations

import numpy as np

from ..bake.bake_targets import dilate
from ..geometry.raster import Projection, rasterize
from .encode import MIN_LENGTH

FLAT = np.array([0.0, 0.0, 1.0], np.float32)  # tangent space, +z out


def chart_mask(uv_triangles: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) bool: texels whose centre lies in one of the UV triangles (T, 3, 2) (the
    rasteriser's fill rule: a centre on an edge shared by two triangles belongs to exactly one)."""
    uv = np.asarray(uv_triangles, np.float64)
    tris = np.concatenate([uv, -np.ones(uv.shape[:2] + (1,))], axis=2)  # at depth 1
    projection = Projection.orthographic(np.eye(4), (0.0, 1.0, 0.0, 1.0), 0.5, 1.5)
    raster = rasterize(tris.astype(np.float32), projection, width, height)
    return np.isfinite(raster.depth)


def pad_normals(normals: np.ndarray, mask: np.ndarray, padding: int
                ) -> tuple[np.ndarray, np.ndarray]:
    """(padded normals (H, W, 3) float32 unit, filled mask (H, W) bool): `normals` inside `mask`
    kept bit for bit, `padding` rings of texels outside grown from them and normalised, the rest
    flat (0, 0, 1)."""
    grown = dilate(np.asarray(normals, np.float32), mask, max(int(padding), 0))
    filled = dilate(mask[..., None].astype(np.float32), mask, max(int(padding), 0))[..., 0] > 0
    out = grown.copy()
    ring = filled & ~mask
    length = np.linalg.norm(out[ring], axis=1, keepdims=True)
    out[ring] = np.where(length > MIN_LENGTH, out[ring] / np.maximum(length, MIN_LENGTH), FLAT)
    out[~filled] = FLAT
    out[mask] = np.asarray(normals, np.float32)[mask]
    return out, filled
