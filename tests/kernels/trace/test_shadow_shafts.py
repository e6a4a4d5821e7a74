"""Shadow rays skipped where a hit's part of its triangle sees a light whole
(kernels/trace/shadow_shafts.py): the same image as casting every ray, fewer rays."""

import numpy as np
import pytest
from scene_builder import build, ortho_camera, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import Light, Material
from classic_bake.kernels.trace import shadow_shafts
from classic_bake.kernels.trace.emitters import lamp_rectangle, point_light
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.shadow_shafts import ClearShafts, child_of, children
from classic_bake.kernels.trace.tracer import trace

GREY = Material(name="grey", base_color=np.full(3, 0.5, np.float32), specular=0.0)


def panel(size=1.0, height=2.0):
    """A square area lamp of radiance 5 facing down at (0, 0, height)."""
    return Light(name="Panel", kind="AREA", position=np.array([0.0, 0.0, height]),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, 5.0), shape="SQUARE",
                 size_x=size, size_y=size)


def box(lo, hi):
    """The 12 triangles of an axis-aligned box, outward."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [[(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
             [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
             [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
             [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
             [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
             [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)]]
    return np.concatenate([quad(f) for f in faces])


def test_children_tile_the_triangle_and_barycentrics_follow_the_point():
    rng = np.random.default_rng(7)
    tris = rng.normal(size=(500, 3, 3))
    bary = rng.dirichlet(np.ones(3), size=500)
    point = np.einsum("nc,ncj->nj", bary, tris)
    kids = children(tris)
    assert kids.shape == (500, 4, 3, 3)
    area = 0.5 * np.linalg.norm(np.cross(kids[..., 1, :] - kids[..., 0, :],
                                         kids[..., 2, :] - kids[..., 0, :]), axis=-1)
    parent = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=-1)
    np.testing.assert_allclose(area, np.repeat(parent[:, None] / 4, 4, axis=1), rtol=1e-9)
    child, inner = child_of(bary)
    assert (inner >= -1e-12).all() and np.allclose(inner.sum(axis=1), 1.0)
    again = np.einsum("nc,ncj->nj", inner, kids[np.arange(500), child])
    np.testing.assert_allclose(again, point, atol=1e-12)
    # Each corner of the triangle lies in its own child.
    corner, at = child_of(np.eye(3))
    assert corner.tolist() == [0, 1, 2] and np.allclose(at, np.eye(3))


def test_a_blocked_floor_triangle_is_split_down_to_the_parts_that_see_the_lamp():
    # A 4 m floor of two triangles under a 1 m lamp, a 0.4 m cube standing near one corner: the
    # two floor triangles' shafts are blocked, but their parts far from the cube see it whole.
    lamp = panel()
    cube = box((1.2, 1.2, 0.0), (1.6, 1.6, 0.4))
    floor = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    tris = np.concatenate([floor, cube])
    bvh = BVH.build(tris.astype(np.float32))
    shafts = ClearShafts(tris, [lamp_rectangle(lamp)], [16], bvh, slack=1e-5)
    # Triangle 0 has corners (-2, -2), (2, -2), (2, 2); these are hits at (-1.2, -1.6) and
    # (1.6, -1.6), far from the cube; then (1.8, 1.6), just beside it, in its shadow.
    far = np.array([[0.8, 0.1, 0.1], [0.1, 0.8, 0.1]])
    near = np.array([[0.05, 0.05, 0.9]])
    tri = np.array([0, 0, 1, 0])
    bary = np.concatenate([far, far[:1], near])
    seen = shafts.clear(0, tri, bary)
    assert seen[:3].all() and not seen[3]
    # Each hit's part is tested: 2 triangles, then 4 parts of each per level, down to the part
    # that holds the hit or sees the lamp whole (a lamp's rectangle: 2 pairs a receiver).
    assert shafts.tested_pairs % 2 == 0 and 2 * (2 + 8) <= shafts.tested_pairs <= 2 * (2 + 8 * 4)
    again = shafts.tested_pairs
    np.testing.assert_array_equal(shafts.clear(0, tri, bary), seen)
    assert shafts.tested_pairs == again  # the answers are kept


def lamp_of(kind: str) -> Light:
    """A square panel, a point lamp or a sun over the floor."""
    if kind == "AREA":
        return panel(size=1.5, height=2.5)
    if kind == "POINT":
        return point_light("P", (0.1, -0.2, 2.5), np.full(3, 20.0))
    d = np.array([0.3, 0.2, -1.0]) / np.linalg.norm([0.3, 0.2, -1.0])
    return Light(name="Sun", kind="SUN", position=np.zeros(3), direction=d,
                 axis_x=np.array([1.0, 0.0, 0.0]), axis_y=np.array([0.0, 1.0, 0.0]),
                 irradiance=np.full(3, 3.0))


@pytest.mark.parametrize("kind", ["AREA", "POINT", "SUN"])
def test_skipping_clear_shadow_rays_leaves_the_image_as_casting_them(monkeypatch, kind):
    # The floor and cube under a lamp, seen from above with edges sampled: every pixel as when
    # every shadow ray is cast, and many rays never cast.
    lamp = lamp_of(kind)
    cube = box((0.3, 0.2, 0.0), (0.9, 0.8, 0.6))
    floor = quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    cam = ortho_camera((0, 0, 4), (0, 0, -1), (0, 1, 0), 4.0, (48, 48))
    scene = build([(floor, GREY), (cube, GREY)], cam, [lamp])
    settings = TracerSettings(max_depth=0, adaptive=4, area_samples=4)
    # A small view: its shafts would not pay (SHAFT_WORTH), but here every receiver is tested.
    monkeypatch.setattr(shadow_shafts, "SHAFT_WORTH", 1.0)
    skipped = trace(scene, settings)
    monkeypatch.setattr(shadow_shafts, "SHAFT_WORTH", np.inf)
    cast = trace(scene, settings)
    assert cast.stats.clear_shadow_rays == 0
    assert skipped.stats.shadow_rays + skipped.stats.clear_shadow_rays == cast.stats.shadow_rays
    # Most of the floor sees the lamp whole: 48-80% of the rays are skipped (a point lamp or a
    # sun, one ray a hit, splits the floor into coarser parts than the panel's 16 rays a hit).
    assert skipped.stats.clear_shadow_rays > 0.4 * cast.stats.shadow_rays
    np.testing.assert_array_equal(skipped.image, cast.image)
