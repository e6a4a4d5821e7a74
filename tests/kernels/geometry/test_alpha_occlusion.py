"""Any-hit transmittance through surfaces with alpha (`geometry/alpha_occlusion.py`) and the
shadow map's alpha test (`shadow/cutouts.py`), against products of known alphas."""

import numpy as np
from scene_builder import build, quad

from classic_bake.kernels.geometry.alpha_occlusion import (
    AlphaOccluder,
    layered_hits,
    transmittance,
)
from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.raster import Projection, look_at
from classic_bake.kernels.geometry.scene import Material, Texture
from classic_bake.kernels.progress import drain
from classic_bake.kernels.shading.alpha import alpha_aware, scene_alpha
from classic_bake.kernels.shadow.cutouts import Cutout, cutout_depth_steps

OFFSET = 1e-5


def _card(z, mat):
    return (quad([[0, 0, z], [1, 0, z], [1, 1, z], [0, 1, z]]), mat)


def _checker_alpha():
    """Alpha 1 where floor(2u) + floor(2v) is odd (u < 0.5 < v and u > 0.5 > v), 0 elsewhere."""
    return Texture("CHECKER", scale=2.0, color1=np.ones(3, np.float32),
                   color2=np.zeros(3, np.float32))


def _rays(xy, z0=2.0):
    xy = np.asarray(xy, np.float64)
    origins = np.column_stack([xy, np.full(len(xy), z0)])
    return origins, np.tile([0.0, 0.0, -1.0], (len(xy), 1))


def test_constant_alphas_multiply_and_opaque_stops():
    scene = build([_card(1.5, Material("a", alpha=0.5)), _card(1.0, Material("b", alpha=0.25)),
                   _card(0.0, Material("ground"))])
    alpha = scene_alpha(scene)
    bvh = BVH.build(scene.triangles)
    origins, dirs = _rays([[0.3, 0.3], [0.7, 0.6], [2.0, 2.0]])
    above_ground = transmittance(bvh, origins, dirs, 0.0, 1.9, alpha, OFFSET, alpha.opaque)
    np.testing.assert_allclose(above_ground, [0.375, 0.375, 1.0], atol=1e-12)
    through = transmittance(bvh, origins, dirs, 0.0, np.inf, alpha, OFFSET, alpha.opaque)
    np.testing.assert_allclose(through, [0.0, 0.0, 1.0])


def test_texture_alpha_gives_the_texture_shape():
    scene = build([_card(1.0, Material("leaf", alpha_texture=_checker_alpha()))])
    alpha = scene_alpha(scene)
    bvh = BVH.build(scene.triangles)
    rng = np.random.default_rng(1)
    xy = rng.uniform(0.02, 0.98, (400, 2))
    xy = xy[np.min(np.abs(xy - 0.5), axis=1) > 0.02]  # away from the squares' edges
    origins, dirs = _rays(xy)
    t = transmittance(bvh, origins, dirs, 0.0, np.inf, alpha, OFFSET)
    solid = (xy[:, 0] < 0.5) != (xy[:, 1] < 0.5)
    np.testing.assert_array_equal(t, np.where(solid, 0.0, 1.0))


def test_occluder_blocks_in_proportion_to_alpha():
    scene = build([_card(1.0, Material("half", alpha=0.3))])
    alpha = scene_alpha(scene)
    occ = AlphaOccluder(BVH.build(scene.triangles), alpha, OFFSET, alpha.opaque,
                        np.random.default_rng(2))
    origins, dirs = _rays(np.full((20000, 2), 0.4))
    blocked = occ.occluded(origins, dirs, 0.0, np.inf)
    assert abs(blocked.mean() - 0.3) < 0.015
    assert occ.triangle_count == 2  # the BVH's other members pass through


def test_no_alpha_no_lookup():
    scene = build([_card(1.0, Material("opaque"))])
    bvh = BVH.build(scene.triangles)
    assert scene_alpha(scene) is None and alpha_aware(bvh, scene, OFFSET) is bvh


def test_transmittance_reads_through_an_occluder():
    """The tracer may be handed radiosity's wrapped BVH (two-pass): transmittance stays exact."""
    scene = build([_card(1.0, Material("half", alpha=0.3))])
    wrapped = alpha_aware(BVH.build(scene.triangles), scene, OFFSET)
    origins, dirs = _rays(np.full((8, 2), 0.4))
    t = transmittance(wrapped, origins, dirs, 0.0, np.inf, scene_alpha(scene), OFFSET)
    np.testing.assert_allclose(t, 0.7)


