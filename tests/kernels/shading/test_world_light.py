"""The world as a light at infinity (kernels/world_light.py): each patch's share of open sky against
closed forms, and the radiosity solve that carries pi L_w s as a source."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, floor_quad, grey, inward_box, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.form_factors.closed_forms import parallel_rectangles
from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon
from classic_bake.kernels.radiosity.lightmap import bake_steps
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity
from classic_bake.kernels.shading.world_light import sky_factors, world_irradiance

FAST = dict(samples_per_side=2, visibility_samples_per_side=2, hemicube_resolution=16)
WORLD = (0.2, 0.5, 1.0)  # radiance W/(m^2 sr), distinct per channel


def _occluded(triangles):
    return BVH.build(np.asarray(triangles, np.float32)).occluded


def _plate_over_floor():
    """A unit floor facing up and a black unit plate 1 m above it facing down."""
    plate = quad([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]])
    return floor_quad(), plate


def test_an_open_plane_sees_the_whole_sky_and_a_closed_box_none():
    floor = floor_quad()
    normals = np.tile([0.0, 0.0, 1.0], (2, 1))
    rng = np.random.default_rng(0)
    s = sky_factors(floor, normals, np.arange(2), _occluded(floor), 1.0, 64, rng)
    np.testing.assert_array_equal(s, 1.0)
    box = inward_box()
    n = np.cross(box[:, 1] - box[:, 0], box[:, 2] - box[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    np.testing.assert_array_equal(sky_factors(box, n, np.arange(12), _occluded(box), 1.0, 64, rng),
                                  0.0)


def test_sky_share_under_a_plate_is_one_minus_the_form_factor():
    """Each floor patch's s against 1 - F(centroid -> plate) (exact point-to-polygon factor), and
    the floor's area mean against 1 - F12 of directly opposed unit squares 1 m apart, 0.19982
    (form_factors.json, C-11). 1024 rays per patch: s to about 0.01."""
    floor, plate = _plate_over_floor()
    scene = build([(floor, grey(0.5)), (plate, grey(0.0))])
    patches = patching.make_patches(scene, 0.2)
    on_floor = patches.normals[:, 2] > 0.5
    s = sky_factors(patches.corners[on_floor], patches.normals[on_floor],
                    patches.parent[on_floor], _occluded(scene.triangles), 1.0, 1024,
                    np.random.default_rng(1))
    centroids = patches.corners[on_floor].mean(axis=1)
    up = np.tile([0.0, 0.0, 1.0], (len(centroids), 1))
    square = np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float)  # CCW facing down
    exact = 1.0 - point_to_polygon(centroids, up, square[None], np.array([[0, 0, -1.0]]))
    np.testing.assert_allclose(s, exact, atol=0.03)
    areas = patches.areas[on_floor]
    mean = float((s * areas).sum() / areas.sum())
    np.testing.assert_allclose(mean, 1.0 - parallel_rectangles(1.0, 1.0, 1.0), atol=0.005)


def test_second_sky_casts_stay_within_their_budget():
    """The floor patches under the plate see the sky in part, so each asks for a second cast of
    4x or 16x its rays (`world_irradiance`). Under a budget they cast 4x only, as many of them
    as it pays for, the noisiest (least open) first; without one, all of them."""
    floor, plate = _plate_over_floor()
    scene = build([(floor, grey(0.5)), (plate, grey(0.0))])
    patches = patching.make_patches(scene, 0.1)
    up = patches.normals[:, 2] > 0.5
    occluded = _occluded(scene.triangles)
    cast = []

    def counted(origins, dirs, *args, **kwargs):
        cast.append(len(origins))
        return occluded(origins, dirs, *args, **kwargs)

    def rays(budget):
        cast.clear()
        world_irradiance(np.array(WORLD), patches.corners[up], patches.normals[up],
                         patches.parent[up], counted, 1.0, 16, np.random.default_rng(2),
                         budget=budget)
        return sum(cast) - 16 * int(up.sum())  # past the first cast's 16 rays each

    free = rays(None)
    assert free > 64 * 10  # hundreds of patches cast again
    assert rays(64 * 10) == 64 * 10  # ten patches at 4 x 16 rays


def test_a_face_lying_on_another_sees_no_sky():
    """A unit box resting on a 3 m floor, its base in the floor's plane: the base (facing down,
    flat on the floor) and the floor under the box see no sky, as Cycles' rays, which start on
    the surface, meet the other face at once; the floor's far corners see nearly all of it, and
    the box's top all of it (lifted in front of the base, its rays saw the whole sky below)."""
    from classic_bake.kernels.geometry.scene import geometric_normals

    floor = quad([[-1, -1, 0], [2, -1, 0], [2, 2, 0], [-1, 2, 0]])
    box = inward_box()[:, ::-1]  # outward faces; the base at z = 0 faces down
    scene = build([(floor, grey(0.5)), (box, grey(0.5))])
    patches = patching.make_patches(scene, 0.25)
    s = sky_factors(patches.corners, patches.normals, patches.parent,
                    _occluded(scene.triangles), 3.0, 256, np.random.default_rng(2))
    centre = patches.corners.mean(axis=1)
    normal_z = patches.normals[:, 2]
    base = normal_z < -0.5
    corners_xy = patches.corners[:, :, :2]
    inside = np.all((corners_xy >= 0.0) & (corners_xy <= 1.0), axis=(1, 2))  # wholly under it
    under = (normal_z > 0.5) & (centre[:, 2] < 0.5) & inside
    top = (normal_z > 0.5) & (centre[:, 2] > 0.5)
    assert base.sum() > 0 and under.sum() > 0
    np.testing.assert_array_equal(s[base], 0.0)
    np.testing.assert_array_equal(s[under], 0.0)
    # Started behind the top, a grazing ray from within a few offsets of its edge leaves through
    # the side face (1 ray in 256 at one patch here): a bias of the order offset / patch size.
    np.testing.assert_allclose(s[top], 1.0, atol=0.01)
    far = (normal_z > 0.5) & (np.linalg.norm(centre[:, :2] - 0.5, axis=1) > 1.8)
    assert far.sum() > 0 and s[far].min() > 0.9
    assert geometric_normals(scene.triangles[patches.parent[base]])[:, 2].max() < -0.99


