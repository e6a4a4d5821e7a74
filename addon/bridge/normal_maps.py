"""Normal maps into Blender (issue 40): the UV triangles of an object's evaluated mesh (the charts a
map covers), normal-map images written with `foreach_set` (float, Non-Color data), and the material
wiring Image Texture (Non-Color) -> Normal Map (tangent space, the map's UV layer) -> the Principled
BSDF's Normal, undone without loss by `unwire_normal_map`.

Non-destructive wiring: the nodes added carry the custom property `NORMAL_MAP_TAG`; the link each
BSDF's Normal had before (a Bump node's, say) is recorded in the material's custom property
`PREVIOUS_NORMAL_LINKS` (JSON: {BSDF node name: [source node name, output socket identifier]})
and the source node stays in the tree, unlinked. `unwire_normal_map(material)` removes the tagged
nodes and links the recorded sources back; in the interface one Ctrl+Z undoes the whole operator.
"""

from __future__ import annotations

import json
from contextlib import contextmanager
from dataclasses import replace

import bpy
import numpy as np

from ...kernels.normalmap.high_to_low import HighMesh, LowMesh
from . import write_back
from .images import flip_rows
from .materials import MaterialReader
from .mesh import (
    mesh_corner_normals,
    mesh_positions,
    mesh_triangles,
    mesh_uv,
    world_corner_normals,
)
from .nodes import follow
from .request import SnapshotRequest
from .tangents import loop_triangle_tangents, world_tangents
from .transforms import matrix_array

NORMAL_MAP_TAG = "classic_bake_normal_map"  # custom property on every node the wiring adds
PREVIOUS_NORMAL_LINKS = "classic_bake_previous_normal"  # material property: links replaced
NON_COLOR = "Non-Color"  # Blender's colour space name for data images (both 4.5 and 5.x)


def active_render_uv_name(mesh) -> str | None:
    """The name of the mesh's active render UV layer (None: it has no UV layer)."""
    layer = next((lay for lay in mesh.uv_layers if lay.active_render), None)
    return None if layer is None else layer.name


def object_uv_triangles(obj, depsgraph, uv_name: str | None):
    """The charts of `obj`'s evaluated mesh (modifiers applied) in UV layer `uv_name` (None: the
    active render layer): (uv (T, 3, 2) float64, world (T, 3, 3) float64 corner positions in
    metres, material slot (T,) int32, the layer's name), or None when the mesh lacks the layer.
    Nothing is written: the evaluated mesh is freed again."""
    with _evaluated_uv(obj, depsgraph, uv_name) as (mesh, loop_uv, name):
        if loop_uv is None:
            return None
        verts, loops, _, slots = mesh_triangles(mesh)
        matrix = matrix_array(obj.matrix_world)
        local = mesh_positions(mesh).astype(np.float64)
        world = local @ matrix[:3, :3].T + matrix[:3, 3]
        return (loop_uv[loops].astype(np.float64), world[verts], slots.copy(), name)


