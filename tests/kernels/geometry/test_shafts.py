"""Shaft culling (kernels/shafts.py, BVH.convex_clear): the hull's planes hold both triangles, a
blocker in the shaft is found, geometry on or beside the shaft is not, and no pair called clear
has a blocked segment (sampled with shadow rays through the same BVH)."""

from __future__ import annotations

import numpy as np
import pytest

from classic_bake.kernels.geometry.bvh import BVH, BVHSettings
from classic_bake.kernels.geometry.shafts import clear_pairs, hull_planes

FLOOR = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
LAMP = np.array([[0.0, 0.0, 2.0], [0.0, 1.0, 2.0], [1.0, 0.0, 2.0]])  # faces down


def random_triangles(rng, count, spread, size):
    return rng.random((count, 1, 3)) * spread + size * rng.standard_normal((count, 3, 3))


def points_in(tris, rng, count):
    """(P, count, 3) uniform points on each triangle (P, 3, 3)."""
    u = rng.random((len(tris), count, 2))
    u = np.where(u.sum(axis=-1, keepdims=True) > 1.0, 1.0 - u, u)
    return (tris[:, None, 0] + u[..., :1] * (tris[:, None, 1] - tris[:, None, 0])
            + u[..., 1:] * (tris[:, None, 2] - tris[:, None, 0]))


def test_hull_planes_hold_both_triangles_and_every_segment_between_them():
    rng = np.random.default_rng(3)
    a = random_triangles(rng, 200, 1.0, 0.3)
    b = random_triangles(rng, 200, 1.0, 0.3)
    normals, offsets = hull_planes(a, b)
    assert normals.shape[1] <= 20
    # Every used plane is a unit normal; each pair has at least the 4 faces of a tetrahedron.
    used = np.isfinite(offsets)
    assert np.allclose(np.linalg.norm(normals[used], axis=1), 1.0)
    assert (used.sum(axis=1) >= 4).all()
    t = rng.random((200, 50, 1))
    segment_points = (1 - t) * points_in(a, rng, 50) + t * points_in(b, rng, 50)
    side = np.einsum("pkc,pvc->pkv", normals, segment_points) - offsets[..., None]
    assert (side[np.broadcast_to(used[..., None], side.shape)] <= 1e-9).all()


def test_a_blocker_between_floor_and_lamp_is_found_and_one_beside_the_shaft_is_not():
    floor_and_lamp = [FLOOR, LAMP]
    between = np.array([[[0.1, 0.1, 1.0], [0.6, 0.1, 1.0], [0.1, 0.6, 1.0]]])
    beside = between + [3.0, 0.0, 0.0]
    for blocker, expect in ((between, False), (beside, True)):
        bvh = BVH.build(np.concatenate([np.stack(floor_and_lamp), blocker]))
        assert clear_pairs(FLOOR[None], LAMP[None], bvh, 1e-6)[0] == expect


def test_surfaces_touching_the_shaft_do_not_block_it():
    """A floor patch's own triangle, a coplanar neighbour, the lamp's other half and a wall
    standing on the floor patch's edge (leaning away from the lamp) all touch the shaft's
    boundary: nothing enters it."""
    neighbour = np.array([[1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    lamp_half = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 2.0], [1.0, 1.0, 2.0]])
    wall = np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 3.0]])  # the x = 0 plane
    bvh = BVH.build(np.stack([FLOOR, neighbour, LAMP, lamp_half, wall]))
    assert clear_pairs(FLOOR[None], LAMP[None], bvh, 1e-6)[0]
    # Tilt the wall into the shaft: it enters.
    tilted = wall + np.array([[0, 0, 0], [0, 0, 0], [0.5, 0, 0]])
    bvh = BVH.build(np.stack([FLOOR, neighbour, LAMP, lamp_half, tilted]))
    assert not clear_pairs(FLOOR[None], LAMP[None], bvh, 1e-6)[0]


@pytest.mark.parametrize(("count", "size"), [(20, 0.05), (400, 0.01)])  # one leaf, a tree
def test_no_pair_called_clear_has_a_blocked_segment(count, size):
    rng = np.random.default_rng(count)
    scene = random_triangles(rng, count, 1.0, size)
    bvh = BVH.build(scene, BVHSettings(brute_force_below=24))
    a = random_triangles(rng, 1500, 1.0, 0.05)
    b = a.mean(axis=1, keepdims=True) + random_triangles(rng, 1500, 0.5, 0.05) - 0.25
    clear = clear_pairs(a, b, bvh, 1e-9)
    assert 0.05 < clear.mean() < 0.95  # both answers occur
    x, y = points_in(a, rng, 100), points_in(b, rng, 100)
    seg = (y - x).reshape(-1, 3)
    length = np.linalg.norm(seg, axis=1)
    blocked = bvh.occluded(x.reshape(-1, 3), seg / length[:, None], 0.0, length).reshape(-1, 100)
    assert not blocked[clear].any()
    # Conservative but not vacuous: most pairs with no blocked segment are found clear.
    assert clear[~blocked.any(axis=1)].mean() > 0.5


def test_open_above_finds_the_floor_under_a_box_and_ignores_a_ceiling():
    """A floor under a ceiling (facing down: a front face seen from the floor) with a closed
    box standing on part of it: only the floor patches the box's top hangs over are roofed."""
    from classic_bake.kernels.geometry.shafts import open_above

    def square(z, x0, x1, up):
        c = [[x0, x0, z], [x1, x0, z], [x1, x1, z], [x0, x1, z]]
        c = c if up else c[::-1]
        return np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]])

    top = square(0.3, 0.1, 0.4, up=True)  # the box's lid, facing up like the floor
    bvh = BVH.build(np.concatenate([square(0.0, 0.0, 1.0, up=True), square(1.0, 0.0, 1.0, False),
                                    top]))
    cells = np.linspace(0.0, 1.0, 11)
    patches = np.concatenate([square(0.0, 0.0, 0.1, up=True) + [x, y, 0.0]
                              for x in cells[:-1] for y in cells[:-1]])
    centre = patches.mean(axis=1)
    up = np.tile([0.0, 0.0, 1.0], (len(patches), 1))
    unroofed = open_above(patches, up, 2.0, bvh, 1e-6)
    under = ((centre[:, :2] > 0.1) & (centre[:, :2] < 0.4)).all(axis=1)
    assert not unroofed[under].any()
    # A cell's width from the box the floor is open (a cell touching the footprint only at a
    # corner may count as roofed: the test is conservative there).
    away = (centre[:, :2] > 0.5).any(axis=1)
    assert unroofed[away].all()
