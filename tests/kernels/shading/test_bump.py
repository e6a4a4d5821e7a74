"""Bump mapping (kernels/bump.py) and the shading modes of the tracer: tangent frames, the matrix
M = [t; b; n], height slopes and normal maps against closed forms, Gouraud against Phong."""

import numpy as np
import pytest
from scene_builder import build, ortho_camera, quad

from classic_bake.kernels.geometry.scene import Light, Material, Texture
from classic_bake.kernels.shading import bump
from classic_bake.kernels.trace.emitters import point_light
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace


def random_triangles(n, seed=0):
    rng = np.random.default_rng(seed)
    tris = rng.normal(size=(n, 3, 3))
    uvs = rng.uniform(0, 1, (n, 3, 2))
    normals = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    return tris, uvs, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def test_uv_derivatives_reproduce_the_triangle_edges():
    tris, uvs, _ = random_triangles(200)
    dpdu, dpdv = bump.uv_derivatives(tris, uvs)
    for k in (1, 2):
        duv = uvs[:, k] - uvs[:, 0]
        np.testing.assert_allclose(dpdu * duv[:, :1] + dpdv * duv[:, 1:], tris[:, k] - tris[:, 0],
                                   atol=1e-8)


def test_tangent_frame_is_orthonormal_and_m_takes_it_to_the_axes():
    tris, uvs, n = random_triangles(200, seed=1)
    dpdu, dpdv = bump.uv_derivatives(tris, uvs)
    t, b, n = bump.tangent_frame(n, dpdu, dpdv)
    m = bump.frame_matrix(t, b, n)
    # The lecture's verification: M t = x, M b = y, M n = z.
    for vector, axis in ((t, 0), (b, 1), (n, 2)):
        np.testing.assert_allclose(np.einsum("nij,nj->ni", m, vector), np.eye(3)[axis][None].repeat(
            200, 0), atol=1e-12)
    # t follows dp/du; b = n x t, or its opposite where the UV map is mirrored, so that b always
    # runs along dp/dv.
    assert np.all(np.einsum("ij,ij->i", t, dpdu) > 0)
    assert np.all(np.einsum("ij,ij->i", b, dpdv) >= 0)
    mirrored = np.einsum("ij,ij->i", np.cross(n, t), dpdv) < 0
    assert 0 < mirrored.sum() < 200  # random UVs: both windings occur
    np.testing.assert_allclose(b[~mirrored], np.cross(n, t)[~mirrored], atol=1e-12)


def ramp(width=64, slope=1.0, axis=0):
    """A height image rising by `slope` per UV unit along u (axis 0) or v (axis 1), EXTEND wrap.
    Bilinear interpolation of texel centres on a line is the line: the slope is exact."""
    centres = (np.arange(width) + 0.5) / width
    h = slope * (centres[None, :] if axis == 0 else centres[::-1, None])  # row 0 is v near 1
    pixels = np.ones((width, width, 4), np.float32)
    pixels[..., :3] = np.broadcast_to(h[..., None], (width, width, 3))
    return Texture(kind="IMAGE", pixels=pixels, extension="EXTEND")


@pytest.mark.parametrize("axis", [0, 1])
def test_height_slope_of_a_ramp(axis):
    uv = np.random.default_rng(2).uniform(0.1, 0.9, (100, 2))
    slope = bump.height_slope(ramp(slope=0.7, axis=axis), uv)
    # float32 texels differenced 0.1 texel apart: a relative error of a few 1e-5 remains.
    np.testing.assert_allclose(slope[:, axis], 0.7, rtol=2e-4)
    np.testing.assert_allclose(slope[:, 1 - axis], 0.0, atol=2e-4)