@contextmanager
def _evaluated_uv(obj, depsgraph, uv_name: str | None):
    """`obj`'s evaluated mesh (modifiers applied), its UV layer `uv_name` (None: the active
    render layer) as (L, 2) per corner and the layer's name: (mesh, None, name) when the mesh
    lacks the layer. The evaluated mesh is freed on leaving."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        name = uv_name or active_render_uv_name(mesh)
        yield mesh, (None if name is None else mesh_uv(mesh, name)), name
    finally:
        evaluated.to_mesh_clear()


def _world_corners(obj, mesh):
    """(world positions (T, 3, 3) float64 m, world unit corner normals (T, 3, 3) float64,
    corner loops (T, 3), material slots (T,), the corner order) of `obj`'s mesh, its triangles
    wound counter-clockwise in the world (re-wound where the object is mirrored)."""
    verts, loops, _, slots = mesh_triangles(mesh)
    matrix = matrix_array(obj.matrix_world)
    linear = matrix[:3, :3]
    order = [0, 2, 1] if np.linalg.det(linear) < 0.0 else [0, 1, 2]
    world = mesh_positions(mesh).astype(np.float64) @ linear.T + matrix[:3, 3]
    normals = world_corner_normals(mesh, matrix)
    return world[verts[:, order]], normals[loops[:, order]], loops[:, order], slots, order


def low_mesh(obj, depsgraph, uv_name: str | None) -> tuple[LowMesh, str] | None:
    """`obj`'s evaluated mesh as the low mesh of a high -> low bake: its UV layer `uv_name`
    (None: the active render layer) with the MikkTSpace frames on it, all in world space; and
    the layer's name. None when the mesh lacks the layer."""
    with _evaluated_uv(obj, depsgraph, uv_name) as (mesh, loop_uv, name):
        if loop_uv is None:
            return None
        _, tri_loops, tri_polys, _ = mesh_triangles(mesh)
        frames = loop_triangle_tangents(mesh, mesh_positions(mesh), mesh_corner_normals(mesh),
                                        loop_uv, tri_loops, tri_polys)
        world, normals, loops, _, order = _world_corners(obj, mesh)
        tangents, signs = world_tangents(frames[0][:, order], frames[1][:, order],
                                         matrix_array(obj.matrix_world))
        return LowMesh(uv=loop_uv[loops].astype(np.float64), positions=world, normals=normals,
                       tangents=tangents, signs=signs), name


def high_mesh(obj, depsgraph) -> HighMesh:
    """`obj`'s evaluated mesh (modifiers applied: a Subdivision Surface or Displace gives the
    detail) as the high mesh of a high -> low bake: world triangles and shading normals."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        world, normals, _, _, _ = _world_corners(obj, mesh)
        return HighMesh(triangles=world, normals=normals)
    finally:
        evaluated.to_mesh_clear()


def write_normal_image(name: str, rgb: np.ndarray, image=None):
    """Put a normal map's colours (H, W, 3) float32 in [0, 1] (row 0 top) into a float Blender
    image tagged Non-Color (no transfer curve on the way in or out), alpha 1. Reuses `image`
    (resized if needed) or creates a new image `name`. Returns the image."""
    rgb = np.asarray(rgb, np.float32)
    height, width = rgb.shape[:2]
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = rgb[..., :3]
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    # Before the size and the pixels: setting the colour space (even to the one it has) reloads a
    # generated image at its generated size, dropping its pixels.
    image.colorspace_settings.name = NON_COLOR
    if tuple(image.size) != (width, height):
        if image.source == "GENERATED":  # so that a reload keeps the new size
            image.generated_width, image.generated_height = width, height
        if tuple(image.size) != (width, height):
            image.scale(width, height)
    image.pixels.foreach_set(np.ascontiguousarray(flip_rows(rgba)).ravel())
    image.update()
    return image


def replaced_bump(mat):
    """The Bump node whose link into a BSDF's Normal `wire_normal_map` replaced in `mat` (it
    stays in the tree, unlinked), or None."""
    tree = mat.node_tree if mat is not None else None
    if tree is None:
        return None
    for source_name, _identifier in json.loads(mat.get(PREVIOUS_NORMAL_LINKS, "{}")).values():
        node = tree.nodes.get(source_name)
        if node is not None and node.type == "BUMP":
            return node
    return None


def material_before_wiring(mat, material):
    """The kernel `material` of a Blender material `mat` as it read before `wire_normal_map`
    replaced its Bump node: that node's height texture, Strength and Distance again (so a map is
    made from the material's own relief however often it is made). Unwired: `material` itself."""
    bump = replaced_bump(mat)
    if bump is None:
        return material
    node, _ = follow(bump.inputs["Height"])
    ignored: list[str] = []
    texture = (None if node is None else
               MaterialReader(SnapshotRequest())._texture(node, ignored, "Bump height", False))
    distance = float(bump.inputs["Distance"].default_value)
    return replace(material, normal_texture=None, height_texture=texture,
                   bump_strength=float(bump.inputs["Strength"].default_value),
                   bump_distance=-distance if bump.invert else distance)


