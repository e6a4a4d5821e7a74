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
