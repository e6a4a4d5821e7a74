"""The one crossing between Blender data and kernel arrays.

`snapshot.snapshot()` reads the evaluated depsgraph (modifiers applied, instances expanded) into a
kernel `Scene`; `write_back` puts kernel results back as images and colour attributes and wires
materials to show them, `mesh` writes UV layers. Everything moves through `foreach_get`/`foreach_set` into
preallocated typed arrays. The conventions that differ between Blender and the kernels live here:

* images: Blender stores rows bottom-up, kernels top-down (`images.flip_rows`);
* mirrored objects (negative determinant): corners 1 and 2 are swapped so that every kernel
  triangle winds counter-clockwise around the normal Blender shades with (`mesh`);
* colour: byte images in sRGB are decoded to linear here, except textures, which keep their
  encoding and decode each look-up after interpolation, as Cycles does (`Texture.encoding`);
* lights: Blender's power is turned into radiometric quantities by `kernels/shading/lights.py`.

| module     | what it computes                                                            |
|------------|-----------------------------------------------------------------------------|
| request    | `SnapshotRequest`: what one bake reads                                      |
| transforms | Blender matrices as arrays, unit vectors                                    |
| nodes      | shader node trees: the tree of a datablock, the node feeding a socket       |
| images     | images read as pixel arrays (sRGB decoding, row order)                      |
| mesh       | positions, triangles, corner normals, UVs; one mesh instance in world space; |
|            | UV layers written, lightmap UVs made with xatlas                            |
| materials  | node-tree materials as kernel `Material`s, textures, mixes, what is ignored |
| socket_values | what a socket reads: a constant, or a texture with its node chain folded in |
| socket_fallback | sockets it cannot read, baked by Cycles over the object's UVs, cached  |
| tree_digest | a digest of a node tree (the fallback's cache key)                          |
| lights     | lights as kernel `Light`s                                                   |
| light_linking | lamps' light and shadow linking over the scene's objects                 |
| ray_visibility | objects' Cycles ray visibility: what the kernels honour, what is noted     |
| camera     | the camera as a kernel `Camera`, the render size                            |
| world      | the world shader: uniform colour, radiance map (read, or rendered by Cycles) |
| snapshot   | `snapshot`: the kernel `Scene` of the evaluated depsgraph                   |
| write_back | images and colour attributes written back, materials wired to show them     |
| normal_maps| normal-map images (Non-Color), UV charts of evaluated meshes, the Normal   |
|            | Map wiring of materials and its undo                                        |

This facade re-exports the public names for callers that use `bridge.<name>`; `bridge.snapshot`
is therefore the function (`from .bridge.snapshot import ...` reaches the module). No module of
this package imports the facade (or anything that does): they import each other's modules.
"""

from .camera import read_camera, render_resolution
from .images import flip_rows, image_pixels, srgb_to_linear, stored_srgb
from .lights import light_power, read_light
from .materials import DEFAULT_MATERIAL, DEFAULT_MATERIAL_NAME, MAX_SHADER_MIX_DEPTH, mix_materials
from .mesh import (
    ensure_lightmap_uv,
    generated_coordinates,
    lightmap_loop_uv,
    mesh_corner_normals,
    mesh_positions,
    mesh_triangles,
    mesh_uv,
    write_uv_layer,
)
from .request import SnapshotRequest
from .snapshot import snapshot
from .world import environment_mean, read_world, read_world_texture, world_mapping
from .write_back import (
    WIRING_TAG,
    pack_image,
    read_color_attribute,
    save_image_exr,
    unwire_baked_display,
    wire_baked_display,
    write_color_attribute,
    write_corner_values,
    write_image,
)

__all__ = [
    "DEFAULT_MATERIAL", "DEFAULT_MATERIAL_NAME", "MAX_SHADER_MIX_DEPTH", "SnapshotRequest",
    "WIRING_TAG", "ensure_lightmap_uv", "environment_mean", "flip_rows", "generated_coordinates",
    "image_pixels", "light_power", "lightmap_loop_uv", "mesh_corner_normals", "mesh_positions",
    "mesh_triangles", "mesh_uv", "mix_materials", "pack_image", "read_camera",
    "read_color_attribute", "read_light", "read_world", "read_world_texture", "render_resolution",
    "save_image_exr", "snapshot", "srgb_to_linear", "stored_srgb", "unwire_baked_display",
    "wire_baked_display", "world_mapping", "write_color_attribute", "write_corner_values",
    "write_image", "write_uv_layer",
]
