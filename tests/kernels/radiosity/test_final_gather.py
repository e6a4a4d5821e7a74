"""The final gather: exact direct light from emissive triangles at receivers, the visibility
estimator in a penumbra, enclosure probes, and what it adds to a coarse patch solution."""

from __future__ import annotations

import numpy as np
import pytest
from scene_builder import build, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.coincident import CoincidentFaces
from classic_bake.kernels.geometry.scene import Material, geometric_normals
from classic_bake.kernels.radiosity import emitters as em
from classic_bake.kernels.radiosity import final_gather as fg
from classic_bake.kernels.radiosity.settings import FinalGatherSettings, RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity


def grey(rho, emission=0.0, name="grey"):
    """Lambertian (Specular IOR Level 0: no specular layer over the base)."""
    return Material(name=name, base_color=np.full(3, rho, np.float32), specular=0.0,
                    emission=np.full(3, emission, np.float32))


def square(z, half, up, cx=0.0, cy=0.0):
    """Two triangles of an axis-aligned square at height z, facing +z (up) or -z."""
    c = [[cx - half, cy - half, z], [cx + half, cy - half, z], [cx + half, cy + half, z],
         [cx - half, cy + half, z]]
    return quad(c if up else c[::-1])


def corner_factor(a, b, c):
    """Differential area to a parallel a x b rectangle at distance c, below one of its corners
    (Howell's catalogue, C-11)."""
    x, y = a / c, b / c
    return (x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
            + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))) / (2 * np.pi)


def gather_inputs(scene, rays=16):
    bvh = BVH.build(scene.triangles)
    emitters = em.emitters_of(scene, FinalGatherSettings(emitter_rays=rays))

    def occluded(o, d, t0, t1):
        return bvh.occluded(o, d, t0, t1)

    return bvh, emitters, occluded


def test_an_unhidden_emitter_gives_the_exact_factor():
    """Under the centre of a 1 x 1 emitter at height 0.5 (radiance 2), nothing in between: the
    estimator's visible share is exactly 1, so H = pi L F with F the closed form."""
    scene = build([(square(0.5, 0.5, up=False), grey(0.0, emission=2.0, name="lamp")),
                   (square(0.0, 2.0, up=True), grey(0.5))])
    _, emitters, occluded = gather_inputs(scene)
    assert len(emitters.triangles) == 2
    points = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.0], [1.5, 0.0, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (3, 1))
    h = em.emitter_irradiance(emitters, points, normals, occluded, 1e-6, np.random.default_rng(0))
    centre = 4 * corner_factor(0.5, 0.5, 0.5)
    below_corner = corner_factor(1.0, 1.0, 0.5)
    assert h[0] == pytest.approx(np.full(3, np.pi * 2.0 * centre), rel=1e-9)
    assert h[1] == pytest.approx(np.full(3, np.pi * 2.0 * below_corner), rel=1e-9)
    # Off to the side: the closed form of the sum of signed corner rectangles.
    side = corner_factor(2.0, 0.5, 0.5) - corner_factor(1.0, 0.5, 0.5)
    assert h[2] == pytest.approx(np.full(3, np.pi * 2.0 * 2 * side), rel=1e-9)


