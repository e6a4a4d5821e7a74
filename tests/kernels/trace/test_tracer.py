"""Whitted ray tracing (kernels/tracer.py) on scenes with closed-form answers.

Fresnel and slab values: tests/data/fresnel_snell.json.
"""


from dataclasses import replace

import numpy as np
import pytest
from reference_data import reference
from scene_builder import build, ortho_camera, persp_camera, quad, uv_sphere

from classic_bake.kernels.bake.camera_view import stratified_offsets
from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.camera import camera_rays
from classic_bake.kernels.geometry.scene import Light, Material, Texture
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.shading.specular_layer import ggx_highlight, schlick_grazing_curve
from classic_bake.kernels.trace import shadow_shafts
from classic_bake.kernels.trace.emitters import point_light, scene_emitters
from classic_bake.kernels.trace.settings import TracerSettings, auto_settings
from classic_bake.kernels.trace.tracer import Tracer, trace

REF = reference("fresnel_snell.json")
EXACT = TracerSettings(max_depth=48, adaptive=0, min_weight=0.0)
GLASS = Material(name="glass", base_color=np.ones(3, np.float32), transmission=1.0, roughness=0.0,
                 ior=1.5, specular=0.5)


def emitter(level=1.0):
    return Material(name="emit", base_color=np.zeros(3, np.float32), specular=0.0,
                    emission=np.full(3, level, np.float32))


def test_diffuse_plane_under_a_point_light_is_rho_e_over_pi_at_every_pixel():
    rho, intensity, height = 0.5, 40.0, 2.0
    plane = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 3.0, (16, 16))
    light = point_light("P", (0.3, -0.2, height), np.full(3, intensity))
    mat = Material(name="white", base_color=np.full(3, rho, np.float32), specular=0.0)
    scene = build([(plane, mat)], cam, [light])
    image = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    # Pixel centres of the orthographic camera on the plane z = 0.
    xs = -1.5 + (np.arange(16) + 0.5) / 16 * 3.0
    x, y = np.meshgrid(xs, xs[::-1])
    d2 = (x - 0.3) ** 2 + (y + 0.2) ** 2 + height**2
    expected = rho / np.pi * intensity * height / d2**1.5  # E = I cos / d^2, cos = h / d
    np.testing.assert_allclose(image[..., 0], expected, rtol=1e-5)


def test_fresnel_reflectance_at_normal_incidence_is_0_04():
    # Ortho camera looks down at a glass surface; an emitter of radiance 1 behind the camera is seen
    # only in the reflection; the refracted ray escapes into the black world.
    glass_top = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    light = quad([(-2, -2, 3), (-2, 2, 3), (2, 2, 3), (2, -2, 3)])  # faces down
    cam = ortho_camera((0, 0, 2), (0, 0, -1), (0, 1, 0), 1.0, (4, 4))
    scene = build([(glass_top, GLASS), (light, emitter())], cam)
    image = trace(scene, EXACT).image
    np.testing.assert_allclose(image, REF["R0 n=1.5"], rtol=1e-5)


@pytest.mark.parametrize("depth, expected", [
    (0, 0.0),  # the refracted ray (one bounce past the limit) meets the slab's far side: no light
    (1, REF["T two interfaces at normal incidence n=1.5 (1-R0)^2"]),  # its ray sees the emitter
    (48, REF["T slab incoherent multiple reflections n=1.5 (1-R)/(1+R)"]),
])
def test_glass_slab_transmission_by_depth(depth, expected):
    # A slab between z = 0 and z = 0.2 over an emitter: (1-R)^2 sum R^2k, truncated by the depth.
    # The rays of one bounce past max_depth see emitters (Cycles' Max Bounces).
    top = quad([(-1, -1, 0.2), (1, -1, 0.2), (1, 1, 0.2), (-1, 1, 0.2)])
    bottom = quad([(-1, -1, 0), (-1, 1, 0), (1, 1, 0), (1, -1, 0)])
    light = quad([(-2, -2, -1), (2, -2, -1), (2, 2, -1), (-2, 2, -1)])  # faces up
    cam = ortho_camera((0, 0, 2), (0, 0, -1), (0, 1, 0), 1.0, (2, 2))
    scene = build([(np.concatenate([top, bottom]), GLASS), (light, emitter())], cam)
    image = trace(scene, TracerSettings(max_depth=depth, adaptive=0, min_weight=0.0)).image
    assert image[0, 0, 0] == pytest.approx(expected, rel=1e-6, abs=1e-7)


def test_an_absorbing_slab_keeps_beer_lambert_of_each_crossing():
    # Coloured glass: a medium of absorption sigma (1/m) between the slab's faces, d = 0.2 m
    # apart. Each crossing keeps a = exp(-sigma d); the light through sums (1-R)^2 a (R a)^2k:
    # (1-R)^2 a / (1 - R^2 a^2), R the normal-incidence reflectance.
    sigma, d = np.array([0.0, 2.0, 10.0]), 0.2
    glass = replace(GLASS, absorption=sigma.astype(np.float32))
    top = quad([(-1, -1, d), (1, -1, d), (1, 1, d), (-1, 1, d)])
    bottom = quad([(-1, -1, 0), (-1, 1, 0), (1, 1, 0), (1, -1, 0)])
    light = quad([(-2, -2, -1), (2, -2, -1), (2, 2, -1), (-2, 2, -1)])  # faces up
    cam = ortho_camera((0, 0, 2), (0, 0, -1), (0, 1, 0), 1.0, (2, 2))
    scene = build([(np.concatenate([top, bottom]), glass), (light, emitter())], cam)
    image = trace(scene, EXACT).image
    r, a = REF["R0 n=1.5"], np.exp(-sigma * d)
    # rtol: rays start `Tracer.offset` off the faces they leave (no acne), so each crossing is
    # measured a little short: 6e-4 relative here at sigma d = 2
    np.testing.assert_allclose(image[0, 0], (1 - r) ** 2 * a / (1 - r**2 * a**2), rtol=1e-3)
    # the clear channel is the clear slab's
    assert image[0, 0, 0] == pytest.approx(REF["T slab incoherent multiple reflections n=1.5 (1-R)/(1+R)"],
                                           rel=1e-6)