@pytest.mark.parametrize("uv_scale", [1.0, 2.0, 0.5])
def test_a_height_ramp_tilts_the_normal_by_the_slope_times_the_distance(uv_scale):
    # Plane z = 0 with u = uv_scale * x, v = uv_scale * y: h rises by slope * uv_scale per metre
    # along x, so the displaced surface p + D h n has the normal (-D slope uv_scale, 0, 1).
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float)
    uvs = tri[:, :, :2] * uv_scale
    dpdu, dpdv = bump.uv_derivatives(tri, uvs)
    n = np.array([[0.0, 0.0, 1.0]])
    slope, distance = 0.7, 0.3
    got = bump.bumped_normals(n, dpdu, dpdv, np.array([[slope, 0.0]]), distance)
    expected = np.array([-distance * slope * uv_scale, 0.0, 1.0])
    np.testing.assert_allclose(got[0], expected / np.linalg.norm(expected), atol=1e-12)
    half = bump.bumped_normals(n, dpdu, dpdv, np.array([[slope, 0.0]]), distance, strength=0.0)
    np.testing.assert_allclose(half[0], n[0], atol=1e-12)  # strength 0: no bump


def test_normal_map_colours_are_tangent_frame_normals():
    tris, uvs, n = random_triangles(50, seed=3)
    dpdu, dpdv = bump.uv_derivatives(tris, uvs)
    t, b, n = bump.tangent_frame(n, dpdu, dpdv)
    flat = bump.normal_mapped(n, dpdu, dpdv, np.tile([0.5, 0.5, 1.0], (50, 1)))
    np.testing.assert_allclose(flat, n, atol=1e-12)  # (0, 0, 1): the normal itself
    theta = 0.4
    tilted = bump.normal_mapped(n, dpdu, dpdv, np.tile(
        [0.5 + 0.5 * np.sin(theta), 0.5, 0.5 + 0.5 * np.cos(theta)], (50, 1)))
    np.testing.assert_allclose(tilted, np.sin(theta) * t + np.cos(theta) * n, atol=1e-12)
    along_v = bump.normal_mapped(n, dpdu, dpdv, np.tile([0.5, 1.0, 0.5], (50, 1)))
    np.testing.assert_allclose(along_v, b, atol=1e-12)  # green is along v, mirrored or not


def test_extreme_heights_give_unit_normals_on_the_visible_side():
    tris, uvs, n = random_triangles(100, seed=4)
    dpdu, dpdv = bump.uv_derivatives(tris, uvs)
    slopes = np.random.default_rng(5).normal(size=(100, 2)) * 1e4
    got = bump.bumped_normals(n, dpdu, dpdv, slopes, distance=10.0)
    assert np.all(np.isfinite(got))
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-9)
    assert np.all(np.einsum("ij,ij->i", got, n) > 0)  # n* = (x, y, 1) never turns past 90 degrees


SUN_E = 2.0
RHO = 0.5


def sunlit_plane(texture=None, distance=0.0):
    plane = quad([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])
    mat = Material(name="bumpy", base_color=np.full(3, RHO, np.float32), specular=0.0,
                   height_texture=texture, bump_distance=distance)
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=np.array([0.0, 0.0, -1.0]),
                axis_x=np.array([1.0, 0.0, 0.0]), axis_y=np.array([0.0, 1.0, 0.0]),
                irradiance=np.full(3, SUN_E))
    # UV = xy: the camera sees u, v in [0.25, 0.75], inside the ramp's texels.
    cam = ortho_camera((0.5, 0.5, 3), (0, 0, -1), (0, 1, 0), 0.5, (8, 8))
    return build([(plane, mat)], cam, [sun])


def test_a_sunlit_ramp_is_lambert_with_the_tilted_normal():
    # UV = xy (scene_builder), so a ramp of slope s per UV unit and distance D tilts the normal by
    # atan(D s): the sun overhead gives rho / pi E cos(tilt) = rho / pi E / sqrt(1 + (D s)^2).
    slope, distance = 0.8, 1.5
    scene = sunlit_plane(ramp(slope=slope), distance)
    expected = RHO / np.pi * SUN_E / np.sqrt(1 + (distance * slope) ** 2)
    bumped = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    np.testing.assert_allclose(bumped, expected, rtol=2e-4)
    for mode in ("flat", "gouraud", "phong"):  # no bump: the flat plane's value
        plain = trace(scene, TracerSettings(max_depth=0, adaptive=0, shading=mode)).image
        np.testing.assert_allclose(plain, RHO / np.pi * SUN_E, rtol=1e-5)


