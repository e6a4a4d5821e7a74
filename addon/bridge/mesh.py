"""Mesh geometry as arrays: positions, loop triangles, corner normals, UVs and Generated
coordinates through `foreach_get`, and one evaluated mesh instance as a `MeshChunk` in world space;
lightmap UV layers made with xatlas (`kernels.bake.lightmap_uv.unwrap`) and written with
`foreach_set`.

Mirrored objects (negative determinant) get corners 1 and 2 swapped, so that every kernel
triangle winds counter-clockwise around the normal Blender shades with.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .attributes import attribute_names, corner_attribute
from .tangents import (
    loop_triangle_tangents,
    normal_map_layer,
    normal_texture_layer,
    world_tangents,
)
from .transforms import matrix_array

# An object whose triangles together cover no more than this is skipped as having no area (scale
# 0, or every face collapsed): it covers no texel, and xatlas charts nothing of it. 1 um^2.
ZERO_AREA_M2 = 1e-12
# Farther out than this from the origin a vertex is taken as broken: Blender stores an inf
# coordinate as FLT_MAX (3.4e38), float32 keeps ~100 m of precision at 1e9 m, and xatlas loops for
# minutes on such input. A million kilometres.
MAX_COORDINATE_M = 1e9


@dataclass
class MeshChunk:
    """One evaluated mesh (an object or an instance) in world space, per triangle corner; the
    snapshot stacks the chunks into the kernel `Scene`. slot_ids hold material slots until the
    snapshot maps them to its material table."""

    name: str
    source_name: str
    is_instance: bool
    triangles: np.ndarray  # (T, 3, 3) float32, world
    normals: np.ndarray | None  # (T, 3, 3) float32, world, unit
    uv: np.ndarray | None  # (T, 3, 2) float32
    lightmap_uv: np.ndarray | None  # (T, 3, 2) float32
    generated: np.ndarray | None  # (T, 3, 3) float32 Generated texture coordinates
    slot_ids: np.ndarray  # (T,) int32 material slot per triangle
    corner_loops: np.ndarray  # (T, 3) int32
    corner_verts: np.ndarray  # (T, 3) int32
    slot_materials: list = field(default_factory=list)
    topology_matches_original: bool = True
    # MikkTSpace frames on the UV layer the materials' Normal Map nodes read (None: no node).
    tangents: np.ndarray | None = None  # (T, 3, 3) float32, world, unit
    tangent_signs: np.ndarray | None = None  # (T, 3) float32, +1 or -1: b = sign (n x t)
    # UVs the normal-map image is looked up on where that is not the active render layer (a UV
    # Map node into its Image Texture naming another layer); None: `uv`.
    normal_map_uv: np.ndarray | None = None  # (T, 3, 2) float32
    # The attributes the slot materials' Color Attribute and Attribute nodes name, per corner:
    # name -> (T, 3, 3) float32 linear, or None where the mesh lacks it (`attributes.py`).
    attributes: dict = field(default_factory=dict)
    # (T, 3, 3) float32: per triangle, the attribute its material reads (set by the snapshot
    # once materials are read); None: no material reads one.
    colors: np.ndarray | None = None
    # The ray kinds Cycles hides the object from (`snapshot.hidden_from`), set by the snapshot.
    hidden_from: tuple = ()


def mesh_triangles(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(corner_verts (T, 3), corner_loops (T, 3), polygon (T,), material slot (T,)) of a mesh, int32."""
    tris = mesh.loop_triangles
    count = len(tris)
    verts = np.empty(count * 3, np.int32)
    loops = np.empty(count * 3, np.int32)
    polys = np.empty(count, np.int32)
    slots = np.empty(count, np.int32)
    tris.foreach_get("vertices", verts)
    tris.foreach_get("loops", loops)
    tris.foreach_get("polygon_index", polys)
    tris.foreach_get("material_index", slots)
    return verts.reshape(-1, 3), loops.reshape(-1, 3), polys, slots


def mesh_positions(mesh) -> np.ndarray:
    """Vertex positions (V, 3) float32, object space."""
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def mesh_corner_normals(mesh) -> np.ndarray:
    """Corner (loop) normals (L, 3) float32, object space, with custom and sharp normals honoured."""
    normals = np.empty(len(mesh.loops) * 3, np.float32)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        mesh.corner_normals.foreach_get("vector", normals)
    else:  # pragma: no cover - older than the manifest allows
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", normals)
    return normals.reshape(-1, 3)


def mesh_uv(mesh, name: str | None) -> np.ndarray | None:
    """Per-loop UVs (L, 2) float32 of layer `name` (None: the active render layer), or None."""
    layers = mesh.uv_layers
    if name is None:
        layer = next((lay for lay in layers if lay.active_render), None)
    else:
        layer = layers.get(name)
    if layer is None:
        return None
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    layer.uv.foreach_get("vector", uv)
    return uv.reshape(-1, 2)