def test_a_partly_covering_surface_blends_with_what_lies_behind():
    # Cycles shades a surface of alpha a as a S + (1 - a) T. A white diffuse card of alpha 0.3
    # under a point light, over an emitter of radiance 2 (which the card's shadow does not
    # dim: emitters shine, they are not lit): 0.3 rho E / pi + 0.7 x 2 at every pixel.
    rho, intensity, height, a = 0.5, 10.0, 1.0, 0.3
    card = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    glow = quad([(-3, -3, -1), (3, -3, -1), (3, 3, -1), (-3, 3, -1)])
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 0.2, (2, 2))
    light = point_light("P", (0.0, 0.0, height), np.full(3, intensity))
    mat = Material(name="veil", base_color=np.full(3, rho, np.float32), specular=0.0, alpha=a)
    scene = build([(card, mat), (glow, emitter(2.0))], cam, [light])
    image = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    xs = (np.arange(2) + 0.5) / 2 * 0.2 - 0.1
    d2 = xs[:, None] ** 2 + xs[None, :] ** 2 + height**2
    lit = rho / np.pi * intensity * height / d2**1.5
    np.testing.assert_allclose(image[..., 0], a * lit + (1 - a) * 2.0, rtol=1e-5)


def prism_scene(ior):
    """A right-angle glass prism: light enters the top face, meets the hypotenuse at 45 degrees and
    leaves through the side face towards an emitter at x = -0.5."""
    a, b, c = np.array([0.0, 1.0]), np.array([1.0, 1.0]), np.array([0.0, 0.0])  # (x, z)

    def p(xz, y):
        return (xz[0], y, xz[1])

    y0, y1 = -1.0, 1.0
    tris = [
        quad([p(a, y0), p(a, y1), p(b, y1), p(b, y0)]),  # top z = 1
        quad([p(c, y0), p(c, y1), p(a, y1), p(a, y0)]),  # side x = 0
        quad([p(b, y0), p(b, y1), p(c, y1), p(c, y0)]),  # hypotenuse x = z
    ]
    caps = np.array([[p(a, y0), p(b, y0), p(c, y0)], [p(a, y1), p(c, y1), p(b, y1)]])
    solid = np.concatenate(tris + [caps])[:, ::-1]  # listed clockwise from outside: flip to CCW
    light = quad([(-0.5, -2, -1), (-0.5, 2, -1), (-0.5, 2, 2), (-0.5, -2, 2)])
    glass = Material(name="glass", base_color=np.ones(3, np.float32), transmission=1.0,
                     roughness=0.0, ior=ior)
    cam = ortho_camera((0.5, 0, 3), (0, 0, -1), (0, 1, 0), 0.2, (2, 2))
    return build([(solid, glass), (light, emitter())], cam)


def test_total_internal_reflection_in_a_prism():
    # n = 1.5: 45 degrees is beyond the 41.8-degree critical angle, so the hypotenuse is a perfect
    # mirror: the prism acts as a folded slab, (1 - R)^2 sum R^2k = (1 - R)/(1 + R), where the
    # light reflected at the exit face returns via the hypotenuse and the top face.
    image = trace(prism_scene(1.5), EXACT).image
    expected = REF["T slab incoherent multiple reflections n=1.5 (1-R)/(1+R)"]
    assert image[0, 0, 0] == pytest.approx(expected, rel=1e-5)
    shallow = trace(prism_scene(1.5), TracerSettings(max_depth=2, adaptive=0, min_weight=0.0)).image
    assert shallow[0, 0, 0] == pytest.approx((1 - REF["R0 n=1.5"]) ** 2, rel=1e-5)


def test_below_the_critical_angle_the_prism_leaks():
    # n = 1.3: critical angle 50.3 degrees > 45, so most light leaves through the hypotenuse.
    from classic_bake.kernels.shading.optics import fresnel_dielectric

    r0 = ((1.3 - 1) / 2.3) ** 2
    r45 = fresnel_dielectric(np.array([np.cos(np.radians(45))]), 1.3)[0]
    image = trace(prism_scene(1.3), EXACT).image
    assert image[0, 0, 0] == pytest.approx((1 - r0) ** 2 * r45, rel=1e-5)


def acne_scene():
    # A sphere lit by a point light: every lit pixel must match the unshadowed diffuse value.
    sphere = uv_sphere((0, 0, 0), 1.0, rings=24, segments=48)
    mat = Material(name="white", base_color=np.full(3, 0.8, np.float32), specular=0.0)
    cam = ortho_camera((0, -5, 0), (0, 1, 0), (0, 0, 1), 2.2, (48, 48))
    return build([(sphere, mat)], cam, [point_light("P", (3, -3, 3), np.full(3, 50.0))])


def test_zero_offset_shows_acne_and_the_default_offset_none():
    scene = acne_scene()
    clean = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image[..., 0]
    acne = trace(scene, TracerSettings(max_depth=0, adaptive=0, offset_scale=0.0)).image[..., 0]
    lit = clean > 0
    speckled = np.count_nonzero(acne[lit] < 0.5 * clean[lit])
    assert speckled > 0.01 * lit.sum()  # self-shadowing speckles without an offset
    # With the default offset no lit pixel goes dark (the reference: shadow rays never re-hit).
    unshadowed = trace(scene, TracerSettings(max_depth=0, adaptive=0, offset_scale=0.0)).stats
    assert unshadowed.shadow_rays > 0
    assert np.all(clean[lit] > 0)


