"""Casters with alpha: a shadow map that keeps a leaf card's texture shape, not its quad, and
lets a tinted window's light through in part.

A shadow map holds one depth per texel. A fragment of a triangle whose material has alpha
(`Material.alpha`: leaves, fences, decals, alpha-blended glass) is looked up at its own point
(the texel centre's ray from the light meets the triangle's plane at the depth the rasteriser
interpolated, and that point's barycentrics give the texture coordinates): where alpha is 1 it
is an opaque caster, drawn into the depth map; where it is 0 it casts nothing; in between it is
a veil: the view's `veil` multiplies what each such fragment lets through, 1 - alpha, and
`veil_depth` keeps the nearest one's depth. A receiver behind a texel's nearest veil gets the
product (`depth_test.py`), as Cycles' shadow rays pass each surface with weight 1 - alpha.

Known deviation: a receiver between two veils of one texel (inside an alpha-blended box) takes
both, where Cycles' shadow ray crosses the nearer one only.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..geometry.raster import Projection, iter_fragments
from ..progress import Steps

# Alpha at or above this is opaque (a depth-map fragment), at or below CLEAR_ALPHA nothing: the
# 8-bit alpha of an image texture rounds within 1/255 of 1 and 0 (filtered edges aside).
OPAQUE_ALPHA = 1.0 - 1.0 / 512.0
CLEAR_ALPHA = 1.0 / 512.0
# Without a veil buffer, the real-time alpha test: a fragment is kept where alpha >= 0.5.
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
                       cutout: Cutout, veil_out: tuple[np.ndarray, np.ndarray] | None = None
                       ) -> Steps[np.ndarray]:
    """Z-buffer (T, 3, 3) world triangles into the (H, W) float32 `depth_out` (depth-tested
    against what it holds), the fragments of `cutout.cut` triangles by their alpha (module
    docstring): opaque ones drawn, partly covering ones into `veil_out` (what they let through,
    the nearest one's depth: (H, W) float32 each, multiplied and min-ed in place; None: kept
    where alpha >= ALPHA_CLIP, the real-time alpha test). Yields progress in [0, 1], returns
    `depth_out`."""
    height, width = depth_out.shape
    arrays = [depth_out, *(veil_out or ())]
    flats = [a.reshape(-1) for a in arrays]
    if not all(np.may_share_memory(f, a) for f, a in zip(flats, arrays, strict=True)):
        raise ValueError("depth_out and veil_out must be C-contiguous")
    flat, veil_flat = flats[0], (flats[1:] if veil_out is not None else None)
    tris = np.asarray(triangles)
    for frags, progress in iter_fragments(tris, projection, width, height):
        if len(frags.pixel):
            keep = np.ones(len(frags.pixel), bool)
            tested = np.flatnonzero(cutout.cut[frags.triangle])
            if tested.size:
                tri = frags.triangle[tested]
                points = fragment_points(projection, frags.pixel[tested], frags.depth[tested],
                                         width, height)
                alpha = cutout.alpha(tri, barycentrics(tris[tri], points))
                if veil_flat is None:
                    keep[tested] = alpha >= ALPHA_CLIP
                else:
                    keep[tested] = alpha >= OPAQUE_ALPHA
                    part = (alpha > CLEAR_ALPHA) & (alpha < OPAQUE_ALPHA)
                    at = frags.pixel[tested[part]]
                    np.multiply.at(veil_flat[0], at, (1.0 - alpha[part]).astype(np.float32))
                    np.minimum.at(veil_flat[1], at, frags.depth[tested[part]].astype(np.float32))
            np.minimum.at(flat, frags.pixel[keep], frags.depth[keep].astype(np.float32))
        yield progress
    return depth_out
