"""Source clusters of the hierarchical solver (kernels/source_clusters.py): far groups of small
roots share their shadow rays and take the disc form of their factors. The tree, the partition
of every leaf's view, the disc factors against the exact ones, the shared visibility against
per-root rays, and the solver with and without clusters (agreement, furnace)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from radiosity_scenes import reflected_means
from scene_builder import build, grey, lamp_room_with_ball, quad, tessellated_box, uv_sphere

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import geometric_normals, triangle_areas
from classic_bake.kernels.radiosity import source_clusters as sc
from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon
from classic_bake.kernels.radiosity.form_factors.sampling import sample_patches
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity

LINK_EPSILON = RadiositySettings().link_epsilon


def _roots(triangles: np.ndarray) -> sc.SourceTree:
    return sc.build(triangles, geometric_normals(triangles), triangle_areas(triangles))


def _ball_and_floor():
    """A ball of 1024 triangles (outward) over a 4 x 4 m floor of 32 triangles (upward)."""
    ball = uv_sphere((0.0, 0.0, 1.0), 0.5, rings=16, segments=32)
    floor = np.concatenate([quad([[x, y, 0], [x + 0.5, y, 0], [x + 0.5, y + 0.5, 0],
                                  [x, y + 0.5, 0]])
                            for x in np.arange(-2, 2, 1.0) for y in np.arange(-2, 2, 1.0)])
    return ball, floor


def test_every_node_holds_its_childrens_roots_inside_its_sphere():
    """The runs of `order` nest (a node's run is its two children's), every root lies in one
    top, and every corner of a node's roots lies inside its sphere."""
    ball, floor = _ball_and_floor()
    triangles = np.concatenate([ball, floor])
    tree = _roots(triangles)
    assert sorted(tree.order) == list(range(len(triangles)))
    assert (tree.hi[tree.tops] - tree.lo[tree.tops]).sum() == len(triangles)
    inner = np.flatnonzero(tree.left >= 0)
    assert np.all(tree.lo[tree.left[inner]] == tree.lo[inner])
    assert np.all(tree.hi[tree.left[inner]] == tree.lo[tree.right[inner]])
    assert np.all(tree.hi[tree.right[inner]] == tree.hi[inner])
    assert np.all(tree.hi[tree.left < 0] - tree.lo[tree.left < 0] == 1)  # single roots end it
    for node in range(len(tree)):
        corners = triangles[tree.order[tree.lo[node]:tree.hi[node]]].reshape(-1, 3)
        assert np.linalg.norm(corners - tree.centre[node], axis=1).max() <= tree.radius[node] + 1e-12


def _view(tree, triangles, leaves, side=2):
    """far_groups and member_links of leaves (triangles, (L, 3, 3)) as the solver calls them."""
    points, weights = sample_patches(leaves, side, "midpoint")
    normals = geometric_normals(leaves)
    group_p, group_n, near_p, near_q = sc.far_groups(tree, np.arange(len(leaves)),
                                                     leaves.mean(axis=1), points, normals)
    group, root, factor, close = sc.member_links(tree, group_p, group_n, points[group_p],
                                                 weights[group_p], normals[group_p],
                                                 triangle_areas(triangles))
    return points, weights, normals, group_p, group_n, near_p, near_q, group, root, factor, close


def _floor_leaves():
    """The ball and floor's triangles, their tree, every third floor triangle as leaves, and
    `_view` of those leaves."""
    ball, floor = _ball_and_floor()
    triangles = np.concatenate([ball, floor])
    tree = _roots(triangles)
    return triangles, tree, floor[::3], _view(tree, triangles, floor[::3])


def test_each_leaf_reaches_every_root_it_sees_once():
    """Leaves on the floor: every ball triangle with a positive exact factor from a leaf's
    points is reached once, as a far group's root or as a near root; far nodes are at most
    SEPARATION of their distance to the leaf's nearest point wide."""
    triangles, tree, leaves, view = _floor_leaves()
    points, weights, normals, group_p, group_n, near_p, near_q, group, root, factor, _ = view
    assert len(group_p) > 0 and len(near_p) > 0
    gap = np.linalg.norm(tree.centre[group_n][:, None] - points[group_p], axis=2).min(axis=1)
    assert np.all(tree.radius[group_n] <= sc.SEPARATION * gap)
    reached = np.concatenate([group_p[group] * len(triangles) + root,
                              near_p * len(triangles) + near_q])
    assert len(np.unique(reached)) == len(reached)  # never twice
    for leaf in range(len(leaves)):
        exact = np.einsum("s,st->t", weights[leaf], point_to_polygon(
            points[leaf][:, None], normals[leaf], triangles[None], geometric_normals(triangles)))
        seen = set(np.flatnonzero(exact > 0.0))
        got = set(root[group_p[group] == leaf]) | set(near_q[near_p == leaf])
        assert seen <= got