def test_facing_mirrors_lose_energy_at_the_depth_limit():
    # Two emissive mirrors face each other; a ray between them sees E * sum_k rho^k, k up to one
    # bounce past the depth (those rays see what shines, as Cycles' do after Max Bounces).
    rho, e = 0.8, 1.0
    mirror = Material(name="mirror", base_color=np.full(3, rho, np.float32), metallic=1.0,
                      roughness=0.0, emission=np.full(3, e, np.float32))
    a = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])  # faces +z
    b = quad([(-1, -1, 1), (-1, 1, 1), (1, 1, 1), (1, -1, 1)])  # faces -z
    cam = ortho_camera((0, 0, 0.5), (0, 0, -1), (0, 1, 0), 0.5, (2, 2))
    lost = []
    for depth in range(6):
        scene = build([(a, mirror), (b, mirror)], cam)
        image = trace(scene, TracerSettings(max_depth=depth, adaptive=0, min_weight=0.0)).image
        expected = e * sum(rho**k for k in range(depth + 2))
        assert image[0, 0, 0] == pytest.approx(expected, rel=1e-6)
        lost.append(e / (1 - rho) - image[0, 0, 0])
    np.testing.assert_allclose(lost, e * rho ** (np.arange(6) + 2) / (1 - rho), rtol=1e-5)


def test_weight_threshold_prunes_and_counts():
    image_full = trace(prism_scene(1.5), EXACT)
    pruned = trace(prism_scene(1.5), TracerSettings(max_depth=48, adaptive=0, min_weight=0.05))
    assert pruned.stats.pruned_branches > 0
    assert pruned.stats.secondary_rays < image_full.stats.secondary_rays
    # The branches cut carry less than min_weight each: the image barely moves.
    np.testing.assert_allclose(pruned.image, image_full.image, atol=0.01)


def test_auto_settings_trace_only_as_deep_as_needed():
    diffuse = build([(quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), Material(name="d", specular=0.0))])
    assert auto_settings(diffuse).max_depth == 0
    assert auto_settings(prism_scene(1.5)).max_depth > 2


def test_no_nan_with_degenerate_triangles_and_grazing_rays():
    plane = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    degenerate = np.array([[[0, 0, 0.5], [0, 0, 0.5], [0, 0, 0.5]], [[0, 0, 1], [1, 1, 1], [2, 2, 1]]])
    cam = ortho_camera((0, -3, 0.0), (0, 1, 0), (0, 0, 1), 2.0, (8, 8))  # grazing the plane
    scene = build([(plane, GLASS), (degenerate, GLASS)], cam, [point_light("P", (0, 0, 2), np.ones(3))],
                  world=(0.2, 0.3, 0.4))
    image = trace(scene, TracerSettings(max_depth=8)).image
    assert np.all(np.isfinite(image))


def test_emissive_surface_lights_a_diffuse_plane():
    # A 0.2 m emissive square 2 m above a white plane, facing down: irradiance below its centre is
    # L * integral of cos cos / r^2 over the square (midpoint rule on a 400 x 400 grid, exact to
    # 1e-6); the tracer's fixed 4 x 4 pattern per triangle must land within 0.2%.
    rho, radiance, side, height = 0.5, 10.0, 0.2, 2.0
    plane = quad([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)])
    h = side / 2
    lamp = quad([(-h, -h, height), (-h, h, height), (h, h, height), (h, -h, height)])
    cam = ortho_camera((0, 0, 1), (0, 0, -1), (0, 1, 0), 0.01, (2, 2))
    mat = Material(name="white", base_color=np.full(3, rho, np.float32), specular=0.0)
    scene = build([(plane, mat), (lamp, emitter(radiance))], cam)
    image = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    g = (np.arange(400) + 0.5) / 400 * side - h
    x, y = np.meshgrid(g, g)
    r2 = x * x + y * y + height**2
    irradiance = radiance * np.sum(height**2 / r2**2) * (side / 400) ** 2
    np.testing.assert_allclose(image[..., 0], rho / np.pi * irradiance, rtol=2e-3)


def test_an_emitter_touching_a_surface_lights_it_within_the_physical_bound():
    # A 1 m emissive wall standing on a white floor, its lowest samples 5 mm above it: no floor
    # point can receive more than the whole hemisphere's worth, pi L (radiance rho L). Each of
    # the emitter's samples stands for a disc of its share of the area (Wallace's approximation),
    # so a sample millimetres away does not count as a point light: 1 / d^2 made the floor by
    # the wall's foot hundreds of times too bright. Far away the disc is the point: the sum of
    # cos cos / d^2 over the samples, within 0.3% (d^2 = 6 m^2 against a / pi = 0.01 m^2).
    rho, radiance = 0.5, 10.0
    plane = quad([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)])
    mat = Material(name="white", base_color=np.full(3, rho, np.float32), specular=0.0)
    settings = TracerSettings(max_depth=0, adaptive=0)

    def scene_seen_by(camera, foot):
        wall = quad([(0, -0.5, foot), (0, 0.5, foot), (0, 0.5, foot + 1), (0, -0.5, foot + 1)])
        return build([(plane, mat), (wall, emitter(radiance))], camera)

    probe = scene_seen_by(ortho_camera((0.05, 0, 1), (0, 0, -1), (0, 1, 0), 0.08, (2, 2)), 0.0)
    foot = 0.005 - scene_emitters(probe, settings).area_points[:, 2].min()
    # The floor beside the wall's foot, 1 to 9 cm from it: the camera never sees the wall.
    near = trace(scene_seen_by(ortho_camera((0.05, 0, 1), (0, 0, -1), (0, 1, 0), 0.08, (32, 32)),
                               foot), settings).image
    assert near.max() <= rho * radiance * (1.0 + 1e-6)
    assert near.max() > 0.1 * rho * radiance  # lit: the wall is right there
    far_scene = scene_seen_by(ortho_camera((2.5, 0, 1), (0, 0, -1), (0, 1, 0), 0.2, (2, 2)), foot)
    far = trace(far_scene, settings).image
    points = scene_emitters(far_scene, settings).area_points  # 1 m^2 shared out equally
    for i, y in enumerate(np.array([0.05, -0.05])):
        for j, x in enumerate(2.5 + np.array([-0.05, 0.05])):
            d = points - np.array([x, y, 0.0])
            d2 = np.einsum("ij,ij->i", d, d)
            g = d[:, 2] * np.abs(d[:, 0]) / d2**2  # cos at the floor x cos at the wall / d^2
            expected = rho / np.pi * radiance * g.sum() / len(points)
            assert far[i, j, 0] == pytest.approx(expected, rel=3e-3)