def unwire_normal_map(mat) -> None:
    """Remove what `wire_normal_map` added to `mat` and link the recorded sources back into the
    BSDFs' Normal inputs."""
    tree = mat.node_tree
    if tree is None:
        return
    for node in [n for n in tree.nodes if n.get(NORMAL_MAP_TAG)]:
        tree.nodes.remove(node)
    previous = json.loads(mat.get(PREVIOUS_NORMAL_LINKS, "{}"))
    for bsdf_name, (source_name, identifier) in previous.items():
        bsdf, source = tree.nodes.get(bsdf_name), tree.nodes.get(source_name)
        if bsdf is None or source is None or bsdf.inputs["Normal"].is_linked:
            continue
        socket = next((s for s in source.outputs if s.identifier == identifier), None)
        if socket is not None:
            tree.links.new(socket, bsdf.inputs["Normal"])
    if PREVIOUS_NORMAL_LINKS in mat:
        del mat[PREVIOUS_NORMAL_LINKS]


def wire_normal_map(obj, image, uv_map: str, keep_bump: bool = False) -> tuple[list, list[str]]:
    """Wire `image` as a tangent-space normal map read through `uv_map` into every Principled
    BSDF of `obj`'s materials: Image Texture (Non-Color) -> Normal Map (TANGENT) -> Normal.

    The link each BSDF's Normal had is recorded and removed (the node it came from stays in the
    tree; `unwire_normal_map` restores it). With `keep_bump`, a Bump node that fed the Normal and
    has its own Normal input free keeps its place and takes the map there (both reliefs apply);
    otherwise it is disconnected (a map made from that Bump's height replaces it). Returns
    (materials wired, one reason per material not wired)."""
    wired, skipped = [], []
    for mat in write_back.materials_to_wire(obj, single_user=True, suffix="normal map"):
        unwire_normal_map(mat)  # wiring again replaces the previous wiring, losing nothing
        tree = mat.node_tree
        bsdfs = [n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"]
        if not bsdfs:
            skipped.append(f"{obj.name}: material '{mat.name}' has no Principled BSDF to take "
                           "the normal map")
            continue
        nodes, links = tree.nodes, tree.links
        x, y = bsdfs[0].location
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_map
        texture = nodes.new("ShaderNodeTexImage")
        texture.image = image
        texture.interpolation = "Linear"
        texture.extension = "REPEAT"  # as the height was read: UVs beyond [0, 1] tile the map
        normal_map = nodes.new("ShaderNodeNormalMap")
        normal_map.space = "TANGENT"
        normal_map.uv_map = uv_map
        links.new(uv.outputs["UV"], texture.inputs["Vector"])
        links.new(texture.outputs["Color"], normal_map.inputs["Color"])
        for node, dx in ((uv, -1000.0), (texture, -800.0), (normal_map, -450.0)):
            node[NORMAL_MAP_TAG] = True
            node.location = (x + dx, y - 650.0)
        previous = {}
        for bsdf in bsdfs:
            socket = bsdf.inputs["Normal"]
            if socket.is_linked:
                link = socket.links[0]
                source = link.from_node
                if (keep_bump and source.type == "BUMP"
                        and not source.inputs["Normal"].is_linked):
                    links.new(normal_map.outputs["Normal"], source.inputs["Normal"])
                    continue
                previous[bsdf.name] = [source.name, link.from_socket.identifier]
                links.remove(link)
            links.new(normal_map.outputs["Normal"], socket)
        mat[PREVIOUS_NORMAL_LINKS] = json.dumps(previous)
        wired.append(mat)
    return wired, skipped
