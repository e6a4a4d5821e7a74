"""Heights in metres on stretched UV maps (kernels/normalmap/surface_metric.py) and a material's
Bump-node height as a source (texture_height.py), against closed forms: a uniformly scaled map
gives G = I / L (the map of strength D / L), a stretched one diag(1 / Lu, 1 / Lv), a mirrored one
keeps b along +v, and the normals equal the Bump node's n - D grad h in the frame."""

import numpy as np

from classic_bake.kernels.geometry.scene import Texture
from classic_bake.kernels.normalmap.dilate import chart_mask
from classic_bake.kernels.normalmap.from_height import NormalMapSettings, normal_map
from classic_bake.kernels.normalmap.heights import ProceduralHeight
from classic_bake.kernels.normalmap.surface_metric import (
    metric_normals,
    slope_matrices,
    texel_triangles,
)
from classic_bake.kernels.normalmap.texture_height import TextureHeight

UV_SQUARE = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])


def rectangle(lu: float, lv: float) -> np.ndarray:
    """The unit UV square's two triangles on an lu x lv metre rectangle in z = 0."""
    return np.concatenate([UV_SQUARE * [lu, lv], np.zeros((2, 3, 1))], axis=2)


def test_uniform_and_stretched_maps_give_their_scale():
    g, bad = slope_matrices(UV_SQUARE, rectangle(4.0, 4.0), 1.0)
    np.testing.assert_allclose(g, np.broadcast_to(np.eye(2) / 4.0, g.shape), atol=1e-12)
    g, _ = slope_matrices(UV_SQUARE, rectangle(2.0, 0.5), 1.0)
    np.testing.assert_allclose(g, np.broadcast_to(np.diag([0.5, 2.0]), g.shape), atol=1e-12)
    assert not bad.any()


def test_mirrored_uvs_keep_b_along_plus_v_and_degenerate_ones_fall_back():
    mirrored = UV_SQUARE * [-1.0, 1.0] + [1.0, 0.0]  # u runs along -x
    g, _ = slope_matrices(mirrored, rectangle(3.0, 3.0), 1.0)
    # t = dp/du = -x / 3; grad u = -x / 3: grad u . t = 1/3; b along +v = +y: grad v . b = 1/3.
    np.testing.assert_allclose(g, np.broadcast_to(np.eye(2) / 3.0, g.shape), atol=1e-12)
    collapsed = np.zeros((1, 3, 2))
    g, bad = slope_matrices(collapsed, rectangle(1.0, 1.0)[:1], 5.0)
    assert bad.all() and np.allclose(g, np.eye(2) / 5.0)


def test_sheared_map_matches_the_bump_gradient():
    """On a sheared parametrisation the map's normal is the Bump node's n - D grad h in the frame
    (t = dp/du unit, b in the plane along +v), for a ramp h = a u + c v."""
    world = np.array([[[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.5, 1.0, 0.0]]])
    uv = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]])
    g, _ = slope_matrices(uv, world, 1.0)
    a, c, distance = 0.3, -0.7, 0.2
    dpdu, dpdv = world[0, 1] - world[0, 0], world[0, 2] - world[0, 1]
    # grad h: the plane vector with grad h . dp/du = a, grad h . dp/dv = c.
    grad = np.linalg.solve(np.array([dpdu[:2], dpdv[:2]]), [a, c])
    t = dpdu / np.linalg.norm(dpdu)
    b = np.array([-t[1], t[0]])
    expected = np.array([-distance * grad @ t[:2], -distance * grad @ b, 1.0])
    expected /= np.linalg.norm(expected)
    flat_slopes = np.array([[-a, -c, 1.0]]) / np.linalg.norm([a, c, 1.0])  # strength 1
    got = metric_normals(flat_slopes, g, distance)[0]
    np.testing.assert_allclose(got, expected, atol=1e-6)


def test_uniform_metric_equals_the_scalar_strength():
    source = ProceduralHeight("orange_peel")
    size, metres, distance = 32, 4.0, 0.01
    unit = normal_map(source, NormalMapSettings(size=size, strength=1.0)).normals
    scalar = normal_map(source, NormalMapSettings(size=size, strength=distance / metres)).normals
    g, _ = slope_matrices(UV_SQUARE, rectangle(metres, metres), 1.0)
    ids = texel_triangles(UV_SQUARE, size, size)
    assert np.array_equal(ids >= 0, chart_mask(UV_SQUARE, size, size))
    got = metric_normals(unit.reshape(-1, 3), g[ids.ravel()], distance).reshape(size, size, 3)
    np.testing.assert_allclose(got, scalar, atol=2e-6)


def test_texture_height_is_the_luminance_times_its_factor():
    pixels = np.zeros((2, 2, 4), np.float32)
    pixels[..., 0] = 1.0  # red: luminance 0.2126
    texture = Texture(kind="IMAGE", pixels=pixels)
    uv = np.array([[0.25, 0.25], [0.75, 0.75]])
    np.testing.assert_allclose(TextureHeight(texture).heights(uv), 0.2126, atol=1e-4)
    np.testing.assert_allclose(TextureHeight(texture, -1.0).heights(uv), -0.2126, atol=1e-4)
    assert TextureHeight(texture).resolution == (2, 2)
    assert TextureHeight(Texture(kind="CHECKER")).resolution is None
