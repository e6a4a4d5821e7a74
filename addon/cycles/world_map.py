"""The world shader rendered alone by Cycles into an equirectangular radiance map
(`render_world_map`), for world shaders the bridge cannot read itself."""

from __future__ import annotations

import contextlib

import bpy
import mathutils
import numpy as np

from .models import direct
from .runner import exr_output, render_once
from .settings import TEMP_PREFIX, SettingsLog, configure

# The world rendered alone into a map (`render_world_map`): a panoramic camera sees the sky the
# way Cycles' Environment Texture is read (kernels/shading/world_light.equirect_uv): the image centre along
# world +x, its top +z, u = 1/4 along +y. Cycles' equirectangular camera looks down its own -z
# with +y up and -x at u = 1/4 (measured with a world that shows its direction as colour), so its
# axes in the world are x_cam = -y, y_cam = +z, z_cam = -x.
WORLD_CAMERA_MATRIX = ((0.0, 0.0, -1.0, 0.0), (-1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 1.0))
# (W, H) of the map: texels of 0.47 degrees; the default sky's sun disc (0.545 degrees) covers a
# few. Measured on a Multiple Scattering sky, sun 30 degrees up, as the irradiance of an upward
# plane summed over the map (red), at 256 samples: 768 x 384 81.42 in 1.2 s on a 2-core
# machine, 1024 x 512 81.52 in 1.9 s (4096 samples 81.64), 2048 x 1024 81.55 in 6.9 s,
# 512 x 256 79.0 in 0.6 s (its sun texels too coarse).
WORLD_MAP_SIZE = (768, 384)
# Samples a texel at most: the sun disc's rim texels need them (1024 x 512 at 64: 80.1, 2% low,
# as the disc's coverage of a texel is sampled); adaptive sampling stops the smooth sky's early.
# A 1-px box filter: each texel is its area's mean, so the texels' sum keeps a sun's power.
WORLD_MAP_SAMPLES = 256
WORLD_MAP_MIN_SAMPLES = 8
WORLD_MAP_NOISE = 0.002
# What a Light Path node reads on a diffuse bounce ray that escapes to the world, the rays that
# light surfaces (`render_world_map(lighting=True)`): the flags of a first diffuse bounce, an
# unbounded length. Outputs not named here read 0.
DIFFUSE_RAY_PATH = {"Is Diffuse Ray": 1.0, "Is Reflection Ray": 1.0, "Ray Length": 1e30,
                    "Ray Depth": 1.0, "Diffuse Depth": 1.0}


def render_world_map(world, size: tuple[int, int] = WORLD_MAP_SIZE,
                     samples: int = WORLD_MAP_SAMPLES, lighting: bool = False
                     ) -> tuple[np.ndarray, float]:
    """The world's radiance over all directions as an equirectangular map, rendered by Cycles:
    ((H, W, 3) float32 linear, row 0 top, laid out as an Environment Texture's image; seconds).

    For world shaders the bridge cannot read itself (a Sky Texture, procedural textures, mixes
    of shaders). A temporary scene holds the world and a panoramic camera (`WORLD_CAMERA_MATRIX`)
    and nothing else; it is removed afterwards, the world untouched. A camera sees the world as a
    camera ray does; with `lighting`, a copy of the world whose Light Path nodes (in its own tree)
    read as a diffuse bounce ray's (`DIFFUSE_RAY_PATH`) is rendered instead: the world that
    lights surfaces (a common set-up shows the camera a backdrop and lights with a map)."""
    width, height = (int(v) for v in size)
    # Every temporary datablock is removed on the way out, in reverse order of making.
    with contextlib.ExitStack() as stack:
        if lighting:
            world = _diffuse_ray_world(world)
            stack.callback(bpy.data.worlds.remove, world)
        temp = bpy.data.scenes.new(f"{TEMP_PREFIX}_world")
        stack.callback(bpy.data.scenes.remove, temp)
        camera = bpy.data.cameras.new(f"{TEMP_PREFIX}_world")
        stack.callback(bpy.data.cameras.remove, camera)
        camera.type = "PANO"
        camera.panorama_type = "EQUIRECTANGULAR"
        obj = bpy.data.objects.new(f"{TEMP_PREFIX}_world", camera)
        stack.callback(bpy.data.objects.remove, obj)
        temp.world = world
        temp.collection.objects.link(obj)
        temp.camera = obj
        obj.matrix_world = mathutils.Matrix(WORLD_CAMERA_MATRIX)  # rows as written
        log = SettingsLog()
        stack.callback(log.restore)
        # world_lighting: the model leaves the (shared) world's ray visibility alone.
        configure(temp, direct(world_lighting=True), log)
        log.set(temp.cycles, "pixel_filter_type", "BOX")
        log.set(temp.cycles, "filter_width", 1.0)
        log.set(temp.cycles, "use_adaptive_sampling", True)
        log.set(temp.cycles, "adaptive_min_samples", WORLD_MAP_MIN_SAMPLES)
        log.set(temp.cycles, "adaptive_threshold", WORLD_MAP_NOISE)
        with exr_output(temp, log, (width, height)) as folder:
            return render_once(temp, log, samples, 0, folder)


def _diffuse_ray_world(world):
    """A temporary copy of `world` whose Light Path nodes' links come from Value nodes holding
    what a diffuse bounce ray reads (`DIFFUSE_RAY_PATH`; the caller removes the copy)."""
    copy = world.copy()
    copy.name = f"{TEMP_PREFIX}_world"
    tree = copy.node_tree
    for node in [n for n in tree.nodes if n.type == "LIGHT_PATH"]:
        for output in node.outputs:
            for link in list(output.links):
                value = tree.nodes.new("ShaderNodeValue")
                value.outputs[0].default_value = DIFFUSE_RAY_PATH.get(output.name, 0.0)
                tree.links.new(value.outputs[0], link.to_socket)
    return copy