def test_floor_by_a_mesh_lights_foot_takes_its_finer_samples(monkeypatch):
    # A 1 m x 0.5 m emissive wall of 8 x 8 quads (a mesh light of 128 triangles: 64 samples in
    # all, one per 0.09 m) standing 1 cm above a white floor; the floor 2 to 10 cm beside it.
    # Exact: rho / pi L integral of cos cos / d^2 over the wall (midpoint rule, 800 x 400).
    # Measured: within 7.1% everywhere with the finer samples, 41% with the coarse ones alone.
    from classic_bake.kernels.trace import tracer as tracer_module

    rho, radiance, foot, height = 0.5, 10.0, 0.01, 0.5
    plane = quad([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)])
    mat = Material(name="white", base_color=np.full(3, rho, np.float32), specular=0.0)
    ys, zs = np.linspace(-0.5, 0.5, 9), np.linspace(foot, foot + height, 9)
    wall = np.concatenate([quad([(0, ys[i], zs[j]), (0, ys[i + 1], zs[j]), (0, ys[i + 1], zs[j + 1]),
                                 (0, ys[i], zs[j + 1])]) for i in range(8) for j in range(8)])
    scene = build([(plane, mat), (wall, emitter(radiance))],
                  ortho_camera((0.06, 0, 1), (0, 0, -1), (0, 1, 0), 0.08, (8, 8)))
    centres = (np.arange(8) + 0.5) / 100 - 0.04  # the pixels' offsets from the view's centre, m
    y, z = np.meshgrid((np.arange(800) + 0.5) / 800 - 0.5, foot + (np.arange(400) + 0.5) / 400 * height)
    exact = np.array([[rho / np.pi * radiance * np.sum(x * z / (x * x + (y - v) ** 2 + z * z) ** 2)
                       * height / 320000 for x in 0.06 + centres] for v in centres[::-1]])
    settings = TracerSettings(max_depth=0, adaptive=0)
    fine = np.abs(trace(scene, settings).image[..., 0] / exact - 1.0).max()
    monkeypatch.setattr(tracer_module, "REFINE_REACH", 0.0)
    coarse = np.abs(trace(scene, settings).image[..., 0] / exact - 1.0).max()
    assert fine < 0.08 and coarse > 3.0 * fine


def sun(direction, irradiance):
    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    return Light(name="Sun", kind="SUN", position=np.zeros(3), direction=d,
                 axis_x=np.array([1.0, 0.0, 0.0]), axis_y=np.array([0.0, 1.0, 0.0]),
                 irradiance=np.full(3, irradiance))


def checker_floor(scale, camera):
    tex = Texture(kind="CHECKER", color1=np.array([0.8, 0.1, 0.1], np.float32),
                  color2=np.array([0.1, 0.7, 0.2], np.float32), scale=scale)
    mat = Material(name="checker", base_color=np.ones(3, np.float32), specular=0.0,
                   base_color_texture=tex)
    floor = quad([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)])
    return build([(floor, mat)], camera, [sun((0, 0, -1), 3.0)])


def test_texture_filter_averages_a_checker_finer_than_the_pixels():
    # Ortho pixels of 3/16 m aligned with checker squares of 3/32 m: every pixel holds 2 x 2
    # squares, so its box-filtered base colour is exactly the mean of the two colours.
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 3.0, (16, 16))
    scene = checker_floor(32.0 / 3.0, cam)
    mean = (np.array([0.8, 0.1, 0.1]) + np.array([0.1, 0.7, 0.2])) / 2
    filtered = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    np.testing.assert_allclose(filtered, np.broadcast_to(mean * 3.0 / np.pi, filtered.shape), rtol=1e-5)
    point = trace(scene, TracerSettings(max_depth=0, adaptive=0, texture_filter=1)).image
    # A point sample sees one colour or the other: red 0.8 or 0.1, never the mean 0.45.
    assert np.abs(point[..., 0] - mean[0] * 3.0 / np.pi).min() > 0.3


def oblique_checker():
    """A fine checker floor seen obliquely, squares shrinking to a fraction of a pixel far away,
    and its reference: 16 x 16 point samples a pixel (256 rays)."""
    cam = persp_camera((0, -6, 1.5), (0, 1, -0.6), (0, 0, 1), np.radians(60), (48, 32))
    scene = checker_floor(4.0, cam)
    reference = trace(scene, TracerSettings(max_depth=0, supersample=16, adaptive=0,
                                            texture_filter=1)).image
    return scene, reference


def test_texture_filter_matches_supersampling_in_perspective():
    # The filtered pixel centres land as close to 16 x 16 supersampling as 12 x 12 does (measured
    # 4e-4 and 8e-4); point-sampled centres alias (0.19).
    scene, reference = oblique_checker()
    filtered = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    point = trace(scene, TracerSettings(max_depth=0, adaptive=0, texture_filter=1)).image
    assert rel_mse(filtered, reference) < 1.5e-3
    assert rel_mse(point, reference) > 0.1


