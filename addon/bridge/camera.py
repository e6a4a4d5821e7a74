"""The scene camera as a kernel `Camera`, and the render size."""

from __future__ import annotations

from ...kernels.geometry.camera import image_plane
from ...kernels.geometry.scene import Camera
from .transforms import matrix_array, unit


def render_resolution(scene) -> tuple[int, int]:
    """The render size in pixels, percentage applied as Blender does (integer truncation)."""
    r = scene.render
    pct = r.resolution_percentage
    return max(1, r.resolution_x * pct // 100), max(1, r.resolution_y * pct // 100)


def read_camera(scene, cam_obj, resolution: tuple[int, int] | None = None) -> Camera:
    """The scene camera as a kernel `Camera`; raises ValueError for panoramic cameras."""
    cam = cam_obj.data
    if cam.type not in ("PERSP", "ORTHO"):
        raise ValueError(f"camera '{cam_obj.name}' is {cam.type}: only perspective and "
                         "orthographic cameras are modelled")
    resolution = resolution or render_resolution(scene)
    r = scene.render
    plane_min, plane_max = image_plane(
        cam.type,
        resolution,
        lens_mm=cam.lens,
        sensor_width_mm=cam.sensor_width,
        sensor_height_mm=cam.sensor_height,
        sensor_fit=cam.sensor_fit,
        ortho_scale=cam.ortho_scale,
        shift=(cam.shift_x, cam.shift_y),
        pixel_aspect=(r.pixel_aspect_x, r.pixel_aspect_y),
    )
    matrix = matrix_array(cam_obj.matrix_world)
    for k in range(3):  # rigid: the camera's scale does not change its view
        matrix[:3, k] = unit(matrix[:3, k])
    return Camera(kind=cam.type, matrix_world=matrix, plane_min=plane_min, plane_max=plane_max,
                  resolution=tuple(resolution), clip_start=float(cam.clip_start),
                  clip_end=float(cam.clip_end))
