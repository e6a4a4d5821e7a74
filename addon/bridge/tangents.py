"""MikkTSpace tangent frames of a Blender mesh, per triangle corner, in world space.

The frames a tangent-space normal map is read in (Blender's Normal Map node, Cycles, EEVEE) and
made in (a bake): `kernels/normalmap/mikktspace.py` computes them as `Mesh.calc_tangents` does,
from the mesh's positions, corner normals and a UV layer. `calc_tangents` refuses faces of more
than four corners; here such a face is split into its loop triangles first (Blender's own
triangulation of it), the rest of the mesh is taken as it is.

World space: a tangent is a direction along the surface, so it moves with the object's linear
map and is normalised again (object-space frames are unit; their interpolation is what the
Normal Map node uses, so the world frames must be unit too). A mirroring transform (negative
determinant) turns n x t round, so the bitangent sign flips with it: b stays where the object's
own b was taken.
"""

from __future__ import annotations

import numpy as np

from ...kernels.normalmap.mikktspace import mikktspace_tangents
from .nodes import follow, tree_nodes

# Faces with more corners than this are split into their loop triangles (MikkTSpace's limit).
MIKKTSPACE_MAX_CORNERS = 4
MIN_LENGTH = 1e-12


def mesh_faces(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(corner verts (L,), face starts (F,), face sizes (F,)) int64 of a mesh."""
    corner_verts = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", corner_verts)
    starts = np.empty(len(mesh.polygons), np.int32)
    sizes = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    mesh.polygons.foreach_get("loop_total", sizes)
    return corner_verts.astype(np.int64), starts.astype(np.int64), sizes.astype(np.int64)


def loop_triangle_tangents(mesh, positions: np.ndarray, corner_normals: np.ndarray,
                           loop_uv: np.ndarray, tri_loops: np.ndarray, tri_polys: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """(tangents (T, 3, 3) float32 unit, signs (T, 3) float32) object space, per corner of a
    mesh's loop triangles, from its positions (V, 3), corner normals (L, 3) and a UV layer
    (L, 2); tri_loops (T, 3) and tri_polys (T,) as `mesh.mesh_triangles` reads them."""
    corner_verts, starts, sizes = mesh_faces(mesh)
    normals = np.asarray(corner_normals)
    big = sizes > MIKKTSPACE_MAX_CORNERS
    index = np.asarray(tri_loops, np.int64).copy()  # (T, 3) rows of the frames below
    if big.any():
        split = np.flatnonzero(big[tri_polys])  # loop triangles of the large faces
        extra = index[split].reshape(-1)  # their corners, appended
        count = len(corner_verts)
        corner_verts = np.concatenate([corner_verts, corner_verts[extra]])
        normals = np.concatenate([normals, normals[extra]])
        loop_uv = np.concatenate([loop_uv, loop_uv[extra]])
        starts = np.concatenate([starts[~big], count + 3 * np.arange(len(split))])
        sizes = np.concatenate([sizes[~big], np.full(len(split), 3)])
        index[split] = count + np.arange(3 * len(split)).reshape(-1, 3)
    frames = mikktspace_tangents(positions, corner_verts, normals, loop_uv, starts, sizes)
    return frames.tangents[index], frames.signs[index]


def world_tangents(tangents: np.ndarray, signs: np.ndarray, matrix: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Object-space corner frames (..., 3), (...) moved into world space by `matrix` (4, 4):
    (unit tangents float32, signs float32, flipped when the matrix mirrors)."""
    linear = np.asarray(matrix, np.float64)[:3, :3]
    t = np.asarray(tangents, np.float64) @ linear.T
    length = np.linalg.norm(t, axis=-1, keepdims=True)
    t = np.divide(t, length, out=np.zeros_like(t), where=length > MIN_LENGTH)
    mirror = -1.0 if np.linalg.det(linear) < 0.0 else 1.0
    return t.astype(np.float32), (np.asarray(signs, np.float32) * mirror).astype(np.float32)


def _tangent_normal_maps(materials):
    """The tangent-space Normal Map nodes of `materials` (Blender materials, None for empty
    slots), in slot and node order, those inside node groups where their Group node stands."""
    for mat in materials:
        tree = getattr(mat, "node_tree", None)
        if tree is not None:
            yield from (node for node in tree_nodes(tree)
                        if node.type == "NORMAL_MAP" and node.space == "TANGENT")


def _render_layer(mesh) -> str | None:
    return next((lay.name for lay in mesh.uv_layers if lay.active_render), None)


def normal_texture_layer(materials, mesh) -> str | None:
    """The UV layer the image feeding the first tangent-space Normal Map node of `materials` is
    looked up on, on `mesh`: the layer a UV Map node into the Image Texture's Vector names
    (through a Mapping node too), else the active render layer (an unlinked Vector, a UV Map node
    naming no layer or one the mesh lacks: Blender's default UVs). None: no such node, or the
    mesh has no UV layer."""
    for node in _tangent_normal_maps(materials):
        texture, _ = follow(node.inputs["Color"])
        vector = None
        if texture is not None and texture.type == "TEX_IMAGE":
            vector, _ = follow(texture.inputs["Vector"])
            if vector is not None and vector.type == "MAPPING":
                vector, _ = follow(vector.inputs["Vector"])
        if (vector is not None and vector.type == "UVMAP" and vector.uv_map
                and mesh.uv_layers.get(vector.uv_map) is not None):
            return vector.uv_map
        return _render_layer(mesh)
    return None


def normal_map_layer(materials, mesh) -> str | None:
    """The UV layer the first tangent-space Normal Map node of `materials` (Blender materials,
    None for empty slots) reads on `mesh`: its UV Map, or the active render layer when that is
    empty or not on the mesh. None: no material has such a node, or the mesh no UV layer."""
    for node in _tangent_normal_maps(materials):
        if node.uv_map and mesh.uv_layers.get(node.uv_map) is not None:
            return node.uv_map
        return _render_layer(mesh)
    return None
