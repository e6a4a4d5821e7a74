"""Bake targets (kernels/bake_targets.py) and direct light with shadow maps (kernels/direct_light.py)."""

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scene_builder import build, mirror_highlight, mirror_view, ortho_camera, quad

from classic_bake.kernels.bake.bake_targets import (
    SAMPLE_SHIFT,
    corner_targets,
    dilate,
    lightmap_targets,
)
from classic_bake.kernels.geometry.scene import Light, Material, Texture
from classic_bake.kernels.progress import drain
from classic_bake.kernels.shading import direct_light as dl
from classic_bake.kernels.shadow.shadowmap import Receivers

WHITE = Material(name="white", base_color=np.full(3, 0.8, np.float32), specular=0.0)


def sun(direction, strength=3.0):
    d = np.asarray(direction, np.float64)
    d /= np.linalg.norm(d)
    return Light(name="Sun", kind="SUN", position=np.zeros(3), direction=d,
                 axis_x=np.array([1.0, 0, 0]), axis_y=np.array([0, 1.0, 0]),
                 irradiance=np.full(3, strength))


def spot(position, direction, size_deg=80.0, intensity=50.0):
    d = np.asarray(direction, np.float64)
    d /= np.linalg.norm(d)
    x = np.cross(d, [0, 0, 1.0]) if abs(d[2]) < 0.99 else np.array([1.0, 0, 0])
    x /= np.linalg.norm(x)
    return Light(name="Spot", kind="SPOT", position=np.asarray(position, np.float64), direction=d,
                 axis_x=x, axis_y=np.cross(d, x), intensity=np.full(3, intensity),
                 spot_size=np.radians(size_deg))


def ground_with_lightmap(size=4.0):
    """A ground quad whose lightmap UVs map [-size/2, size/2]^2 onto [0.1, 0.9]^2."""
    h = size / 2
    tris = quad([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)])
    scene = build([(tris, WHITE)])
    lm = 0.1 + 0.8 * (scene.triangles[:, :, :2].astype(np.float64) + h) / size
    return replace(scene, lightmap_uv=lm.astype(np.float32))


def test_lightmap_targets_sit_at_texel_centres_on_the_surface():
    scene = ground_with_lightmap()
    t = lightmap_targets(scene, 0, 64)
    # Texels whose centres lie inside [0.1, 0.9]^2 are exactly those baked.
    centres = (np.arange(64) + 0.5) / 64
    inside = (centres > 0.1) & (centres < 0.9)
    expected = np.outer(inside[::-1], inside)
    np.testing.assert_array_equal(t.mask, expected)
    # Sampled a few thousandths of a texel off the centre, as Blender's bake samples
    # (SAMPLE_SHIFT). The tolerance, 1e-4 m, is 0.1% of a texel (0.08 m): the positions agree to
    # float32 rounding of the UVs.
    u = (t.cols + 0.5 + SAMPLE_SHIFT[0]) / 64
    v = 1 - (t.rows + 0.5 - SAMPLE_SHIFT[1]) / 64
    np.testing.assert_allclose(t.points[:, 0], (u - 0.1) / 0.8 * 4 - 2, atol=1e-4)
    np.testing.assert_allclose(t.points[:, 1], (v - 0.1) / 0.8 * 4 - 2, atol=1e-4)
    np.testing.assert_allclose(t.points[:, 2], 0, atol=1e-6)
    np.testing.assert_allclose(t.normals, np.tile([0, 0, 1.0], (len(t), 1)), atol=1e-6)


def test_dilation_fills_the_padding_ring_from_the_chart():
    mask = np.zeros((8, 8), bool)
    mask[3:5, 3:5] = True
    image = np.zeros((8, 8, 1), np.float32)
    image[mask] = 2.0
    out = dilate(image, mask, 2)
    assert np.all(out[1:7, 1:7] == 2.0)  # two rings grown
    assert np.all(out[0] == 0.0) and np.all(out[:, 0] == 0.0)  # the third ring is not


def test_corner_targets_are_the_triangle_corners():
    scene = ground_with_lightmap()
    t = corner_targets(scene, 0)
    np.testing.assert_allclose(t.points, scene.triangles.reshape(-1, 3), atol=1e-6)
    np.testing.assert_array_equal(t.corner_index, np.arange(6))