def test_disc_factors_of_far_roots_are_within_two_percent_of_the_exact_ones():
    """The far roots the solver keeps (factor at most the link bound, not `close`) take the disc
    form A cos cos / (pi d^2 + A): against the exact point-to-polygon factor at the same points,
    each root within 2% (measured 0.7%), their sum per leaf within 0.5% (measured 0.23%)."""
    triangles, _, _, view = _floor_leaves()
    points, weights, normals, group_p, _, _, _, group, root, factor, close = view
    kept = (factor <= LINK_EPSILON) & ~close
    group, root, factor = group[kept], root[kept], factor[kept]
    leaf = group_p[group]
    exact = np.einsum("ms,ms->m", weights[leaf], point_to_polygon(
        points[leaf], normals[leaf][:, None], triangles[root][:, None],
        geometric_normals(triangles)[root][:, None]))
    assert len(root) > 1000
    each = np.abs(factor / exact - 1.0)
    assert each.max() < 0.02
    sums = np.bincount(leaf, factor) / np.bincount(leaf, exact)
    assert np.all(np.abs(sums[np.bincount(leaf) > 0] - 1.0) < 0.005)


def test_a_groups_shared_rays_estimate_its_factor_weighted_visibility():
    """A wall of 400 small triangles seen from a point past a screen that hides its left half:
    one group of all of them, 4000 rays drawn by factor, against sum F_m V_m / sum F_m with V_m
    from one ray to each root's centroid (0.53 here; measured 0.526): within 0.03."""
    wall = np.concatenate([quad([[x, 3.0, z], [x + 0.1, 3.0, z], [x + 0.1, 3.0, z + 0.1],
                                 [x, 3.0, z + 0.1]])  # facing -y
                           for x in np.arange(-1.0, 1.0, 0.1) for z in np.arange(0.0, 1.0, 0.1)])
    screen = quad([[-1.0, 1.5, -1.0], [0.0, 1.5, -1.0], [0.0, 1.5, 2.0], [-1.0, 1.5, 2.0]])
    bvh = BVH.build(np.concatenate([wall, screen]).astype(np.float32))
    tree = _roots(wall)
    x = np.array([[[0.05, 0.0, 0.5]]])
    normal = np.array([[0.0, 1.0, 0.0]])
    group, root, factor, _ = sc.member_links(tree, np.zeros(1, np.int64), tree.tops[:1], x,
                                             np.ones((1, 1)), normal, triangle_areas(wall))
    assert len(root) == len(wall)
    start = np.array([0, len(root)])
    share = _answered(sc.group_share_steps(tree, start, root, factor, x, np.ones((1, 1)), normal,
                                           np.array([4000]), 1e-6, np.random.default_rng(1)),
                      bvh)
    centroid = wall[root].mean(axis=1)
    seg = centroid - x[0, 0]
    length = np.linalg.norm(seg, axis=1)
    hidden = bvh.occluded(np.repeat(x[0], len(root), axis=0), seg / length[:, None], 1e-6,
                          length * (1 - 1e-6))
    truth = float(np.sum(factor * ~hidden) / factor.sum())
    assert 0.3 < truth < 0.7
    assert share[0] == pytest.approx(truth, abs=0.03)


def _answered(steps, bvh):
    try:
        request = next(steps)
        while True:
            origins, directions, t_max = request
            request = steps.send(bvh.occluded(origins, directions, 0.0, t_max))
    except StopIteration as stop:
        return stop.value


@pytest.mark.slow
def test_the_solver_with_source_clusters_agrees_with_every_link_exact():
    """A lit room with a ball of 1024 triangles (over MIN_ROOTS roots): over a third of the links
    are reached through far groups (measured 42%; fewer groups than links, each casting the rays
    of one link), and the area means of the room's and the ball's reflected light agree with
    every link exact within 1% (measured 0.07%)."""
    scene = lamp_room_with_ball()
    settings = RadiositySettings(solver="hierarchical", patch_budget=60, final_gather=False,
                                 samples_per_side=2, refine_levels=0)
    clustered = solve_radiosity(scene, settings)
    exact = solve_radiosity(scene, replace(settings, cluster_sources=False))
    level = clustered.stats["hierarchy"]["per_refinement"][-1]
    assert level["clustered_links"] > level["links"] / 3
    assert level["cluster_groups"] < level["clustered_links"]
    assert exact.stats["hierarchy"]["per_refinement"][-1]["clustered_links"] == 0

    np.testing.assert_allclose(reflected_means(clustered, (0, 2)),  # the room, the ball
                               reflected_means(exact, (0, 2)), rtol=0.01)


@pytest.mark.slow
def test_furnace_with_source_clusters():
    """A closed box of 1728 small triangles emitting E = pi L and reflecting rho = 0.9 (which
    amplifies a row-sum error of the disc factors ten times), solved by the hierarchical solver
    through far groups: B = E / (1 - rho) on every patch within 1% (measured 0.36%; 0.48% with
    every link exact)."""
    rho = 0.9
    scene = build([(tessellated_box(12), grey(rho, emission=1.0))])
    result = solve_radiosity(scene, RadiositySettings(
        solver="hierarchical", patch_budget=60, tolerance=1e-7, samples_per_side=2,
        refine_levels=0))
    assert result.stats["hierarchy"]["per_refinement"][-1]["clustered_links"] > 0
    np.testing.assert_allclose(result.radiosity, np.pi / (1.0 - rho), rtol=0.01)
