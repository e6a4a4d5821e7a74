"""Ray differentials (Igehy, "Tracing Ray Differentials", SIGGRAPH 1999): how a ray's hit point
and direction move as its pixel moves across the image, carried through mirror reflection and
refraction. The tracer filters the textures seen in mirrors and through glass over the pixel's
footprint with them, as it filters the textures the camera sees directly.

Every array pairs the two image axes: (2, N, 3), [0] per pixel to the right, [1] per pixel down,
world metres per pixel (positions) or per pixel (unit directions). First order: exact for flat
mirrors, a tangent-plane approximation of a curved one's footprint.
"""

from __future__ import annotations

import numpy as np

from ..geometry.camera import camera_hit_derivatives
from ..geometry.frames import barycentric_gradients
from ..geometry.scene import Scene
from ..geometry.vec import row_dot
from ..shading.pixel_texture import Footprint

# GRAZING_COS (geometry/camera.py): below this |cos| between a ray and the plane it meets, the
# footprint would stretch without bound along the plane; the hit's position derivatives are
# taken as zero (`plane_transfer`). Below this cos of the refracted ray (grazing, at the edge of
# total internal reflection) the direction's derivative 1 / cos_t blows up: its change is taken
# as zero.
MIN_COS_T = 1e-3


def camera_derivatives(fp: Footprint, rays: np.ndarray, dirs: np.ndarray, p: np.ndarray,
                       n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`camera_hit_derivatives` of camera rays rays (M,) int, indices into the footprint."""
    return camera_hit_derivatives(fp.camera, fp.width, fp.height, fp.x[rays], fp.y[rays], dirs,
                                  p, n)


class TriangleFrames:
    """Per triangle, what carrying a hit's change across a triangle needs, built once per scene:
    grad (T, 2, 3) the gradients of the barycentrics b1, b2 in the triangle's plane (b1's change
    is grad[:, 0] . dp), and turn (T, 2, 3) the corner normals' differences n1 - n0, n2 - n0 (the
    interpolated normal's change per unit of b1, b2)."""

    def __init__(self, scene: Scene):
        # float32: 48 bytes a triangle; a derivative needs no more than its 7 digits
        self.grad = barycentric_gradients(scene.triangles).astype(np.float32)
        n = scene.normals
        self.turn = np.stack([n[:, 1] - n[:, 0], n[:, 2] - n[:, 0]], 1).astype(np.float32)


def normal_derivatives(frames: TriangleFrames, tri: np.ndarray, ns: np.ndarray, length: np.ndarray,
                       side: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """Derivatives (2, M, 3) of the shading normal ns (M, 3) unit, the corner normals of
    triangles tri (M,) interpolated (length (M,) before normalising) and turned to side (M,) +-1,
    as the hit moves by dp (2, M, 3)."""
    grad, turn = frames.grad[tri], frames.turn[tri]
    d_raw = row_dot(dp, grad[:, 0])[..., None] * turn[:, 0] + row_dot(dp, grad[:, 1])[..., None] * turn[:, 1]
    # raw / |raw| differentiated: the change across the unit normal, over the length
    return (d_raw - ns * row_dot(ns, d_raw)[..., None]) * (side / length)[:, None]


def reflected(dirs: np.ndarray, n: np.ndarray, dd: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """Direction derivatives (2, N, 3) of r = d - 2 (d . n) n."""
    c = row_dot(dirs, n)
    dc = row_dot(dd, n) + row_dot(dirs, dn)
    return dd - 2.0 * (c[:, None] * dn + dc[..., None] * n)


def refracted(dirs: np.ndarray, n: np.ndarray, eta: np.ndarray, t_dir: np.ndarray, dd: np.ndarray,
              dn: np.ndarray) -> np.ndarray:
    """Direction derivatives (2, N, 3) of Snell's t = eta d - (eta c + cos_t) n, c = d . n."""
    c = row_dot(dirs, n)
    cos_t = -row_dot(t_dir, n)  # > 0: t leaves on the far side of n
    dc = row_dot(dd, n) + row_dot(dirs, dn)
    ok = cos_t > MIN_COS_T
    dmu = -(eta + eta * eta * c / np.where(ok, cos_t, 1.0))[None] * dc
    mu = -(eta * c + cos_t)
    out = eta[:, None] * dd + mu[:, None] * dn + dmu[..., None] * n
    out[:, ~ok] = 0.0
    return out