def test_unoccluded_sun_render_is_exact():
    scene = ground_with_lightmap()
    d = np.array([0.3, -0.4, -1.0])
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 2.0, (8, 8))
    scene = replace(scene, camera=cam, lights=(sun(d),))
    image = drain(dl.render_steps(scene, dl.DirectLightSettings()))
    cos = -d[2] / np.linalg.norm(d)
    np.testing.assert_allclose(image, 0.8 / np.pi * 3.0 * cos, rtol=1e-5)


def test_the_view_shows_a_checker_finer_than_its_pixels_as_the_mean_colour():
    """Ortho pixels of 3/16 m over checker squares of 3/32 m: every pixel holds 2 x 2 squares,
    so its box-filtered base colour is the two colours' mean exactly (Cycles' pixel filter),
    where the pixel centre alone sees one or the other."""
    tex = Texture(kind="CHECKER", color1=np.array([0.8, 0.1, 0.1], np.float32),
                  color2=np.array([0.1, 0.7, 0.2], np.float32), scale=32.0 / 3.0)
    mat = Material(name="checker", base_color=np.ones(3, np.float32), specular=0.0,
                   base_color_texture=tex)
    floor = quad([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)])
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 3.0, (16, 16))
    scene = build([(floor, mat)], cam, [sun((0, 0, -1), 3.0)])
    image = drain(dl.render_steps(scene, dl.DirectLightSettings()))
    mean = (np.array([0.8, 0.1, 0.1]) + np.array([0.1, 0.7, 0.2])) / 2
    np.testing.assert_allclose(image, np.broadcast_to(mean * 3.0 / np.pi, image.shape), rtol=1e-5)


def test_the_view_shows_only_diffuse_reflection():
    """Metal and glass reflect nothing diffusely (black, as Cycles' direct-light render but for
    their highlights); under a specular layer of roughness 0 the base shows 1 - F(cos) of its
    colour at the view angle (`specular_layer.py`). An orthographic camera 60 degrees off the
    normal, a vertical sun: lambertian 0.8 E / pi, layered 0.8 (1 - F(0.5)) E / pi."""
    from classic_bake.kernels.shading.optics import fresnel_dielectric

    ground = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    forward = np.array([0.0, -np.sin(np.radians(60)), -np.cos(np.radians(60))])
    cam = ortho_camera(-5.0 * forward, forward, (0, 0, 1), 0.5, (4, 4))
    expected = {
        "metal": 0.0, "glass": 0.0, "lambertian": 0.8 * 3.0 / np.pi,
        "layered": 0.8 * (1.0 - fresnel_dielectric(np.array([0.5]), 1.0 / 1.5)[0]) * 3.0 / np.pi}
    for name, value in expected.items():
        mat = Material(name=name, base_color=np.full(3, 0.8, np.float32), roughness=0.0,
                       specular=0.0 if name == "lambertian" else 0.5,
                       metallic=1.0 if name == "metal" else 0.0,
                       transmission=1.0 if name == "glass" else 0.0)
        scene = build([(ground, mat)], camera=cam, lights=[sun([0, 0, -1])])
        image = drain(dl.render_steps(scene, dl.DirectLightSettings()))
        np.testing.assert_allclose(image, value, rtol=1e-3, atol=1e-9, err_msg=name)


def test_the_view_draws_the_layers_lamp_highlight():
    """A black plane under a specular layer (roughness 0.3, F0 0.04), a sun 45 degrees off the
    normal and an orthographic camera in the mirror direction: every pixel sees the half vector
    along the normal, the analytic GGX highlight (`mirror_highlight`); Cycles' direct-light
    render draws the highlight too."""
    black = Material(name="b", base_color=np.zeros(3, np.float32), specular=0.5, roughness=0.3)
    ground = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    cam, sun_dir = mirror_view(45.0)
    scene = build([(ground, black)], camera=cam, lights=[sun(sun_dir)])
    image = drain(dl.render_steps(scene, dl.DirectLightSettings()))
    np.testing.assert_allclose(image, mirror_highlight(0.3, 0.04, 3.0, 45.0), rtol=1e-6)


