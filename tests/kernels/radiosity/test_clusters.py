"""The clustered solver (kernels/clusters.py): patches of finely tessellated meshes solved as
groups. Furnace, agreement with the hierarchical solver on the same patches, the grouping rule, and
auto's choice."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from radiosity_scenes import reflected_means
from scene_builder import build, grey, lamp_room_with_ball, quad, tessellated_box

from classic_bake.kernels.radiosity import clusters
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity

FAST = dict(samples_per_side=2, visibility_samples_per_side=2, refine_levels=0)


@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_furnace_of_a_finely_tessellated_box(rho):
    """A closed box of 1728 small triangles, every one emitting E = pi L and reflecting rho:
    auto solves it as groups, and B = E / (1 - rho) on every patch. rho = 0.9 amplifies a
    row-sum error ten times."""
    scene = build([(tessellated_box(12), grey(rho, emission=1.0))])
    result = solve_radiosity(scene, RadiositySettings(patch_budget=60, tolerance=1e-7, **FAST))
    level = result.stats["levels"][-1]
    assert result.stats["solver"] == "clustered"
    assert level["groups"] <= 0.1 * result.stats["patches"]
    assert level["clustered_patches"] == result.stats["patches"] == 1728
    np.testing.assert_allclose(result.radiosity, np.pi / (1.0 - rho), rtol=0.01 if rho < 0.6 else 0.03)


def test_groups_keep_to_one_object_cell_and_side():
    """Small patches are grouped by object, grid cell and normal direction: the two sides of a
    thin tessellated sheet never share a group, nor do two objects in one cell; a large patch is
    a group of its own. Receiver points are member centroids, weighing 1 / CLUSTER_POINTS."""
    sheet = tessellated_box(8, 0.2)[:128]  # the bottom face of a small box: 128 triangles
    back = sheet[:, ::-1] + np.array([0.0, 0.0, 0.01])  # the same sheet 1 cm up, facing away
    other = sheet + np.array([0.0, 0.0, 0.05])
    big = quad([[-2, -2, -1], [2, -2, -1], [2, 2, -1], [-2, 2, -1]])
    scene = build([(sheet, grey(0.5)), (back, grey(0.5)), (other, grey(0.5)), (big, grey(0.5))])
    size = 0.5
    patches = patching.make_patches(scene, size)
    groups = clusters.group_patches(patches, size)
    small = patches.areas < clusters.CLUSTER_AREA_SHARE * size * size
    assert small.sum() == 384 and not small[patches.object_ids == 3].any()
    for g in range(groups.count):
        members = groups.members[groups.starts[g]:groups.starts[g + 1]]
        assert len(set(patches.object_ids[members])) == 1
        assert np.allclose(patches.normals[members], patches.normals[members[0]])
        if not small[members].all():
            assert len(members) == 1
    # Three objects, one cell and one side each (the sheet spans 0.2 m, inside one 0.5 m cell).
    assert (~groups.lone).sum() == 3 and groups.count == 3 + (~small).sum()
    points, normals, weights = clusters.receiver_points(patches, groups, 2)
    many = np.flatnonzero(~groups.lone)
    np.testing.assert_allclose(weights[many], 1.0 / clusters.CLUSTER_POINTS)
    centroids = patches.corners.mean(axis=1)
    for g in many:  # every receiver point is some member's centroid, with its normal
        members = groups.members[groups.starts[g]:groups.starts[g + 1]]
        d = np.linalg.norm(points[g][:, None] - centroids[members][None], axis=2)
        assert np.allclose(d.min(axis=1), 0.0)
        np.testing.assert_allclose(normals[g], np.broadcast_to(patches.normals[members[0]],
                                                               normals[g].shape))


def test_coarse_groups_put_an_object_under_half_a_patch_in_six():
    """Coarse groups (what auto falls back to rather than a matrix over thousands of patches): a
    finely tessellated ball a quarter of the patch size across (0.43 of it on its box's diagonal)
    is grouped by the six faces of the cube map alone, one group each wherever its parts fall in
    the grid: the solve resolves indirect light no finer than a patch. The same ball four times
    larger keeps the finer directions, as both do in the groups auto tries first."""
    from scene_builder import uv_sphere

    size = 1.0
    floor = quad([[-4, -4, 0], [4, -4, 0], [4, 4, 0], [-4, 4, 0]])
    for radius, tiny in ((0.125, True), (0.5, False)):
        # centred on a grid corner, so that its parts fall in eight cells
        ball = uv_sphere((0.0, 0.0, 2.0), radius, rings=12, segments=24)
        scene = build([(floor, grey(0.5)), (ball, grey(0.5))])
        patches = patching.make_patches(scene, size)
        groups = clusters.group_patches(patches, size, coarse=True)
        of_ball = np.unique(groups.of_patch[patches.object_ids == 1])
        fine = clusters.group_patches(patches, size)
        assert len(np.unique(fine.of_patch[patches.object_ids == 1])) > 6
        assert len(of_ball) == 6 if tiny else len(of_ball) > 6
        if tiny:  # each group holds the normals of one dominant axis and sign
            for g in of_ball:
                members = groups.members[groups.starts[g]:groups.starts[g + 1]]
                n = patches.normals[members]
                axis = np.abs(n).argmax(axis=1)
                assert len(set(zip(axis, n[np.arange(len(n)), axis] > 0, strict=True))) == 1


def test_split_children_group_apart_by_their_direct_light():
    """A refinement's children (level > 0) lit in different octaves, or unlit, never share a
    group, so a shadow edge's split stays split in the clustered solve; first meshings group as
    before whatever their light, and without the direct light nothing changes."""
    ground = quad([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]])  # inside one grid cell
    scene = build([(ground, grey(0.5))])
    size = 8.0  # every patch under CLUSTER_AREA_SHARE x size^2 = 4 m^2
    first = patching.make_patches(scene, size)
    patches, _ = patching.split_children(scene, first, np.ones(len(first), bool))
    patches, _ = patching.split_children(scene, patches, patches.level == 1)
    assert (patches.level == 2).sum() == 16 * len(first)
    x = patches.corners.mean(axis=1)[:, 0]
    direct = np.where(x[:, None] < 2.0, 0.0, 3.0) * np.ones(3)  # a shadow edge along x = 2
    direct[x > 3.0] = 1.0  # an octave and a half down
    before = clusters.group_patches(patches, size)
    after = clusters.group_patches(patches, size, direct)
    assert before.count == 1
    assert after.count == 3
    lum = direct[:, 0]
    for g in range(after.count):
        members = after.members[after.starts[g]:after.starts[g + 1]]
        assert len(set(lum[members])) == 1
    octaves = clusters.light_bucket(np.array([4.0, 2.0, 1.9, 0.9, 0.0])[:, None] * np.ones(3))
    assert np.array_equal(octaves, [0, 1, 1, 2, clusters.LIGHT_OCTAVES + 1])
    # First meshings keep their groups, lit or not.
    lit = np.arange(len(first))[:, None] * np.ones(3)  # every first patch in its own octave
    assert clusters.group_patches(first, size, lit).count == clusters.group_patches(first,
                                                                                   size).count


@pytest.mark.slow
def test_clustered_agrees_with_the_hierarchical_solver_on_the_same_patches():
    """The lamp-lit room with a ball of 992 triangles: the clustered solve (179 unknowns)
    against the hierarchical solver over all 1070 patches, which agrees with Gauss-Seidel within
    0.5% on a coarser ball (Gauss-Seidel's dense matrix takes 7 s there, a minute here). Area
    means of the room's and the ball's reflected light agree within 1% (measured 0.1%), and the
    ball's orange light tints the floor under it alike: red over blue 1.273 and 1.270."""
    scene = lamp_room_with_ball()
    settings = RadiositySettings(patch_budget=60, final_gather=False, **FAST)
    clustered = solve_radiosity(scene, replace(settings, solver="clustered"))
    full = solve_radiosity(scene, replace(settings, solver="hierarchical"))
    assert clustered.stats["solver"] == "clustered" and full.stats["solver"] == "hierarchical"
    assert len(clustered.patches) == len(full.patches)
    assert clustered.stats["levels"][-1]["groups"] < 0.2 * len(clustered.patches)

    np.testing.assert_allclose(reflected_means(clustered, (0, 2)),  # the room, the ball
                               reflected_means(full, (0, 2)), rtol=0.01)

    def floor_tint(result):  # red over blue of the floor's light around the ball
        centre = result.patches.corners.mean(axis=1)
        under = (centre[:, 2] < 1e-6) & (np.linalg.norm(centre[:, :2] - 0.5, axis=1) < 0.35)
        b = result.radiosity[under]
        return float(np.average(b[:, 0] / b[:, 2], weights=result.patches.areas[under]))

    assert floor_tint(full) > 1.05  # the orange ball's light tints the grey floor
    assert floor_tint(clustered) == pytest.approx(floor_tint(full), rel=0.01)


@pytest.mark.slow
def test_auto_clusters_only_what_cuts_the_unknowns_fourfold():
    """auto runs the clustered solver on the tessellated room, and not when clusters are off,
    nor on a room of a few large triangles."""
    scene = lamp_room_with_ball()
    settings = RadiositySettings(patch_budget=60, **FAST)
    assert solve_radiosity(scene, settings).stats["solver"] == "clustered"
    assert solve_radiosity(scene, replace(settings, clusters=False)).stats["solver"] != "clustered"
    coarse = build([(tessellated_box(1), grey(0.5, emission=1.0))])
    assert solve_radiosity(coarse, settings).stats["solver"] != "clustered"
    with pytest.raises(ValueError, match="ray-cast"):
        RadiositySettings(solver="clustered", method="hemicube")


def test_auto_takes_the_coarse_groups_only_past_the_matrix_solvers_cap():
    """60 small tessellated boxes (108 triangles each, a tenth of the patch size across): past
    AUTO_MATRIX_MAX_PATCHES patches auto may take the coarse groups (six per box; the solve
    takes them where the finer ones do not pay); 20 such boxes stay under the cap and get none,
    nor does a solver other than auto."""
    from classic_bake.kernels.radiosity.planning import AUTO_MATRIX_MAX_PATCHES, coarse_groups_pay

    def boxes(count: int):
        box = tessellated_box(3, 0.1)[:, ::-1]  # outward
        return build([(box + np.array([0.3 * (k % 10), 0.3 * (k // 10), 0.0]), grey(0.5))
                      for k in range(count)])

    size = 1.0
    many = patching.make_patches(boxes(60), size)
    assert len(many) > AUTO_MATRIX_MAX_PATCHES
    coarse = coarse_groups_pay(many, size, RadiositySettings())
    assert coarse is not None and coarse.groups.count == 60 * 6 and coarse.cell == size
    assert coarse_groups_pay(many, size, RadiositySettings(solver="progressive")) is None
    assert coarse_groups_pay(patching.make_patches(boxes(20), size), size, RadiositySettings()) is None


def test_coarse_groups_widen_their_grid_until_they_fit():
    """A 4 m room of 19,200 small triangles over 1 m patches: its coarse groups at the patch size
    (six walls of 4 x 4 cells) break a memory limit that their groups over a grid twice as wide
    (2 x 2 cells a wall) fit, so auto clusters over that grid rather than hand every triangle to
    progressive refinement; the solve regroups at that width and keeps the furnace's B = E / (1 -
    rho) within 2%."""
    from classic_bake.kernels.radiosity.planning import clustered_bytes, coarse_groups_pay

    room = build([(tessellated_box(40, 4.0), grey(0.5, emission=1.0))])
    size = 1.0
    patches = patching.make_patches(room, size)
    settings = RadiositySettings(patch_size=size, dense_memory_limit=clustered_bytes(6 * 4),
                                 **FAST)
    assert coarse_groups_pay(patches, size, replace(settings, dense_memory_limit=1 << 40)).cell == size
    coarse = coarse_groups_pay(patches, size, settings)
    assert coarse is not None and coarse.cell == 2.0 * size and coarse.groups.count == 6 * 4
    assert coarse_groups_pay(patches, size, replace(settings, dense_memory_limit=1)) is None
    result = solve_radiosity(room, replace(settings, shadow_splits=0, near_splits=0))
    assert result.stats["solver"] == "clustered" and result.stats["levels"][-1]["groups"] == 6 * 4
    assert result.stats["coarse_groups"] == {"cell_m": 2.0 * size, "pooled": False}
    np.testing.assert_allclose(result.radiosity, np.pi / (1.0 - 0.5), rtol=0.02)


def test_small_objects_of_one_cell_pool_their_groups_when_nothing_else_fits():
    """60 small boxes (six coarse groups each at any grid width: one object never shares a group
    with another) break a memory limit that 36 groups fit: auto then pools the boxes whose
    centres share a cell of the grid, six groups a cell, rather than shoot every triangle; the
    boxes of one cell are grouped by the side they face, boxes of other cells apart."""
    from classic_bake.kernels.radiosity.planning import clustered_bytes, coarse_groups_pay

    boxes = build([(tessellated_box(3, 0.1)[:, ::-1] + np.array([0.3 * (k % 10), 0.3 * (k // 10), 0]),
                    grey(0.5)) for k in range(60)])
    size = 1.0
    patches = patching.make_patches(boxes, size)
    settings = RadiositySettings(dense_memory_limit=clustered_bytes(36))
    coarse = coarse_groups_pay(patches, size, settings)
    assert coarse is not None and coarse.pooled and coarse.cell == size
    # box centres: x in 0.05 .. 2.75 (cells 0-2), y in 0.05 .. 1.55 (cells 0-1)
    assert coarse.groups.count == 3 * 2 * 6
    centre_cell = np.floor(patches.corners.mean(axis=1)[:, :2] / size).astype(int)
    first = patches.object_ids == patches.object_ids[0]
    same_group = coarse.groups.of_patch == coarse.groups.of_patch[np.flatnonzero(first)[0]]
    assert (centre_cell[same_group] == centre_cell[first][0]).all()
    assert len(np.unique(patches.object_ids[same_group])) > 1