def test_no_rays_for_a_black_world_or_none_asked():
    floor = floor_quad()
    normals = np.tile([0.0, 0.0, 1.0], (2, 1))

    def refuse(*args):
        raise AssertionError("no ray may be cast")

    rng = np.random.default_rng(0)
    parents = np.arange(2)
    np.testing.assert_array_equal(world_irradiance(np.zeros(3), floor, normals, parents, refuse,
                                                   1.0, 64, rng), 0.0)
    np.testing.assert_array_equal(world_irradiance(np.array(WORLD), floor, normals, parents,
                                                   refuse, 1.0, 0, rng), 0.0)


@pytest.mark.parametrize("solver", ["gauss_seidel", "progressive", "hierarchical"])
def test_the_solve_carries_the_world_light_onto_an_open_floor(solver):
    """A grey floor under a black plate, lit by the world alone: every floor patch's B is
    rho pi L_w s, its mean rho pi L_w (1 - F12); the plate, black, sends nothing back. With
    world_rays 0 the floor stays black."""
    floor, plate = _plate_over_floor()
    scene = build([(floor, grey(0.5)), (plate, grey(0.0))], world=WORLD)
    settings = RadiositySettings(solver=solver, patch_budget=60, refine_levels=0,
                                 final_gather=False, world_rays=256, **FAST)
    result = solve_radiosity(scene, settings)
    on_floor = result.patches.normals[:, 2] > 0.5
    areas = result.patches.areas[on_floor]
    mean = (result.radiosity[on_floor] * areas[:, None]).sum(axis=0) / areas.sum()
    expected = 0.5 * np.pi * np.array(WORLD) * (1.0 - parallel_rectangles(1.0, 1.0, 1.0))
    np.testing.assert_allclose(mean, expected, rtol=0.01)
    dark = solve_radiosity(scene, RadiositySettings(solver=solver, patch_budget=60,
                                                    refine_levels=0, final_gather=False,
                                                    world_rays=0, **FAST))
    np.testing.assert_array_equal(dark.radiosity, 0.0)


