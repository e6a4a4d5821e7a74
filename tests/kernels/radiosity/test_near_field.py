"""Near-field splits (kernels/radiosity/near_field.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scene_builder import build, grey, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import Light
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.near_field import near_shares
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity


def test_the_near_share_under_a_plane_is_its_cosine_weighted_share():
    """Patches facing a parallel plane at distance d, rays of length L (their longest edge): a ray
    at angle theta from the normal meets the plane within L when cos(theta) >= d / L, and the
    cosine-weighted share of such directions is 1 - (d / L)^2. Averaged over many patches (16
    stratified rays each) within 0.03; nothing above: 0."""
    floor = quad([[0, 0, 0], [4, 0, 0], [4, 4, 0], [0, 4, 0]])
    patches = patching.make_patches(build([(floor, grey(0.5))]), 0.2)
    longest = np.linalg.norm(patches.corners - np.roll(patches.corners, -1, axis=1),
                             axis=2).max(axis=1)
    assert np.ptp(longest) < 1e-9  # one size: one expected share
    for d in (0.05, 0.1, 0.15):
        ceiling = quad([[-10, -10, d], [-10, 10, d], [10, 10, d], [10, -10, d]])  # faces down
        bvh = BVH.build(ceiling)
        share = near_shares(patches, bvh.occluded, 5.0).mean()
        assert share == pytest.approx(1.0 - (d / longest[0]) ** 2, abs=0.03)
    assert not near_shares(patches, BVH.build(ceiling + [0, 0, 5.0]).occluded, 5.0).any()


def test_near_splits_give_the_light_behind_a_plate_by_a_wall():
    """A sun straight down on a 2 m floor, a wall at its end and a 1 m plate (two faces) 16 cm in
    front of the wall: the light between them falls off fourfold up the wall, from the lit strip
    of floor. With 1 m patches the wall's gathered light behind the plate is 57% off (RMS) of
    0.2 m patches'; two near-field splits, which split only the patches the plate and the wall
    face at close range, bring it within 25% with under a third of the fine patches."""
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=np.array([0, 0, -1.0]),
                axis_x=np.array([1.0, 0, 0]), axis_y=np.array([0, 1.0, 0]),
                irradiance=np.full(3, 1.0))
    y = 2.0 - 0.16
    floor = quad([[-1, 0, 0], [1, 0, 0], [1, 2, 0], [-1, 2, 0]])
    wall = quad([[-1, 2, 0], [1, 2, 0], [1, 2, 1.5], [-1, 2, 1.5]])  # faces -y
    plate = np.concatenate([quad([[-0.5, y, 0], [0.5, y, 0], [0.5, y, 1], [-0.5, y, 1]]),
                            quad([[-0.5, y, 0], [-0.5, y, 1], [0.5, y, 1], [0.5, y, 0]])])
    scene = build([(floor, grey(0.6)), (wall, grey(0.6)), (plate, grey(0.6))], lights=(sun,))
    heights = np.linspace(0.03, 0.97, 16)
    wall_tri = np.flatnonzero(scene.object_ids == 1)
    # Points on the wall behind the plate, x = 0.013 (inside one triangle of each), up its height.
    points = np.column_stack([np.full_like(heights, 0.013), np.full_like(heights, 2.0), heights])
    tri, bary = _locate(scene.triangles[wall_tri], points)

    def wall_light(**settings):
        result = solve_radiosity(scene, RadiositySettings(refine_levels=0, shadow_splits=0,
                                                          **settings))
        return result.exitance_at(wall_tri[tri], bary)[:, 0], len(result.patches)

    fine, fine_count = wall_light(patch_size=0.2, near_splits=0)
    assert fine[0] > 4 * fine[len(fine) // 2]  # the near field: it falls off fourfold

    def rms(values):
        return float(np.sqrt(np.mean((values / fine - 1.0) ** 2)))

    coarse, _ = wall_light(patch_size=1.0, near_splits=0)
    split, split_count = wall_light(patch_size=1.0, near_splits=2)
    assert rms(coarse) > 0.45  # 0.57
    assert rms(split) < 0.25  # 0.21
    assert split_count < fine_count / 3  # 337 against 1280


def _locate(triangles: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points (P, 3) on the triangles (T, 3, 3): the triangle each lies in and its
    barycentric coordinates (P, 3)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    found, weights = [], []
    for p in points:
        for k in range(len(triangles)):
            uv = np.linalg.lstsq(np.column_stack([b[k] - a[k], c[k] - a[k]]), p - a[k],
                                 rcond=None)[0]
            if uv.min() >= -1e-9 and uv.sum() <= 1.0 + 1e-9:
                found.append(k)
                weights.append([1.0 - uv.sum(), uv[0], uv[1]])
                break
    return np.array(found), np.array(weights)
