"""A lamp's highlight averaged over a pixel (kernels/shading/highlight_spread.py,
specular_layer.pixel_highlight), against the pixel means of the unfiltered lobe over 32 x 32
points."""

import numpy as np
import pytest

from classic_bake.kernels.geometry.camera import camera_ray_lines, image_plane
from classic_bake.kernels.geometry.scene import Camera
from classic_bake.kernels.shading.highlight_spread import (
    PIXEL_SLOPE_VARIANCE,
    SPREAD_CAP,
    NormalFootprint,
    TrianglePatch,
    normal_derivatives,
    triangle_patches,
    widened_roughness,
)
from classic_bake.kernels.shading.specular_layer import pixel_highlight

SIDE = 9  # pixels per side of the patch
# The light and the eye 16.7 degrees either side of +z: the highlight's peak is where n = +z.
TO_LIGHT = np.array([0.0, 0.3, 1.0]) / np.hypot(0.3, 1.0)
TO_EYE = TO_LIGHT * [1.0, -1.0, 1.0]


def paraboloid_normals(x, y, k):
    """(N, 3) unit normals of a paraboloid whose normal turns by k (radians, nearly) per pixel,
    at image positions x, y (N,) in pixels from its apex."""
    n = np.stack([k * x, k * y, np.ones_like(x)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def highlight(normals, roughness, footprint=None):
    count = len(normals)
    return pixel_highlight(normals, np.tile(TO_LIGHT, (count, 1)), np.tile(TO_EYE, (count, 1)),
                           np.full(count, roughness), np.ones((count, 3)), footprint)[:, 0]


def patch(k):
    """Pixel centres of a SIDE x SIDE patch, the apex 0.3 px off a centre (rows, cols, x, y)."""
    rows, cols = np.divmod(np.arange(SIDE * SIDE), SIDE)
    return rows, cols, cols - SIDE // 2 + 0.3, rows - SIDE // 2 + 0.3


def pixel_means(k, roughness, points=32):
    """(SIDE^2,) each pixel's mean of the lobe over points x points positions in it."""
    _, _, x, y = patch(k)
    offsets = (np.arange(points) + 0.5) / points - 0.5
    ox, oy = (a.ravel() for a in np.meshgrid(offsets, offsets))
    return np.array([highlight(paraboloid_normals(cx + ox, cy + oy, k), roughness).mean()
                     for cx, cy in zip(x, y, strict=True)])


def rel_mse(values, truth):
    return float(np.mean((values - truth) ** 2) / np.mean(truth ** 2))


@pytest.mark.parametrize("k", [0.02, 0.05, 0.1])
@pytest.mark.parametrize("roughness", [0.1, 0.15, 0.25, 0.5])
def test_a_pixel_shows_its_mean_of_the_highlight(k, roughness):
    """The footprint's lobe against the pixels' means: relMSE under 4e-3 over the patch (up to
    0.81 with the lobe at the centre normal alone: roughness 0.1 at 0.1 per pixel, the highlight
    between the centres) and the sum within 1.5%, but for that narrowest lobe, about as wide as
    the spacing of its 8 x 8 sub-normals, whose sampling sums 6.4% over."""
    rows, cols, x, y = patch(k)
    normals = paraboloid_normals(x, y, k)
    slopes = normal_derivatives(normals, rows, cols, np.zeros(len(rows), np.int64), (SIDE, SIDE))
    footprint = NormalFootprint.of_pixels(slopes, rows, cols)
    truth = pixel_means(k, roughness)
    filtered = highlight(normals, roughness, footprint)
    assert rel_mse(filtered, truth) < 4e-3
    assert filtered.sum() == pytest.approx(truth.sum(), rel=0.07 if (k, roughness) == (0.1, 0.1) else 0.015)
    if roughness == 0.1 and k >= 0.05:
        assert rel_mse(highlight(normals, roughness), truth) > 0.3


def test_derivatives_follow_a_smooth_surface():
    """Inside the patch the derivatives are the differences to a neighbouring centre: |dn/dx|^2
    + |dn/dy|^2 within 3% of 2 k^2 on a paraboloid near its apex."""
    k = 0.05
    rows, cols, x, y = patch(k)
    normals = paraboloid_normals(x, y, k)
    slopes = normal_derivatives(normals, rows, cols, np.zeros(len(rows), np.int64), (SIDE, SIDE))
    spread = NormalFootprint.of_pixels(slopes, rows, cols).spread.reshape(SIDE, SIDE)
    assert spread[3:6, 3:6] == pytest.approx(2 * k * k, rel=0.03)
    half = NormalFootprint.of_pixels(slopes, rows, cols, cell=0.5).spread.reshape(SIDE, SIDE)
    np.testing.assert_allclose(half, spread / 4)  # a sub-pixel cell spans a quarter of the area


def test_a_neighbour_of_another_object_or_across_a_crease_does_not_count():
    """A column of another object's pixels facing elsewhere, and a crease on one side of a
    pixel, leave the derivatives those of the pixel's own smooth side."""
    k = 0.05
    rows, cols, x, y = patch(k)
    normals = paraboloid_normals(x, y, k)
    ids = np.zeros(len(rows), np.int64)
    reference = normal_derivatives(normals, rows, cols, ids, (SIDE, SIDE))
    other = cols == 6
    normals[other] = [1.0, 0.0, 0.0]
    ids[other] = 1
    slopes = normal_derivatives(normals, rows, cols, ids, (SIDE, SIDE))
    np.testing.assert_allclose(slopes.dx[:, 5], reference.dx[:, 4])  # the one-sided step inside
    np.testing.assert_allclose(slopes.dy[:, 5], reference.dy[:, 5])
    creased = normals.copy()
    creased[cols == 6] = [0.0, 0.7071, 0.7071]
    slopes = normal_derivatives(creased, rows, cols, np.zeros(len(rows), np.int64), (SIDE, SIDE))
    np.testing.assert_allclose(slopes.dx[:, 5], reference.dx[:, 4])


def test_widening_is_capped_and_absent_without_a_footprint():
    roughness = np.array([0.1, 0.5])
    assert widened_roughness(roughness, None) is roughness
    wide = widened_roughness(roughness, np.array([0.012, 1e3]))
    assert wide[0] ** 4 == pytest.approx(0.1 ** 4 + 0.012 * PIXEL_SLOPE_VARIANCE)
    assert wide[1] ** 4 == pytest.approx(0.5 ** 4 + SPREAD_CAP)


def tilted_camera(kind, res=(64, 48)):
    """A camera at (0.3, -0.2, 4) looking down -z, turned 20 degrees about x."""
    lo, hi = image_plane(kind, res, lens_mm=50.0, ortho_scale=2.0)
    c, s = np.cos(np.radians(20.0)), np.sin(np.radians(20.0))
    m = np.eye(4)
    m[:3, :3] = [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]
    m[:3, 3] = [0.3, -0.2, 4.0]
    return Camera(kind=kind, matrix_world=m, plane_min=lo, plane_max=hi, resolution=res,
                  clip_start=0.0)


def seen_normal(camera, res, x, y, corners, normals):
    """The interpolated unit normal where the camera line through image point (x, y) meets the
    triangle's plane, and its barycentrics: the brute-force reference."""
    o, d, *_ = camera_ray_lines(camera, *res, np.array([x]), np.array([y]))
    e1, e2 = corners[1] - corners[0], corners[2] - corners[0]
    n = np.cross(e1, e2)
    p = o[0] + d[0] * np.dot(corners[0] - o[0], n) / np.dot(d[0], n)
    b = np.linalg.lstsq(np.stack([e1, e2], 1), p - corners[0], rcond=None)[0]
    bary = np.array([1.0 - b.sum(), b[0], b[1]])
    raw = bary @ normals
    return raw / np.linalg.norm(raw), bary


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_a_triangles_normal_slopes_are_its_change_to_the_next_pixel(kind):
    """triangle_patches (ray differentials through the triangle's barycentrics) against the
    interpolated normal at the next pixels' hits, by central differences of a twentieth of a
    pixel: barycentrics and the normal's slopes within 1e-3 of their change (a bevel's corner
    normals 50 degrees apart)."""
    res = (64, 48)
    camera = tilted_camera(kind, res)
    corners = np.array([[-0.4, -0.1, 0.0], [0.5, 0.05, 0.3], [0.0, 0.6, -0.2]])
    normals = np.array([[0.0, -0.77, 0.64], [0.1, 0.0, 1.0], [0.0, 0.2, 0.98]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    row, col = 21, 30
    _, bary = seen_normal(camera, res, col + 0.5, row + 0.5, corners, normals)
    patch = triangle_patches(camera, (res[1], res[0]), np.array([row]), np.array([col]),
                             corners[None], normals[None], bary[None], np.ones(1))
    slopes = patch.slopes()
    h = 0.05
    for k, (ox, oy) in enumerate(((h, 0.0), (0.0, h))):
        plus, b_plus = seen_normal(camera, res, col + 0.5 + ox, row + 0.5 + oy, corners, normals)
        minus, b_minus = seen_normal(camera, res, col + 0.5 - ox, row + 0.5 - oy, corners, normals)
        expected = (plus - minus) / (2 * h)
        assert np.linalg.norm(expected) > 1e-3
        np.testing.assert_allclose(slopes[k][0], expected, atol=1e-3 * np.linalg.norm(expected))
        db = (b_plus - b_minus) / (2 * h)
        np.testing.assert_allclose((patch.dx, patch.dy)[k][0], db, atol=1e-3 * np.linalg.norm(db))
    back = triangle_patches(camera, (res[1], res[0]), np.array([row]), np.array([col]),
                            corners[None], normals[None], bary[None], -np.ones(1))
    np.testing.assert_allclose(back.slopes()[0], -slopes[0])  # seen from behind: turned over


def test_a_sub_pixel_ray_on_a_bevel_sweeps_its_own_triangles_normals():
    """A sub-pixel ray (a third of a pixel) on a bevel whose normals turn 50 degrees across it,
    in a pixel on a flat face (no change between the neighbours): the footprint takes the
    bevel's own slopes and is swept on the bevel, whose normals never pass its corners'."""
    flat = normal_derivatives(np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([0, 0, 1, 1]),
                              np.array([0, 1, 0, 1]), np.zeros(4, np.int64), (2, 2))
    corners = np.array([[[0.0, -0.77, 0.64], [0.0, -0.77, 0.64], [0.0, 0.0, 1.0]]])
    corners /= np.linalg.norm(corners, axis=2, keepdims=True)
    # the ray a fifth of the way across the bevel; the bevel 1/6 px wide (along y)
    patch = TrianglePatch(np.array([[0.4, 0.4, 0.2]]), np.zeros((1, 3)),
                          np.array([[-3.0, -3.0, 6.0]]), corners)
    fp = NormalFootprint.of_pixels(flat, np.array([0]), np.array([0]), 1.0 / 3.0, patch=patch)
    np.testing.assert_allclose(fp.dy, patch.slopes()[1] / 3.0)
    assert fp.smooth[0] and fp.own[0]  # swept (sub_sides), on the triangle
    lo, hi = corners[0, 0], corners[0, 2]
    for ox, oy in ((0.0, -0.5), (0.0, 0.5), (0.3, 0.2)):
        n = fp.normals_at(np.array([[0.0, 0.0, 1.0]]), ox, oy)[0]
        arc = np.arccos(np.clip(lo @ hi, -1, 1))
        assert np.arccos(np.clip(n @ lo, -1, 1)) + np.arccos(np.clip(n @ hi, -1, 1)) <= arc + 1e-9


def test_a_relief_mapped_sample_keeps_its_mapped_normal():
    """The same bevel under a normal map (the pixel's slopes marked as relief): its own
    triangle's slopes widen the lobe but the sweeps never put the triangle's unmapped normals in
    place of the map's (an imported apple's tilted normal map lost its shading)."""
    relief = normal_derivatives(np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([0, 0, 1, 1]),
                                np.array([0, 1, 0, 1]), np.zeros(4, np.int64), (2, 2),
                                np.ones(4, bool))
    corners = np.array([[[0.0, -0.77, 0.64], [0.0, -0.77, 0.64], [0.0, 0.0, 1.0]]])
    corners /= np.linalg.norm(corners, axis=2, keepdims=True)
    patch = TrianglePatch(np.array([[0.4, 0.4, 0.2]]), np.zeros((1, 3)),
                          np.array([[-3.0, -3.0, 6.0]]), corners)
    fp = NormalFootprint.of_pixels(relief, np.array([0]), np.array([0]), 1.0 / 3.0, patch=patch)
    mapped = np.array([[0.6, 0.0, 0.8]])
    assert not fp.own[0] and not fp.smooth[0] and fp.spread[0] > 0.1
    np.testing.assert_allclose(fp.centres(mapped), mapped)
    mirror = fp.own_triangles()
    assert not mirror.own[0]
    n = mirror.normals_at(mapped, 0.0, 0.5)[0]  # along the slopes, about the mapped normal
    expected = mapped[0] + 0.5 * mirror.dy[0]
    np.testing.assert_allclose(n, expected / np.linalg.norm(expected))