def test_a_closed_room_is_not_lit_by_the_world_outside():
    """Furnace box: B = E / (1 - rho) with or without a bright world (its every ray is blocked)."""
    scene = build([(inward_box(), grey(0.5, emission=1.0))], world=(5.0, 5.0, 5.0))
    result = solve_radiosity(scene, RadiositySettings(patch_budget=40, refine_levels=0, **FAST))
    np.testing.assert_allclose(result.radiosity, np.pi / 0.5, rtol=0.01)


def test_the_gather_reads_the_world_light_at_every_texel():
    """The final gather counts the world's light as indirect, interpolated from the patches: an
    open floor's lightmap (no lamp, no plate) is rho L_w everywhere, B / pi."""
    floor = floor_quad()
    scene = build([(floor, grey(0.5))], world=WORLD)
    scene = replace(scene, lightmap_uv=scene.uv.copy(),
                    objects=[replace(o, has_lightmap_uv=True) for o in scene.objects])
    result = solve_radiosity(scene, RadiositySettings(patch_budget=16, **FAST))
    bakes = drain(bake_steps(scene, result, [0], {0: 8}, 1))
    texels = bakes[0].lightmap[bakes[0].lightmap_mask]
    np.testing.assert_allclose(texels, np.broadcast_to(0.5 * np.array(WORLD), texels.shape),
                               rtol=1e-3)