@pytest.mark.parametrize("size", [(64, 64), (61, 63)])
def test_texture_filter_averages_a_minified_image_like_supersampling(size):
    # An image of random texels, about 64 to the metre, on the floor seen obliquely: far away a
    # pixel covers many texels. Filtered pixel centres (the image's mip pyramid; an odd side's
    # levels share its texels out by area) against 16 x 16 point samples a pixel: 9.9e-4 and
    # 9.4e-4 (the 3 x 3 boxes read at their centres: 9.3e-3); point-sampled centres alias (0.15).
    rng = np.random.default_rng(4)
    pixels = np.ones((*size, 4), np.float32)
    pixels[..., :3] = rng.random((*size, 3), np.float32)
    image = Material(name="image", base_color=np.ones(3, np.float32), specular=0.0,
                     base_color_texture=Texture(kind="IMAGE", pixels=pixels))
    floor = quad([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)])  # UV: x, y in metres
    cam = persp_camera((0, -6, 1.5), (0, 1, -0.6), (0, 0, 1), np.radians(60), (48, 32))
    scene = build([(floor, image)], cam, [sun((0, 0, -1), 3.0)])
    reference = trace(scene, TracerSettings(max_depth=0, supersample=16, adaptive=0,
                                            texture_filter=1)).image
    filtered = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    point = trace(scene, TracerSettings(max_depth=0, adaptive=0, texture_filter=1)).image
    print(size, "filtered", rel_mse(filtered, reference), "point", rel_mse(point, reference))
    assert rel_mse(filtered, reference) < 2e-3
    assert rel_mse(point, reference) > 0.1


def test_supersampling_with_the_texture_filter_is_no_less_accurate_than_pixel_centres():
    # 2 x 2 filtered samples a pixel take ceil(3 / 2) = 2 x 2 boxes each. One box over a
    # half-pixel cell (the bounding box of its slanted image) blurred the checker: 2 x 2 samples
    # came out less accurate than the filtered pixel centres.
    scene, reference = oblique_checker()
    centres = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    quads = trace(scene, TracerSettings(max_depth=0, supersample=2, adaptive=0)).image
    assert rel_mse(quads, reference) < rel_mse(centres, reference)


def test_edge_sub_samples_share_out_an_area_lights_samples(monkeypatch):
    # Two halves of one grey (two objects: an edge down the middle) under a square area light of
    # 4 x 4 samples and nothing in between. Each edge pixel's 4 x 4 sub-samples take one light
    # sample each (weighted 16) instead of all 16: one shadow ray per sub-sample, and the pixel
    # still sums every light sample once. Against every sub-sample taking every light sample,
    # the pixel differs by 0.36% (sub-sample position and light sample now go together); its
    # centre sample alone by 0.06%.
    grey_a = Material(name="a", base_color=np.full(3, 0.5, np.float32), specular=0.0)
    grey_b = Material(name="b", base_color=np.full(3, 0.5, np.float32), specular=0.0)
    left = quad([(-1, -1, 0), (0, -1, 0), (0, 1, 0), (-1, 1, 0)])
    right = quad([(0, -1, 0), (1, -1, 0), (1, 1, 0), (0, 1, 0)])
    light = Light(name="Panel", kind="AREA", position=np.array([0.3, 0.1, 2.0]),
                  direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                  axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, 5.0), shape="SQUARE",
                  size_x=1.0, size_y=1.0)
    cam = ortho_camera((0, 0, 3), (0, 0, -1), (0, 1, 0), 1.6, (16, 16))
    scene = build([(left, grey_a), (right, grey_b)], cam, [light])
    monkeypatch.setattr(shadow_shafts, "SHAFT_WORTH", np.inf)  # every shadow ray cast
    settings = TracerSettings(max_depth=0, adaptive=0, area_samples=4)
    centres = trace(scene, settings)
    edges = trace(scene, TracerSettings(max_depth=0, adaptive=4, area_samples=4))
    count = edges.stats.edge_pixels
    assert count == 32  # the two columns along the middle
    assert edges.stats.shadow_rays == 256 * 16 + count * 16 * 1
    changed = np.abs(edges.image - centres.image).max(axis=2) > 0
    assert changed.sum() == count  # the edge pixels, resampled
    tracer = Tracer(scene, BVH.build(scene.triangles), settings)
    full = np.zeros((16, 16, 3))
    for ox, oy in stratified_offsets(4):  # every sub-sample against every light sample
        o, d = camera_rays(cam, 16, 16, offsets=(ox, oy))
        full += tracer.radiance(o.reshape(-1, 3), d.reshape(-1, 3)).reshape(16, 16, 3) / 16
    np.testing.assert_allclose(edges.image[changed], full[changed], rtol=5e-3)


@pytest.mark.parametrize("lobe_rays", [1, 8])
def test_a_rough_metal_reflects_its_surroundings(lobe_rays):
    """A rough gold plane (roughness 0.4) seen 60 degrees off its normal under a world of
    radiance 2 all round: the lobe's rays (or one mirror ray) carry its
    albedo, Schlick's Fresnel of the base colour with the grazing term averaged over the lobe
    (`specular_layer.schlick_grazing_curve`; it used to be black: only roughness below
    `mirror_roughness` made a metal reflect), times what Cycles' restored multiple scattering
    keeps of a coloured lobe, E + F_ms (1 - E) (`energy_compensation`)."""
    gold = np.array([0.9, 0.7, 0.4])
    metal = Material(name="gold", base_color=gold.astype(np.float32), metallic=1.0, roughness=0.4)
    t = np.radians(60.0)
    forward = np.array([0.0, np.sin(t), -np.cos(t)])
    cam = ortho_camera(-3.0 * forward, forward, (0, 0, 1), 0.4, (4, 4))
    scene = build([(quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]), metal)], cam,
                  world=(2.0, 2.0, 2.0))
    result = trace(scene, TracerSettings(max_depth=1, adaptive=0, lobe_rays=lobe_rays))
    image = result.image
    assert (result.stats.lobe_rays > 0) == (lobe_rays > 1)
    from classic_bake.kernels.shading.specular_layer import energy_compensation, lobe_albedo

    mu, rough = np.array([np.cos(t)]), np.array([0.4])
    grazing = schlick_grazing_curve(mu, 0.4)[0]
    kept = lobe_albedo(mu, rough)[0][0] * energy_compensation(mu, rough, gold[None])[0]
    expected = 2.0 * (gold + (1.0 - gold) * grazing) * kept
    # The tracer reads a table of 65 views: within 1e-3 of the integral.
    np.testing.assert_allclose(image, np.broadcast_to(expected, image.shape), atol=2e-3)