def coordinates_problem(points: np.ndarray) -> str | None:
    """Why world-space points (..., 3), m, are unusable (nan, inf, or beyond MAX_COORDINATE_M),
    or None."""
    if not np.isfinite(points).all():
        return "has non-finite vertex coordinates (nan or inf)"
    largest = float(np.abs(points).max()) if points.size else 0.0
    if largest > MAX_COORDINATE_M:
        return (f"has vertex coordinates out of range ({largest:.3g} m from the origin, beyond "
                f"{MAX_COORDINATE_M:.0e} m: an infinite coordinate in the file?)")
    return None


def triangles_problem(corners: np.ndarray) -> str | None:
    """Why triangles (T, 3, 3) world space, m, cannot be baked or traced, or None: no faces,
    a nan or inf coordinate (xatlas would loop for minutes; the BVH would be meaningless),
    coordinates too large to square, or no area at all."""
    if corners.shape[0] == 0:
        return "has no faces"
    why = coordinates_problem(corners)
    if why is not None:
        return why
    c = corners.astype(np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1).sum()
    if area <= ZERO_AREA_M2:
        return f"has no surface area ({area:.3g} m^2: scale 0 or every face collapsed)"
    return None


def object_problem(obj) -> str | None:
    """Why mesh object `obj` (its own mesh in world space, modifiers not applied) cannot be given
    lightmap UVs or baked, or None (`triangles_problem`)."""
    verts, _, _, _ = mesh_triangles(obj.data)
    matrix = matrix_array(obj.matrix_world)
    with np.errstate(over="ignore", invalid="ignore"):
        world = (mesh_positions(obj.data).astype(np.float64) @ matrix[:3, :3].T
                 + matrix[:3, 3]).astype(np.float32)
    return triangles_problem(world[verts])


def generated_coordinates(positions: np.ndarray, texspace) -> np.ndarray:
    """(V, 3) float64 Blender's Generated texture coordinates of object-space positions (V, 3):
    the texture space of `texspace` (a mesh: centre +- size, its bounding box when automatic)
    mapped to the unit cube, as Cycles reads them (its "orco" coordinates; the evaluated
    positions stand for the undeformed ones, which differ only under deforming modifiers)."""
    centre = np.array(texspace.texspace_location, np.float64)
    size = np.array(texspace.texspace_size, np.float64)
    size = np.where(size != 0.0, size, 1.0)
    return (positions - (centre - size)) / (2.0 * size)


def world_corner_normals(mesh, matrix: np.ndarray) -> np.ndarray:
    """(L, 3) float64 unit world normals of `mesh`'s face corners placed by `matrix` (4, 4).
    Normals transform with the inverse transpose; a zero-scale axis leaves them as they are, and
    a zero normal stays zero."""
    linear = matrix[:3, :3]
    try:
        normal_matrix = np.linalg.inv(linear).T
    except np.linalg.LinAlgError:
        normal_matrix = np.eye(3)
    loop_n = mesh_corner_normals(mesh).astype(np.float64) @ normal_matrix.T
    length = np.linalg.norm(loop_n, axis=1, keepdims=True)
    return np.divide(loop_n, length, out=np.zeros_like(loop_n), where=length > 0)


def mesh_chunk(
    name, source_name, is_instance, mesh, matrix, request, original_mesh, slot_materials,
    texspace=None,
) -> MeshChunk:
    """`mesh` placed by `matrix` (4, 4) as a `MeshChunk`, reading what `request` asks for.
    original_mesh: the object's own mesh (None for instances), compared to tell whether modifiers
    changed the topology; texspace: the mesh whose texture space gives Generated coordinates."""
    corner_verts, corner_loops, polys, slots = mesh_triangles(mesh)
    local = mesh_positions(mesh).astype(np.float64)
    world = local @ matrix[:3, :3].T + matrix[:3, 3]
    mirrored = np.linalg.det(matrix[:3, :3]) < 0.0
    order = [0, 2, 1] if mirrored else [0, 1, 2]
    loop_triangles = corner_loops  # Blender's own corner order (the tangent frames read it)
    corner_verts = corner_verts[:, order]
    corner_loops = corner_loops[:, order]
    triangles = world[corner_verts].astype(np.float32)

    normals = None
    if request.normals:
        normals = world_corner_normals(mesh, matrix)[corner_loops].astype(np.float32)

    uv = None
    generated = None
    if request.uv:
        loop_uv = mesh_uv(mesh, None)
        uv = None if loop_uv is None else loop_uv[corner_loops]
        # Texture space: the original mesh's (Cycles' orco), else this one's.
        generated = generated_coordinates(local, texspace or mesh)[corner_verts].astype(np.float32)
    tangents = signs = None
    layer = normal_map_layer(slot_materials, mesh) if request.normals and request.uv else None
    if layer is not None:  # the frames the Normal Map node reads the map in
        frames = loop_triangle_tangents(mesh, mesh_positions(mesh), mesh_corner_normals(mesh),
                                        mesh_uv(mesh, layer), loop_triangles, polys)
        tangents, signs = world_tangents(frames[0][:, order], frames[1][:, order], matrix)
    normal_map_uv = None
    texture_layer = normal_texture_layer(slot_materials, mesh) if layer is not None else None
    if texture_layer is not None and not mesh.uv_layers[texture_layer].active_render:
        normal_map_uv = mesh_uv(mesh, texture_layer)[corner_loops]
    lightmap_uv = None
    if request.lightmap_uv:
        loop_uv = mesh_uv(mesh, request.lightmap_uv)
        lightmap_uv = None if loop_uv is None else loop_uv[corner_loops]

    attributes = {}
    if request.materials and request.textures:
        attributes = {name: corner_attribute(mesh, name, corner_loops, corner_verts, polys)
                      for name in attribute_names(slot_materials)}
    matches = original_mesh is not None and (
        len(original_mesh.loops) == len(mesh.loops)
        and len(original_mesh.vertices) == len(mesh.vertices)
    )
    return MeshChunk(
        name=name,
        source_name=source_name,
        is_instance=is_instance,
        triangles=triangles,
        normals=normals,
        uv=uv,
        lightmap_uv=lightmap_uv,
        generated=generated,
        slot_ids=slots,
        corner_loops=corner_loops,
        corner_verts=corner_verts,
        slot_materials=slot_materials,
        topology_matches_original=matches,
        tangents=tangents,
        tangent_signs=signs,
        normal_map_uv=normal_map_uv,
        attributes=attributes,
    )


