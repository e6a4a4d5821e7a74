"""Image plane and camera rays (kernels/camera.py), against Blender's view-plane rules."""

import numpy as np
import pytest

from classic_bake.kernels.geometry.camera import camera_ray_lines, camera_rays, image_plane
from classic_bake.kernels.geometry.scene import Camera


def test_auto_fit_uses_the_sensor_width_for_the_larger_side():
    lo, hi = image_plane("PERSP", (200, 100), lens_mm=50.0, sensor_width_mm=36.0)
    np.testing.assert_allclose(hi - lo, [36 / 50, 36 / 50 / 2])
    lo, hi = image_plane("PERSP", (100, 200), lens_mm=50.0, sensor_width_mm=36.0)
    np.testing.assert_allclose(hi - lo, [36 / 50 / 2, 36 / 50])


def test_shift_is_a_fraction_of_the_fitted_side():
    lo, hi = image_plane("ORTHO", (200, 100), ortho_scale=4.0, shift=(0.25, -0.5))
    np.testing.assert_allclose((lo + hi) / 2, [1.0, -2.0])
    np.testing.assert_allclose(hi - lo, [4.0, 2.0])


def test_vertical_fit_and_pixel_aspect():
    lo, hi = image_plane("PERSP", (100, 100), lens_mm=24.0, sensor_height_mm=24.0,
                         sensor_fit="VERTICAL", pixel_aspect=(2.0, 1.0))
    np.testing.assert_allclose(hi - lo, [2.0, 1.0])


def make_camera(kind="PERSP", res=(4, 2)):
    lo, hi = image_plane(kind, res, lens_mm=50.0, ortho_scale=2.0)
    m = np.eye(4)
    m[:3, 3] = [0.0, 0.0, 5.0]
    return Camera(kind=kind, matrix_world=m, plane_min=lo, plane_max=hi, resolution=res,
                  clip_start=0.0)


def test_rays_pass_through_pixel_centres_top_row_first():
    cam = make_camera()
    origins, dirs = camera_rays(cam)
    assert origins.shape == dirs.shape == (2, 4, 3)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0)
    # Top-left pixel centre at plane (-3/8 w, +1/4 h) in camera space (x right, y up, -z forward).
    w = 36 / 50
    expected = np.array([-3 / 8 * w, 1 / 4 * (w / 2), -1.0])
    np.testing.assert_allclose(dirs[0, 0], expected / np.linalg.norm(expected))
    # Rows go down, columns go right.
    assert dirs[1, 0, 1] < dirs[0, 0, 1] and dirs[0, 1, 0] > dirs[0, 0, 0]


def test_orthographic_rays_are_parallel_from_the_plane():
    cam = make_camera("ORTHO", (2, 2))
    origins, dirs = camera_rays(cam)
    np.testing.assert_allclose(dirs, np.broadcast_to([0.0, 0.0, -1.0], dirs.shape))
    np.testing.assert_allclose(origins[0, 0], [-0.5, 0.5, 5.0])


@pytest.mark.parametrize("size", [(8, 4), (16, 8)])
def test_other_resolutions_keep_the_framing(size):
    cam = make_camera()
    _, small = camera_rays(cam, *size)
    # The frame corners are the same whatever the pixel count: compare extreme pixel edges.
    _, edge = camera_rays(cam, size[0], size[1], offsets=(0.0, 0.0))
    np.testing.assert_allclose(edge[0, 0], camera_rays(cam, 4, 2, offsets=(0.0, 0.0))[1][0, 0])
    assert small.shape == (size[1], size[0], 3)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_ray_lines_are_the_camera_rays_and_move_affinely(kind):
    cam = make_camera(kind, (6, 4))
    o_px, d_px = camera_rays(cam, 6, 4, offsets=(0.25, 0.75))  # (H, W, 3)
    row, col = np.divmod(np.arange(24), 6)
    x, y = col + 0.25, row + 0.75
    o, d, o_x, o_y, d_x, d_y = camera_ray_lines(cam, 6, 4, x, y)
    # Same lines: the ray origins lie on them and the directions are parallel.
    dn = d / np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_allclose(dn, d_px.reshape(-1, 3), atol=1e-12)
    off = o_px.reshape(-1, 3) - o
    np.testing.assert_allclose(np.cross(off, dn), 0.0, atol=1e-12)
    # Half a pixel to the right and down: the line through (x + 0.5, y + 0.5).
    o2, d2, *_ = camera_ray_lines(cam, 6, 4, x + 0.5, y + 0.5)
    np.testing.assert_allclose(o + 0.5 * (o_x + o_y), o2, atol=1e-12)
    np.testing.assert_allclose(d + 0.5 * (d_x + d_y), d2, atol=1e-12)


def test_pixel_rays_are_the_camera_rays_of_those_pixels():
    """`pixel_rays` through (col + ox, row + oy) gives the same floats as `camera_rays` at those
    offsets, perspective and orthographic."""
    from scene_builder import ortho_camera, persp_camera

    from classic_bake.kernels.geometry.camera import pixel_rays

    for cam in (persp_camera((1, 2, 3), (0.2, 1, -0.3), (0, 0, 1), 1.0, (37, 23)),
                ortho_camera((1, 2, 3), (0.2, 1, -0.3), (0, 0, 1), 2.0, (37, 23))):
        origins, dirs = camera_rays(cam, 37, 23, offsets=(0.25, 0.75))
        rows, cols = np.nonzero(np.ones((23, 37), bool))
        o, d = pixel_rays(cam, 37, 23, cols + 0.25, rows + 0.75)
        np.testing.assert_array_equal(o, origins[rows, cols])
        np.testing.assert_array_equal(d, dirs[rows, cols])
