"""High/low mesh pairs for high -> low normal-map bakes, and Cycles' own NORMAL bake of a pair
(tangent space, Selected to Active): what tests/blender/test_normalmap_high_to_low.py checks the
kernels against and bench/normalmap.py times them against.

Imported only where real Blender (the pip `bpy` module) runs.
"""

import time

import bpy
import numpy as np
from blender_parts import principled


def low_and_high(kind: str, levels: int = 3, displace: float = 0.0, noise_scale: float = 0.25):
    """(low, high): a low-poly mesh with its UV map and a material (kind "cube": a flat-shaded
    2 m cube; "cylinder": a smooth 12-sided cylinder, 1 m radius, 2 m tall), and a detailed
    version of it: a copy with a Subdivision Surface of `levels`, smooth shaded, and with
    `displace` > 0 a Displace modifier after it, moving the surface along its normals by
    `displace` m times a Clouds texture of `noise_scale` (a relief a few texels across when
    small)."""
    if kind == "cube":
        bpy.ops.mesh.primitive_cube_add(size=2.0)
    else:
        bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=1.0, depth=2.0,
                                            end_fill_type="TRIFAN")
        bpy.ops.object.shade_smooth()
    low = bpy.context.object
    low.name = "Low"
    mat, _ = principled("Low")
    low.data.materials.append(mat)
    high = low.copy()
    high.data = low.data.copy()
    high.name = "High"
    bpy.context.scene.collection.objects.link(high)
    modifier = high.modifiers.new("Subdivision", "SUBSURF")
    modifier.levels = modifier.render_levels = levels
    if displace > 0.0:
        texture = bpy.data.textures.new("Relief", "CLOUDS")
        texture.noise_scale = noise_scale
        relief = high.modifiers.new("Relief", "DISPLACE")
        relief.texture, relief.strength, relief.mid_level = texture, displace, 0.5
    for poly in high.data.polygons:
        poly.use_smooth = True
    return low, high


def cycles_normal_bake(low, high, size: int, cage: float, max_ray: float, samples: int = 1,
                       seed: int = 0) -> tuple[np.ndarray, float]:
    """Cycles' tangent-space NORMAL bake of `high` into `low`'s UV map with Selected to Active,
    cage extrusion `cage` and max ray distance `max_ray` (m), `samples` per texel (the first at
    the texel's centre, the rest jittered over it): ((size, size, 4) float32 colours, row 0 at
    the top, alpha 0 where not baked; the bake operator's wall-clock seconds)."""
    from classic_bake.addon import bridge

    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples, scene.cycles.seed = "CPU", samples, seed
    image = bpy.data.images.new("Cycles", size, size, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(np.zeros(size * size * 4, np.float32))  # alpha 0: not baked
    tree = low.active_material.node_tree
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    tree.nodes.active = node
    for obj in scene.objects:
        obj.select_set(obj in (low, high))
    bpy.context.view_layer.objects.active = low
    start = time.perf_counter()
    assert bpy.ops.object.bake(
        type="NORMAL", normal_space="TANGENT", normal_r="POS_X", normal_g="POS_Y",
        normal_b="POS_Z", margin=0, use_selected_to_active=True, cage_extrusion=cage,
        max_ray_distance=max_ray, target="IMAGE_TEXTURES") == {"FINISHED"}
    seconds = time.perf_counter() - start
    tree.nodes.remove(node)
    pixels = bridge.image_pixels(image)
    bpy.data.images.remove(image)
    return pixels, seconds
