"""Heights in metres on a stretched UV map: the slopes a Bump node gives, per texel.

A Bump node of Distance D bends the normal to n* ∝ n − D ∇h, ∇h the height's gradient on the
surface. With h_u, h_v its slopes per UV unit, ∇h = h_u ∇u + h_v ∇v, where ∇u, ∇v (1/m) are the
dual basis of dp/du, dp/dv in the triangle's plane. In the tangent frame (t = dp/du made unit,
b perpendicular to t in the plane and along +v, as MikkTSpace's b = sign (n x t) runs; n the
normal) the perturbed normal is n* = normalize(x, y, 1) with

    (x, y) = −D G (h_u, h_v),    G = [[∇u·t, ∇v·t], [∇u·b, ∇v·b]]   (1/m, per triangle)

On a UV map scaled uniformly by L metres per UV unit G = I / L, and the map is `from_height`'s
with strength s = D / L; on a stretched map (a UV sphere: 3.1 m of u around the equator, none at
the poles) G follows the stretch texel by texel, which one strength cannot.

Shapes: UV triangles (T, 3, 2), world triangles (T, 3, 3) metres; maps (H, W, ...) with row 0 at
the top, texel (i, j) at u = (j + 0.5) / W, v = 1 - (i + 0.5) / H.
"""

from __future__ import annotations

import numpy as np

from ..geometry.raster import Projection, rasterize
from .from_height import slope_normals

# |det [uv1 - uv0, uv2 - uv0]| below this: the triangle has no usable UV parametrisation (its
# matrix falls back to the object's mean metres per UV unit).
DEGENERATE_UV_DET = 1e-14
# Triangles with a squared-length cross product below this (m^4) have no plane.
DEGENERATE_AREA2 = 1e-24


def slope_matrices(uv: np.ndarray, world: np.ndarray, fallback_metres: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """(G (T, 2, 2) float64 in 1/m, degenerate (T,) bool) of UV triangles (T, 3, 2) on world
    triangles (T, 3, 3): see the module docstring. Triangles without a UV parametrisation or
    without area get I / fallback_metres."""
    uv = np.asarray(uv, np.float64)
    p = np.asarray(world, np.float64)
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    normal = np.cross(e1, e2)
    area2 = np.einsum("ij,ij->i", normal, normal)
    bad = (np.abs(det) <= DEGENERATE_UV_DET) | (area2 <= DEGENERATE_AREA2)
    safe = np.where(bad, 1.0, det)[:, None]
    dpdu = (d2[:, 1:2] * e1 - d1[:, 1:2] * e2) / safe  # (T, 3)
    dpdv = (-d2[:, 0:1] * e1 + d1[:, 0:1] * e2) / safe
    g11 = np.einsum("ij,ij->i", dpdu, dpdu)
    g12 = np.einsum("ij,ij->i", dpdu, dpdv)
    g22 = np.einsum("ij,ij->i", dpdv, dpdv)
    gram = g11 * g22 - g12 * g12
    bad |= gram <= DEGENERATE_AREA2
    gram = np.where(bad, 1.0, gram)[:, None]
    grad_u = (g22[:, None] * dpdu - g12[:, None] * dpdv) / gram  # dual basis, 1/m
    grad_v = (-g12[:, None] * dpdu + g11[:, None] * dpdv) / gram
    t = dpdu / np.sqrt(np.where(bad, 1.0, g11))[:, None]
    b = dpdv - np.einsum("ij,ij->i", dpdv, t)[:, None] * t  # in the plane, along +v
    b = b / np.maximum(np.linalg.norm(b, axis=1), 1e-300)[:, None]
    out = np.empty((len(uv), 2, 2))
    out[:, 0, 0] = np.einsum("ij,ij->i", grad_u, t)
    out[:, 0, 1] = np.einsum("ij,ij->i", grad_v, t)
    out[:, 1, 0] = np.einsum("ij,ij->i", grad_u, b)
    out[:, 1, 1] = np.einsum("ij,ij->i", grad_v, b)
    out[bad] = np.eye(2) / fallback_metres
    return out, bad


def texel_triangles(uv_triangles: np.ndarray, width: int, height: int) -> np.ndarray:
    """(H, W) int64: the UV triangle whose interior holds each texel centre, -1 outside every one
    (the rasteriser and fill rule of `dilate.chart_mask`, so `ids >= 0` is that mask)."""
    uv = np.asarray(uv_triangles, np.float64)
    tris = np.concatenate([uv, -np.ones(uv.shape[:2] + (1,))], axis=2)  # at depth 1
    projection = Projection.orthographic(np.eye(4), (0.0, 1.0, 0.0, 1.0), 0.5, 1.5)
    raster = rasterize(tris.astype(np.float32), projection, width, height, with_triangle_ids=True)
    return raster.triangle


def metric_normals(unit_normals: np.ndarray, texel_matrix: np.ndarray, distance: float
                   ) -> np.ndarray:
    """(N, 3) float32 unit tangent-space normals of a relief `distance` metres per unit of height,
    from the normals (N, 3) of the same height made with strength 1 (normalize(−h_u, −h_v, 1):
    the slopes per UV unit are −x/z, −y/z) and each texel's matrix G (N, 2, 2) in 1/m."""
    n = np.asarray(unit_normals, np.float64)
    z = np.maximum(n[:, 2], 1e-300)
    slopes = np.stack([-n[:, 0] / z, -n[:, 1] / z], axis=1)  # (h_u, h_v) per UV unit
    surface = np.einsum("nij,nj->ni", np.asarray(texel_matrix, np.float64), slopes)  # 1/m
    out, _ = slope_normals(surface[:, 0], surface[:, 1], float(distance))
    return out.astype(np.float32)
