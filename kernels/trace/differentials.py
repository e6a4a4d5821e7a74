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

from ..geometry.camera import camera_ray_lines
from ..geometry.scene import Scene
from ..shading.pixel_texture import GRAZING_COS, Footprint

# GRAZING_COS (surface.py): below this |cos| between a ray and the plane it meets, the footprint
# would stretch without bound along the plane; the hit's position derivatives are taken as zero.
# Below this cos of the refracted ray (grazing, at the edge of total internal reflection) the
# direction's derivative 1 / cos_t blows up: its change is taken as zero.
MIN_COS_T = 1e-3


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row dot products over the last axis: (..., 3) x (..., 3) -> (...), by component (twice as
    fast as einsum on (2, N, 3) x (N, 3))."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def camera_derivatives(fp: Footprint, rays: np.ndarray, dirs: np.ndarray, p: np.ndarray,
                       n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Of camera rays rays (M,) int (indices into the footprint) with unit directions dirs (M, 3)
    hitting planes of normal n (M, 3) at p (M, 3): the hit's derivatives (2, M, 3) m/pixel and
    the direction's (2, M, 3) /pixel."""
    o, d, o_x, o_y, d_x, d_y = camera_ray_lines(fp.camera, fp.width, fp.height, fp.x[rays],
                                                fp.y[rays])
    length = np.sqrt(_dot(d, d))[:, None]
    s = _dot(p - o, d)[:, None] / (length * length)  # p = o + s d
    do = np.stack(np.broadcast_arrays(o_x, o_y))[:, None, :]  # (2, 1, 3): the lines' shift
    dd = np.stack(np.broadcast_arrays(d_x, d_y))[:, None, :]
    unit_dd = (dd - dirs * _dot(dirs, dd)[..., None]) / length  # d / |d| differentiated
    return transfer(do + s * dd, np.zeros_like(unit_dd), dirs, np.zeros(len(p)), n), unit_dd


def transfer(dp: np.ndarray, dd: np.ndarray, dirs: np.ndarray, t: np.ndarray,
             n: np.ndarray) -> np.ndarray:
    """Hit derivatives (2, N, 3) of rays leaving points with derivatives dp along unit dirs (N, 3)
    (direction derivatives dd) to hits at distance t (N,) on planes of normal n (N, 3):
    dp' = dp + t dd + dt dirs, dt chosen to keep the hit in the plane."""
    q = dp + t[:, None] * dd
    cos = _dot(dirs, n)
    ok = np.abs(cos) > GRAZING_COS * np.sqrt(_dot(n, n))
    dt = -_dot(q, n) / np.where(ok, cos, 1.0)
    q += dt[..., None] * dirs
    q[:, ~ok] = 0.0
    return q


class TriangleFrames:
    """Per triangle, what carrying a hit's change across a triangle needs, built once per scene:
    grad (T, 2, 3) the gradients of the barycentrics b1, b2 in the triangle's plane (b1's change
    is grad[:, 0] . dp), and turn (T, 2, 3) the corner normals' differences n1 - n0, n2 - n0 (the
    interpolated normal's change per unit of b1, b2)."""

    def __init__(self, scene: Scene):
        v = scene.triangles.astype(np.float64)
        e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
        d11, d12, d22 = _dot(e1, e1), _dot(e1, e2), _dot(e2, e2)
        # A degenerate triangle is never hit (the BVH drops it): any finite gradient does.
        det = np.where(d11 * d22 - d12 * d12 > 0.0, d11 * d22 - d12 * d12, 1.0)[:, None]
        # float32: 48 bytes a triangle; a derivative needs no more than its 7 digits
        self.grad = np.stack([(d22[:, None] * e1 - d12[:, None] * e2) / det,
                              (d11[:, None] * e2 - d12[:, None] * e1) / det], 1).astype(np.float32)
        n = scene.normals
        self.turn = np.stack([n[:, 1] - n[:, 0], n[:, 2] - n[:, 0]], 1).astype(np.float32)


def normal_derivatives(frames: TriangleFrames, tri: np.ndarray, ns: np.ndarray, length: np.ndarray,
                       side: np.ndarray, dp: np.ndarray) -> np.ndarray:
    """Derivatives (2, M, 3) of the shading normal ns (M, 3) unit, the corner normals of
    triangles tri (M,) interpolated (length (M,) before normalising) and turned to side (M,) +-1,
    as the hit moves by dp (2, M, 3)."""
    grad, turn = frames.grad[tri], frames.turn[tri]
    d_raw = _dot(dp, grad[:, 0])[..., None] * turn[:, 0] + _dot(dp, grad[:, 1])[..., None] * turn[:, 1]
    # raw / |raw| differentiated: the change across the unit normal, over the length
    return (d_raw - ns * _dot(ns, d_raw)[..., None]) * (side / length)[:, None]


def reflected(dirs: np.ndarray, n: np.ndarray, dd: np.ndarray, dn: np.ndarray) -> np.ndarray:
    """Direction derivatives (2, N, 3) of r = d - 2 (d . n) n."""
    c = _dot(dirs, n)
    dc = _dot(dd, n) + _dot(dirs, dn)
    return dd - 2.0 * (c[:, None] * dn + dc[..., None] * n)


def refracted(dirs: np.ndarray, n: np.ndarray, eta: np.ndarray, t_dir: np.ndarray, dd: np.ndarray,
              dn: np.ndarray) -> np.ndarray:
    """Direction derivatives (2, N, 3) of Snell's t = eta d - (eta c + cos_t) n, c = d . n."""
    c = _dot(dirs, n)
    cos_t = -_dot(t_dir, n)  # > 0: t leaves on the far side of n
    dc = _dot(dd, n) + _dot(dirs, dn)
    ok = cos_t > MIN_COS_T
    dmu = -(eta + eta * eta * c / np.where(ok, cos_t, 1.0))[None] * dc
    mu = -(eta * c + cos_t)
    out = eta[:, None] * dd + mu[:, None] * dn + dmu[..., None] * n
    out[:, ~ok] = 0.0
    return out
