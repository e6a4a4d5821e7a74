"""Camera rays through pixel centres, and the image-plane geometry of Blender's cameras.

The lecture's backward tracing: "cast rays from the centre of projection through each pixel centre".
`image_plane` reproduces Blender's view-plane computation (sensor fit, pixel aspect, lens shift) so a
kernel render lines up pixel for pixel with Cycles' render of the same camera.
"""

from __future__ import annotations

import numpy as np

from .scene import Camera
from .vec import row_dot

# A ray this close to edge-on with the plane it meets (|cos|) takes its hit's move across the
# pixel as zero (`plane_transfer`), and a cell's sample ray keeps its centre's texture
# coordinates (`pixel_texture`): along the plane the move runs off towards infinity.
GRAZING_COS = 1e-4

# Rays that are sub-samples of pixels: (stratum of each ray (N,) int, number of strata m). A
# pixel's m sub-samples may share out a light's samples among them (`Tracer._area_direct`,
# `emitters.emitter_irradiance`, `lamps.light_visibility`).
Strata = tuple[np.ndarray, int]


def strata_rows(strata: Strata | None, rows) -> Strata | None:
    """The strata of the rays `rows` (an index or mask into the N rays), None for None."""
    return None if strata is None else (strata[0][rows], strata[1])


def image_plane(
    kind: str,
    resolution: tuple[int, int],
    *,
    lens_mm: float = 50.0,
    sensor_width_mm: float = 36.0,
    sensor_height_mm: float = 24.0,
    sensor_fit: str = "AUTO",
    ortho_scale: float = 6.0,
    shift: tuple[float, float] = (0.0, 0.0),
    pixel_aspect: tuple[float, float] = (1.0, 1.0),
) -> tuple[np.ndarray, np.ndarray]:
    """(plane_min, plane_max) (2,) each: the image-plane rectangle at distance 1 (PERSP) or in m (ORTHO).

    | parameter     | range               | default | unit                                        |
    |---------------|---------------------|---------|---------------------------------------------|
    | kind          | PERSP, ORTHO        |         |                                             |
    | resolution    | (W, H) >= 1         |         | pixels, render percentage applied           |
    | lens_mm       | > 0                 | 50      | mm (PERSP)                                  |
    | sensor_*_mm   | > 0                 | 36, 24  | mm; AUTO fit uses the width for the larger side |
    | sensor_fit    | AUTO, HORIZONTAL, VERTICAL | AUTO |                                          |
    | ortho_scale   | > 0                 | 6       | m across the fitted side (ORTHO)            |
    | shift         | any                 | (0, 0)  | fractions of the fitted side                |
    | pixel_aspect  | > 0                 | (1, 1)  | Blender's pixel_aspect_x, _y                |

    Follows Blender's `BKE_camera_params_compute_viewplane`: the fitted side of the (aspect-corrected)
    frame spans the sensor (or ortho_scale), and the shift moves the plane by fractions of that side.
    """
    width, height = resolution
    frame_x = width * pixel_aspect[0]
    frame_y = height * pixel_aspect[1]
    if sensor_fit == "AUTO":
        fit_horizontal = frame_x >= frame_y
        sensor = sensor_width_mm
    else:
        fit_horizontal = sensor_fit == "HORIZONTAL"
        sensor = sensor_width_mm if fit_horizontal else sensor_height_mm
    # Size of the fitted side of the image plane: at distance 1 for a pinhole, metres for ortho.
    fitted = ortho_scale if kind == "ORTHO" else sensor / lens_mm
    if fit_horizontal:
        size = np.array([fitted, fitted * frame_y / frame_x])
    else:
        size = np.array([fitted * frame_x / frame_y, fitted])
    centre = np.asarray(shift, np.float64) * fitted
    return centre - 0.5 * size, centre + 0.5 * size


def pixel_plane_coords(camera: Camera, width: int, height: int, offsets=(0.5, 0.5)) -> np.ndarray:
    """Image-plane (x, y) of every pixel's sample point, (H, W, 2) float64, row 0 at the top.

    `offsets` are the sample's position inside the pixel in [0, 1) (0.5, 0.5: the pixel centre).
    """
    lo, hi = camera.plane_min, camera.plane_max
    x = lo[0] + (np.arange(width) + offsets[0]) / width * (hi[0] - lo[0])
    y = hi[1] - (np.arange(height) + offsets[1]) / height * (hi[1] - lo[1])
    out = np.empty((height, width, 2))
    out[..., 0] = x[None, :]
    out[..., 1] = y[:, None]
    return out


def camera_rays(
    camera: Camera, width: int | None = None, height: int | None = None, offsets=(0.5, 0.5)
) -> tuple[np.ndarray, np.ndarray]:
    """World-space rays through the pixels: origins and unit directions, each (H, W, 3) float64.

    width/height default to the camera's render resolution; another size keeps the same framing.
    PERSP rays start at the eye; ORTHO rays start on the image plane through the camera origin.
    Both start `clip_start` along the ray, as in Blender.
    """
    width = width or camera.resolution[0]
    height = height or camera.resolution[1]
    return _rays_through(camera, pixel_plane_coords(camera, width, height, offsets))


