"""Alpha-clipped casters against Cycles: a leaf card (a quad whose image's alpha is a disc with a
square hole, linked to the Principled Alpha) over a ground plane under a sun. The ground's
shadow from the shadow map and from the tracer's shadow rays has the texture's shape, as in
Cycles' SHADOW bake (transparent shadows), and so has radiosity's lit ground."""

from dataclasses import replace

import bpy
import numpy as np
from blender_parts import plane, principled

from classic_bake.addon import cycles as cr
from classic_bake.addon.bridge.request import SnapshotRequest
from classic_bake.addon.bridge.snapshot import snapshot
from classic_bake.jobs.radiosity import radiosity_bake_job
from classic_bake.jobs.shadowmap import shadow_bake_job
from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.shading.direct_light import DirectLightSettings
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import Tracer, trace

SIZE = 128  # ground lightmap texels per side
GROUND = 4.0  # m, the ground's side (z = 0)
CARD = 2.0  # m, the leaf card's side (z = CARD_HEIGHT)
CARD_HEIGHT = 1.0
IMAGE = 128  # alpha image texels per side
SUN_TILT = 0.3  # rad from straight down, about x
# Cycles stops a shadow ray at its first alpha surface unless transparent bounces are allowed.
TRANSPARENT_BOUNCES = 8
LIMIT = 0.01  # the check: under 1% of the ground's texels disagree


def _alpha_image() -> np.ndarray:
    """(IMAGE, IMAGE) alpha in {0, 1} over UV (row 0 at v = 0, Blender's pixel order): a disc of
    radius 0.42 about the centre with a square hole [0.4, 0.6]^2 in it."""
    c = (np.arange(IMAGE) + 0.5) / IMAGE
    u, v = np.meshgrid(c, c)
    disc = (u - 0.5) ** 2 + (v - 0.5) ** 2 < 0.42 ** 2
    hole = (np.abs(u - 0.5) < 0.1) & (np.abs(v - 0.5) < 0.1)
    return (disc & ~hole).astype(np.float32)


def _leaf_card():
    mat, bsdf = principled("Leaf", base=(0.2, 0.6, 0.1))
    image = bpy.data.images.new("LeafAlpha", IMAGE, IMAGE, alpha=True, float_buffer=True)
    rgba = np.zeros((IMAGE, IMAGE, 4), np.float32)
    rgba[..., :3] = (0.2, 0.6, 0.1)
    rgba[..., 3] = _alpha_image()
    image.pixels.foreach_set(rgba.ravel())
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    mat.node_tree.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    h = CARD / 2
    mesh = bpy.data.meshes.new("Card")
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap").uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Card", mesh)
    obj.location = (0.0, 0.0, CARD_HEIGHT)
    bpy.context.scene.collection.objects.link(obj)


def _scene():
    ground_mat, _ = principled("GroundMat", base=(0.8, 0.8, 0.8))
    ground = plane(ground_mat, size=GROUND)
    ground.name = "Ground"
    _leaf_card()
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = 0.0  # hard shadows, as the kernels model a sun
    obj = bpy.data.objects.new("Sun", sun)
    obj.rotation_euler = (SUN_TILT, 0.0, 0.0)
    bpy.context.scene.collection.objects.link(obj)
    return bpy.context.scene


def _texel_points() -> np.ndarray:
    """(SIZE * SIZE, 3) world points of the ground's lightmap texel centres (row 0 at the top):
    the plane's Lightmap UVs span it linearly."""
    c = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(c, 1.0 - c)
    return np.column_stack([(u.ravel() - 0.5) * GROUND, (v.ravel() - 0.5) * GROUND,
                            np.zeros(SIZE * SIZE)])


def _cycles_lit(scene) -> tuple[np.ndarray, np.ndarray]:
    """Cycles' SHADOW bake of the ground: (lit (SIZE, SIZE) bool, valid mask)."""
    model = replace(cr.direct(), transparent_bounces=TRANSPARENT_BOUNCES)
    images, _, masks = cr.bake_lightmaps(scene, model, 4, ["Ground"], "Lightmap", SIZE, "SHADOW")
    return images["Ground"][..., 0] > 0.5, masks["Ground"]


def _disagree(ours: np.ndarray, theirs: np.ndarray, valid: np.ndarray) -> float:
    return np.count_nonzero((ours != theirs) & valid) / np.count_nonzero(valid)