def test_square_occluder_shadow_mask_matches_geometry():
    # A 1 m plate 1 m above the ground under a vertical sun: a 1 m^2 shadow right below it.
    scene = ground_with_lightmap()
    plate = quad([(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)])
    both = build([(scene.triangles, WHITE), (plate, WHITE)], lights=[sun([0, 0, -1])])
    lm = np.concatenate([scene.lightmap_uv, np.zeros((2, 3, 2), np.float32)])
    both = replace(both, lightmap_uv=lm)
    t = lightmap_targets(both, 0, 128)
    vis = np.ones((1, len(t)), np.float32)
    spacing = 4.0 / (128 * 0.8)
    list(dl.light_visibility_steps(both, Receivers.of(t.points, t.geo_normals), spacing,
                                   dl.DirectLightSettings(), vis))
    mask = dl.shadow_mask(dl.irradiance_per_light(both, t.points, t.normals), vis)
    shadowed_area = np.count_nonzero(mask < 0.5) * spacing**2
    assert shadowed_area == pytest.approx(1.0, abs=4 * spacing)  # a texel ring along the border
    under = np.all(np.abs(t.points[:, :2]) < 0.5 - spacing, axis=1)
    assert np.all(mask[under] == 0) and np.all(mask[np.any(np.abs(t.points[:, :2]) > 0.5 + spacing, 1)] == 1)


def test_an_unlit_plate_casts_no_shadow_and_lights_nothing():
    """The plate of `test_square_occluder_shadow_mask_matches_geometry`, unlit and glowing
    (`Material.camera_only`): shadow maps leave it out, it emits nothing into the scene, and
    every ray kind but the camera's passes it."""
    from classic_bake.kernels.geometry.scene import triangle_emission

    scene = ground_with_lightmap()
    plate = quad([(-0.5, -0.5, 1), (0.5, -0.5, 1), (0.5, 0.5, 1), (-0.5, 0.5, 1)])
    unlit = Material(name="unlit", base_color=np.zeros(3, np.float32), specular=0.0,
                     emission=np.full(3, 2.0, np.float32), camera_only=True)
    both = build([(scene.triangles, WHITE), (plate, unlit)], lights=[sun([0, 0, -1])])
    both = replace(both, lightmap_uv=np.concatenate([scene.lightmap_uv,
                                                     np.zeros((2, 3, 2), np.float32)]))
    t = lightmap_targets(both, 0, 64)
    vis = np.zeros((1, len(t)), np.float32)
    list(dl.light_visibility_steps(both, Receivers.of(t.points, t.geo_normals), 4.0 / 51.2,
                                   dl.DirectLightSettings(), vis))
    assert np.all(vis == 1.0)
    assert np.all(triangle_emission(both) == 0.0)  # the plate glows for the camera alone
    assert both.ray_hidden("camera") is None
    for kind in ("shadow", "glossy", "diffuse"):
        np.testing.assert_array_equal(both.ray_hidden(kind), [False, False, True, True])


def test_tilted_spot_has_no_acne_off_its_axis():
    # The spot points 40 degrees off vertical: receivers facing the light lie off the map's axis,
    # where linear view depth still varies across a texel (the perspective slope term).
    scene = build([(quad([(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)]), WHITE)],
                  lights=[spot((0, 0, 3), (np.sin(np.radians(40)), 0, -np.cos(np.radians(40))))])
    xs = np.linspace(-3, 6, 181)
    pts = np.stack(np.meshgrid(xs, np.linspace(-3, 3, 121)), -1).reshape(-1, 2)
    pts = np.concatenate([pts, np.zeros((len(pts), 1))], 1)
    normals = np.tile([0, 0, 1.0], (len(pts), 1))
    e = dl.irradiance_per_light(scene, pts, normals)
    vis = np.ones((1, len(pts)), np.float32)
    list(dl.light_visibility_steps(scene, Receivers.of(pts, normals), 0.05, dl.DirectLightSettings(), vis))
    lit = e[0, :, 0] > 0
    assert lit.sum() > 1000 and np.all(vis[0, lit] == 1.0)


def test_map_resolution_follows_the_receivers():
    light = sun([0, 0, -1])
    pts = np.random.default_rng(0).random((100, 3)) * [10, 10, 0]
    fine = dl.map_resolution(light, pts, 0.005)
    coarse = dl.map_resolution(light, pts, 0.05)
    assert coarse < fine <= dl.MAX_MAP and coarse >= dl.MIN_MAP


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.floats(1e-4, 10.0), st.integers(0, 6)), min_size=1, max_size=6))
def test_median_spacing_is_the_median_of_the_repeated_spacings(groups):
    spacings, counts = zip(*groups, strict=True)
    if sum(counts) == 0:
        assert dl.median_spacing(spacings, counts) == 1.0
        return
    assert dl.median_spacing(spacings, counts) == pytest.approx(np.median(np.repeat(spacings, counts)))
