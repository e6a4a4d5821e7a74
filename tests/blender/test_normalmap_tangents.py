"""MikkTSpace tangents made by the kernels (kernels/normalmap/mikktspace.py) against Blender's own
`Mesh.calc_tangents`: every face corner's tangent within 1e-4 and its bitangent sign equal, on
meshes made here (UV sphere, cube with UV seams, mirrored UVs, a low-poly cylinder, Suzanne,
zero-area and random UVs, collapsed faces) and on every mesh of the sample scenes. Also the
lecture's frame against MikkTSpace: the angle between them per corner."""

from pathlib import Path

import bmesh
import bpy
import numpy as np
import pytest

from classic_bake.kernels.normalmap.lecture_frame import frame_angles, lecture_frames
from classic_bake.kernels.normalmap.mikktspace import bitangents, mikktspace_tangents

SAMPLES = Path(__file__).resolve().parents[2] / "sample_blends"
# Equal to float rounding: Blender's float32 arithmetic is followed step by step (measured: 0 on
# every mesh here); the issue asks for 1e-4.
TOLERANCE = 1e-4


def _get(collection, attribute, width, dtype=np.float32):
    out = np.empty(len(collection) * width, dtype)
    collection.foreach_get(attribute, out)
    return out.reshape(-1, width) if width > 1 else out


def mesh_arrays(mesh):
    """(positions, corner_verts, corner_normals, corner_uvs, face_starts, face_sizes) of the
    active UV map, as the bridge hands them to the kernels."""
    return (_get(mesh.vertices, "co", 3), _get(mesh.loops, "vertex_index", 1, np.int32),
            _get(mesh.corner_normals, "vector", 3), _get(mesh.uv_layers.active.uv, "vector", 2),
            _get(mesh.polygons, "loop_start", 1, np.int32),
            _get(mesh.polygons, "loop_total", 1, np.int32))


def blender_tangents(mesh):
    mesh.calc_tangents(uvmap=mesh.uv_layers.active.name)
    return _get(mesh.loops, "tangent", 3), _get(mesh.loops, "bitangent_sign", 1)


def triangulate_ngons(mesh):
    """calc_tangents takes triangles and quads only: split larger faces (caps, n-gons)."""
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bmesh.ops.triangulate(bm, faces=[f for f in bm.faces if len(f.verts) > 4])
    bm.to_mesh(mesh)
    bm.free()
    return mesh


def compare(mesh):
    arrays = mesh_arrays(mesh)
    tangents, signs = blender_tangents(mesh)
    ours = mikktspace_tangents(*arrays)
    difference = np.abs(ours.tangents - tangents).max(axis=1)
    assert difference.max() <= TOLERANCE, f"max tangent difference {difference.max():.3g}"
    assert np.array_equal(ours.signs, signs), f"{int((ours.signs != signs).sum())} signs differ"
    # b = sign (n x t), as Blender's loop.bitangent (what the Normal Map node uses).
    np.testing.assert_allclose(bitangents(arrays[2], ours), _get(mesh.loops, "bitangent", 3),
                               atol=TOLERANCE)
    return ours, arrays


def add(kind, smooth=True, **options):
    getattr(bpy.ops.mesh, f"primitive_{kind}_add")(**options)
    if smooth:
        bpy.ops.object.shade_smooth()
    return triangulate_ngons(bpy.context.object.data)


def set_uvs(mesh, uv):
    mesh.uv_layers.active.uv.foreach_set("vector", np.ascontiguousarray(uv, np.float32).ravel())


def uv_sphere():
    return add("uv_sphere", segments=32, ring_count=16)


def cube_with_seams():
    return add("cube", smooth=False)


def mirrored_plane():
    mesh = add("grid", smooth=False, x_subdivisions=8, y_subdivisions=8)
    uv = _get(mesh.uv_layers.active.uv, "vector", 2)
    uv[:, 0] = np.abs(uv[:, 0] - 0.5)  # u mirrored about the plane's middle
    set_uvs(mesh, uv)
    return mesh


def low_poly_cylinder():
    return add("cylinder", vertices=6, end_fill_type="TRIFAN")


def suzanne():
    return add("monkey")


def zero_area_uvs():
    mesh = add("uv_sphere", segments=12, ring_count=6)
    uv = _get(mesh.uv_layers.active.uv, "vector", 2)
    for face in list(mesh.polygons)[::3]:
        uv[face.loop_start:face.loop_start + face.loop_total] = uv[face.loop_start]
    set_uvs(mesh, uv)
    return mesh


def random_uvs():
    mesh = add("monkey", smooth=False)
    set_uvs(mesh, np.random.default_rng(0).random((len(mesh.loops), 2)))
    return mesh


def collapsed_faces():
    mesh = add("grid", smooth=False, x_subdivisions=4, y_subdivisions=4)
    mesh.vertices[6].co = mesh.vertices[7].co.copy()  # quads with two corners at one point
    mesh.vertices[12].co = mesh.vertices[18].co.copy()
    mesh.update()
    return mesh


@pytest.mark.parametrize("build", [uv_sphere, cube_with_seams, mirrored_plane, low_poly_cylinder,
                                   suzanne, zero_area_uvs, random_uvs, collapsed_faces],
                         ids=lambda f: f.__name__)
def test_tangents_equal_calc_tangents(build):
    mesh = build()
    ours, arrays = compare(mesh)
    assert np.all(np.isfinite(ours.tangents))
    if build is mirrored_plane:
        assert (ours.signs < 0).any() and (ours.signs > 0).any()
    if build is zero_area_uvs:
        assert ours.groupless_triangles > 0 and ours.unassigned_corners > 0
    if build is collapsed_faces:
        assert ours.degenerate_triangles > 0


def sample_meshes():
    return sorted(p.stem for p in SAMPLES.glob("*.blend"))


@pytest.mark.parametrize("scene", sample_meshes())
def test_tangents_equal_calc_tangents_on_the_sample_scenes(open_sample, scene):
    open_sample(scene)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    compared = 0
    for obj in list(bpy.data.objects):
        if obj.type != "MESH" or not obj.data.uv_layers:
            continue
        mesh = triangulate_ngons(bpy.data.meshes.new_from_object(obj.evaluated_get(depsgraph)))
        for layer in mesh.uv_layers:
            mesh.uv_layers.active = layer
            compare(mesh)
            compared += 1
    assert compared > 0


def test_lecture_frame_against_mikktspace():
    """The angle between the lecture's per-triangle frame and MikkTSpace's: nil on a plane,
    degrees on a low-poly curved mesh (the chart's data)."""
    plane = add("grid", smooth=False, x_subdivisions=3, y_subdivisions=3)
    arrays = mesh_arrays(plane)
    mikk = mikktspace_tangents(*arrays)
    lecture = lecture_frames(*arrays)
    assert frame_angles(arrays[2], mikk.tangents, mikk.signs, lecture.tangents,
                        lecture.signs).max() < 1e-3
    for mesh in (low_poly_cylinder(), suzanne()):
        arrays = mesh_arrays(mesh)
        mikk = mikktspace_tangents(*arrays)
        lecture = lecture_frames(*arrays)
        angle = frame_angles(arrays[2], mikk.tangents, mikk.signs, lecture.tangents, lecture.signs)
        assert np.all(np.isfinite(angle)) and angle.max() > 0.1