def test_reader_takes_the_alpha_texture():
    _scene()
    scene = snapshot(bpy.context, SnapshotRequest(textures=False))
    leaf = next(m for m in scene.materials if m.name == "Leaf")
    assert leaf.has_alpha and leaf.alpha_texture is not None
    assert not any("alpha" in reason for reason in leaf.ignored)
    assert list(leaf.alpha_texture.weights) == [0, 0, 0, 1]


def test_leaf_card_shadow_has_the_texture_shape():
    """Shadow map, tracer and radiosity against Cycles' SHADOW bake of the ground, binarised
    (visibility at 0.5; radiosity's radiance halfway between its lit and shadowed medians)."""
    scene = _scene()
    theirs, valid = _cycles_lit(scene)
    uv = LightmapUVSettings(resolution=SIZE, padding=2)
    summary = drain(shadow_bake_job(bpy.context, DirectLightSettings(), "Lightmap", uv,
                                    render=False))
    mask = valid & summary.lightmaps["Ground"][1]
    shadow_map = summary.extra["per_light"]["Ground"][0] > 0.5  # (SIZE, SIZE)
    # The tracer's shadow rays from the same texel centres towards the sun.
    kernel_scene = snapshot(bpy.context, SnapshotRequest(textures=False))
    tracer = Tracer(kernel_scene, BVH.build(kernel_scene.triangles), TracerSettings())
    sun = kernel_scene.lights[0]
    points = _texel_points() + np.array([0.0, 0.0, tracer.offset])
    to_sun = np.tile(-np.asarray(sun.direction, np.float64), (len(points), 1))
    traced = tracer._visible(points, to_sun, np.inf).reshape(SIZE, SIZE) > 0.5
    # Radiosity: the ground's radiance, lit where the sun reaches it.
    solved = drain(radiosity_bake_job(bpy.context, RadiositySettings(), "Lightmap", uv,
                                      render=False))
    radiance = solved.lightmaps["Ground"][0][..., :3].mean(axis=2)
    mask &= solved.lightmaps["Ground"][1]
    middle = 0.5 * (np.median(radiance[mask & theirs]) + np.median(radiance[mask & ~theirs]))
    opaque_card = np.count_nonzero(~theirs & mask) / np.count_nonzero(mask)
    figures = {name: _disagree(ours, theirs, mask)
               for name, ours in (("shadow map", shadow_map), ("tracer", traced),
                                   ("radiosity", radiance > middle))}
    print(f"shadowed {opaque_card:.2%} of the ground; disagreeing texels: "
          + ", ".join(f"{k} {v:.3%}" for k, v in figures.items()))
    assert 0.05 < opaque_card < 0.3  # the disc's shadow, not the card's square (25%)
    for name, share in figures.items():
        assert share < LIMIT, (name, share)


VIEW = 48  # px per side of the view from above


def _leaf_pixels(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels showing the lit leaf (green over red), not the grey or shadowed ground."""
    return (image[..., 1] > 2.0 * image[..., 0]) & (image[..., 1] > 0.05)


def test_camera_sees_through_the_holes():
    """The tracer's camera rays blend the leaf card by its alpha, as Cycles does: the leaf's
    pixels are Cycles' (measured: 0.13% disagree, all at the leaf's edges)."""
    scene = _scene()
    cam = bpy.data.cameras.new("Top")
    cam.type, cam.ortho_scale = "ORTHO", CARD * 1.2
    obj = bpy.data.objects.new("Top", cam)
    obj.location = (0.0, 0.0, 5.0)
    scene.collection.objects.link(obj)
    scene.camera = obj
    model = replace(cr.whitted(2), transparent_bounces=TRANSPARENT_BOUNCES)
    cycles, _ = cr.render_camera(scene, model, 16, resolution=(VIEW, VIEW))
    ours = trace(snapshot(bpy.context, SnapshotRequest(), resolution=(VIEW, VIEW)),
                 TracerSettings(max_depth=2)).image
    theirs = _leaf_pixels(cycles)
    share = np.count_nonzero(_leaf_pixels(ours) != theirs) / theirs.size
    print(f"leaf pixels {theirs.mean():.2%}; disagreeing {share:.2%}")
    assert 0.2 < theirs.mean() < 0.6 and share < 0.03