def _panel_over_chrome():
    """(a 1 m area lamp of radiance 5 at z = 2 facing down, a chrome material, a 10 m floor)."""
    lamp = Light(name="Panel", kind="AREA", position=np.array([0.0, 0.0, 2.0]),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, 5.0), size_x=1.0,
                 size_y=1.0)
    chrome = Material(name="chrome", base_color=np.full(3, 0.9, np.float32), metallic=1.0,
                      roughness=0.0)
    return lamp, chrome, quad([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)])


def test_mirrors_and_glass_show_area_lamps_the_camera_does_not():
    """A 1 m area lamp of radiance 5 hangs 2 m over a chrome floor, facing down, and an
    orthographic camera looks at the floor 30 degrees off vertical: the rays it reflects meet the
    lamp, which shows with Schlick's Fresnel of the chrome (Cycles' lamps are visible to glossy
    and transmission rays); the camera looking at the lamp itself sees the black world."""
    lamp, chrome, floor = _panel_over_chrome()
    t = np.radians(30.0)
    forward = np.array([0.0, np.sin(t), -np.cos(t)])
    # Aimed at the floor 1.15 m before the lamp's foot: the mirror rays rise to it at (0, 0, 2).
    target = np.array([0.0, -2.0 * np.tan(t), 0.0])
    cam = ortho_camera(target - 3.0 * forward, forward, (0, 0, 1), 0.2, (2, 2))
    scene = build([(floor, chrome)], cam, [lamp])
    image = trace(scene, TracerSettings(max_depth=1, adaptive=0)).image
    fresnel = 0.9 + 0.1 * (1.0 - np.cos(t)) ** 5
    np.testing.assert_allclose(image, 5.0 * fresnel, rtol=1e-6)
    up = ortho_camera((0.0, 0.0, 0.5), (0, 0, 1), (0, 1, 0), 0.2, (2, 2))
    looking_up = trace(build([(floor, chrome)], up, [lamp]), TracerSettings(max_depth=1, adaptive=0))
    assert looking_up.image.max() == 0.0


def test_a_lamp_seen_in_a_mirror_through_a_rough_lobe_is_not_a_hot_spot():
    """The path camera -> plate -> chrome floor -> area lamp: a black plate's specular layer
    sends its one ray along the mirror direction to the floor, whose mirror ray meets the lamp.
    Smooth, the plate shows the lamp (Fresnel of the layer and the chrome times L = 5); rough
    (0.5), its one ray stands for a lobe that Cycles blurs over the surface, and the lamp's
    sharp image through it would be a hot spot: rays past a rough lobe see no area lamp, as the
    lobe's own ray does not (the plate is above the lamp, which lights it not at all)."""
    lamp, chrome, floor = _panel_over_chrome()
    t = np.radians(30.0)
    down = np.array([0.0, np.sin(t), -np.cos(t)])  # meets the floor and rises to the lamp
    plate_at = np.array([0.0, -2.0 * np.tan(t), 0.0]) - 3.0 * down
    normal = down - np.array([0.0, 1.0, 0.0])  # turns the camera's +y ray into `down`
    normal /= np.linalg.norm(normal)
    a = np.array([1.0, 0.0, 0.0])
    b = np.cross(normal, a)
    plate = quad([plate_at + 0.2 * (sa * a + sb * b) for sa, sb in
                  ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    cam = ortho_camera(plate_at - 2.0 * np.array([0.0, 1.0, 0.0]), (0, 1, 0), (0, 0, 1), 0.05,
                       (2, 2))
    images = {}
    for roughness in (0.0, 0.5):
        layer = Material(name="layer", base_color=np.zeros(3, np.float32), specular=0.5,
                         roughness=roughness)
        scene = build([(floor, chrome), (plate, layer)], cam, [lamp])
        images[roughness] = trace(scene, TracerSettings(max_depth=2, adaptive=0)).image
    assert images[0.0].min() > 0.05  # the path exists: a smooth plate shows the lamp
    assert images[0.5].max() == 0.0


def test_two_lamps_shadow_rays_in_one_call_and_the_profile(monkeypatch):
    """Two point lamps low on either side; a wall beyond the view hides the right one from every
    pixel: each pixel is the left lamp's rho/pi E alone (all lamps' shadow rays share one BVH
    call, each lamp's answers go to its own hits). The profile names the phases."""
    rho, intensity, height = 0.5, 400.0, 1.0
    plane = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    wall = quad([(3, -5, 0), (3, 5, 0), (3, 5, 5), (3, -5, 5)])
    cam = ortho_camera((0, 0, 5), (0, 0, -1), (0, 1, 0), 3.0, (16, 16))
    lights = [point_light("L", (-6.0, 0.0, height), np.full(3, intensity)),
              point_light("R", (6.0, 0.0, height), np.full(3, intensity))]
    mat = Material(name="white", base_color=np.full(3, rho, np.float32), specular=0.0)
    scene = build([(plane, mat), (wall, mat)], cam, lights)
    monkeypatch.setattr(shadow_shafts, "SHAFT_WORTH", np.inf)  # every shadow ray cast
    result = trace(scene, TracerSettings(max_depth=0, adaptive=0))
    xs = -1.5 + (np.arange(16) + 0.5) / 16 * 3.0
    x, y = np.meshgrid(xs, xs[::-1])
    d2 = (x + 6.0) ** 2 + y**2 + height**2
    np.testing.assert_allclose(result.image[..., 0], rho / np.pi * intensity * height / d2**1.5,
                               rtol=1e-5)
    phases = result.stats.phases
    assert {"traversal", "shadow traversal", "surface", "light sampling"} <= set(phases["seconds"])
    assert "pixels depth 0" in phases["by_label"]
    assert result.stats.shadow_rays == 2 * 16 * 16


def test_a_mirror_direction_below_the_surface_bends_as_cycles_does():
    # A mirror whose shading normals lean 10 degrees away from a camera looking down at 16.7
    # degrees: reflected about them, the view would go under the surface. Cycles bends the normal
    # towards the geometric one until the reflection just leaves the surface (bump.valid_reflection),
    # so the mirror shows what lies along the surface (a green strip on the horizon), not what
    # the geometric mirror direction sees (a red panel 16.7 degrees up). A custom-normal mirror
    # cube's bevel showed Cycles' horizon there only so (relMSE 4.7e3 -> 5.0e-3).
    mirror = Material(name="mirror", base_color=np.ones(3, np.float32), metallic=1.0,
                      roughness=0.0, specular=0.0)
    floor = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])

    def panel(z0, z1, colour):
        tris = quad([(-6, -4, z0), (-6, -4, z1), (-6, 4, z1), (-6, 4, z0)])
        return tris, Material(name=str(colour), base_color=np.zeros(3, np.float32), specular=0.0,
                              emission=np.array(colour, np.float32))

    view = np.array([-np.cos(np.radians(16.7)), 0.0, -np.sin(np.radians(16.7))])
    cam = ortho_camera(-view * 3.0, view, (0, 0, 1), 0.1, (2, 2))
    scene = build([(floor, mirror), panel(1.2, 2.4, (1.0, 0.0, 0.0)),
                   panel(0.0, 0.4, (0.0, 1.0, 0.0))], cam)
    tilt = np.radians(10.0)
    normals = scene.normals.copy()
    normals[:2] = (-np.sin(tilt), 0.0, np.cos(tilt))  # the mirror's two triangles
    image = trace(replace(scene, normals=normals), TracerSettings(max_depth=1, adaptive=0)).image
    np.testing.assert_allclose(image.reshape(-1, 3), np.tile([0.0, 1.0, 0.0], (4, 1)), atol=1e-6)