def test_shadow_map_alpha_test_keeps_the_texture_shape():
    scene = build([_card(1.0, Material("leaf", alpha_texture=_checker_alpha()))])
    alpha = scene_alpha(scene)
    view = look_at(np.array([0.5, 0.5, 3.0]), np.array([0.0, 0.0, -1.0]), np.array([0.0, 1.0, 0.0]))
    size = 64
    projection = Projection.orthographic(view, (-0.5, 0.5, -0.5, 0.5), 0.1, 10.0)
    depth = np.full((size, size), np.inf, np.float32)
    cut = Cutout(np.ones(scene.triangle_count, bool),
                 lambda tri, bary: alpha(tri, bary[:, 1], bary[:, 2]))
    drain(cutout_depth_steps(scene.triangles, projection, depth, cut))
    # Map texel (i, j) sees u = (j + 0.5) / size, v = 1 - (i + 0.5) / size.
    u = (np.arange(size) + 0.5) / size
    v = 1.0 - u
    solid = (u[None, :] < 0.5) != (v[:, None] < 0.5)
    np.testing.assert_array_equal(np.isfinite(depth), solid)
    np.testing.assert_allclose(depth[solid], 2.0, atol=1e-5)


def test_seeing_rays_pass_the_holes():
    """Through a hole (alpha 0) the ground, on the leaf (alpha 1) the card: each ray's front
    surface, nothing behind an opaque one, a miss where there is nothing."""
    scene = build([_card(1.0, Material("leaf", alpha_texture=_checker_alpha())),
                   _card(0.0, Material("ground"))])
    alpha = scene_alpha(scene)
    origins, dirs = _rays([[0.25, 0.75], [0.25, 0.25], [0.75, 0.75], [0.75, 0.25], [3.0, 3.0]])
    layers = layered_hits(BVH.build(scene.triangles), origins, dirs, 0.0, np.inf, alpha, OFFSET,
                          alpha.opaque)
    np.testing.assert_array_equal(np.sort(layers.ray), np.arange(5))  # one surface each
    hits = layers.front_hits(5)
    np.testing.assert_array_equal(scene.object_ids[hits.tri[:4]], [0, 1, 1, 0])
    np.testing.assert_allclose(hits.t[:4], [1.0, 2.0, 2.0, 1.0], atol=1e-5)
    assert hits.tri[4] == -1


def test_layers_weigh_each_surface_by_what_reaches_it():
    """Cycles' blend a S + (1 - a) T, front to back: cards of alpha 0.5 and 0.25 over the ground
    give weights 0.5, 0.5 x 0.25 and the rest 0.375 to the ground; a ray past the cards only
    (beside the ground) ends in a miss of weight 0.375; a ray that meets nothing, a miss of 1."""
    scene = build([_card(1.5, Material("a", alpha=0.5)), _card(1.0, Material("b", alpha=0.25)),
                   _card(0.0, Material("ground"))])
    alpha = scene_alpha(scene)
    bvh = BVH.build(scene.triangles)
    origins, dirs = _rays([[0.3, 0.3], [2.0, 2.0]])
    layers = layered_hits(bvh, origins, dirs, 0.0, np.inf, alpha, OFFSET, alpha.opaque)
    np.testing.assert_array_equal(layers.ray, [0, 1, 0, 0])  # layer by layer
    np.testing.assert_allclose(layers.weight, [0.5, 1.0, 0.125, 0.375], atol=1e-12)
    np.testing.assert_array_equal(scene.object_ids[layers.hits.tri[[0, 2, 3]]], [0, 1, 2])
    assert layers.hits.tri[1] == -1
    np.testing.assert_allclose(layers.hits.t[[0, 2, 3]], [0.5, 1.0, 2.0], atol=1e-5)
    above = layered_hits(bvh, origins[:1], dirs[:1], 0.0, 1.9, alpha, OFFSET, alpha.opaque)
    assert above.hits.tri[-1] == -1 and above.weight[-1] == 0.375  # the light left past 1.9


def test_rays_pass_objects_hidden_from_them_whatever_their_alpha():
    """Cycles' ray visibility (`Scene.ray_hidden`, `shading/alpha.ray_coverage`): a card hidden
    from camera rays is transparent to them (the ground behind it is seen) and still blocks
    shadow rays; a half-transparent card in front stays half seen."""
    from dataclasses import replace

    from classic_bake.kernels.shading.alpha import ray_coverage

    scene = build([_card(1.5, Material("veil", alpha=0.5)), _card(1.0, Material("card")),
                   _card(0.0, Material("ground"))])
    scene = replace(scene, objects=tuple(replace(o, hidden_from=("camera",)) if k == 1 else o
                                         for k, o in enumerate(scene.objects)))
    bvh = BVH.build(scene.triangles)
    origins, dirs = _rays([[0.3, 0.3]])
    seen = ray_coverage(scene, "camera")
    layers = layered_hits(bvh, origins, dirs, 0.0, np.inf, seen, OFFSET, seen.opaque)
    np.testing.assert_array_equal(scene.object_ids[layers.hits.tri], [0, 2])  # the card skipped
    np.testing.assert_allclose(layers.weight, [0.5, 0.5])
    shadow = ray_coverage(scene, "shadow")  # the alpha alone: the card blocks
    assert transmittance(bvh, origins, dirs, 0.0, 1.9, shadow, OFFSET, shadow.opaque)[0] == 0.0
    opaque = build([_card(1.0, Material("card")), _card(0.0, Material("ground"))])
    assert ray_coverage(opaque, "camera") is None  # nothing hidden, nothing covered: plain hits
