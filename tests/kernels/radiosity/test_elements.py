"""Elements: a coarse solution's indirect light gathered at finer elements (`elements.py`)."""

from __future__ import annotations

import numpy as np
from scene_builder import build, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import Light, Material
from classic_bake.kernels.radiosity import elements
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.elements import ELEMENT_PAIRS
from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity


def grey(rho):
    """Lambertian (Specular IOR Level 0: no specular layer over the base)."""
    return Material(name=f"grey{rho}", base_color=np.full(3, rho, np.float32), specular=0.0)


def lit_wall_and_floor():
    """A 1 m wall in the x = 0 plane facing +x (rho 0.8) lit head on by a sun travelling along -x
    (3 W/m^2), standing on a 1 m floor (rho 0.05) that the grazing sun does not light: the floor's
    light is the wall's B = 2.4 W/m^2 times the factor to it, less than 0.2% from the second
    bounce off the dark floor."""
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=np.array([-1.0, 0, 0]),
                axis_x=np.array([0, 1.0, 0]), axis_y=np.array([0, 0, 1.0]),
                irradiance=np.full(3, 3.0))
    wall = quad([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]])
    floor = quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    return build([(wall, grey(0.8)), (floor, grey(0.05))], lights=(sun,))


def test_elements_place_the_light_a_coarse_patch_spreads_evenly():
    """One patch per triangle (four in all). The floor's exitance at points 0.05-0.95 m from the
    wall follows rho_f B_w F(x -> wall), F exact, within 8.5% with elements (4 per patch: linear
    between vertices 0.5 m apart where F curves; 2% with 16); the patches alone hold one linear
    piece per triangle and miss it by over 30% near the wall."""
    scene = lit_wall_and_floor()
    x = np.array([0.05, 0.2, 0.4, 0.6, 0.8, 0.95])
    points = np.stack([x, np.full_like(x, 0.3), np.zeros_like(x)], axis=1)
    wall = np.array([[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1.0]])
    exact = 0.05 * 2.4 * point_to_polygon(points, np.array([0, 0, 1.0]), wall)
    # The floor's triangles (2, 3) and the points' barycentric coordinates in them.
    tri = np.where(points[:, 0] > points[:, 1], 2, 3)
    corners = scene.triangles[tri].astype(np.float64)  # on the floor: solve in (x, y)
    system = np.concatenate([corners[:, :, :2].transpose(0, 2, 1), np.ones((len(x), 1, 3))], 1)
    bary = np.linalg.solve(system, np.column_stack([points[:, :2], np.ones(len(x))])[..., None])
    bary = bary[..., 0]
    errors = {}
    for pairs in (ELEMENT_PAIRS, 0):
        result = solve_radiosity(scene, RadiositySettings(patch_size=10.0, element_pairs=pairs,
                                                          near_splits=0),
                                 BVH.build(scene.triangles))
        assert result.stats["patches"] == 4
        got = result.exitance_at(tri, bary)[:, 0]
        errors[pairs] = np.abs(got / exact - 1.0)
    assert errors[ELEMENT_PAIRS].max() < 0.085
    assert errors[0].max() > 0.3


def test_descend_finds_the_element_subdivided_put_there():
    """Points at random in patches of a triangle: the element `descend` names, at the local
    coordinates it returns, is the same world point, for 1 to 3 levels."""
    scene = lit_wall_and_floor()
    patches = patching.make_patches(scene, 0.6)
    rng = np.random.default_rng(3)
    which = rng.integers(0, len(patches), 500)
    local = rng.dirichlet([1.0, 1.0, 1.0], 500)
    world = np.einsum("mk,mkc->mc", local, patches.corners[which])
    for levels in (1, 2, 3):
        fine = patching.subdivided(scene, patches, levels)
        assert len(fine) == len(patches) * 4 ** levels
        np.testing.assert_allclose(fine.areas.reshape(len(patches), -1).sum(axis=1),
                                   patches.areas, rtol=1e-12)
        index, inner = patching.descend(local, levels)
        assert ((index >= 0) & (index < 4 ** levels)).all()
        got = np.einsum("mk,mkc->mc", inner, fine.corners[which * 4 ** levels + index])
        np.testing.assert_allclose(got, world, atol=1e-12)


def test_element_levels_stay_within_the_pair_budget():
    assert elements.element_levels(74, 74, ELEMENT_PAIRS) == 1  # 4 x 74 x 74 = 21.9k
    assert elements.element_levels(176, 176, ELEMENT_PAIRS) == 0  # 4 x 176 x 176 = 124k
    assert elements.element_levels(4, 4, ELEMENT_PAIRS) == elements.MAX_LEVELS
    assert elements.element_levels(4, 4, 1 << 30) == elements.MAX_LEVELS
    assert elements.element_levels(4, 4, 0) == 0


def test_element_factors_are_exact_near_and_within_the_disc_forms_error_far():
    """Receivers around a unit square patch (two triangles): within DISC_FORM_RADII of a
    triangle's corner radius the factor is `point_to_polygon`'s exactly; beyond, the disc form
    is within 6% of the head-on factor at that distance (these half-squares: at worst 5.3%, at
    2.1 radii, the median 0.05%; random well-shaped triangles at 2 radii: 99% within 8%)."""
    scene = build([(quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), grey(0.5))])
    patches = patching.make_patches(scene, 10.0)
    rng = np.random.default_rng(5)
    points = np.column_stack([rng.uniform(-3, 4, 400), rng.uniform(-3, 4, 400),
                              rng.uniform(0.05, 3, 400)])
    normals = rng.normal(size=(400, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    sources = np.arange(len(patches))
    got = elements.element_factors(points, normals, patches, sources)
    exact = point_to_polygon(points[:, None], normals[:, None], patches.corners[None],
                             patches.normals[None])
    centre = patches.corners.mean(axis=1)
    radius = np.linalg.norm(patches.corners - centre[:, None], axis=2).max(axis=1)
    dist2 = ((points[:, None] - centre[None]) ** 2).sum(axis=2)
    near = dist2 < (elements.DISC_FORM_RADII * radius) ** 2
    assert near.any() and (~near).any()
    np.testing.assert_array_equal(got[near], exact[near])
    head_on = patches.areas / (np.pi * dist2 + patches.areas)
    assert (np.abs(got - exact)[~near] <= 0.06 * head_on[~near]).all()


def test_patch_visibility_is_symmetric_and_sees_a_blocker():
    """Two facing unit squares 1 m apart (two patches each), then with a 3 m plate between: the
    visible share is 1 between the squares' patches without the plate, 0 with it, the same
    both ways."""
    lower = quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    upper = quad([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]])
    plate = quad([[-1, -1, 0.5], [2, -1, 0.5], [2, 2, 0.5], [-1, 2, 0.5]])
    for parts, want in (([lower, upper], 1.0), ([lower, upper, plate], 0.0)):
        scene = build([(p, grey(0.5)) for p in parts])
        patches = patching.make_patches(scene, 10.0)
        bvh = BVH.build(scene.triangles)
        index = np.arange(4)
        share = elements.patch_visibility(patches, index, bvh.occluded, 1e-6,
                                          np.random.default_rng(0))
        np.testing.assert_array_equal(share, share.T)
        np.testing.assert_allclose(share[:2, 2:4], want)