def pixel_rays(camera: Camera, width: int, height: int, x: np.ndarray, y: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """`camera_rays` through image points x, y (N,) in pixels of a width x height image (x right
    from the left edge, y down from the top: pixel (col, row) with offsets (ox, oy) is
    (col + ox, row + oy)), for a few pixels of a large image: origins and unit directions (N, 3),
    the same floats as `camera_rays` gives those pixels."""
    lo, hi = camera.plane_min, camera.plane_max
    xy = np.empty((len(x), 2))
    xy[:, 0] = lo[0] + np.asarray(x, np.float64) / width * (hi[0] - lo[0])
    xy[:, 1] = hi[1] - np.asarray(y, np.float64) / height * (hi[1] - lo[1])
    return _rays_through(camera, xy)


def _rays_through(camera: Camera, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays through image-plane points xy (..., 2): origins and unit directions (..., 3)."""
    rot = camera.matrix_world[:3, :3]
    eye = camera.matrix_world[:3, 3]
    forward = -rot[:, 2]  # the camera looks down its local -Z
    if camera.kind == "ORTHO":
        origins = eye + xy[..., 0:1] * rot[:, 0] + xy[..., 1:2] * rot[:, 1]
        directions = np.broadcast_to(forward, origins.shape).copy()
        origins = origins + camera.clip_start * directions
        return origins, directions
    local = np.concatenate([xy, -np.ones(xy.shape[:-1] + (1,))], axis=-1)  # camera space, z = -1
    directions = local @ rot.T
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    # Blender clips along the view axis, so the start distance along a ray is clip_start / cos.
    cos_axis = directions @ forward
    origins = eye + directions * (camera.clip_start / cos_axis)[..., None]
    return origins, directions


def camera_reach(camera: Camera, directions: np.ndarray) -> np.ndarray:
    """(N,) how far camera rays (`camera_rays`, unit directions (N, 3)) go from their origins
    before Blender's far clip plane, clip_end along the view axis: (clip_end - clip_start) / cos
    for a perspective camera, clip_end - clip_start for an orthographic one (Cycles' tmax)."""
    length = max(camera.clip_end - camera.clip_start, 0.0)
    if camera.kind == "ORTHO":
        return np.full(len(directions), length)
    forward = -camera.matrix_world[:3, 2]
    return length / np.maximum(np.asarray(directions, np.float64) @ forward, 1e-12)


def camera_ray_lines(camera: Camera, width: int, height: int, x: np.ndarray, y: np.ndarray):
    """The lines of the camera rays through image points, and how they move across the image.

    x, y (N,) in pixels of a width x height image, x to the right from the left edge and y down
    from the top edge (pixel (col, row) has its centre at (col + 0.5, row + 0.5)).
    Returns (o, d, o_x, o_y, d_x, d_y): the line o + s d (N, 3) float64 through each point, d
    NOT normalised, and the (3,) changes of o and d per pixel to the right (x) and down (y). Both
    are affine in (x, y): PERSP lines share the eye (o_x = o_y = 0), ORTHO lines the direction
    (d_x = d_y = 0). Lines, not rays: the start at clip_start is left out, which moves no line.
    """
    lo, hi = camera.plane_min, camera.plane_max
    rot = camera.matrix_world[:3, :3]
    eye = camera.matrix_world[:3, 3]
    px = lo[0] + np.asarray(x, np.float64) / width * (hi[0] - lo[0])  # image plane, camera space
    py = hi[1] - np.asarray(y, np.float64) / height * (hi[1] - lo[1])
    step_x = rot[:, 0] * (hi[0] - lo[0]) / width
    step_y = -rot[:, 1] * (hi[1] - lo[1]) / height
    zero = np.zeros(3)
    if camera.kind == "ORTHO":
        o = eye + px[:, None] * rot[:, 0] + py[:, None] * rot[:, 1]
        d = np.broadcast_to(-rot[:, 2], o.shape)
        return o, d, step_x, step_y, zero, zero
    d = px[:, None] * rot[:, 0] + py[:, None] * rot[:, 1] - rot[:, 2]
    return np.broadcast_to(eye, d.shape), d, zero, zero, step_x, step_y


def camera_hit_derivatives(camera: Camera, width: int, height: int, x: np.ndarray,
                           y: np.ndarray, dirs: np.ndarray | None, p: np.ndarray, n: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Ray differentials (Igehy, "Tracing Ray Differentials", 1999) of camera rays through
    image points (x, y) (M,) pixels of a width x height image, with unit directions dirs (M, 3)
    (None: the lines' own, normalised), hitting planes of normal n (M, 3) at p (M, 3): the hit's
    derivatives (2, M, 3) m/pixel and the direction's (2, M, 3) /pixel, [0] along x, [1] along
    y."""
    o, d, o_x, o_y, d_x, d_y = camera_ray_lines(camera, width, height, x, y)
    length = np.sqrt(row_dot(d, d))[:, None]
    dirs = d / length if dirs is None else dirs
    s = row_dot(p - o, d)[:, None] / (length * length)  # p = o + s d
    do = np.stack(np.broadcast_arrays(o_x, o_y))[:, None, :]  # (2, 1, 3): the lines' shift
    dd = np.stack(np.broadcast_arrays(d_x, d_y))[:, None, :]
    unit_dd = (dd - dirs * row_dot(dirs, dd)[..., None]) / length  # d / |d| differentiated
    return plane_transfer(do + s * dd, np.zeros_like(unit_dd), dirs, np.zeros(len(p)), n), unit_dd


def plane_transfer(dp: np.ndarray, dd: np.ndarray, dirs: np.ndarray, t: np.ndarray,
                   n: np.ndarray) -> np.ndarray:
    """Hit derivatives (2, N, 3) of rays leaving points with derivatives dp along unit dirs (N, 3)
    (direction derivatives dd) to hits at distance t (N,) on planes of normal n (N, 3):
    dp' = dp + t dd + dt dirs, dt chosen to keep the hit in the plane; 0 edge-on (GRAZING_COS)."""
    q = dp + t[:, None] * dd
    cos = row_dot(dirs, n)
    ok = np.abs(cos) > GRAZING_COS * np.sqrt(row_dot(n, n))
    dt = -row_dot(q, n) / np.where(ok, cos, 1.0)
    q += dt[..., None] * dirs
    q[:, ~ok] = 0.0
    return q
