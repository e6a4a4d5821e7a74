"""A world lit by an equirectangular Environment Texture (kernels/world_light.py): the background
the camera sees and the sky light a floor receives, against Cycles."""

import math

import bpy
import numpy as np

from classic_bake.addon import bridge, cycles_reference
from classic_bake.addon.jobs import radiosity_bake_job
from classic_bake.kernels.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.metrics import rel_mse
from classic_bake.kernels.radiosity import RadiositySettings
from classic_bake.kernels.tracer import TracerSettings, trace


def _hdri_world(pixels: np.ndarray, strength: float = 1.0):
    """The scene's world: an Environment Texture of float `pixels` (H, W, 3), row 0 at the top."""
    height, width = pixels.shape[:2]
    image = bpy.data.images.new("Sky", width, height, alpha=True, float_buffer=True)
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = pixels
    image.pixels.foreach_set(rgba[::-1].ravel())  # Blender stores the bottom row first
    scene = bpy.context.scene
    scene.world = bpy.data.worlds.new("HDRI")
    if bpy.app.version < (5, 0, 0):
        scene.world.use_nodes = True
    tree = scene.world.node_tree
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = strength
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    return scene


def test_the_camera_sees_the_environment_map_as_cycles_does():
    """A smooth map (red along u, green along v) seen by a 60-degree camera looking along +x
    from the origin, the map's centre: the tracer's escaping rays read it as Cycles' background
    does (relMSE under 1e-4 against a 16-sample box-filtered render; no geometry in view)."""
    height, width = 64, 128
    v, u = np.mgrid[0:height, 0:width]
    pixels = np.stack([(u + 0.5) / width, 1.0 - (v + 0.5) / height,
                       np.full((height, width), 0.2)], axis=-1).astype(np.float32)
    scene = _hdri_world(pixels, strength=1.5)
    bpy.ops.mesh.primitive_plane_add(size=0.1, location=(-5.0, 0.0, 0.0))  # behind the camera
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(60.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, math.radians(-90.0))  # looking along +x
    scene.collection.objects.link(cam)
    scene.camera = cam
    resolution = (48, 32)
    snap = bridge.snapshot(resolution=resolution)
    assert snap.world_texture is not None
    ours = trace(snap, TracerSettings(max_depth=1, adaptive=0, supersample=2),
                 resolution=resolution).image
    theirs, _ = cycles_reference.render_camera(scene, cycles_reference.whitted(1), 16,
                                               resolution=resolution)
    error = rel_mse(ours, theirs)
    print(f"background relMSE {error:.2e}")
    assert error < 1e-4


def test_a_floor_under_a_bright_sky_and_dark_ground_is_lit_from_above():
    """A sky of radiance 1.2 above the horizon over a ground of 0.1 below (no lamp), a grey floor
    and a box over it: the radiosity bake against Cycles' world-lit DIFFUSE bake (128 samples).
    The floor sees the sky only, so the map's mean (0.65) would leave it 46% dark; read along
    each sky ray, both objects' means within 3%."""
    from blender_parts import principled

    height, width = 32, 64
    pixels = np.full((height, width, 3), 0.1, np.float32)
    pixels[: height // 2] = 1.2
    scene = _hdri_world(pixels)
    grey, _ = principled("Grey", base=(0.6, 0.6, 0.6))
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.active_object.data.materials.append(grey)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, 0.0, 0.75))
    bpy.context.active_object.data.materials.append(grey)
    uv = LightmapUVSettings(resolution=32, padding=2)
    summary = None
    for step in radiosity_bake_job(bpy.context, RadiositySettings(patch_budget=150), "Lightmap",
                                   uv, render=False):
        summary = step
    sizes = summary["lightmap_sizes"]
    for name in ("Plane", "Cube"):
        images, _, masks = cycles_reference.bake_lightmaps(
            scene, cycles_reference.radiosity(world_lighting=True), 128, [name], "Lightmap",
            sizes[name], "DIFFUSE")
        texels, baked = summary["lightmaps"][name]
        valid = baked & masks[name]
        ratio = texels[valid][:, :3].mean() / images[name][valid][:, :3].mean()
        print(f"{name}: mean ours/cycles {ratio:.3f}")
        assert abs(ratio - 1.0) < 0.03, (name, ratio)