def write_uv_layer(mesh, name: str, loop_uv: np.ndarray):
    """Create UV layer `name` on `mesh` with per-loop UVs (L, 2); existing layers stay untouched.

    Raises ValueError if a layer of that name exists (never overwritten) or the mesh has no room.
    The active and active-render layers are kept as they were.
    """
    if mesh.uv_layers.get(name) is not None:
        raise ValueError(f"mesh '{mesh.name}' already has a UV layer '{name}'")
    active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
    render = next((lay.name for lay in mesh.uv_layers if lay.active_render), None)
    layer = mesh.uv_layers.new(name=name, do_init=False)
    if layer is None:
        raise ValueError(f"mesh '{mesh.name}' cannot take another UV layer (Blender allows 8)")
    layer.uv.foreach_set("vector", np.ascontiguousarray(loop_uv, np.float32).ravel())
    if active is not None:
        mesh.uv_layers.active = mesh.uv_layers[active]
    if render is not None:
        mesh.uv_layers[render].active_render = True
    mesh.update()
    return mesh.uv_layers[name]


def lightmap_loop_uv(obj, settings, largest: int | None = None) -> tuple[np.ndarray, dict]:
    """Unwrap `obj`'s original mesh with xatlas: per-loop lightmap UVs (L, 2) and a summary
    (charts, utilization, split_polygons, resolution: the texels per side that held the charts,
    up to `largest` where `settings.resolution` could not: `lightmap_uv.unwrap`).

    Texel density follows world-space size (the object's scale applied), so charts of one object
    get the same density. Each polygon is kept in one chart (`unwrap`'s `polygons`); one whose
    triangles still disagree on a loop's UV (none should) is counted in the summary
    (`split_polygons`), the last triangle's UV winning.
    """
    from ...kernels.bake.lightmap_uv import unwrap

    mesh = obj.data
    corner_verts, corner_loops, polys, _ = mesh_triangles(mesh)
    matrix = matrix_array(obj.matrix_world)
    with np.errstate(over="ignore", invalid="ignore"):
        world = mesh_positions(mesh).astype(np.float64) @ matrix[:3, :3].T
    why = coordinates_problem(world)
    if why is not None:  # never handed to xatlas, which loops on them
        raise ValueError(f"object '{obj.name}' {why}")
    try:
        result = unwrap(world, corner_verts, settings, polys, largest)
    except ValueError as exc:
        raise type(exc)(f"object '{obj.name}': {exc}") from exc  # UnwrapCrash stays one
    loop_uv = np.zeros((len(mesh.loops), 2), np.float32)
    flat_loops = corner_loops.ravel()
    flat_uv = result.corner_uv.reshape(-1, 2)
    loop_uv[flat_loops] = flat_uv
    # A loop written by several triangles must have received the same UV from each.
    disagree = np.any(np.abs(loop_uv[flat_loops] - flat_uv) > 0, axis=1).reshape(-1, 3).any(1)
    summary = {"charts": result.chart_count, "utilization": result.utilization,
               "split_polygons": int(np.unique(polys[disagree]).size),
               "resolution": result.resolution or settings.resolution}
    return loop_uv, summary


def ensure_lightmap_uv(obj, name: str, settings, largest: int | None = None
                       ) -> tuple[bool, dict]:
    """Give `obj`'s mesh a lightmap UV layer `name` unless it has one (`lightmap_loop_uv`, its
    `largest`). Returns (created, summary)."""
    if obj.type != "MESH":
        raise ValueError(f"object '{obj.name}' is a {obj.type}, not a mesh: no lightmap UVs")
    if obj.data.uv_layers.get(name) is not None:
        return False, {}
    loop_uv, summary = lightmap_loop_uv(obj, settings, largest)
    write_uv_layer(obj.data, name, loop_uv)
    return True, summary