@pytest.mark.parametrize("sun_side", [1.0, -1.0])
def test_a_low_sun_on_a_ramp_is_masked_by_the_relief(sun_side):
    """The ramp's normal tilted by d = atan(D s) towards -x, the sun 60 degrees from the zenith on
    either side: Lambert with the tilted normal times Cycles' bump shadowing term, the GGX masking
    G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 60)) of alpha^2 = tan^2(d) / 8 (`bump.bump_shadowing`),
    0.892 here. Turned from the sun (behind the tilted normal) it is dark either way."""
    slope, distance = 0.8, 1.5
    scene = sunlit_plane(ramp(slope=slope), distance)
    theta = np.radians(60.0)
    to_sun = np.array([sun_side * np.sin(theta), 0.0, np.cos(theta)])
    sun = scene.lights[0]
    from dataclasses import replace

    scene = replace(scene, lights=(replace(sun, direction=-to_sun),))
    tilted = np.array([-distance * slope, 0.0, 1.0]) / np.hypot(distance * slope, 1.0)
    alpha2 = (distance * slope) ** 2 / 8.0
    masking = 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * np.tan(theta) ** 2))
    expected = RHO / np.pi * SUN_E * max(tilted @ to_sun, 0.0) * masking
    got = bump.bump_shadowing(np.array([[0.0, 0.0, 1.0]]), tilted[None], to_sun[None])
    np.testing.assert_allclose(got, masking if tilted @ to_sun > 0.0 else 0.0, rtol=1e-12)
    image = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    np.testing.assert_allclose(image, expected, rtol=2e-4)


def test_bump_shadowing_leaves_untilted_normals_and_blocks_light_under_the_surface():
    up = np.array([[0.0, 0.0, 1.0]])
    low = np.array([[np.sin(1.4), 0.0, np.cos(1.4)]])
    np.testing.assert_array_equal(bump.bump_shadowing(up, up, low), 1.0)  # no relief: 1
    # A normal tilted towards +x sees a light just below the smooth surface's horizon (cos to
    # the tilted normal > 0): Cycles sends it nothing.
    tilted = np.array([[np.sin(0.5), 0.0, np.cos(0.5)]])
    below = np.array([[np.cos(0.1), 0.0, -np.sin(0.1)]])
    assert (tilted @ below[0])[0] > 0.0
    np.testing.assert_array_equal(bump.bump_shadowing(up, tilted, below), 0.0)


def test_bump_leaves_the_silhouette_alone():
    # The lecture: bump mapping changes the normals, never the outline. A bumpy square seen
    # against black: the same pixels are covered with and without the bump.
    noise = np.random.default_rng(6).uniform(0, 1, (32, 32))
    pixels = np.ones((32, 32, 4), np.float32)
    pixels[..., :3] = noise[..., None]
    scene = sunlit_plane(Texture(kind="IMAGE", pixels=pixels), distance=0.05)
    cam = ortho_camera((0, 0, 3), (0, 0.3, -1), (0, 1, 0), 3.0, (32, 32))
    scene = build([(scene.triangles.astype(float), scene.materials[1])], cam, list(scene.lights))
    bumped = trace(scene, TracerSettings(max_depth=0, adaptive=0)).image
    plain = trace(scene, TracerSettings(max_depth=0, adaptive=0, shading="phong")).image
    np.testing.assert_array_equal(bumped.max(axis=2) > 0, plain.max(axis=2) > 0)
    assert np.abs(bumped - plain).max() > 0.01  # while the shading inside does change