def test_a_half_hidden_emitter_in_the_penumbra():
    """A blocker hides the x < 0 half of the emitter from receivers on the line x = 0 below it:
    the kernel-weighted visible share is 1/2 by symmetry. Stratified rays (4 x 4 per triangle)
    land within 0.08 of it, and the pilot pass does not stop at the penumbra."""
    blocker = np.concatenate([quad([[-1.0, -1.0, 0.25], [0.0, -1.0, 0.25], [0.0, 1.0, 0.25],
                                    [-1.0, 1.0, 0.25]])])
    scene = build([(square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp")),
                   (blocker, grey(0.5)), (square(0.0, 2.0, up=True), grey(0.5))])
    _, emitters, occluded = gather_inputs(scene, rays=32)
    points = np.stack([np.zeros(20), np.linspace(-0.1, 0.1, 20), np.zeros(20)], axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (20, 1))
    h = em.emitter_irradiance(emitters, points, normals, occluded, 1e-6, np.random.default_rng(1))
    # Unhidden value from the same estimator (factor only) on a scene without the blocker.
    open_scene = build([(square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp")),
                        (square(0.0, 2.0, up=True), grey(0.5))])
    _, open_emitters, open_occluded = gather_inputs(open_scene, rays=32)
    full = em.emitter_irradiance(open_emitters, points, normals, open_occluded, 1e-6,
                                 np.random.default_rng(1))
    share = h[:, 0] / full[:, 0]
    assert np.all(np.abs(share - 0.5) < 0.08)
    assert abs(share.mean() - 0.5) < 0.03


@pytest.mark.parametrize("rays", [2, 8])
def test_few_points_per_side_still_see_a_penumbra(rays):
    """With 1 x 1 or 2 x 2 points per emitter triangle there is no pilot to stop at: every
    receiver on the penumbra's centre line casts its whole set, so with 2 x 2 most see part of
    each triangle (a share strictly between 0 and 1), and their mean share stays near 1/2. (The
    old pilot of one ray for 2 x 2 gave every receiver 0 or 1.)"""
    blocker = quad([[-1.0, -1.0, 0.25], [0.0, -1.0, 0.25], [0.0, 1.0, 0.25], [-1.0, 1.0, 0.25]])
    scene = build([(square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp")),
                   (blocker, grey(0.5)), (square(0.0, 2.0, up=True), grey(0.5))])
    _, emitters, occluded = gather_inputs(scene, rays=rays)
    assert set(emitters.per_side) == {1 if rays == 2 else 2}
    count = 400
    points = np.stack([np.zeros(count), np.linspace(-0.1, 0.1, count), np.zeros(count)], axis=1)
    normals = np.tile([0.0, 0.0, 1.0], (count, 1))
    h = em.emitter_irradiance(emitters, points, normals, occluded, 1e-6, np.random.default_rng(2))
    full = em.emitter_irradiance(emitters, points, normals, lambda o, d, t0, t1:
                                 np.zeros(len(o), bool), 1e-6, np.random.default_rng(2))
    share = h[:, 0] / full[:, 0]
    assert abs(share.mean() - 0.5) < 0.05
    partial = np.mean((share > 0.01) & (share < 0.99))
    assert partial > (0.8 if rays == 8 else -1.0)


def test_pixel_sub_samples_share_out_the_emitter_points():
    """A camera view's edge pass: 4 x 4 sub-samples of each pixel (strata) on the penumbra's
    centre line of the half-hidden emitter. Each triangle's 3 x 3 points grow to 4 x 4 and each
    sub-sample casts one of them, so a pixel of 16 casts 16 rays per triangle where each casting
    the whole set would cast 16 x 9 (less the pilot's saving); unhidden, every sub-sample keeps
    the exact factor; half hidden, the pixels' shares stay near 1/2 (three seeds: mean
    0.49-0.50, every pixel within 0.06-0.09 of 1/2; casting every point, within 0.05-0.06)."""
    blocker = quad([[-1.0, -1.0, 0.25], [0.0, -1.0, 0.25], [0.0, 1.0, 0.25], [-1.0, 1.0, 0.25]])
    lamp = (square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp"))
    floor = (square(0.0, 2.0, up=True), grey(0.5))
    _, emitters, occluded = gather_inputs(build([lamp, (blocker, grey(0.5)), floor]), rays=18)
    assert set(emitters.per_side) == {3}
    pixels, m = 50, 16
    points = np.repeat(np.stack([np.zeros(pixels), np.linspace(-0.1, 0.1, pixels),
                                 np.zeros(pixels)], axis=1), m, axis=0)  # pixel-major
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    strata = (np.tile(np.arange(m), pixels), m)
    rays = []

    def counting(o, d, t0, t1):
        rays.append(len(o))
        return occluded(o, d, t0, t1)

    shared = em.emitter_irradiance(emitters, points, normals, counting, 1e-6,
                                   np.random.default_rng(3), strata=strata)
    assert sum(rays) == len(points) * 2  # one point of each of the two triangles
    _, _, open_occluded = gather_inputs(build([lamp, floor]), rays=18)
    exact = em.emitter_irradiance(emitters, points, normals, open_occluded, 1e-6,
                                  np.random.default_rng(3))
    unhidden = em.emitter_irradiance(emitters, points, normals, open_occluded, 1e-6,
                                     np.random.default_rng(3), strata=strata)
    np.testing.assert_allclose(unhidden, exact, rtol=1e-12)
    share = (shared[:, 0] / exact[:, 0]).reshape(pixels, m).mean(axis=1)
    assert abs(share.mean() - 0.5) < 0.02 and np.all(np.abs(share - 0.5) < 0.12)


def test_pixel_sub_samples_share_out_an_area_lamps_grid():
    """The area lamp's 4 x 4 grid of shadow-ray targets shared among a pixel's 4 x 4 or 2 x 2
    sub-samples: each sub-sample sees 1 or 4 of the grid's points, and the sub-samples of a
    pixel at one point together see all 16, so their mean visibility equals the unshared one
    exactly (a fixed grid); 3 x 3 sub-samples (9 does not divide 16) keep the whole grid."""
    from classic_bake.kernels.geometry.scene import Light
    from classic_bake.kernels.radiosity.lamps import light_visibility

    panel = Light(name="Panel", kind="AREA", position=np.array([0.0, 0.0, 0.5]),
                  direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                  axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, 1.0), size_x=0.5,
                  size_y=0.5)
    blocker = quad([[-1.0, -1.0, 0.25], [0.0, -1.0, 0.25], [0.0, 1.0, 0.25], [-1.0, 1.0, 0.25]])
    bvh = BVH.build(build([(blocker, grey(0.5))]).triangles)
    origins = np.stack([np.linspace(-0.3, 0.3, 7), np.zeros(7), np.full(7, 1e-3)], axis=1)
    whole = light_visibility(panel, origins, bvh.occluded, 4)
    assert 0.0 < whole[3] < 1.0  # the middle origin is in the penumbra
    rays = []

    def counting(o, d, t0, t1):
        rays.append(len(o))
        return bvh.occluded(o, d, t0, t1)

    for m, cast in ((16, 1), (4, 4), (9, 16)):
        rays.clear()
        repeated = np.repeat(origins, m, axis=0)
        shared = light_visibility(panel, repeated, counting, 4,
                                  strata=(np.tile(np.arange(m), len(origins)), m))
        assert sum(rays) == len(repeated) * cast
        np.testing.assert_allclose(shared.reshape(-1, m).mean(axis=1), whole, atol=1e-12)


def test_thinned_emitters_keep_a_texels_rays():
    """Sub-texel points averaged k x k to one texel take ceil(n / k) points per side each, so the
    texel's mean rests on at least the n x n rays of one receiver: n = 3 -> 2 at k = 2 (16 in
    all), 1 stays 1; the triangles and their radiance are the same."""
    scene = build([(square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp")),
                   (square(0.0, 2.0, up=True), grey(0.5))])
    _, emitters, _ = gather_inputs(scene, rays=16)
    assert emitters.per_side.tolist() == [3, 3]
    thin = emitters.thinned(2)
    assert thin.per_side.tolist() == [2, 2] and emitters.per_side.tolist() == [3, 3]
    assert (2 * thin.per_side) ** 2 @ np.ones(2) >= emitters.per_side ** 2 @ np.ones(2)
    assert emitters.thinned(3).per_side.tolist() == [1, 1]
    assert thin.triangles is emitters.triangles and thin.radiance is emitters.radiance


def test_enclosure_probes_find_the_inside_of_solids_only():
    """Floor points under a closed cube are inside it; points beside it are not, nor are points
    under a single-sided sheet (its back face above them, but open to the sides)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) * 0.4
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    cube = np.concatenate([quad(v[f]) for f in faces])  # outward normals
    sheet = square(0.3, 0.2, up=True, cx=1.5, cy=0.2)  # faces up: the floor sees its back
    floor = square(0.0, 3.0, up=True)
    scene = build([(cube, grey(0.5)), (sheet, grey(0.5)), (floor, grey(0.5))])
    bvh = BVH.build(scene.triangles)
    normals_t = geometric_normals(scene.triangles)
    points = np.array([[0.2, 0.2, 0.0], [0.05, 0.35, 0.0], [0.6, 0.2, 0.0], [1.5, 0.2, 0.0],
                       [-1.0, -1.0, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    inside = fg.enclosed(points, normals, bvh.intersect, normals_t, 1e-6)
    assert inside.tolist() == [True, True, False, False, False]


def _cube(lo, hi):
    """A closed box from corner lo to hi, outward normals."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = lo + (hi - lo) * np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                                   [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = [[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]]
    return np.concatenate([quad(v[f]) for f in faces])


def test_enclosure_probes_see_through_a_second_solid_inside_the_first():
    """Two boxes that pass through each other on a floor, under a ceiling that faces down (a
    front face from below) and a closed box hanging in the open: the floor under either box or
    both is inside (a probe from under one box crosses the other's walls on its way out of the
    first); the floor beside them and the floor under the hanging box (entered and left, then
    the ceiling) are open."""
    a = _cube([0.0, 0.0, 0.0], [0.4, 0.4, 0.4])
    b = _cube([0.25, 0.1, 0.0], [0.65, 0.3, 0.6])
    hanging = _cube([1.4, 1.4, 1.0], [1.6, 1.6, 1.2])
    floor = square(0.0, 3.0, up=True)
    ceiling = square(2.0, 3.0, up=False)
    scene = build([(a, grey(0.5)), (b, grey(0.5)), (hanging, grey(0.5)), (floor, grey(0.5)),
                   (ceiling, grey(0.5))])
    bvh = BVH.build(scene.triangles)
    normals_t = geometric_normals(scene.triangles)
    points = np.array([[0.1, 0.2, 0.0], [0.3, 0.2, 0.0], [0.37, 0.12, 0.0], [0.55, 0.2, 0.0],
                       [1.0, 0.2, 0.0], [1.5, 1.5, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    inside = fg.enclosed(points, normals, bvh.intersect, normals_t, 1e-6)
    assert inside.tolist() == [True, True, True, True, False, False]


def test_the_gather_draws_the_shadow_that_coarse_patches_blur():
    """A lamp over a floor with a blocker between them, 16 patches: the patch solution smears
    the blocker's shadow over its patches; the gather's umbra is black (nothing else lights the
    floor there but the dark underside of the blocker) and its open floor matches the exact
    unshadowed value."""
    blocker = square(0.5, 0.15, up=False)  # faces down: the floor sees its front, which is dark
    scene = build([(square(1.0, 0.2, up=False), grey(0.0, emission=5.0, name="lamp")),
                   (blocker, grey(0.0, name="black")), (square(0.0, 1.0, up=True), grey(0.5))])
    floor = scene.object_slice(2)
    tri = np.full(3, floor.start, np.int64)
    # Receivers on the floor's first triangle (corners (-1,-1), (1,-1), (1,1)): the centre and a
    # point far from the shadow.
    corners = scene.triangles[floor.start].astype(np.float64)
    targets = np.array([[0.0, 0.0, 0.0], [0.9, -0.9, 0.0], [0.5, -0.5, 0.0]])
    m = np.column_stack([corners[1] - corners[0], corners[2] - corners[0]])[:2]
    uv = np.linalg.solve(m, (targets[:, :2] - corners[0, :2]).T).T
    bary = np.column_stack([1 - uv.sum(axis=1), uv])
    settings = RadiositySettings(patch_budget=16, refine_levels=0, solver="gauss_seidel")
    result = solve_radiosity(scene, settings)
    gathered = result.exitance_at(tri, bary)
    smeared = result.exitance_at(tri, bary, interpolated=True)
    assert gathered[0].max() < 1e-9  # the umbra: no direct light, no indirect
    assert smeared[0].max() > 0.05 * gathered[2].max()  # the patches cannot hold it
    # The open floor: rho pi L F, nothing in the way (the floor's true indirect is zero: only
    # black surfaces and the lamp face it). What the patches add is the solver's and the gather's
    # two samplings of the same direct light disagreeing near the shadow (measured 0.15% here).
    lamp = scene.triangles[scene.object_slice(0)].astype(np.float64)
    from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon
    f = point_to_polygon(targets[1], np.array([0.0, 0.0, 1.0]),
                         lamp[:, [0, 1, 2]], np.tile([0.0, 0.0, -1.0], (2, 1))).sum()
    assert gathered[1] == pytest.approx(np.full(3, 0.5 * np.pi * 5.0 * f), rel=5e-3)
    assert result.stats["final_gather"]["emitter_triangles"] == 2


def test_clear_shafts_skip_the_rays_and_change_nothing():
    """Lamp, blocker and floor as above, floor patches of 0.25: the patches far from the blocker
    see the lamp whole (`clear_shafts`), the ones under it do not; receivers of clear patches get
    the same irradiance without a single shadow ray (the ratio estimator is exact when nothing
    blocks), and the others the same as before from the same rays."""
    from classic_bake.kernels.radiosity.patches import locate, make_patches

    scene = build([(square(1.0, 0.2, up=False), grey(0.0, emission=5.0, name="lamp")),
                   (square(0.5, 0.15, up=False), grey(0.0, name="black")),
                   (square(0.0, 1.0, up=True), grey(0.5))])
    bvh, emitters, occluded = gather_inputs(scene)
    patches = make_patches(scene, 0.25)
    floor = np.flatnonzero(patches.object_ids == 2)
    clear = em.clear_shafts(patches, emitters, bvh, 1e-5)
    assert clear[floor].any() and not clear[floor].all()
    rng = np.random.default_rng(5)
    uv = rng.random((4000, 2))
    uv = np.where(uv.sum(axis=1, keepdims=True) > 1, 1 - uv, uv)
    bary = np.column_stack([1 - uv.sum(axis=1), uv])
    tri = np.full(4000, scene.object_slice(2).start, np.int64) + rng.integers(0, 2, 4000)
    points = np.einsum("mk,mkc->mc", bary, scene.triangles[tri].astype(np.float64))
    normals = np.tile([0.0, 0.0, 1.0], (4000, 1))
    patch, _ = locate(patches, tri, bary)
    rays = []

    def counting(o, d, t0, t1):
        rays.append(len(o))
        return occluded(o, d, t0, t1)

    plain = em.emitter_irradiance(emitters, points, normals, counting, 1e-5,
                                  np.random.default_rng(0))
    plain_rays, rays[:] = sum(rays), []
    culled = em.emitter_irradiance(emitters, points, normals, counting, 1e-5,
                                   np.random.default_rng(0), clear=clear[patch])
    seen_whole = clear[patch].all(axis=1)
    assert seen_whole.mean() > 0.3
    assert np.array_equal(culled[seen_whole], plain[seen_whole])
    assert sum(rays) < 0.8 * plain_rays
    # Receivers that still cast rays draw other random points: the same to the estimator's noise.
    assert culled[~seen_whole].sum() == pytest.approx(plain[~seen_whole].sum(), rel=0.02)


def grid_box(cells: int) -> np.ndarray:
    """The unit cube's six faces, inward normals, each cut into cells x cells quads."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = [[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]]
    out = []
    t = np.linspace(0.0, 1.0, cells + 1)
    for f in faces:
        a, b, d = v[f[0]], v[f[1]], v[f[3]]
        for i in range(cells):
            for j in range(cells):
                p = [a + (b - a) * t[i + di] + (d - a) * t[j + dj]
                     for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1))]
                out.append(quad(p))
    return np.concatenate(out)


@pytest.mark.parametrize("cells", [1, 3])
def test_furnace_through_the_gather_with_and_without_shot_emitters(cells):
    """A closed box whose walls all emit E = pi L and reflect rho: B = E / (1 - rho) at every
    receiver, whether the walls' light is shot first and gathered per receiver (12 emissive
    triangles) or, past `max_emitters` (108 triangles), carried by the patches (then it all
    arrives as interpolated 'indirect')."""
    scene = build([(grid_box(cells), grey(0.6, emission=1.0))])
    settings = RadiositySettings(patch_budget=60, refine_levels=0, tolerance=1e-6,
                                 solver="gauss_seidel")
    result = solve_radiosity(scene, settings)
    assert result.stats["final_gather"]["emitter_triangles"] == (12 if cells == 1 else 0)
    rng = np.random.default_rng(2)
    tri = rng.integers(0, scene.triangle_count, 200)
    bary = rng.dirichlet(np.ones(3), 200)
    np.testing.assert_allclose(result.exitance_at(tri, bary), np.pi / (1.0 - 0.6), rtol=0.01)
    # The patches themselves, shot or carried.
    np.testing.assert_allclose(result.radiosity, np.pi / (1.0 - 0.6), rtol=0.01)


def test_emitter_points_are_uniform_and_stratified_over_the_triangle():
    """The visibility estimator weighs its points alike, so they must be spread by area: each of
    the four midpoint sub-triangles (a quarter of the area) gets a quarter of the points, and
    every point set keeps one point per cell (no two sets of the same cell differ in count)."""
    tri = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    y = em.stratified_triangle_points(tri, 4000, 4, np.random.default_rng(3))  # (4000, 16, 3)
    b1, b2 = y[..., 0] / 2.0, y[..., 1]
    b0 = 1.0 - b1 - b2
    assert np.all((b0 >= -1e-12) & (b1 >= -1e-12) & (b2 >= -1e-12))
    corners = [b0 > 0.5, b1 > 0.5, b2 > 0.5]
    for near in corners:
        assert near.mean() == pytest.approx(0.25, abs=0.005)
    # Stratified: every set has exactly 16 / 4 points in the corner sub-triangle of corner 0
    # (b0 > 0.5 is sqrt(u) < 0.5, the first quarter of the cells' rows: 4 whole cells).
    assert np.all(corners[0].sum(axis=1) == 4)


# --- reusing what neighbouring receivers' rays found --------------------------------------------


def test_visibility_states_record_lit_umbra_penumbra_and_behind():
    """Below a lamp half hidden by a blocker: a receiver far on the open side sees every emitter
    triangle whole (CLEAR), one deep under the blocker sees none (HIDDEN), one under the blocker's
    edge is in the penumbra (UNKNOWN), one facing away has the lamp behind it (AWAY). Passing
    those states back as `known` gives the same irradiance without rays: CLEAR is the exact
    unoccluded factor, HIDDEN zero."""
    blocker = quad([[-1.0, -1.0, 0.25], [0.0, -1.0, 0.25], [0.0, 1.0, 0.25], [-1.0, 1.0, 0.25]])
    scene = build([(square(0.5, 0.25, up=False), grey(0.0, emission=1.0, name="lamp")),
                   (blocker, grey(0.5)), (square(0.0, 2.0, up=True), grey(0.5))])
    _, emitters, occluded = gather_inputs(scene, rays=32)
    points = np.array([[0.9, 0.0, 0.0], [-0.9, 0.0, 0.0], [0.0, 0.0, 0.0], [0.9, 0.0, 0.0]])
    normals = np.array([[0.0, 0.0, 1.0]] * 3 + [[0.0, 0.0, -1.0]])
    states = np.zeros((4, len(emitters.triangles)), np.int8)
    h = em.emitter_irradiance(emitters, points, normals, occluded, 1e-6,
                              np.random.default_rng(4), states_out=states)
    assert np.all(states[0] == em.CLEAR) and np.all(states[1] == em.HIDDEN)
    assert np.any(states[2] == em.UNKNOWN) and np.all(states[3] == em.AWAY)
    assert h[1] == pytest.approx(np.zeros(3)) and h[3] == pytest.approx(np.zeros(3))

    def never_called(*_):
        raise AssertionError("a known state must not cast rays")

    known = states[[0, 1, 3]]
    again = em.emitter_irradiance(emitters, points[[0, 1, 3]], normals[[0, 1, 3]], never_called,
                                  1e-6, np.random.default_rng(5), known=known)
    np.testing.assert_array_equal(again, h[[0, 1, 3]])
    # CLEAR taken as given even where a blocker stands: the caller vouches for it.
    hidden_told_clear = em.emitter_irradiance(
        emitters, points[1:2], normals[1:2], never_called, 1e-6, np.random.default_rng(6),
        known=np.full((1, len(emitters.triangles)), em.CLEAR, np.int8))
    assert hidden_told_clear[0, 0] > 0.0


def test_agreed_visibility_needs_every_source_to_agree():
    """A receiver among sources takes CLEAR or HIDDEN only when all of them say so (AWAY
    abstains); a disagreement, a penumbra, a missing source or nothing but AWAY leaves it
    UNKNOWN. The enclosure is agreed the same way."""
    c, h, u, a = em.CLEAR, em.HIDDEN, em.UNKNOWN, em.AWAY
    seen = fg.Visibility(np.array([[c], [c], [h], [h], [u], [a], [a]], np.int8),
                         np.array([0, 0, 1, 1, 0, 0, 0], np.int8))
    sources = np.array([[0, 1], [0, 5], [2, 3], [2, 6], [0, 2], [0, 4], [5, 6], [0, -1]])
    agreed = seen.agreed(sources)
    assert agreed.emitters[:, 0].tolist() == [c, c, h, h, u, u, u, u]
    assert agreed.inside.tolist() == [0, 0, 1, -1, -1, 0, 0, -1]


def test_reused_visibility_leaves_the_bake_as_it_was():
    """A lightmap bake of a floor with a blocker's penumbra, the later passes reusing the
    lattice's rays, differs from the same bake with every receiver casting its own by no more
    than the estimator's own noise (two seeds' difference, RMS), and casts at least 10% fewer
    rays."""
    from dataclasses import replace

    from classic_bake.kernels.bake.bake_targets import TexelFilterSettings
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.lightmap import bake_steps

    parts = [(square(0.6, 0.15, up=False, cx=0.5, cy=0.5), grey(0.0, emission=2.0, name="lamp")),
             (square(0.25, 0.15, up=False, cx=0.45, cy=0.5), grey(0.5)),
             (square(0.0, 0.5, up=True, cx=0.5, cy=0.5), grey(0.5))]
    scene = build(parts)  # UV = xy: the floor fills the unit square
    scene = replace(scene, lightmap_uv=scene.uv.copy(),
                    objects=[replace(o, has_lightmap_uv=True) for o in scene.objects])
    result = solve_radiosity(scene, RadiositySettings(patch_budget=60, refine_levels=0))
    rays = []
    bvh = result.gather.bvh
    counting = type(bvh).occluded

    def bake(reuse: bool, seed: int = 0):
        gather = replace(result.gather, settings=replace(result.gather.settings, seed=seed))
        original = fg.Visibility.agreed
        if not reuse:
            fg.Visibility.agreed = lambda self, s: fg.Visibility.unknown(len(s),
                                                                        self.emitters.shape[1])
        try:
            rays.clear()
            out = drain(bake_steps(scene, replace(result, gather=gather), [2], {2: 32}, 2,
                                   TexelFilterSettings()))
        finally:
            fg.Visibility.agreed = original
        return out[2].lightmap[out[2].lightmap_mask], sum(rays)

    type(bvh).occluded = lambda self, o, *a, **k: rays.append(len(o)) or counting(self, o, *a, **k)
    try:
        reused, reused_rays = bake(True)
        own, own_rays = bake(False)
        other_seed, _ = bake(False, seed=1)
    finally:
        type(bvh).occluded = counting
    assert reused_rays < 0.9 * own_rays

    def rms(a, b):
        return float(np.sqrt(np.mean((a - b) ** 2)))

    assert rms(reused, own) <= rms(other_seed, own)
    np.testing.assert_allclose(reused.mean(axis=0), own.mean(axis=0), rtol=0.01)


def test_smooth_normals_weigh_the_light_as_cycles_shades_them():
    """A floor whose corner normals lean (a smooth-shaded mesh's interpolated normal) takes each
    light's cosine to that normal, as Cycles' DIFFUSE bake does, and still leaves its rays along
    the face: under a sun straight down (3 W/m^2) and an emissive square above, rho = 0.5, the
    gathered B is rho (E cos + pi L F(x, n_shading)) at every receiver, F the exact factor for
    the leaning normal (nothing else reflects light back). A normal pointing behind the face
    goes dark, as Cycles shades it (the light is behind that normal)."""
    from dataclasses import replace

    from classic_bake.kernels.geometry.scene import Light
    from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon

    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=np.array([0, 0, -1.0]),
                axis_x=np.array([1.0, 0, 0]), axis_y=np.array([0, 1.0, 0]),
                irradiance=np.full(3, 3.0))
    lamp = square(1.0, 0.25, up=False)
    scene = build([(square(0.0, 2.0, up=True), grey(0.5)), (lamp, grey(0.0, 2.0, "lamp"))],
                  lights=(sun,))
    tilt = np.radians(30.0)
    leaning = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    normals = np.array(scene.normals)
    normals[:2] = leaning
    flat = solve_radiosity(scene, RadiositySettings(patch_budget=8), BVH.build(scene.triangles))
    smooth_scene = replace(scene, normals=normals.astype(np.float32))
    smooth = solve_radiosity(smooth_scene, RadiositySettings(patch_budget=8),
                             BVH.build(scene.triangles))
    tri = np.array([0, 0, 1])
    bary = np.array([[0.6, 0.2, 0.2], [0.2, 0.3, 0.5], [0.3, 0.3, 0.4]])
    points = np.einsum("mk,mkc->mc", bary, scene.triangles[tri].astype(np.float64))
    up = np.tile([0.0, 0.0, 1.0], (3, 1))

    def expected(n):
        f = sum(point_to_polygon(points, n, lamp[k][None].astype(np.float64),
                                 np.array([[0.0, 0.0, -1.0]])) for k in range(2))
        return 0.5 * (3.0 * n[:, 2] + np.pi * 2.0 * f)

    got_flat = flat.exitance_at(tri, bary)[:, 0]
    got_smooth = smooth.exitance_at(tri, bary)[:, 0]
    # rel 1e-4: receivers are pulled 1e-4 of the way to their triangle's centroid (RECEIVER_INSET).
    assert got_flat == pytest.approx(expected(up), rel=1e-4)
    assert got_smooth == pytest.approx(expected(np.tile(leaning, (3, 1))), rel=1e-4)
    assert got_smooth.max() < got_flat.min()  # cos 30 deg dims the sun's share
    # Corner normals pointing behind the face: no light reaches them.
    normals[:2] = [0.0, 0.0, -1.0]
    under = solve_radiosity(replace(scene, normals=normals.astype(np.float32)),
                            RadiositySettings(patch_budget=8), BVH.build(scene.triangles))
    assert under.exitance_at(tri, bary)[:, 0] == pytest.approx(0.0, abs=1e-9)


def test_a_back_side_takes_one_bounce_of_the_solution():
    """An inside-out plate: a 0.2 m square 1 m above a 60 m floor (rho 0.5), its front facing up
    into the empty sky, its back facing the floor; a sun straight down (3 W/m^2) lights the floor
    and the front, never the back. A camera looking up at the back sees rho_plate B_floor / pi,
    B_floor = rho_floor E = 1.5 W/m^2, as Cycles shades the side it sees. Folded a little (not a
    flat sheet, `sheets.py`), the back's own rays (`final_gather.ray_gathered_irradiance`) meet the floor
    nearly everywhere (1 - F = 0.1% lies beyond its edge), and read the floor patches' B, whose
    means lose the plate's 0.04 m^2 shadow (1.3% of the cosine-weighted view, which Cycles would
    see): 0.5%; without those rays that back shows nothing. Flat, the plate's back is a copy in
    the solve, which gathers the floor's light whatever the rays."""
    from classic_bake.kernels.geometry.scene import Light

    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=np.array([0, 0, -1.0]),
                axis_x=np.array([1.0, 0, 0]), axis_y=np.array([0, 1.0, 0]),
                irradiance=np.full(3, 3.0))
    flat = square(1.0, 0.1, up=True)
    folded = flat.copy()
    folded[0, 1, 2] += 0.002  # a corner of the first triangle only: a 0.8-degree crease
    tri = np.array([2, 3, 2])
    bary = np.array([[0.6, 0.2, 0.2], [0.2, 0.3, 0.5], [1 / 3, 1 / 3, 1 / 3]])
    expected = 0.8 * 0.5 * 3.0 / np.pi
    for plate, copied in ((folded, False), (flat, True)):
        scene = build([(square(0.0, 30.0, up=True), grey(0.5)), (plate, grey(0.8))],
                      lights=(sun,))
        for rays in (64, 0):
            result = solve_radiosity(scene, RadiositySettings(patch_budget=8, world_rays=rays),
                                     BVH.build(scene.triangles))
            assert (result.back_of is not None) is copied
            want, tolerance = (expected, 0.005) if rays or copied else (0.0, 0.0)
            back = result.back_radiance_at(scene, tri, bary)
            np.testing.assert_allclose(back, want, rtol=tolerance, atol=1e-12)
    # The front, lit by the sun alone (nothing above it), is unchanged by the back.
    assert result.radiance_at(tri, bary) == pytest.approx(np.full((3, 3), 0.8 * 3.0 / np.pi),
                                                          rel=1e-6)


def test_enclosure_probes_count_a_box_bottom_lying_on_the_floor():
    """A box standing on the floor, its bottom in the floor's plane (the floor first, so a ray
    crossing there hits the floor: the lower triangle index wins a tie), a second box through
    its side: a point on that side inside the second box, near the floor, probes down and out
    through the floor where the second box's bottom lies too. It is inside (the coincident
    bottom is crossed first); a point on the floor beside the boxes stays open."""
    floor = square(0.0, 3.0, up=True)
    a = _cube([0.0, 0.0, 0.0], [0.4, 0.4, 0.4])
    b = _cube([0.1, 0.3, 0.0], [0.3, 0.7, 0.3])
    ceiling = square(2.0, 3.0, up=False)
    scene = build([(floor, grey(0.5)), (a, grey(0.5)), (b, grey(0.5)), (ceiling, grey(0.5))])
    bvh = BVH.build(scene.triangles)
    normals_t = geometric_normals(scene.triangles)
    offset = 1e-6
    coincident = CoincidentFaces.find(scene.triangles, normals_t, scene.object_ids, offset)
    points = np.array([[0.2, 0.4, 0.03], [0.2, 0.4, 0.2], [1.0, 1.0, 0.0]])
    normals = np.array([[0.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
    with_pairs = fg.enclosed(points, normals, bvh.intersect, normals_t, offset, coincident)
    assert with_pairs.tolist() == [True, True, False]
    without = fg.enclosed(points, normals, bvh.intersect, normals_t, offset)
    assert without.tolist() == [False, True, False]  # the tie hid box b's bottom


def test_a_sheet_modelled_double_sided_encloses_nothing():
    """A 1 m sheet of two opposite faces in one plane (one object), 0.16 m over a floor: the
    floor's probes meet the sheet, whose faces share a plane, and leave no solid there; the
    floor under it is open, as it is with the sheet single-sided."""
    floor = square(0.0, 2.0, up=True)
    sheet = np.concatenate([square(0.16, 0.5, up=True), square(0.16, 0.5, up=False)])
    scene = build([(floor, grey(0.5)), (sheet, grey(0.5))])
    bvh = BVH.build(scene.triangles)
    normals_t = geometric_normals(scene.triangles)
    offset = 1e-6
    coincident = CoincidentFaces.find(scene.triangles, normals_t, scene.object_ids, offset)
    points = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.0], [1.5, 1.5, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (3, 1))
    assert not fg.enclosed(points, normals, bvh.intersect, normals_t, offset, coincident).any()


def test_receivers_on_an_uneven_patch_gather_their_indirect_light_by_rays(monkeypatch):
    """A 2 x 2 m floor on two patches, a wall of small triangles standing on its x = 1 edge (one
    object, reflectance 0.9), a low sun on the wall: the floor's indirect light runs from the
    wall's foot to a few percent of that at x = -1, which two patches, their corners pulled by
    the wall's small ones, can only hold as their fitted means. Elements whose corners differ by
    more than their mean on patches far larger than their neighbours (`FinalGather.uneven`)
    gather by rays: along
    the far edge the gathered indirect light is the solution's own (512 rays about each of 17
    receivers; 64 each, within 15% on their mean), where the patches' fit gives it 2.9 times."""
    from classic_bake.kernels.geometry.scene import Light

    # the wall in 8 x 4 quads of 0.25 m, facing -x
    wall = np.concatenate([quad([[1.0, y, z + 0.25], [1.0, y + 0.25, z + 0.25],
                                 [1.0, y + 0.25, z], [1.0, y, z]])
                           for y in np.arange(-1.0, 1.0, 0.25) for z in np.arange(0.0, 1.0, 0.25)])
    sun_dir = np.array([1.0, 0.0, -0.35]) / np.linalg.norm([1.0, 0.0, -0.35])
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=sun_dir,
                axis_x=np.array([0.0, 1.0, 0.0]), axis_y=np.array([0.0, 0.0, 1.0]),
                irradiance=np.full(3, 3.0))
    floor = square(0.0, 1.0, up=True)
    scene = build([(np.concatenate([floor, wall]), grey(0.9))], lights=[sun])  # one object
    settings = RadiositySettings(patch_size=4.0, refine_levels=0, shadow_splits=0, near_splits=0,
                                 element_pairs=0, solver="gauss_seidel")
    assert len(solve_radiosity(scene, settings).patches) == 2 + 64
    result = solve_radiosity(scene, settings)
    floor = range(2)  # the floor's triangles, first
    targets = np.column_stack([np.full(17, -0.9), np.linspace(-0.8, 0.8, 17), np.zeros(17)])
    tri, bary = np.zeros(17, np.int64), np.zeros((17, 3))
    for t in floor:  # each target's floor triangle and barycentrics
        c = scene.triangles[t].astype(np.float64)
        m = np.column_stack([c[1] - c[0], c[2] - c[0]])[:2]
        uv = np.linalg.solve(m, (targets[:, :2] - c[0, :2]).T).T
        inside = (uv.min(axis=1) >= 0.0) & (uv.sum(axis=1) <= 1.0)
        tri[inside] = t
        bary[inside] = np.column_stack([1.0 - uv.sum(axis=1), uv])[inside]
    direct = 3.0 * -sun_dir[2]  # the sun on the open floor

    def gathered_indirect():
        return (result.exitance_at(tri, bary)[:, 0] / 0.9 - direct).mean()

    up = np.tile([0.0, 0.0, 1.0], (17, 1))
    truth = fg.ray_gathered_irradiance(result.gather, targets, up, up, 512, result._reflected,
                                       np.random.default_rng(3))[:, 0].mean()
    assert 0.0 < truth < 0.1 * direct
    assert gathered_indirect() == pytest.approx(truth, rel=0.15)
    monkeypatch.setattr(fg, "UNEVEN_RATIO", np.inf)  # no element is uneven: the patches' fit
    monkeypatch.setattr(fg, "STEEP_RATIO", np.inf)
    del result.gather.__dict__["uneven"]  # the cached flags, worked out again
    assert not result.gather.uneven.any()
    assert gathered_indirect() > 2.0 * truth
