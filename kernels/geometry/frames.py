"""Tangent frames and ray offsets: the local geometry every ray-casting kernel shares."""

from __future__ import annotations

import numpy as np

# Ray end points are lifted off their surfaces along the normal by this fraction of the scene's
# bounding-box diagonal: above float32 rounding of coordinates (6e-8 relative), so a float32 BVH
# does not re-hit the surface a ray leaves, and far below any patch size worth meshing.
RAY_OFFSET_REL = 1e-5


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (N, 3) completing unit normals (N, 3) to right-handed frames (t1, t2, n).

    Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017): branch-free, no
    singularity at n = -z.
    """
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t1 = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    t2 = np.stack([b, sign + y * y * a, -y], axis=1)
    return t1, t2


def barycentric_gradients(triangles: np.ndarray) -> np.ndarray:
    """(N, 2, 3) float64: the gradients of the barycentrics b1, b2 (the weights of corners 1
    and 2) of triangles (N, 3, 3) in their planes, so that a point's move dp in the plane moves
    b1 by grad[:, 0] . dp. A degenerate triangle gets a finite gradient (no ray hits it)."""
    v = np.asarray(triangles, np.float64)
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    d11, d12, d22 = (np.einsum("ij,ij->i", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
    det = d11 * d22 - d12 * d12
    det = np.where(det > 0.0, det, 1.0)[:, None]
    return np.stack([(d22[:, None] * e1 - d12[:, None] * e2) / det,
                     (d11[:, None] * e2 - d12[:, None] * e1) / det], axis=1)