def test_an_ior_below_one_reflects_as_its_inverse():
    # The specular layer's F0 = ((ior - 1) / (ior + 1))^2 is the same for ior and 1 / ior, in
    # Cycles' Principled BSDF and in the layer's albedo tables; the lamps' highlights took the
    # IOR clamped at 1 (no highlight) while the tables hid the base as for the inverse.
    plane = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    cam = persp_camera((0, -3, 2), (0, 1, -0.7), (0, 0, 1), np.radians(40), (16, 12))
    light = point_light("P", (0.0, 1.5, 1.5), np.full(3, 40.0))

    def image(ior):
        mat = Material(name="layer", base_color=np.full(3, 0.5, np.float32), roughness=0.4,
                       ior=ior)
        return trace(build([(plane, mat)], cam, [light]),
                     TracerSettings(max_depth=1, adaptive=0)).image

    below, above = image(1.0 / 1.8), image(1.8)
    np.testing.assert_allclose(below, above, rtol=1e-5, atol=1e-7)
    assert np.max(above - image(1.0 + 1e-6)) > 0.01  # the highlight is there to compare


def test_a_layer_takes_lobe_rays_where_its_reflection_outweighs_the_base():
    """A rough layer (roughness 0.5) seen 60 degrees off its normal under a uniform world: over a
    white base its reflection is a small part of every channel (one mirror ray will do), over a
    saturated red it is most of the green and blue (rays across the lobe); both show the same
    world-lit layer, and the same light whichever way it is drawn."""
    t = np.radians(60.0)
    forward = np.array([0.0, np.sin(t), -np.cos(t)])
    cam = ortho_camera(-3.0 * forward, forward, (0, 0, 1), 0.4, (4, 4))
    results = {}
    for name, base in (("white", (0.8, 0.8, 0.8)), ("red", (0.8, 0.01, 0.01))):
        mat = Material(name=name, base_color=np.array(base, np.float32), roughness=0.5)
        scene = build([(quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]), mat)], cam,
                      world=(1.0, 1.0, 1.0))
        results[name] = trace(scene, TracerSettings(max_depth=1, adaptive=0))
    assert results["white"].stats.lobe_rays == 0
    # 8 a pixel, less the few that fall below the surface
    assert 0.9 * 8 * 16 <= results["red"].stats.lobe_rays <= 8 * 16
    # No lamp and a world the diffuse base does not see: both show the layer's albedo times the
    # world's 1, whether one ray or eight carry it.
    np.testing.assert_allclose(results["red"].image, results["white"].image, rtol=1e-6)
    assert np.all(results["red"].image > 0.03)


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_camera_rays_end_at_the_far_clip_plane(kind):
    """A glowing wall 10 m down the view axis under a black world: a camera whose clip_end is 8 m
    sees nothing of it (Cycles' camera rays end at clip_end along the view axis,
    `camera_reach`), one of 12 m sees it at every pixel, corners included (their rays reach
    12 / cos along themselves)."""
    from scene_builder import grey

    from classic_bake.kernels.geometry.camera import camera_reach

    wall = quad([(-20, -20, -10), (20, -20, -10), (20, 20, -10), (-20, 20, -10)])
    camera = (persp_camera((0, 0, 0), (0, 0, -1), (0, 1, 0), 1.2) if kind == "PERSP"
              else ortho_camera((0, 0, 0), (0, 0, -1), (0, 1, 0), 4.0))
    for clip_end, seen in ((8.0, 0.0), (12.0, 2.0)):
        scene = build([(wall, grey(0.0, emission=2.0))],
                      camera=replace(camera, clip_end=clip_end))
        np.testing.assert_allclose(trace(scene, TracerSettings(max_depth=0)).image, seen)
    _, d = camera_rays(replace(camera, clip_end=12.0))
    reach = camera_reach(replace(camera, clip_end=12.0), d.reshape(-1, 3))
    np.testing.assert_allclose(reach * (d.reshape(-1, 3) @ [0.0, 0.0, -1.0]), 12.0)