def test_gouraud_interpolates_the_corners_light_and_misses_a_peak_between_them():
    # One large triangle under a point light close above its middle. Phong: rho / pi I cos / d^2
    # at every pixel's point. Gouraud: the same formula at the three corners, interpolated with
    # the barycentrics, so the bright spot under the lamp is lost (the lecture's comparison).
    tri = np.array([[[-2.0, -2.0, 0.0], [2.0, -2.0, 0.0], [0.0, 2.0, 0.0]]])
    mat = Material(name="white", base_color=np.full(3, RHO, np.float32), specular=0.0)
    lamp = np.array([0.0, -0.5, 0.3])
    cam = ortho_camera((0, -0.5, 3), (0, 0, -1), (0, 1, 0), 0.5, (8, 8))
    scene = build([(tri[0][None], mat)], cam, [point_light("P", lamp, np.full(3, 10.0))])

    def irradiance(p):
        d = lamp - p
        dist = np.linalg.norm(d, axis=-1)
        return 10.0 * d[..., 2] / dist**3

    xs = -0.25 + (np.arange(8) + 0.5) / 8 * 0.5
    x, y = np.meshgrid(xs, -0.5 + xs[::-1])
    points = np.stack([x, y, np.zeros_like(x)], -1)
    phong = trace(scene, TracerSettings(max_depth=0, adaptive=0, shading="phong")).image[..., 0]
    np.testing.assert_allclose(phong, RHO / np.pi * irradiance(points), rtol=1e-5)
    # Barycentrics of the pixel points in the triangle, then the corners' values blended.
    a, b, c = tri[0]
    m = np.array([b - a, c - a])[:, :2].T
    uv = np.linalg.solve(m, (points[..., :2] - a[:2]).reshape(-1, 2).T).T
    weights = np.stack([1 - uv[:, 0] - uv[:, 1], uv[:, 0], uv[:, 1]], 1)
    corners = RHO / np.pi * irradiance(tri[0])
    gouraud = trace(scene, TracerSettings(max_depth=0, adaptive=0, shading="gouraud")).image[..., 0]
    np.testing.assert_allclose(gouraud.reshape(-1), weights @ corners, rtol=1e-5)
    assert gouraud.max() < phong.max() / 10  # the spot under the lamp is gone


def test_unknown_shading_mode_is_refused():
    with pytest.raises(ValueError, match="shading"):
        TracerSettings(shading="toon")


def test_valid_reflection_bends_normals_until_the_view_reflects_above_the_surface():
    rng = np.random.default_rng(7)
    ng = np.tile([0.0, 0.0, 1.0], (2000, 1))
    wo = rng.normal(size=(2000, 3))
    wo[:, 2] = np.abs(wo[:, 2]) * 0.3  # views from the front, many grazing
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    n = rng.normal(size=(2000, 3))
    n[:, 2] = np.abs(n[:, 2]) + 0.2
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    got = bump.valid_reflection(ng, wo, n)
    np.testing.assert_allclose(np.linalg.norm(got, axis=1), 1.0, atol=1e-9)
    reflect = 2 * np.einsum("ij,ij->i", got, wo)[:, None] * got - wo
    floor = np.minimum(bump.REFLECTION_FLOOR_SHARE * wo[:, 2], bump.REFLECTION_FLOOR)
    assert np.all(reflect[:, 2] >= floor - 1e-9)
    before = 2 * np.einsum("ij,ij->i", n, wo)[:, None] * n - wo
    kept = before[:, 2] >= floor
    assert 0 < kept.sum() < 2000
    np.testing.assert_array_equal(got[kept], n[kept])
    # The bent ones keep their azimuth (they turn towards ng in the plane of ng and n) and stop
    # at the floor itself, not beyond; none faces away from the viewer any more.
    bent = ~kept
    azimuth_turn = n[bent][:, 0] * got[bent][:, 1] - n[bent][:, 1] * got[bent][:, 0]
    np.testing.assert_allclose(azimuth_turn, 0.0, atol=1e-9)
    np.testing.assert_allclose(reflect[bent, 2], floor[bent], atol=1e-6)
    assert np.all(np.einsum("ij,ij->i", got, wo) > 0)


