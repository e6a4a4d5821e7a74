"""The exact unoccluded point-to-polygon factor (Lambert's contour formula, see `form_factors`)."""

from __future__ import annotations

import math

import numpy as np

# A point whose distance to a polygon's plane is below this fraction of its distance to the
# polygon's farthest corner sees the polygon edge-on: F = 0. This is the exact value on the plane
# and it also covers points on the polygon's edges and corners, where the contour integrand is 0/0;
# above it, |R_k x R_k+1| >= |edge| * distance stays far from float64 cancellation (1e-16).
PLANE_EPS = 1e-10
# An edge whose endpoints are seen within this sine (relative to |R_k||R_k+1|) of each other lies
# on a line through the point; off the polygon's plane that means gamma ~ 0 (a zero-length edge,
# padding, or the point on the edge's extension), so the edge contributes nothing.
COLLINEAR_EPS = 1e-14

TWO_PI = 2.0 * math.pi


def point_to_polygon(
    points: np.ndarray,
    normals: np.ndarray,
    polygons: np.ndarray,
    polygon_normals: np.ndarray | None = None,
    *,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Exact unoccluded form factor from differential areas to flat polygons (Lambert / Nusselt).

    | argument        | shape           | meaning                                             |
    |-----------------|-----------------|-----------------------------------------------------|
    | points          | (..., 3)        | receiver positions x, world, m                      |
    | normals         | (..., 3)        | receiver unit normals                               |
    | polygons        | (..., K, 3)     | polygon corners, CCW around the front normal, m     |
    | polygon_normals | (..., 3) / None | unit front normals (None: Newell's from corners)    |
    | out             | (...) float64   | optional caller-owned result buffer                 |

    Leading shapes broadcast against each other. Returns F_dx->polygon in [0, 1] per pair: 0 when
    x is behind the polygon or within `PLANE_EPS` of its plane (edge-on, on an edge, on a corner),
    0 for a polygon entirely below x's horizon; polygons crossing the horizon are clipped to it
    (Sutherland-Hodgman, vectorised with a fixed 2K-corner output padded by repeated corners).
    """
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    polygons = np.asarray(polygons, np.float64)
    if polygon_normals is None:
        vector_area = np.cross(polygons, np.roll(polygons, -1, axis=-2)).sum(axis=-2)
        length = np.linalg.norm(vector_area, axis=-1, keepdims=True)
        polygon_normals = np.divide(
            vector_area, length, out=np.zeros_like(vector_area), where=length > 0.0
        )
    polygon_normals = np.asarray(polygon_normals, np.float64)
    k = polygons.shape[-2]
    lead = np.broadcast_shapes(
        points.shape[:-1], normals.shape[:-1], polygons.shape[:-2], polygon_normals.shape[:-1]
    )
    x = np.broadcast_to(points, (*lead, 3)).reshape(-1, 3)
    n = np.broadcast_to(normals, (*lead, 3)).reshape(-1, 3)
    npoly = np.broadcast_to(polygon_normals, (*lead, 3)).reshape(-1, 3)
    rel = np.broadcast_to(polygons, (*lead, k, 3)).reshape(-1, k, 3) - x[:, None, :]  # (M, K, 3)

    result = np.zeros(x.shape[0], np.float64)
    # Front side, off the plane: distance of x in front of the polygon's plane vs its extent.
    distance = -np.einsum("mkc,mc->mk", rel, npoly).mean(axis=1)  # (M,)
    reach = np.sqrt(np.einsum("mkc,mkc->mk", rel, rel).max(axis=1))
    facing = distance > PLANE_EPS * reach
    height = np.einsum("mkc,mc->mk", rel, n)  # (M, K) above x's tangent plane
    whole = facing & np.all(height >= 0.0, axis=1)
    clipped = facing & ~whole & np.any(height > 0.0, axis=1)
    if whole.any():
        result[whole] = contour_sum(rel[whole], n[whole])
    if clipped.any():
        result[clipped] = contour_sum(_clip_above(rel[clipped], height[clipped]), n[clipped])
    np.maximum(result, 0.0, out=result)  # rounding can leave -1e-17 for grazing polygons
    result = result.reshape(lead)
    if out is not None:
        out[...] = result
        return out
    return result


def contour_sum(rel: np.ndarray, n: np.ndarray) -> np.ndarray:
    """1/(2 pi) sum_k gamma_k n.(R_k+1 x R_k)/|R_k+1 x R_k| for (M, K, 3) corners relative to x."""
    nxt = np.roll(rel, -1, axis=1)
    c = np.cross(nxt, rel)  # (M, K, 3): positive n-component for a polygon facing x
    # Lengths through einsum: NumPy reduces a 3-long last axis row by row (3x slower).
    sine = np.sqrt(np.einsum("mkc,mkc->mk", c, c))
    cosine = np.einsum("mkc,mkc->mk", rel, nxt)
    gamma = np.arctan2(sine, cosine)
    length2 = np.einsum("mkc,mkc->mk", rel, rel)
    lengths = np.sqrt(length2 * np.roll(length2, -1, axis=1))
    regular = sine > COLLINEAR_EPS * lengths
    projected = np.einsum("mkc,mc->mk", c, n)
    ratio = np.divide(projected, sine, out=np.zeros_like(sine), where=regular)
    return (gamma * ratio).sum(axis=1) / TWO_PI


def _clip_above(rel: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Clip (M, K, 3) polygons to height >= 0; returns (M, 2K, 3) with repeated-corner padding."""
    m, k = height.shape
    inside = height >= 0.0
    nxt_h = np.roll(height, -1, axis=1)
    crosses = inside != (nxt_h >= 0.0)
    denom = np.where(crosses, height - nxt_h, 1.0)  # nonzero where the signs differ
    t = np.where(crosses, height / denom, 0.0)[..., None]
    slots = np.empty((m, 2 * k, 3))
    slots[:, 0::2] = rel
    slots[:, 1::2] = rel + t * (np.roll(rel, -1, axis=1) - rel)
    valid = np.empty((m, 2 * k), bool)
    valid[:, 0::2] = inside
    valid[:, 1::2] = crosses
    # Fill each invalid slot with the previous valid corner (cyclically): zero-length edges.
    index = np.where(valid, np.arange(2 * k), -1)
    np.maximum.accumulate(index, axis=1, out=index)
    index = np.where(index < 0, index[:, -1:], index)
    return np.take_along_axis(slots, index[..., None], axis=1)