def test_equirectangular_directions_land_where_cycles_reads_them():
    """Cycles' direction_to_equirectangular: +x at the image's centre, +y a quarter to the left,
    -y a quarter to the right, +z along the top row, -z along the bottom."""
    from classic_bake.kernels.shading.world_light import equirect_uv

    dirs = np.array([[1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [1, 0, 1]], float)
    uv = equirect_uv(dirs)
    np.testing.assert_allclose(uv[:3], [[0.5, 0.5], [0.25, 0.5], [0.75, 0.5]], atol=1e-12)
    np.testing.assert_allclose(uv[3:5, 1], [1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(uv[5], [0.5, 0.75], atol=1e-12)  # 45 degrees up: 3/4 of the way


def _sky_map(upper, lower, width=64, height=32):
    """An equirectangular Texture, `upper` above the horizon and `lower` below."""
    from classic_bake.kernels.geometry.scene import Texture

    pixels = np.ones((height, width, 4), np.float32)
    pixels[: height // 2, :, :3] = upper
    pixels[height // 2:, :, :3] = lower
    return Texture(kind="IMAGE", pixels=pixels, extension="REPEAT")


def test_a_mapped_world_lights_a_floor_with_its_upper_half_only():
    """Under a sky of radiance 2 above the horizon and 0 below (mean 1 over the sphere), an open
    floor receives pi x 2 and reflects rho x 2 (B / pi): the uniform mean would give half. A plate
    facing down receives only what the map's bilinear filter spreads below the horizon row."""
    from dataclasses import replace

    floor = floor_quad()
    under = quad([[0, 0, -1], [0, 1, -1], [1, 1, -1], [1, 0, -1]])  # facing down, 1 m below
    scene = build([(floor, grey(0.5)), (under, grey(0.5))], world=(1.0, 1.0, 1.0))
    scene = replace(scene, world_texture=_sky_map(2.0, 0.0))
    result = solve_radiosity(scene, RadiositySettings(patch_budget=16, final_gather=False,
                                                      world_rays=256, **FAST))
    # The floor's and the plate's own patches (the solve adds turned-over copies of both sheets,
    # `radiosity/sheets.py`: the plate's back faces up into the sky around the floor).
    up, down = result.patches.parent < 2, (result.patches.parent >= 2) & (
        result.patches.parent < 4)
    np.testing.assert_allclose(result.radiosity[up], 0.5 * np.pi * 2.0, rtol=0.02)
    assert result.radiosity[down].max() < 0.01 * result.radiosity[up].min()


def _sunny_map(height=64, width=128, sky=0.2, sun=500.0, row=16, col=40):
    """An equirectangular map of a uniform sky and a 2 x 2-texel sun at (row, col)."""
    from classic_bake.kernels.geometry.scene import Texture

    pixels = np.ones((height, width, 4), np.float32)
    pixels[..., :3] = sky
    pixels[row:row + 2, col:col + 2, :3] = sun
    return Texture(kind="IMAGE", pixels=pixels, extension="REPEAT")


def test_a_maps_sun_becomes_a_sun_lamp_and_leaves_the_map():
    """The 2 x 2 sun of a sunny map: one SUN lamp from the texels' mean direction carrying their
    sum L dOmega, the texels zeroed in the map left for the sky rays; turned by a Mapping node,
    the lamp turns back with it; a map with no texel SUN_CONTRAST times its mean has no sun."""
    from classic_bake.kernels.shading.world_light import equirect_uv, extract_suns, texel_directions

    texture = _sunny_map()
    dirs, omega = texel_directions(64, 128)
    spot = (slice(16, 18), slice(40, 42))
    expected = (omega[spot] * 500.0).sum()
    mean_dir = (dirs[spot] * omega[spot][..., None]).sum(axis=(0, 1))
    mean_dir /= np.linalg.norm(mean_dir)
    suns, residual = extract_suns(texture)
    assert len(suns) == 1 and suns[0].kind == "SUN"
    np.testing.assert_allclose(suns[0].irradiance, expected, rtol=1e-6)
    np.testing.assert_allclose(-suns[0].direction, mean_dir, atol=1e-9)
    np.testing.assert_array_equal(residual.pixels[spot][..., :3], 0.0)
    np.testing.assert_array_equal(residual.pixels[20:, :, :3], np.float32(0.2))
    # Read back through the map, the sun lies where its texels meet (u = 41/128, v = 1 - 17/64).
    np.testing.assert_allclose(equirect_uv(-suns[0].direction[None])[0], [41 / 128, 1 - 17 / 64],
                               atol=0.5 / 128)
    # A map read along A d (a quarter turn about z): the sun's world direction is A^-1 m.
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    turned, _ = extract_suns(texture, np.hstack([turn, np.zeros((3, 1))]))
    np.testing.assert_allclose(turn @ -turned[0].direction, mean_dir, atol=1e-9)
    none, same = extract_suns(_sunny_map(sun=0.5))
    assert none == () and same.pixels is not None


def test_a_sunny_map_lights_the_floor_with_a_hard_shadow():
    """A floor with a plate 0.5 m over part of it under the sunny map, no lamp: the sun taken
    from the map shades the floor like a sun lamp of the same irradiance, its shadow sharp, the
    sky (the rest of the map) on top: floor patches in the open against pi-free sums
    E_sun cos + pi 0.2 s (s their sky share), within 2%."""
    from dataclasses import replace

    from classic_bake.kernels.radiosity.sources import with_world_suns

    floor = quad([[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]])
    scene = build([(floor, grey(0.5))], world=(0.2, 0.2, 0.2))
    scene = replace(scene, world_texture=_sunny_map())
    lit = with_world_suns(scene)
    assert len(lit.lights) == 1
    sun = lit.lights[0]
    result = solve_radiosity(scene, RadiositySettings(patch_budget=16, final_gather=False,
                                                      world_rays=256, **FAST))
    assert result.stats["world"] == {"rays_per_patch": 256, "map_suns": 1}  # for metrics.json
    cos = max(float(-sun.direction[2]), 0.0)
    expected = 0.5 * (sun.irradiance * cos + np.pi * 0.2)  # an open floor: s = 1
    np.testing.assert_allclose(result.radiosity, np.broadcast_to(expected, result.radiosity.shape),
                               rtol=0.02)


def test_the_back_of_a_sheet_is_lit_by_the_world_too():
    """A sheet facing down (rho 0.5) under a uniform world, seen from above: the camera sees its
    back, open to the whole sky, which the back's own sky rays find (B / pi = rho L_w on every
    pixel, to the 256 rays' noise); its front, facing the empty space below, gets the world as
    well, and with world_rays 0 the back is black."""
    from scene_builder import ortho_camera

    from classic_bake.kernels.radiosity.view import render_steps

    sheet = quad([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]])  # facing -z
    above = ortho_camera([0.5, 0.5, 3.0], [0, 0, -1], [0, 1, 0], 0.8, (8, 8))
    scene = build([(sheet, grey(0.5))], camera=above, world=WORLD)
    for rays, expected in ((256, 0.5 * np.array(WORLD)), (0, np.zeros(3))):
        result = solve_radiosity(scene, RadiositySettings(patch_budget=8, world_rays=rays, **FAST))
        image = drain(render_steps(scene, result))
        np.testing.assert_allclose(image.reshape(-1, 3), np.broadcast_to(expected, (64, 3)),
                                   atol=1e-9, rtol=0.01)


@pytest.mark.parametrize("rays", [16, 64])
def test_the_sky_rays_stay_within_their_memory_estimate(rays):
    """The radiosity memory estimate counts the sky rays' chunk (`sky_ray_bytes`): tracemalloc's
    peak over `world_irradiance` of 11k patches stays under it (measured 124 and 175 MB against
    138 and 201 MB)."""
    import tracemalloc

    from scene_builder import tessellated_box

    from classic_bake.kernels.shading.world_light import sky_ray_bytes

    scene = build([(tessellated_box(8, 1.0), grey(0.5)), (floor_quad(lo=-3.0, hi=4.0), grey(0.5))])
    patches = patching.make_patches(scene, 0.1)
    occluded = _occluded(scene.triangles)
    tracemalloc.start()
    try:
        world_irradiance(np.ones(3), patches.corners, patches.normals, patches.parent, occluded,
                         7.0, rays, np.random.default_rng(0))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= sky_ray_bytes(len(patches), rays)


def test_sky_through_an_opening_gets_the_rays_it_needs():
    """A closed unit room with a 0.5 m square opening in its ceiling: each floor patch sees the
    sky only through it, s = the exact point-to-polygon factor of the opening (3-7% of the view;
    nothing in between). 64 rays find it a few times a patch (rms 28% off exact); the patches
    whose first rays saw it in part are cast again with up to WORLD_MAX_RAYS: rms 4.4%."""
    from classic_bake.kernels.radiosity.form_factors.sampling import sample_patches
    from classic_bake.kernels.shading.world_light import _world_estimate

    lo, hi = 0.25, 0.75
    ceiling = np.concatenate([  # four quads around the opening, facing down
        quad([[0, 0, 1], [0, lo, 1], [1, lo, 1], [1, 0, 1]]),
        quad([[0, hi, 1], [0, 1, 1], [1, 1, 1], [1, hi, 1]]),
        quad([[0, lo, 1], [0, hi, 1], [lo, hi, 1], [lo, lo, 1]]),
        quad([[hi, lo, 1], [hi, hi, 1], [1, hi, 1], [1, lo, 1]])])
    walls = inward_box()
    walls = walls[geometric_z(walls) > -0.5]  # the box without its own ceiling
    scene = build([(walls, grey(0.5)), (ceiling, grey(0.5))])
    patches = patching.make_patches(scene, 0.1)
    floor = np.flatnonzero((patches.normals[:, 2] > 0.5)
                           & (patches.corners[:, :, 2].max(axis=1) < 0.01))
    corners, normals, parents = (patches.corners[floor], patches.normals[floor],
                                 patches.parent[floor])
    points, weights = sample_patches(corners, 4, "midpoint")
    opening = np.array([[lo, lo, 1], [lo, hi, 1], [hi, hi, 1], [hi, lo, 1]], float)  # faces down
    f = point_to_polygon(points.reshape(-1, 3), np.tile([0.0, 0.0, 1.0], (points.size // 3, 1)),
                         opening[None], np.array([[0, 0, -1.0]])).reshape(weights.shape)
    exact = (f * weights).sum(axis=1) / weights.sum(axis=1)
    occluded = _occluded(scene.triangles)
    world = np.array(WORLD)
    s = world_irradiance(world, corners, normals, parents, occluded, 1.0, 64,
                         np.random.default_rng(3))[:, 2] / (np.pi * world[2])
    first = _world_estimate(world, corners, normals, parents, occluded, 1.0, 64,
                            np.random.default_rng(3))[1]
    assert 0.03 < exact.min() and exact.max() < 0.08

    def rms(v):
        return float(np.sqrt(np.mean((v / exact - 1.0) ** 2)))

    assert rms(s) < 0.08 and rms(s) < 0.3 * rms(first)  # measured 0.044 and 0.28


def geometric_z(triangles):
    e1, e2 = triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    n = np.cross(e1, e2)
    return n[:, 2] / np.linalg.norm(n, axis=1)


def _banded_map(height=64, width=128):
    """An equirectangular Texture of 8 bands of longitude, radiance 0.1 and 2.0 in turn, and
    1.0 below the horizon: detail a patch's few rays sample unevenly."""
    from classic_bake.kernels.geometry.scene import Texture

    pixels = np.ones((height, width, 4), np.float32)
    bands = (np.arange(width) * 8 // width) % 2 == 0
    pixels[: height // 2, :, :3] = np.where(bands, 2.0, 0.1)[None, :, None]
    return Texture(kind="IMAGE", pixels=pixels, extension="REPEAT")


def test_open_patches_under_a_map_get_its_irradiance_without_noise():
    """Under a banded map, the floor patches that see the whole sky take the map's open
    irradiance E(n) (`MappedWorld.irradiance`, tabulated) exactly the same, and E(n) within 0.5%
    of a fine quadrature of the map (the map along 4 x 4 rays alone spreads them by 21% rms);
    the patches under a plate keep E(n) less what their blocked rays would have brought: against
    1024-ray estimates, within 3% of E on average and 15% at most (the rays' noise)."""
    from classic_bake.kernels.shading.world_light import (
        MappedWorld,
        texel_directions,
        world_radiance,
    )

    shaded = floor_quad()                          # under the plate, which hides part of its sky
    plate = quad([[0, 0, 0.5], [0, 1, 0.5], [1, 1, 0.5], [1, 0, 0.5]])
    open_floor = floor_quad(z=2.0, lo=3.0, hi=5.0)  # above everything else: the whole sky
    scene = build([(shaded, grey(0.5)), (plate, grey(0.0)), (open_floor, grey(0.5))],
                  world=(1.0, 1.0, 1.0))
    scene = replace(scene, world_texture=_banded_map())
    patches = patching.make_patches(scene, 0.25)
    on_floor = np.flatnonzero(patches.normals[:, 2] > 0.5)
    args = (patches.corners[on_floor], patches.normals[on_floor], patches.parent[on_floor],
            _occluded(scene.triangles), 5.0)
    world = MappedWorld(scene)
    rng = np.random.default_rng(5)
    e = world_irradiance(world, *args, 16, rng)
    open_sky = patches.corners[on_floor, 0, 2] > 1.0
    assert open_sky.sum() > 50 and (~open_sky).sum() > 10
    dirs, omega = texel_directions(256, 512)
    power = world_radiance(scene, dirs.reshape(-1, 3)) * omega.reshape(-1, 1)
    exact = (np.maximum(dirs.reshape(-1, 3)[:, 2], 0.0)[:, None] * power).sum(axis=0)
    np.testing.assert_allclose(e[open_sky], np.tile(exact, (open_sky.sum(), 1)), rtol=5e-3)
    plain = world_irradiance(lambda d: world_radiance(scene, d), *args, 16, rng)
    assert plain[open_sky, 0].std() > 0.05 * exact[0]
    fine = world_irradiance(world, *[a[~open_sky] for a in args[:3]], *args[3:], 1024, rng)
    under = patches.corners[on_floor][~open_sky].mean(axis=1)
    hidden = (under[:, 0] > 0.2) & (under[:, 0] < 0.8) & (under[:, 1] > 0.2) & (under[:, 1] < 0.8)
    assert (fine[hidden, 0] < 0.7 * exact[0]).all()  # the plate hides much of their sky
    miss = np.abs(e[~open_sky] - fine)[:, 0] / exact[0]
    print(f"shaded patches: mean miss {miss.mean():.4f}, largest {miss.max():.4f}")
    assert miss.mean() < 0.03 and miss.max() < 0.15