def test_a_bump_on_a_normal_map_follows_cycles_bump_node_on_the_mapped_normal():
    # A plane (dp/du = x, dp/dv = y), a normal map of one tilt N, a height h = k u under a Bump
    # node of distance D whose Normal is the map's. Cycles' bump node (svm_node_set_bump) with
    # that Normal: R_u = dp/dv x N, R_v = N x dp/du, det = dp/du . R_u = N_z, and
    # N' = normalize(|det| N - D (dh/du R_u + dh/dv R_v)) = normalize(N_z N - D k (N_z, 0, -N_x)).
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    corner_uvs = tri[:, :, :2].copy()
    tilt = np.array([0.3, -0.2, np.sqrt(1.0 - 0.13)])
    rgb = np.append(0.5 + 0.5 * tilt, 1.0).astype(np.float32)
    normal_map = Texture(kind="IMAGE", pixels=np.tile(rgb, (4, 4, 1)), interpolation="CLOSEST")
    k, distance, side = 0.6, 0.5, 64
    ramp = np.tile((np.arange(side) + 0.5) / side * k, (side, 1)).astype(np.float32)
    heights = Texture(kind="IMAGE", pixels=np.stack([ramp, ramp, ramp, np.ones_like(ramp)], -1),
                      extension="EXTEND")
    material = Material(name="chained", normal_texture=normal_map, height_texture=heights,
                        bump_distance=distance)
    ours = bump.perturb(material, np.array([[0.0, 0.0, 1.0]]), tri, corner_uvs,
                        np.array([[0.3, 0.3]]))
    expected = tilt[2] * tilt - distance * k * np.array([tilt[2], 0.0, -tilt[0]])
    np.testing.assert_allclose(ours[0], expected / np.linalg.norm(expected), atol=1e-5)


def test_normal_map_strength_scales_the_tangent_space_normal_as_cycles_does():
    """Cycles applies a Normal Map's strength s in tangent space: (s x, s y, 1 + min(s, 1)(z - 1))
    before the frame turns it to world space; 0 gives the surface normal, 1 the map."""
    from classic_bake.kernels.shading.bump import strengthened

    local = np.array([[0.6, -0.3, np.sqrt(1 - 0.45)]])
    np.testing.assert_array_equal(strengthened(local, 1.0), local)
    np.testing.assert_allclose(strengthened(local, 0.0), [[0.0, 0.0, 1.0]])
    np.testing.assert_allclose(strengthened(local, 2.0), [[1.2, -0.6, local[0, 2]]])
    half = strengthened(local, 0.5)
    np.testing.assert_allclose(half, [[0.3, -0.15, 1.0 + 0.5 * (local[0, 2] - 1.0)]])
    np.testing.assert_allclose(strengthened(local, -1.0), strengthened(local, 0.0))


def test_a_reliefs_share_of_a_uniform_surround_matches_monte_carlo():
    """`relief_sky_factor` against a Monte Carlo estimate of its integral (uniform directions
    on the smooth normal's hemisphere, 400k of them) at four tilts, within 1%; 1 untilted, and
    below the unshadowed (1 + cos d) / 2, which the shadowing term can only lower."""
    from classic_bake.kernels.shading.bump import bump_shadowing, relief_sky_factor

    rng = np.random.default_rng(3)
    w = rng.normal(size=(400_000, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w[:, 2] = np.abs(w[:, 2])  # uniform on the upper hemisphere: pdf 1 / (2 pi)
    smooth = np.broadcast_to([0.0, 0.0, 1.0], w.shape)
    for tilt in (0.0, 0.4, 0.8, 1.2):
        n = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
        bumped = np.broadcast_to(n, w.shape)
        estimate = 2.0 * np.mean(np.maximum(w @ n, 0.0) * bump_shadowing(smooth, bumped, w))
        factor = relief_sky_factor(smooth[:1], bumped[:1])[0]
        assert factor == pytest.approx(estimate, rel=0.01), tilt
        assert factor <= (1.0 + np.cos(tilt)) / 2.0 + 1e-12
    assert relief_sky_factor(smooth[:1], smooth[:1])[0] == 1.0
