"""Alpha-tested casters: a shadow map that keeps a leaf card's texture shape, not its quad.

A shadow map holds one depth per texel, no transmittance, so partly covered casters (leaves,
fences, decals: a material with alpha, `Material.alpha`) are drawn with the real-time alpha
test: a fragment of such a triangle is kept where the surface's alpha at it is >= `ALPHA_CLIP`
and dropped below. The alpha is looked up at the fragment's own point: the texel centre's ray
from the light meets the triangle's plane at the depth the rasteriser interpolated, and that
point's barycentrics give the texture coordinates.

Known deviation: fractional alpha (0 < alpha < 1) is all or nothing here, where Cycles' shadow
rays pass with weight 1 - alpha; for cut-outs of alpha 0 and 1 the two agree.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..geometry.raster import Projection, iter_fragments
from ..progress import Steps

# The alpha test's threshold (the usual real-time practice: a fragment is kept where alpha >= 0.5).
ALPHA_CLIP = 0.5

# Alpha at points of triangles: (tri (F,) indices into the triangles drawn, barycentrics (F, 3))
# -> (F,) alpha in [0, 1].
AlphaAt = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True, eq=False)
class Cutout:
    """Which of the triangles drawn are alpha-tested, and their alpha.

    cut:   (T,) bool over the triangles drawn: the material has alpha
    alpha: AlphaAt over the same triangle indices
    """

    cut: np.ndarray
    alpha: AlphaAt

    def subset(self, rows: np.ndarray) -> Cutout:
        """The cutout of triangles[rows] (rows: (K,) indices or (T,) bool)."""
        ids = np.arange(len(self.cut))[rows]
        return Cutout(self.cut[ids], lambda tri, bary: self.alpha(ids[tri], bary))


def fragment_points(projection: Projection, pixel: np.ndarray, depth: np.ndarray,
                    width: int, height: int) -> np.ndarray:
    """(F, 3) float64 world points of fragments: flat pixel indices (F,) (row 0 at the top) at
    linear view depths (F,) m, through the pixel centres (`raster.py`'s conventions)."""
    row, col = np.divmod(np.asarray(pixel, np.int64), width)
    left, right, bottom, top = projection.extent
    x = left + (col + 0.5) / width * (right - left)  # image plane: at distance 1 (PERSP) or m
    y = top - (row + 0.5) / height * (top - bottom)
    d = np.asarray(depth, np.float64)
    if projection.kind == "PERSP":
        x, y = x * d, y * d
    view = np.stack([x, y, -d, np.ones_like(d)], axis=1)  # (F, 4) view space
    return (view @ np.linalg.inv(projection.view).T)[:, :3]


def barycentrics(triangles: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(F, 3) float64 barycentrics of points (F, 3) projected onto the planes of triangles
    (F, 3, 3), clipped to the triangle (a texel centre just past an edge reads the edge)."""
    t = np.asarray(triangles, np.float64)
    e1, e2, w = t[:, 1] - t[:, 0], t[:, 2] - t[:, 0], points - t[:, 0]
    d11 = np.einsum("ij,ij->i", e1, e1)
    d12 = np.einsum("ij,ij->i", e1, e2)
    d22 = np.einsum("ij,ij->i", e2, e2)
    w1 = np.einsum("ij,ij->i", w, e1)
    w2 = np.einsum("ij,ij->i", w, e2)
    det = np.maximum(d11 * d22 - d12 * d12, 1e-300)
    b1 = (d22 * w1 - d12 * w2) / det
    b2 = (d11 * w2 - d12 * w1) / det
    bary = np.clip(np.stack([1.0 - b1 - b2, b1, b2], axis=1), 0.0, 1.0)
    return bary / np.maximum(bary.sum(1, keepdims=True), 1e-300)


def cutout_depth_steps(triangles: np.ndarray, projection: Projection, depth_out: np.ndarray,
                       cutout: Cutout) -> Steps[np.ndarray]:
    """Z-buffer (T, 3, 3) world triangles into the (H, W) float32 `depth_out` (depth-tested
    against what it holds), alpha-testing the fragments of `cutout.cut` triangles; yields
    progress in [0, 1], returns `depth_out`."""
    height, width = depth_out.shape
    flat = depth_out.reshape(-1)
    if not np.may_share_memory(flat, depth_out):
        raise ValueError("depth_out must be C-contiguous")
    tris = np.asarray(triangles)
    for frags, progress in iter_fragments(tris, projection, width, height):
        if len(frags.pixel):
            keep = np.ones(len(frags.pixel), bool)
            tested = np.flatnonzero(cutout.cut[frags.triangle])
            if tested.size:
                tri = frags.triangle[tested]
                points = fragment_points(projection, frags.pixel[tested], frags.depth[tested],
                                         width, height)
                bary = barycentrics(tris[tri], points)
                keep[tested] = cutout.alpha(tri, bary) >= ALPHA_CLIP
            np.minimum.at(flat, frags.pixel[keep], frags.depth[keep].astype(np.float32))
        yield progress
    return depth_out