def test_hot_pixels_are_isolated_peaks():
    """`hot_pixels`: a pixel 10x its surroundings and a pair of them are hot; a bright region
    is not, but for its convex corner (4 of 9 bright: traced again, which costs rays, not
    accuracy); nor is a faint peak under HOT_FLOOR."""
    from classic_bake.kernels.trace.tracer import HOT_FLOOR, hot_pixels

    image = np.full((12, 12, 3), 1.0)
    image[2, 2] = 10.0
    image[6, 6:8] = 10.0
    image[8:12, 0:4] = 10.0  # a region: its pixels' neighbourhoods are mostly as bright
    hot = hot_pixels(image)
    assert hot[2, 2] and hot[6, 6] and hot[6, 7]
    assert hot[8, 3] and hot.sum() == 4
    faint = np.full((5, 5, 3), 0.01 * HOT_FLOOR)
    faint[2, 2] = 0.5 * HOT_FLOOR
    assert not hot_pixels(faint).any()


def test_a_glossy_floors_highlight_of_an_area_lamp_is_the_lamps_not_its_samples():
    """A 1 m lamp of radiance 5 hangs 2 m over a polished metal floor (roughness 0.12), seen at
    37 degrees from the floor across its reflection. Its 4 x 4 samples, each its own point, drew
    a grid of spots that a row of pixels crosses between and on: widened by their cells' spread
    (`highlight_spread.sample_roughness`) they join into the lamp's reflection. Against the
    dense integral of the lamp (64 x 64 points, GGX unwidened) along the row: relMSE 0.071
    (0.21 with each sample a point), the row's light 84% of the integral's (60%); at 16 x 16
    samples 1.7e-4."""
    lamp, _, floor = _panel_over_chrome()
    metal = Material(name="metal", base_color=np.full(3, 0.9, np.float32), metallic=1.0,
                     roughness=0.12)
    forward = np.array([0.6, 0.0, -0.8])
    target = np.array([-1.5, 0.0, 0.0])  # the mirror ray from here rises to the lamp's centre
    cam = ortho_camera(target - 3.0 * forward, forward, (0, 0, 1), 2.4, (96, 1))
    scene = build([(floor, metal)], cam, [lamp])
    # The dense integral at each pixel's floor point: sum over points of f cos_i L cos_e da / d^2.
    o, d = (a.reshape(-1, 3) for a in camera_rays(cam, 96, 1))
    p = o - d * (o[:, 2:] / d[:, 2:])
    g = (np.arange(64) + 0.5) / 64 - 0.5
    up = np.tile([0.0, 0.0, 1.0], (len(p), 1))
    wo = np.tile(-forward, (len(p), 1))
    dense = np.zeros(len(p))
    for x, y in zip(*(a.ravel() for a in np.meshgrid(g, g)), strict=True):
        delta = np.array([x, y, 2.0]) - p
        dist = np.linalg.norm(delta, axis=1)
        wi = delta / dist[:, None]
        f_cos = ggx_highlight(up, wi, wo, np.full(len(p), 0.12), np.full((len(p), 3), 0.9))[:, 0]
        dense += f_cos * 5.0 * wi[:, 2] / dist ** 2 / 64 ** 2
    rows = {n: trace(scene, TracerSettings(max_depth=0, adaptive=0, area_samples=n)).image[0, :, 0]
            for n in (4, 16)}
    assert np.mean((rows[16] - dense) ** 2) / np.mean(dense ** 2) < 1e-3  # the integral is right
    assert np.mean((rows[4] - dense) ** 2) / np.mean(dense ** 2) < 0.1
    assert rows[4].sum() / dense.sum() > 0.8


def test_a_linked_lamps_highlights_are_the_same_on_the_objects_it_lights():
    """The polished floor above, cut in two objects through the highlight's middle (the row of
    pixels crosses the cut), under the lamp linked to one half only (light linking): that
    half's highlight is the unlinked lamp's, to rounding, the other half's none."""
    lamp, _, _ = _panel_over_chrome()
    metal = Material(name="metal", base_color=np.full(3, 0.9, np.float32), metallic=1.0,
                     roughness=0.12)
    lit = quad([(-5, -5, 0), (5, -5, 0), (5, 0, 0), (-5, 0, 0)])  # y < 0
    unlit = quad([(-5, 0, 0), (5, 0, 0), (5, 5, 0), (-5, 5, 0)])
    forward = np.array([0.6, 0.0, -0.8])
    cam = ortho_camera(np.array([-1.5, 0.0, 0.0]) - 3.0 * forward, forward, (0, 0, 1), 2.4,
                       (96, 1))  # its row runs along y
    settings = TracerSettings(max_depth=0, adaptive=0, area_samples=4)
    rows = {}
    for name, light in (("all", lamp), ("one", replace(lamp, receivers=np.array([True, False])))):
        rows[name] = trace(build([(lit, metal), (unlit, metal)], cam, [light]), settings).image[0]
    o, d = (a.reshape(-1, 3) for a in camera_rays(cam, 96, 1))
    y = (o - d * (o[:, 2:] / d[:, 2:]))[:, 1]
    assert rows["all"][y < 0].max() > 1.0 and rows["all"][y > 0].max() > 1.0
    np.testing.assert_allclose(rows["one"][y < 0], rows["all"][y < 0], rtol=1e-6)
    assert rows["one"][y > 0].max() == 0.0
